#pragma once
/// \file material.hpp
/// Constitutive models of spec algorithms.md sect. 4.
///  - linear_elastic: small strain, sigma += C : d_eps (molinos paper), 1D
///    uniaxial stress (E), 2D plane strain, 3D.
///  - linear_elastic_finite: wobbes eq. 10,
///    sigma = lambda/J tr(E_s) F + 2 mu / J F E_s,  E_s = sym(F) - I.
///  - neo_hookean: wobbes eq. 11, sigma = lambda ln J / J I + mu / J (F F^T - I).
/// In 1D the uniaxial modulus of the finite-strain models is lambda + 2 mu,
/// which equals E for nu = 0 (the value every 1D benchmark uses).
#include "otmpm/core.hpp"

#include <string>

namespace otmpm {

/// One material: model and elastic constants (Lame parameters derived once).
struct Material {
  enum class Model { linear_elastic, linear_elastic_finite, neo_hookean };
  std::string name;
  Model model = Model::linear_elastic;
  double density = 1.0; ///< reference density rho_0
  double young = 1.0;
  double poisson = 0.0;

  /// Parses "linear_elastic" | "linear_elastic_finite" | "neo_hookean"; InputError otherwise.
  static Model parse_model(const std::string& name);
  /// Throws InputError naming the material and the field unless density and
  /// young are finite and > 0 and -1 < poisson < 0.5 (where lambda() and mu()
  /// are finite and the material is stable). The stress functions assume it.
  void validate() const;
  double lambda() const { return young * poisson / ((1 + poisson) * (1 - 2 * poisson)); }
  double mu() const { return young / (2 * (1 + poisson)); }
  /// P-wave modulus: E in 1D (uniaxial stress), lambda + 2 mu otherwise.
  double p_modulus(int dimension) const { return dimension == 1 ? young : lambda() + 2 * mu(); }
  /// True for the models that need the deformation gradient F.
  bool finite_strain() const { return model != Model::linear_elastic; }
};

/// Small-strain stress increment C : d_eps for the dimension's elasticity
/// (1D: E d_eps; 2D: plane strain; 3D: isotropic).
template <int D> Mat<D> elastic_stress_increment(const Material& mat, const Mat<D>& d_eps);

/// Cauchy stress of a finite-strain model from F (wobbes eqs. 10, 11). Throws
/// InstabilityError unless det F is finite and > 0 (one check per call; the
/// engine checks first and names the particle).
template <int D> Mat<D> cauchy_stress(const Material& mat, const Mat<D>& F);

/// Stored elastic energy density (per unit current volume, used only for the
/// energy monitor): 1/2 sigma : eps with eps the small strain or sym(F) - I.
template <int D> double strain_energy_density(const Mat<D>& sigma, const Mat<D>& eps);

} // namespace otmpm
