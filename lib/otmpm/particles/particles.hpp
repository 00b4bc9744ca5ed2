#pragma once
/// \file particles.hpp
/// Particle (material point) storage: contiguous per-field arrays of
/// fixed-size Eigen types (design.md point 5). Fields follow the notation of
/// spec algorithms.md: x_p, v_p, a_p, m_p, V_p, V0_p, rho_p, F_p, eps_p, sigma_p.
#include "otmpm/core.hpp"

namespace otmpm {

struct Scene;
template <int D> struct CartesianGrid;

/// All particles of a run. `X` is the initial position (the material
/// coordinate used by exact solutions), `x_prev` the previous position used
/// by the OTM velocity (only filled for `otm`), `F` only when a finite-strain
/// model or the `ul` mode needs it (has_F), `lambda` the LME warm start.
/// Optional fields are empty when the run does not use them (a: NPC;
/// lambda: LME/max-ent; cell_hint: element walk and B-splines; length0:
/// tractions); see Engine::allocate_fields.
template <int D> struct Particles {
  AlignedVector<Vec<D>> x, X, v, a, x_prev;
  std::vector<double> m, V, V0, rho;
  AlignedVector<Mat<D>> F, eps, sigma;
  AlignedVector<Vec<D>> lambda;
  std::vector<Index<D>> cell_hint;
  /// Initial particle length per axis (cell size / particles per cell), used
  /// for traction areas A_p = V0_p / l_p[axis] and uGIMP.
  AlignedVector<Vec<D>> length0;
  std::vector<int> material;
  std::vector<int> body;
  bool has_F = false;

  int size() const { return static_cast<int>(x.size()); }
  /// Resizes the fields every run uses to n particles (all zero) and empties
  /// the optional ones (a, F, lambda, cell_hint, x_prev); std::invalid_argument
  /// for n < 0.
  void resize(int n);
  /// Allocates the optional fields a run needs (a = 0, F = I, lambda = 0,
  /// cell_hint = 0), so that a scene pays memory only for what it reads.
  void allocate_optional(bool with_a, bool with_F, bool with_lambda, bool with_cell_hint);

  /// Calls f(name, field) for every per-particle array above, named as its
  /// member, so that code handling all fields (the checkpoint) lists them
  /// here only. A field added to Particles must be added here too.
  template <class F> void for_each_field(F&& f) { visit_fields(*this, f); }
  template <class F> void for_each_field(F&& f) const { visit_fields(*this, f); }

private:
  template <class Self, class F> static void visit_fields(Self& s, F& f) {
    f("x", s.x); f("X", s.X); f("v", s.v); f("a", s.a); f("x_prev", s.x_prev);
    f("m", s.m); f("V", s.V); f("V0", s.V0); f("rho", s.rho);
    f("F", s.F); f("eps", s.eps); f("sigma", s.sigma);
    f("lambda", s.lambda); f("cell_hint", s.cell_hint); f("length0", s.length0);
    f("material", s.material); f("body", s.body);
  }
};

/// Gauss-Legendre points (in [-1, 1]) and weights (sum 2) of order n >= 1.
void gauss_legendre(int n, std::vector<double>& points, std::vector<double>& weights);

/// Seeds the particles of every [[body]] of the scene: the body box is cut
/// into cells of the grid spacing `h` (per axis; the last cell size adjusted so
/// the cells tile the box exactly), each with particles_per_cell^D particles
/// at the Gauss points (volumes = Gauss weights x cell volume) or at the
/// centres of the sub-cells (equal volumes). Sets m, V, V0, rho, velocity
/// (body velocity, velocity_profile, then [[initial_velocity]] boxes).
/// Checks its inputs first (validate_seeding: the bodies, h finite and > 0,
/// the particle count) and throws InputError naming the scene key.
template <int D> Particles<D> seed_particles(const Scene& scene, const Vec<D>& h);

extern template struct Particles<1>;
extern template struct Particles<2>;
extern template struct Particles<3>;

} // namespace otmpm
