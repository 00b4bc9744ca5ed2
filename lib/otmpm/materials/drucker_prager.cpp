/// \file drucker_prager.cpp
/// `model = "drucker_prager"`: a smooth Drucker-Prager cone matched to
/// Mohr-Coulomb in plane strain, non-associated (dilation angle), with
/// cohesion, apex return and a tension cutoff, finite strain (Hencky
/// elasticity on b_e; docs/theory.md sect. 9).
#include "otmpm/materials/hencky_material.hpp"
#include "otmpm/materials/models.hpp"

namespace otmpm {

namespace {

const std::array<ParameterSpec, 4> kParameters{{
    {"friction_angle", "friction angle phi [deg]", std::nullopt, 0.0, false, 90.0, true},
    {"dilation_angle", "dilation angle psi [deg], at most phi", 0.0, 0.0, false, 90.0, true},
    {"cohesion", "cohesion c [Pa]", 0.0, 0.0, false},
    {"tension_cutoff", "largest mean stress (tension positive) [Pa], at most the apex", 0.0, 0.0, false},
}};

/// The Drucker-Prager point update with its derived cone.
struct DruckerPragerModel {
  plasticity::DruckerPrager cone;
  const plasticity::ElasticModuli& elastic() const { return cone.elastic(); }
  template <int D>
  [[gnu::always_inline]] plasticity::PointUpdate update(const Mat<D>& dF, double, plasticity::HenckyState& s) const {
    return plasticity::point::drucker_prager<D>(cone, dF, s);
  }
};

DruckerPragerModel drucker_prager_model(const MaterialParameters& m) {
  plasticity::DruckerPragerParameters p;
  p.elastic = hencky_moduli(m);
  p.friction_angle = m.get("friction_angle", 0.0);
  p.dilation_angle = m.get("dilation_angle", 0.0);
  p.cohesion = m.get("cohesion", 0.0);
  p.tension_cutoff = m.get("tension_cutoff", 0.0);
  try {
    return {plasticity::DruckerPrager(p)};
  } catch (const InputError& e) {
    throw InputError("material '" + m.name + "': " + e.what());
  }
}

template <int D> std::unique_ptr<Material<D>> make_drucker_prager(const MaterialParameters& m) {
  return std::make_unique<HenckyMaterial<D, DruckerPragerModel>>(m, drucker_prager_model(m));
}

} // namespace

const MaterialModel& drucker_prager_model() {
  static const std::array<ParameterValue, 5> example{
      {{"density", 1590.0}, {"young", 10.0e6}, {"poisson", 0.3}, {"friction_angle", 30.0}, {"cohesion", 1.0e3}}};
  static const MaterialModel m{"drucker_prager",
                               "Drucker-Prager soil (cone matched to Mohr-Coulomb in plane strain), finite strain",
                               kParameters, kHenckyState, make_drucker_prager<1>, make_drucker_prager<2>,
                               make_drucker_prager<3>, example, true, true};
  return m;
}

} // namespace otmpm
