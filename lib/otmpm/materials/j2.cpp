/// \file j2.cpp
/// `model = "j2"`: von Mises plasticity with linear isotropic hardening and
/// optional Johnson-Cook rate hardening, finite strain (Hencky elasticity on
/// b_e, radial return in principal Kirchhoff stresses; docs/theory.md sect. 9).
#include "otmpm/materials/hencky_material.hpp"
#include "otmpm/materials/models.hpp"

#include <atomic>

namespace otmpm {

namespace {

const std::array<ParameterSpec, 6> kParameters{{
    {"yield_stress", "initial yield stress sigma_y0 (Johnson-Cook A) [Pa]", std::nullopt, 0.0, true},
    {"hardening_modulus", "linear isotropic hardening modulus H [Pa]", 0.0, 0.0, false},
    {"johnson_cook.B", "Johnson-Cook strain-hardening coefficient [Pa]", std::nullopt, 0.0, false},
    {"johnson_cook.n", "Johnson-Cook strain-hardening exponent", std::nullopt, 0.0, true},
    {"johnson_cook.C", "Johnson-Cook strain-rate coefficient", std::nullopt, 0.0, false},
    {"johnson_cook.reference_strain_rate", "Johnson-Cook reference strain rate [1/s]", std::nullopt, 0.0, true},
}};

/// The J2 point update with its parameters.
struct J2Model {
  plasticity::J2Parameters p;
  const plasticity::ElasticModuli& elastic() const { return p.elastic; }
  template <int D>
  [[gnu::always_inline]] plasticity::PointUpdate update(const Mat<D>& dF, double dt, plasticity::HenckyState& s) const {
    return plasticity::point::j2<D>(p, dF, dt, s);
  }
  /// Plane strain and 3D two particles at a time (HenckyMaterial): without
  /// a Johnson-Cook term, whose return is an iteration.
  bool lanes() const { return !p.johnson_cook; }
  template <class T> [[gnu::always_inline]] auto plane(plasticity::point::PlaneJ2<T>& x) const {
    return plasticity::point::plane_j2(p, x);
  }
  /// Inlined into its caller (for four lanes an AVX2 function).
  template <class T> [[gnu::always_inline]] auto solid(plasticity::point::SolidJ2<T>& x) const {
    return plasticity::point::solid_j2(p, x);
  }
};

J2Model j2_model(const MaterialParameters& m) {
  J2Model model;
  model.p.elastic = hencky_moduli(m);
  model.p.yield_stress = m.get("yield_stress", 0.0);
  model.p.hardening_modulus = m.get("hardening_modulus", 0.0);
  if (m.has("johnson_cook.B"))
    model.p.johnson_cook = plasticity::JohnsonCook{m.get("johnson_cook.B", 0.0), m.get("johnson_cook.n", 1.0),
                                                   m.get("johnson_cook.C", 0.0),
                                                   m.get("johnson_cook.reference_strain_rate", 1.0)};
  try {
    model.p.validate();
  } catch (const InputError& e) {
    throw InputError("material '" + m.name + "': " + e.what());
  }
  return model;
}

template <int D> std::unique_ptr<Material<D>> make_j2(const MaterialParameters& m) {
  return std::make_unique<HenckyMaterial<D, J2Model>>(m, j2_model(m));
}

} // namespace

namespace plasticity::point {

namespace {
/// The four-lane step is allowed (set_wide_lanes).
std::atomic<bool> wide_allowed{true};
} // namespace

bool wide_lanes() {
#ifdef OTMPM_WIDE_LANES
  static const bool avx2 = __builtin_cpu_supports("avx2");
  return avx2 && wide_allowed.load(std::memory_order_relaxed);
#else
  return false;
#endif
}

void set_wide_lanes(bool allowed) { wide_allowed.store(allowed, std::memory_order_relaxed); }

} // namespace plasticity::point

const MaterialModel& j2_model() {
  static const std::array<ParameterValue, 5> example{
      {{"density", 7833.0}, {"young", 200.0e9}, {"poisson", 0.3}, {"yield_stress", 5.0e7}, {"hardening_modulus", 1.0e9}}};
  static const MaterialModel m{"j2", "von Mises plasticity, linear isotropic / Johnson-Cook hardening, finite strain",
                               kParameters, kHenckyState, make_j2<1>, make_j2<2>, make_j2<3>, example, true};
  return m;
}

} // namespace otmpm
