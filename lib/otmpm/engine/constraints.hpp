#pragma once
/// \file constraints.hpp
/// Constraints on node velocities (docs/theory.md sect. 6):
///  - Dirichlet sets: listed node components are held at a prescribed
///    velocity; their force components are removed from the nodal forces and
///    kept as reactions, whose impulse and work enter the energy balance;
///  - rigid walls: a node may not approach a wall faster than it can reach
///    the wall's plane within the step (a node on or behind the plane not at
///    all); the normal velocity removed is the wall's impulse, and Coulomb
///    friction reduces the tangential velocity relative to the wall by
///    friction x the normal velocity removed (not below zero). A node the
///    wall holds stays held - both ways in the velocity fields that only
///    drive the stress update - until the wall would have to pull it, so
///    contact ends when the body's own force takes it off the wall.
#include "otmpm/core.hpp"

#include <array>
#include <string>
#include <vector>

namespace otmpm {

/// A Dirichlet set: node ids and, per entry, which components are fixed and
/// their prescribed velocity (a node may appear in several entries).
template <int D> struct Dirichlet {
  std::vector<int> node;
  std::vector<std::array<bool, 3>> fix;
  std::vector<std::array<double, 3>> value;
};

/// A rigid wall: the plane through `point` (at t = 0) with unit `normal`
/// pointing to the side the material is on, moving at `velocity`, with
/// Coulomb `friction` (0: frictionless).
template <int D> struct Wall {
  std::string name;
  Vec<D> point = Vec<D>::Zero();
  Vec<D> normal = Vec<D>::Zero();
  Vec<D> velocity = Vec<D>::Zero();
  double friction = 0.0;
};

/// How a wall's change dv_I of a nodal velocity-like field v = v0 + c rate
/// reaches the particles: their velocity update reads `rate`, which gets
/// rate_I += dv_I / c; `impulse`: the change is the body's (the wall force
/// counts it) - not for a predictor that only drives the stress update.
/// `hold_rate`: a node held earlier in the step is held by zeroing the
/// normal part of its rate (relative to the wall) instead of setting its
/// velocity - as a Dirichlet set zeroes its force components (npc's
/// corrector, whose predictor the walls already held).
template <int D> struct WallEffect {
  AlignedVector<Vec<D>>* rate = nullptr;
  double c = 0.0;
  bool impulse = true;
  bool hold_rate = false;
};

/// The nodes a velocity constraint acts on: positions, lumped masses, active flags.
template <int D> struct NodeView {
  const AlignedVector<Vec<D>>& x;
  const std::vector<double>& m;
  const std::vector<char>& active;
};

/// The constraints of a run with the bookkeeping derived from them.
template <int D> class Constraints {
public:
  Constraints() = default;
  /// std::invalid_argument unless every node id lies in [0, nodes) and the
  /// prescribed values are finite.
  Constraints(Dirichlet<D> dirichlet, std::vector<Wall<D>> walls, int nodes);

  const Dirichlet<D>& dirichlet() const { return d_; }
  /// constrained()[I * D + k]: component k of node I is fixed.
  const std::vector<char>& constrained() const { return constrained_; }
  /// Sets the fixed components of a nodal velocity-like field to their value.
  void apply_velocity(AlignedVector<Vec<D>>& v) const;
  /// Sets the fixed components of a nodal rate field (an acceleration) to zero.
  void zero_fixed(AlignedVector<Vec<D>>& r) const;
  /// Moves the fixed components of f into `reaction` (zeroing them in f),
  /// adds their impulse dt R to `impulse` and their work dt R . v_prescribed
  /// to `work`.
  void apply_force(AlignedVector<Vec<D>>& f, AlignedVector<Vec<D>>& reaction, double dt, Vec<D>& impulse,
                   double& work) const;
  /// sum over fixed components of 1/2 m_I v_prescribed^2 (zero for fixed supports).
  double prescribed_kinetic_energy(const std::vector<double>& m) const;

  const std::vector<Wall<D>>& walls() const { return walls_; }
  /// Applies the walls at time t to the nodal velocities v of a step dt:
  /// with d_I the distance of node I from the wall plane (positive on the
  /// material side) and u = v_I - v_wall, the normal part u.n is raised to
  /// -max(d_I, 0) / dt when below it, and friction reduces the tangential
  /// part. The change reaches the particles as `effect` says; its impulse
  /// (m_I dv_I summed per wall) and its work (impulse . v_wall) are added
  /// to wall_impulse() and `work`.
  void apply_walls(AlignedVector<Vec<D>>& v, const NodeView<D>& nodes, double t, double dt,
                   const WallEffect<D>& effect, double& work);
  /// The same rule for node increments dx of the step (positions after it:
  /// x_I + dx_I): the normal increment relative to the wall is raised to
  /// -max(d_I, 0); no impulse is counted.
  void apply_walls_to_increment(AlignedVector<Vec<D>>& dx, const NodeView<D>& nodes, double t, double dt) const;
  /// Per wall and node: the node is held by the wall (state carried from
  /// step to step).
  std::vector<std::vector<char>>& held() { return held_; }
  const std::vector<std::vector<char>>& held() const { return held_; }
  /// The impulse each wall gave the body since t = 0 (sum of m_I dv_I).
  const AlignedVector<Vec<D>>& wall_impulse() const { return impulse_; }
  AlignedVector<Vec<D>>& wall_impulse() { return impulse_; }

private:
  Dirichlet<D> d_;
  std::vector<Wall<D>> walls_;
  AlignedVector<Vec<D>> impulse_; ///< per wall
  std::vector<std::vector<char>> held_; ///< per wall and node: held by the wall
  std::vector<int> nodes_;       ///< the distinct nodes of d_.node, ascending
  std::vector<char> constrained_;
};

extern template class Constraints<1>;
extern template class Constraints<2>;
extern template class Constraints<3>;

} // namespace otmpm
