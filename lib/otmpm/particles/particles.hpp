#pragma once
/// \file particles.hpp
/// Particle (material point) storage: contiguous per-field arrays of
/// fixed-size Eigen types (docs/architecture.md). Fields follow the notation of
/// docs/theory.md: x_p, v_p, a_p, m_p, V_p, V0_p, rho_p, F_p, eps_p, sigma_p.
#include "otmpm/core.hpp"

#include <string>
#include <string_view>
#include <vector>

namespace otmpm {

/// A per-particle internal variable (a material's state, Material::state()):
/// `width` doubles per particle, particle p at values[p * width ...].
struct StateField {
  std::string name;
  int width = 1;
  std::vector<double> values;
  double* row(int p) { return values.data() + static_cast<std::size_t>(p) * static_cast<std::size_t>(width); }
  const double* row(int p) const {
    return values.data() + static_cast<std::size_t>(p) * static_cast<std::size_t>(width);
  }
};

/// All particles of a run. `X` is the initial position (the material
/// coordinate used by exact solutions), `x_prev` the previous position (the
/// OTM velocity), `F` the deformation gradient (finite-strain models, `ul`
/// mode, or asked for as output), `a` the acceleration (NPC). Optional
/// fields are empty when the run does not use them; the assembler allocates
/// what the scene's materials and output need, the engine what the
/// integrator keeps (StepNeeds) and what the materials read. The per-point
/// state of the basis (LME multipliers, cell hints) lives in the basis.
template <int D> struct Particles {
  AlignedVector<Vec<D>> x, X, v, a, x_prev;
  std::vector<double> m, V, V0, rho;
  AlignedVector<Mat<D>> F, eps, sigma;
  /// Initial extent of the particle per axis, V0_p = prod_k l_p[k] (the
  /// share of its cell along each axis): its face normal to axis k has the
  /// area V0_p / l_p[k] (traction areas). Filled by the seeding; the
  /// assembler frees it once the traction areas are taken.
  AlignedVector<Vec<D>> length0;
  std::vector<int> material;
  std::vector<int> body;
  /// Internal variables of the materials, by name (Material::state()).
  std::vector<StateField> state;

  int size() const { return static_cast<int>(x.size()); }
  /// Resizes the fields every run uses to n particles (all zero) and empties
  /// the optional ones (a, F, x_prev, state); std::invalid_argument for n < 0.
  void resize(int n);
  /// Allocates the optional fields a run needs (a = 0, F = I), so that a
  /// scene pays memory only for what it reads.
  void allocate_optional(bool with_a, bool with_F);
  /// The state field `name`, added with `width` values per particle, each
  /// particle's row equal to `initial` (width values), when absent.
  /// std::invalid_argument when it exists with another width.
  StateField& add_state(const std::string& name, int width, const double* initial);
  /// The state field `name`, or null.
  StateField* find_state(std::string_view name);
  const StateField* find_state(std::string_view name) const;

  /// Calls f(name, field) for every per-particle array above except the
  /// state fields, named as its member, so that code handling all fields
  /// (the checkpoint) lists them here only. A field added to Particles must
  /// be added here too.
  template <class F> void for_each_field(F&& f) { visit_fields(*this, f); }
  template <class F> void for_each_field(F&& f) const { visit_fields(*this, f); }

private:
  template <class Self, class F> static void visit_fields(Self& s, F& f) {
    f("x", s.x); f("X", s.X); f("v", s.v); f("a", s.a); f("x_prev", s.x_prev);
    f("m", s.m); f("V", s.V); f("V0", s.V0); f("rho", s.rho);
    f("F", s.F); f("eps", s.eps); f("sigma", s.sigma);
    f("length0", s.length0);
    f("material", s.material); f("body", s.body);
  }
};

extern template struct Particles<1>;
extern template struct Particles<2>;
extern template struct Particles<3>;

} // namespace otmpm
