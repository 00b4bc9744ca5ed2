#pragma once
/// \file hencky_plasticity.hpp
/// Finite-strain elastoplasticity at one material point (docs/theory-plasticity.md):
/// the multiplicative split F = F_e F_p with the elastic left Cauchy-Green
/// tensor b_e = F_e F_e^T as state, Hencky (logarithmic) elasticity and return
/// mappings in principal Kirchhoff stresses (de Souza Neto, Peric & Owen,
/// "Computational Methods for Plasticity", ch. 14; Simo 1992). One step:
///
///   b_e_trial = dF b_e dF^T                      (dF = F_{n+1} F_n^{-1} = I + grad(du))
///   e_trial   = 1/2 ln b_e_trial                 (principal Hencky strains e_i = 1/2 ln lambda_i)
///   tau_trial = K tr(e) I + 2 G dev(e)           (Kirchhoff stress, per unit reference volume)
///   return mapping in (tr e, dev e): e_new = e_v_new/3 I + beta dev(e_trial)
///   b_e_new   = exp(2 e_new) = sum_i exp(2 e_new,i) n_i n_i^T
///
/// The caller forms the Cauchy stress sigma = tau / J, J = det F. The update
/// depends on dF only through b_e_trial, so it is exactly objective: a rigid
/// rotation superposed on the motion rotates tau and b_e and changes nothing
/// else.
///
/// Models: J2 (von Mises) with linear isotropic hardening (closed-form radial
/// return) and optional Johnson-Cook rate hardening (safeguarded scalar
/// Newton); Drucker-Prager, a smooth cone matched to Mohr-Coulomb in plane
/// strain, non-associated (dilation angle), with cohesion, apex and a tension
/// cutoff on the mean stress (closed-form returns). Both are pure point
/// functions (no particles, no scene, no allocation; thread-safe on distinct
/// states).
///
/// Dimensions: the state b_e is 3x3 in every dimension. `D` selects the
/// kinematics of dF (and a fast path):
///  - D = 3: dF is a general 3x3 matrix (symmetric eigen-decomposition of b_e_trial);
///  - D = 2: plane strain, dF is the in-plane 2x2 block (dF_zz = 1, dF_xz = dF_yz = 0);
///    b_e keeps the block form (b_xz = b_yz = 0): only the in-plane block and
///    b_zz are read and written (closed-form 2x2 spectral formulas);
///  - D = 1: uniaxial strain, dF = diag(dF_11, 1, 1); b_e is diagonal and only
///    its diagonal is read and written.
/// For the same motion the three give the same stress to round-off
/// (tests/test_plasticity.cpp).
#include "otmpm/core.hpp"

#include <optional>

namespace otmpm::plasticity {

using Mat3 = Mat<3>;

/// Isotropic Hencky elasticity: psi(e) = K/2 tr(e)^2 + G |dev e|^2 per unit
/// reference volume, tau = K tr(e) I + 2 G dev(e). In 1D (uniaxial strain)
/// the axial modulus is K + 4G/3 = lambda + 2 mu, as for the other
/// finite-strain models of elasticity.hpp.
struct ElasticModuli {
  double bulk = 0.0;  ///< K
  double shear = 0.0; ///< G
  /// K = E / (3 (1 - 2 nu)), G = E / (2 (1 + nu)). Throws InputError naming
  /// `young` (finite, > 0) or `poisson` (in (-1, 0.5)).
  static ElasticModuli from_young_poisson(double young, double poisson);
  /// Throws InputError naming `bulk` or `shear` unless both are finite and > 0.
  void validate() const;
};

/// Johnson-Cook hardening added to the J2 yield stress (see J2Parameters).
struct JohnsonCook {
  double B = 0.0;                     ///< strain-hardening coefficient (stress), >= 0
  double n = 1.0;                     ///< strain-hardening exponent, > 0
  double C = 0.0;                     ///< strain-rate coefficient, >= 0
  double reference_strain_rate = 1.0; ///< eps_dot_0 (1/time), > 0
  /// Throws InputError naming `johnson_cook.B`, `.n`, `.C` or
  /// `.reference_strain_rate` when a value is not finite or out of range.
  void validate() const;
};

/// von Mises plasticity with the yield stress
///   sigma_y(eps_p, rate) = (yield_stress + hardening_modulus eps_p + B eps_p^n)
///                          * (1 + C ln(max(1, rate / reference_strain_rate)))
/// (the B and C terms only with johnson_cook), rate = delta eps_p / dt the
/// equivalent plastic strain rate of the step. Yield function
/// f = q - sigma_y with q = sqrt(3/2) |dev tau| (Kirchhoff stress).
struct J2Parameters {
  ElasticModuli elastic;
  double yield_stress = 0.0;      ///< initial yield stress sigma_y0 (Johnson-Cook A), > 0
  double hardening_modulus = 0.0; ///< linear isotropic hardening modulus H, >= 0
  std::optional<JohnsonCook> johnson_cook;
  /// Throws InputError naming the parameter (see ElasticModuli, JohnsonCook;
  /// `yield_stress` finite > 0, `hardening_modulus` finite >= 0).
  void validate() const;
  /// sigma_y at equivalent plastic strain eps_p and plastic strain rate `rate`
  /// (rate only matters with Johnson-Cook C > 0).
  double flow_stress(double eps_p, double rate = 0.0) const;
};

/// Drucker-Prager parameters as the user gives them (angles in degrees).
struct DruckerPragerParameters {
  ElasticModuli elastic;
  double friction_angle = 0.0; ///< phi in degrees, 0 <= phi < 90
  double dilation_angle = 0.0; ///< psi in degrees, 0 <= psi <= phi (psi = phi: associated flow)
  double cohesion = 0.0;       ///< c >= 0 (> 0 when phi = 0)
  /// Largest mean Kirchhoff stress p = tr(tau)/3 (tension positive), >= 0 and
  /// at most the apex of the cone xi c / eta. Default 0: no tensile mean stress.
  double tension_cutoff = 0.0;
  /// Throws InputError naming the parameter when one is out of range.
  void validate() const;
};

/// A validated Drucker-Prager material with the derived cone constants
/// (de Souza Neto et al., ch. 6 for the cone and its Mohr-Coulomb matches,
/// ch. 8 for the return mapping): yield function
///   Phi(tau) = sqrt(J2(s)) + eta p - xi c,  p = tr(tau)/3,  s = dev(tau),
/// plastic potential sqrt(J2(s)) + eta_bar p, and the tension cutoff p <= T.
/// eta, xi match the cone to Mohr-Coulomb in plane strain:
///   eta = 3 tan(phi) / sqrt(9 + 12 tan^2 phi),  xi = 3 / sqrt(9 + 12 tan^2 phi),
/// eta_bar likewise from the dilation angle psi.
class DruckerPrager {
public:
  /// Validates `p` (InputError naming the parameter) and derives the constants.
  explicit DruckerPrager(const DruckerPragerParameters& p);
  const DruckerPragerParameters& parameters() const { return p_; }
  const ElasticModuli& elastic() const { return p_.elastic; }
  double eta() const { return eta_; }
  double xi() const { return xi_; }
  double eta_bar() const { return eta_bar_; }
  /// Mean stress of the apex, xi c / eta (+infinity for phi = 0).
  double apex() const { return apex_; }
  /// The tension cutoff T as used (the parameter, at most apex()).
  double tension_cutoff() const { return cutoff_; }
  /// Phi(tau) = sqrt(J2(dev tau)) + eta tr(tau)/3 - xi c (<= 0 inside the cone).
  double yield_function(const Mat3& tau) const;

private:
  DruckerPragerParameters p_;
  double eta_ = 0.0, xi_ = 0.0, eta_bar_ = 0.0, apex_ = 0.0, cutoff_ = 0.0;
};

/// Per-point state: elastic left Cauchy-Green tensor b_e (3x3 symmetric
/// positive definite in every dimension; identity in the undeformed state),
/// equivalent plastic strain eps_p = sum sqrt(2/3) |delta dev(e_p)| (the
/// accumulated deviatoric plastic log strain; for J2 the hardening variable),
/// and volumetric plastic strain eps_v = sum delta tr(e_p) (Drucker-Prager;
/// > 0 is dilation).
struct HenckyState {
  Mat3 be = Mat3::Identity();
  double eps_p = 0.0;
  double eps_v = 0.0;
};

/// Result of one point update.
struct PointUpdate {
  /// Kirchhoff stress tau = J sigma after the step (3x3: plane strain has
  /// tau_zz, 1D the lateral stresses tau_yy = tau_zz).
  Mat3 kirchhoff = Mat3::Zero();
  /// Stored elastic energy psi(b_e) after the step, per unit reference volume.
  double elastic_energy = 0.0;
  /// The material dissipation of the step, tau_new : delta e_p per unit
  /// reference volume, delta e_p = e_trial - e_new (0 for an elastic step),
  /// >= 0. The engine adds V0 * plastic_work to W_plastic: the stress work of
  /// the next step uses tau_new, so this - and not the whole drop of the
  /// stored energy - is what the body loses to plastic flow
  /// (docs/theory-plasticity.md, "Energy").
  double plastic_work = 0.0;
  /// The algorithmic part of the return, 1/2 delta e_p : C : delta e_p =
  /// O(dt^2) per step: psi(e_trial) - psi(e_new) = plastic_work + return_work.
  double return_work = 0.0;
  /// Newton iterations of the return (0: elastic step or closed-form return).
  int iterations = 0;
  /// True when the return mapping was active.
  bool plastic = false;
};

/// One J2 step: trial b_e from dF, radial return, new state (b_e, eps_p).
/// `dt` (> 0) is only read with Johnson-Cook C > 0 (the plastic strain rate).
/// Assumes p.validate() passed. Throws InstabilityError when det dF is not
/// finite and > 0 or the elastic strain is not finite, and when the
/// Johnson-Cook Newton solve reaches neither |f| <= 1e-12 sigma_y nor, once
/// its bracket has shrunk to round-off, |f| <= 1e-10 sigma_y within 100
/// iterations; std::invalid_argument when Johnson-Cook with C > 0 gets a
/// dt that is not finite and > 0. The state is unchanged when it throws.
template <int D> PointUpdate j2_update(const J2Parameters& p, const Mat<D>& dF, double dt, HenckyState& state);

/// One Drucker-Prager step: trial b_e from dF, return to the cone, the
/// tension cutoff or their corner (the apex when T = apex()), new state
/// (b_e, eps_p, eps_v). Throws InstabilityError as j2_update.
template <int D> PointUpdate drucker_prager_update(const DruckerPrager& m, const Mat<D>& dF, HenckyState& state);

/// Stored elastic energy psi(b_e) = K/2 tr(e)^2 + G |dev e|^2, e = 1/2 ln b_e,
/// per unit reference volume (general 3x3 symmetric positive definite b_e).
double hencky_energy(const ElasticModuli& m, const Mat3& be);
/// Hencky Kirchhoff stress K tr(e) I + 2 G dev(e) of b_e (hyperelastic response).
Mat3 hencky_kirchhoff(const ElasticModuli& m, const Mat3& be);
/// Hencky strain e = 1/2 ln b_e (general 3x3 symmetric positive definite b_e).
Mat3 hencky_strain(const Mat3& be);
/// The inverse of hencky_kirchhoff: b_e = exp(2 e) with e = tr(tau) / (9 K) I
/// + dev(tau) / (2 G), the elastic state whose Kirchhoff stress is tau
/// (symmetric; a geostatic initial stress at F = I, where tau = sigma).
Mat3 hencky_left_cauchy_green(const ElasticModuli& m, const Mat3& tau);

/// Eigen-decomposition A = Q diag(w) Q^T of a symmetric 3x3 matrix by cyclic
/// Jacobi rotations: Q orthonormal and w accurate to round-off relative to
/// |A - tr(A)/3 I| also for repeated eigenvalues. Reads the upper triangle.
void symmetric_eigen(const Mat3& A, Eigen::Vector3d& w, Mat3& Q);

} // namespace otmpm::plasticity
