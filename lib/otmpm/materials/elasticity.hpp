#pragma once
/// \file elasticity.hpp
/// Isotropic elasticity shared by every material model (docs/theory.md
/// sect. 9): the constants E, nu, rho_0 with their Lame
/// parameters, and the stress laws of the three elastic models -
///  - linear_elastic: small strain, sigma += C : d_eps (molinos et al.), 1D
///    uniaxial stress (E), 2D plane strain, 3D;
///  - linear_elastic_finite: wobbes et al. eq. 10,
///    sigma = lambda/J tr(E_s) F + 2 mu / J F E_s,  E_s = sym(F) - I;
///  - neo_hookean: wobbes et al. eq. 11, sigma = lambda ln J / J I + mu / J (F F^T - I).
/// In 1D the uniaxial modulus of the finite-strain models is lambda + 2 mu,
/// which equals E for nu = 0 (the value every 1D benchmark uses).
#include "otmpm/core.hpp"
#include "otmpm/parameters.hpp"

#include <string>

namespace otmpm {

/// The ranges of the constants every material has - the scene keys
/// material.NAME.density, .young and .poisson - read by the scene reader,
/// validate_material and the density column of a particle file alike.
inline constexpr ParameterSpec kDensity{"density", "reference mass density rho_0 [kg/m^3]", std::nullopt, 0.0, true};
inline constexpr ParameterSpec kYoung{"young", "Young's modulus E [Pa]", std::nullopt, 0.0, true};
inline constexpr ParameterSpec kPoisson{"poisson", "Poisson's ratio nu", std::nullopt, -1.0, true, 0.5, true};

/// Density and isotropic elastic constants of a material.
struct ElasticConstants {
  double density = 1.0; ///< reference density rho_0
  double young = 1.0;
  double poisson = 0.0;

  /// Throws InputError "material 'NAME': FIELD must be ..." unless density,
  /// young and poisson lie in their ranges (kDensity, kYoung, kPoisson:
  /// density and young finite and > 0, -1 < poisson < 0.5, where lambda()
  /// and mu() are finite and the material is stable).
  void validate(const std::string& name) const;
  double lambda() const { return young * poisson / ((1 + poisson) * (1 - 2 * poisson)); }
  double mu() const { return young / (2 * (1 + poisson)); }
  /// P-wave modulus: E in 1D (uniaxial stress), lambda + 2 mu otherwise.
  double p_modulus(int dimension) const { return dimension == 1 ? young : lambda() + 2 * mu(); }
};

/// Small-strain stress increment C : d_eps for the dimension's elasticity
/// (1D: E d_eps; 2D: plane strain; 3D: isotropic).
/// Inline: called once per particle and step by the small-strain models.
template <int D> inline Mat<D> elastic_stress_increment(const ElasticConstants& c, const Mat<D>& d_eps) {
  if constexpr (D == 1) {
    return c.young * d_eps;
  } else {
    return c.lambda() * d_eps.trace() * Mat<D>::Identity() + 2.0 * c.mu() * d_eps;
  }
}

/// Cauchy stress of linear_elastic_finite (wobbes eq. 10) from F. Throws
/// InstabilityError unless det F is finite and > 0 (one check per call).
template <int D> Mat<D> linear_elastic_finite_stress(const ElasticConstants& c, const Mat<D>& F);

/// Cauchy stress of neo_hookean (wobbes eq. 11) from F. Throws
/// InstabilityError unless det F is finite and > 0 (one check per call).
template <int D> Mat<D> neo_hookean_stress(const ElasticConstants& c, const Mat<D>& F);

/// rho0 c^2 of the fastest wave of the finite-strain laws at F (the CFL
/// step, docs/theory.md sect. 10): for a longitudinal wave along a
/// principal stretch u, the tangent u dtau/du - tau of the Kirchhoff stress
/// tau = J sigma, the current density being rho0 / J. With b_max >= u^2,
/// the largest row sum of |F F^T| (exact when the stretches lie along the
/// axes):
///  - linear_elastic_finite: (lambda + 2 mu) b_max;
///  - neo_hookean: lambda (1 - ln J) + mu (b_max + 1), at least 0.
/// Both are lambda + 2 mu at F = I (E in 1D); neither depends on the volume
/// change alone as M / rho_p = M J / rho0 would.
template <int D> double linear_elastic_finite_wave_modulus(const ElasticConstants& c, const Mat<D>& F);
template <int D> double neo_hookean_wave_modulus(const ElasticConstants& c, const Mat<D>& F);
/// The stored energy of neo_hookean per unit reference volume, the
/// potential of its stress (sigma = F dW/dF F^T / J):
/// W = lambda/2 (ln J)^2 - mu ln J + mu/2 (tr(F F^T) - D) (in plane strain
/// the out-of-plane stretch is 1 and adds nothing). Throws as neo_hookean_stress.
template <int D> double neo_hookean_energy(const ElasticConstants& c, const Mat<D>& F);

/// Plane strain: the out-of-plane Cauchy stress sigma_zz of
/// linear_elastic_finite for the in-plane F (F_zz = 1, F_xz = F_yz = 0):
/// E_s,zz = 0 and (F E_s)_zz = 0 leave lambda tr(E_s) / J, tr(E_s) = F_xx +
/// F_yy - 2. Throws InstabilityError as linear_elastic_finite_stress.
double linear_elastic_finite_out_of_plane(const ElasticConstants& c, const Mat<2>& F);

/// Plane strain: sigma_zz of neo_hookean for the in-plane F, lambda ln(J) / J
/// ((F F^T)_zz = 1). Throws InstabilityError as neo_hookean_stress.
double neo_hookean_out_of_plane(const ElasticConstants& c, const Mat<2>& F);

} // namespace otmpm
