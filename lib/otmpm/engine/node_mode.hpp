#pragma once
/// \file node_mode.hpp
/// The one place where the two node modes differ (docs/theory.md
/// sect. 3). `mpm`: the nodes are a fixed Eulerian grid; particles must
/// stay inside it. `ul`: the nodes discretise the material and are advected
/// with the increment that moves the particles (x_I += dx_I); the time step
/// follows their current spacing. Everything else - basis table, transfers,
/// integrators - is shared.
#include "otmpm/basis/basis.hpp"

#include <limits>
#include <string>

namespace otmpm {

template <int D> class NodeMode {
public:
  /// `mpm`: nodes fixed; particles must stay inside the open box (lower, upper).
  static NodeMode fixed_grid(const Vec<D>& lower, const Vec<D>& upper);
  /// `ul`: nodes advected with the material.
  static NodeMode advected();

  bool nodes_move() const { return advected_; }
  /// "mpm" or "ul".
  const char* name() const { return advected_ ? "ul" : "mpm"; }
  /// x_I += dx_I (and the family's own advection, e.g. of B-spline knots) in
  /// `ul`; nothing on the fixed grid.
  void advect(Basis<D>& basis, const AlignedVector<Vec<D>>& dx) const;
  /// The nodal spacing h of the CFL condition: h0 on the fixed grid; in `ul`
  /// h0 scaled by how much the smallest node spacing changed since the start
  /// (`spacing0`) for the families whose stencils are cells of the lattice,
  /// and by `gradient_ratio` (the largest |grad N_Ip| of the first basis
  /// table over that of the last one) for the families that search their
  /// support (max-ent): their nodes may approach and pass each other without
  /// the basis' gradients - hence the stiffness - growing (docs/theory.md
  /// sect. 10).
  double cfl_spacing(const Basis<D>& basis, double h0, double spacing0, double gradient_ratio) const;
  /// True unless, on the fixed grid, a particle at x moving at v left the
  /// grid or would leave it in a step dt (always true in `ul`). Inline and
  /// without a branch per particle: it runs for every particle after every
  /// step.
  bool keeps_inside(const Vec<D>& x, const Vec<D>& v, double dt) const {
    if (advected_) return true;
    bool in = grid_.contains(x);
    in &= grid_.contains(Vec<D>(x + dt * v));
    return in;
  }
  /// keeps_inside for every particle of [p0, p1) of the finite positions x
  /// and velocities v (a non-finite one may pass: finite_state tests those):
  /// the smallest and largest coordinates of x and x + dt v, taken with
  /// vector operations over the particles, lie strictly inside the box - for
  /// finite values keeps_inside's answer.
  bool keep_inside(const Vec<D>* x, const Vec<D>* v, int p0, int p1, double dt) const {
    if (advected_) return true;
    constexpr double inf = std::numeric_limits<double>::infinity();
    Vec<D> least = Vec<D>::Constant(inf), most = Vec<D>::Constant(-inf);
    for (int p = p0; p < p1; ++p) {
      const Vec<D> y = x[p] + dt * v[p];
      least = least.cwiseMin(x[p]).cwiseMin(y);
      most = most.cwiseMax(x[p]).cwiseMax(y);
    }
    return (least.array() > grid_.lo.array()).all() && (most.array() < grid_.hi.array()).all();
  }
  /// Why keeps_inside(x, v, dt) is false, for the diagnosis.
  std::string leaving(const Vec<D>& x, const Vec<D>& v) const;

private:
  bool advected_ = false;
  PositionBox<D> grid_; ///< the fixed grid's open box (mpm)
};

extern template class NodeMode<1>;
extern template class NodeMode<2>;
extern template class NodeMode<3>;

} // namespace otmpm
