/// \file elastic.cpp
/// The three elastic models (elasticity.hpp) as Material<D>:
/// linear_elastic (small strain; molinos et al.), linear_elastic_finite
/// (wobbes et al. eq. 10) and neo_hookean (wobbes et al. eq. 11). None has
/// internal variables; the stored energy is neo_hookean's potential V0_p W(F_p)
/// and, for the two laws without a potential, the work of the law's own
/// stress along the straight path to the particle's state (docs/theory.md
/// eqs. 11.1a-11.1b).
#include "otmpm/materials/hencky_solid_j2.hpp"
#include "otmpm/materials/models.hpp"
#include "otmpm/materials/pore_fluid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <type_traits>

namespace otmpm {

namespace {

/// phi_1(a) = int_0^1 exp(-(1 - s) a) ds and phi_2(a) = int_0^1 s exp(-(1 -
/// s) a) ds (docs/theory.md eq. 11.1a): the weights of linear_elastic's work
/// along the straight strain path, on which the volume is V exp(-(1 - s) a),
/// a = tr eps. Their Taylor series below |a| = 0.1 (terms to a^7: relative
/// error below 1e-15), where the closed forms lose digits to cancellation.
struct StraightPathWeights {
  double phi1, phi2;
  explicit StraightPathWeights(double a) {
    if (std::abs(a) < 0.1) {
      series(a, phi1, phi2);
    } else {
      phi1 = -std::expm1(-a) / a;
      phi2 = (a + std::expm1(-a)) / (a * a);
    }
  }
  /// The series for |a| < 0.1: sum_k (-a)^k / (k + 1)! and (-a)^k / (k + 2)!,
  /// k = 7 .. 0 (Horner; inline, so that a loop of them vectorises).
  static void series(double a, double& phi1, double& phi2) {
    double f1 = 0.0, f2 = 0.0;
    for (int k = 7; k >= 0; --k) {
      f1 = kInverseFactorial[k + 1] - a * f1;
      f2 = kInverseFactorial[k + 2] - a * f2;
    }
    phi1 = f1, phi2 = f2;
  }
  /// 1 / n!, n = 0 .. 9, made once by the compiler (the energy pass runs every step).
  static constexpr std::array<double, 10> kInverseFactorial = [] {
    std::array<double, 10> inverse{};
    double f = 1.0;
    for (int n = 0; n < 10; ++n) {
      if (n > 1) f *= n;
      inverse[static_cast<std::size_t>(n)] = 1.0 / f;
    }
    return inverse;
  }();
};

/// Particles per batch of LinearElastic::add_energies' weights.
constexpr int kEnergyBatch = 64;

#ifdef OTMPM_WIDE_LANES
/// The series loop of straight_path_weights compiled for AVX2 (four
/// particles per instruction; no FMA, so each value has the bits of the
/// portable loop), chosen where plasticity::point::wide_lanes() allows it.
[[gnu::target("avx2"), gnu::noinline]] void straight_path_series_avx2(const double* a, int n, double* phi1,
                                                                      double* phi2) {
  for (int i = 0; i < n; ++i) StraightPathWeights::series(a[i], phi1[i], phi2[i]);
}
#endif

/// StraightPathWeights of a = tr eps_i for the n strains eps[0, n), into
/// phi1[i] and phi2[i]: the series for every i in one loop the compiler
/// vectorises, then the closed form where |a| >= 0.1 - each value the one
/// StraightPathWeights gives (the same operations in the same order).
template <int D> void straight_path_weights(const Mat<D>* eps, int n, double* phi1, double* phi2) {
  double a[kEnergyBatch];
  for (int i = 0; i < n; ++i) a[i] = eps[i].trace();
#ifdef OTMPM_WIDE_LANES
  if (plasticity::point::wide_lanes()) straight_path_series_avx2(a, n, phi1, phi2);
  else
#endif
    for (int i = 0; i < n; ++i) StraightPathWeights::series(a[i], phi1[i], phi2[i]);
  for (int i = 0; i < n; ++i)
    if (!(std::abs(a[i]) < 0.1)) {
      const StraightPathWeights w(a[i]);
      phi1[i] = w.phi1, phi2[i] = w.phi2;
    }
}

/// The work of a law sigma(F) without a potential along the straight path
/// F(s) = I + s (F - I), per reference volume: int_0^1 J(s) sigma(F(s)) :
/// ((F - I) F(s)^-1) ds (docs/theory.md eq. 11.1b; the stress power sigma : L
/// of the forces), by 4-point Gauss-Legendre (exact in 1D, where the
/// integrand of linear_elastic_finite is a polynomial of degree 1). A path
/// through det F(s) <= 0 (a rotation near half a turn, where the law has no
/// meaning) counts 1/2 sigma : (sym(F) - I) J instead.
template <int D, Mat<D> (*Law)(const ElasticConstants&, const Mat<D>&)>
double straight_path_work(const ElasticConstants& c, const Mat<D>& F, const Mat<D>& sigma, const Mat<D>& eps) {
  static constexpr double x[4] = {0.0694318442029737, 0.3300094782075719, 0.6699905217924281, 0.9305681557970263};
  static constexpr double w[4] = {0.1739274225687269, 0.3260725774312731, 0.3260725774312731, 0.1739274225687269};
  const Mat<D> dF = F - Mat<D>::Identity();
  double work = 0.0;
  for (int k = 0; k < 4; ++k) {
    const Mat<D> Fs = Mat<D>::Identity() + x[k] * dF;
    const double J = Fs.determinant();
    if (!(J > 0.0)) return 0.5 * F.determinant() * sigma.cwiseProduct(eps).sum();
    work += w[k] * J * Law(c, Fs).cwiseProduct(dF * Fs.inverse()).sum();
  }
  return work;
}

/// Small strain (docs/theory.md): d_eps = sym(H), eps += d_eps,
/// sigma += C : d_eps, rho /= 1 + tr d_eps, V = m / rho; F_p = (I + H) F_p
/// when F is kept (ul mode, or asked for as output).
template <int D> class LinearElastic final : public Material<D> {
public:
  explicit LinearElastic(const MaterialParameters& p) : Material<D>(p), c_(p.elastic()) {}
  bool needs_deformation_gradient() const override { return false; }
  void update(Particles<D>& P, int p0, int p1, const Mat<D>* H, double) const override {
    // Locals: the stores below cannot alias them (the constants are doubles too).
    const ElasticConstants c = c_;
    Mat<D>* F = P.F.empty() ? nullptr : P.F.data();
    Mat<D>* eps = P.eps.data();
    Mat<D>* sigma = P.sigma.data();
    double* rho = P.rho.data();
    double* V = P.V.data();
    const double* m = P.m.data();
    for (int p = p0; p < p1; ++p) {
      const Mat<D>& h = H[p - p0];
      if (F) F[p] = (Mat<D>::Identity() + h) * F[p];
      const Mat<D> d_eps = 0.5 * (h + h.transpose());
      eps[p] += d_eps;
      sigma[p] += elastic_stress_increment<D>(c, d_eps);
      const double dilation = 1.0 + d_eps.trace();
      if (!(dilation > 0.0)) [[unlikely]]
        throw ParticleFailure{p, "volume change 1 + tr(d_eps) = " + format_number(dilation) + " <= 0"};
      rho[p] /= dilation;
      V[p] = m[p] / rho[p];
    }
  }
  /// The energy stored since the start, the work of the stress along the
  /// straight path to eps_p (docs/theory.md eq. 11.1a), V_p (phi_1(a)
  /// sigma0_p : eps_p + phi_2(a) eps_p : C : eps_p), a = tr eps_p, with the
  /// initial stress sigma0_p = sigma_p - C : eps_p (a geostatic start; 0
  /// otherwise); to first order in eps_p V_p (sigma0_p + C : eps_p / 2) : eps_p.
  void add_energies(const Particles<D>& P, int p0, int p1, double& stored, double&) const override {
    const ElasticConstants c = c_;
    double phi1[kEnergyBatch], phi2[kEnergyBatch];
    for (int q0 = p0; q0 < p1; q0 += kEnergyBatch) {
      const int q1 = std::min(p1, q0 + kEnergyBatch);
      straight_path_weights(P.eps.data() + q0, q1 - q0, phi1, phi2);
      for (int p = q0; p < q1; ++p) {
        const Mat<D> c_eps = elastic_stress_increment<D>(c, P.eps[p]);
        stored += P.V[p] * (phi1[p - q0] * (P.sigma[p] - c_eps).cwiseProduct(P.eps[p]).sum() +
                            phi2[p - q0] * c_eps.cwiseProduct(P.eps[p]).sum());
      }
    }
  }
  /// sigma_zz = sigma0_zz + lambda tr(eps_p): eps_p starts at 0 and takes
  /// the increments d_eps of sigma_p (d_eps_zz = 0); sigma0_zz is the
  /// particle's initial out-of-plane stress (kInitialOutOfPlaneStressField,
  /// 0 without one).
  void out_of_plane_stress(const Particles<D>& P, int p0, int p1, double* out) const override {
    if constexpr (D != 2) {
      Material<D>::out_of_plane_stress(P, p0, p1, out);
    } else {
      const double lambda = c_.lambda();
      const StateField* initial = P.find_state(kInitialOutOfPlaneStressField);
      for (int p = p0; p < p1; ++p)
        out[p - p0] = lambda * (P.eps[p](0, 0) + P.eps[p](1, 1)) +
                      (initial ? initial->values[static_cast<std::size_t>(p)] : 0.0);
    }
  }

private:
  ElasticConstants c_;
};

/// A finite-strain law without a stored-energy potential.
struct NoPotential {};
/// neo_hookean's potential W(F) (neo_hookean_energy).
template <int D> struct NeoHookeanPotential {
  static double density(const ElasticConstants& c, const Mat<D>& F) { return neo_hookean_energy<D>(c, F); }
};

/// Finite strain: F_p = (I + H) F_p, V_p = det F_p V0_p, rho_p = m_p / V_p,
/// sigma_p = Law(F_p), eps_p = sym(F_p) - I (for the energy monitor).
/// ZzLaw: sigma_zz of the law in plane strain from the in-plane F_p
/// (out_of_plane_stress); WaveLaw: rho0 c^2 of its fastest wave at F_p;
/// Potential: the law's stored energy per reference volume,
/// Potential::density(c, F_p) = W(F_p) (NoPotential: a law without one,
/// counted as its work along the straight path to F_p, straight_path_work).
template <int D, Mat<D> (*Law)(const ElasticConstants&, const Mat<D>&),
          double (*ZzLaw)(const ElasticConstants&, const Mat<2>&),
          double (*WaveLaw)(const ElasticConstants&, const Mat<D>&), class Potential = NoPotential>
class FiniteElastic final : public Material<D> {
public:
  explicit FiniteElastic(const MaterialParameters& p) : Material<D>(p), c_(p.elastic()) {}
  bool needs_deformation_gradient() const override { return true; }
  /// c_p^2 = WaveLaw(F_p) / rho0_p, rho0_p = m_p / V0_p.
  void max_wave_speed2(const Particles<D>& P, int p0, int p1, double& c2) const override {
    for (int p = p0; p < p1; ++p) c2 = std::max(c2, WaveLaw(c_, P.F[p]) * P.V0[p] / P.m[p]);
  }
  void update(Particles<D>& P, int p0, int p1, const Mat<D>* H, double) const override {
    const ElasticConstants c = c_; // a local: the stores below cannot alias it
    for (int p = p0; p < p1; ++p) {
      P.F[p] = (Mat<D>::Identity() + H[p - p0]) * P.F[p];
      const double J = P.F[p].determinant();
      if (!(J > 0.0)) [[unlikely]]
        throw ParticleFailure{p, "det F = " + format_number(J) + " <= 0"};
      P.V[p] = J * P.V0[p];
      P.rho[p] = P.m[p] / P.V[p];
      P.sigma[p] = Law(c, P.F[p]);
      P.eps[p] = 0.5 * (P.F[p] + P.F[p].transpose()) - Mat<D>::Identity();
    }
  }
  void add_energies(const Particles<D>& P, int p0, int p1, double& stored, double&) const override {
    if constexpr (std::is_same_v<Potential, NoPotential>)
      for (int p = p0; p < p1; ++p) stored += P.V0[p] * straight_path_work<D, Law>(c_, P.F[p], P.sigma[p], P.eps[p]);
    else
      for (int p = p0; p < p1; ++p) stored += P.V0[p] * Potential::density(c_, P.F[p]);
  }
  /// sigma_zz = ZzLaw(F_p): the law evaluated on the F_p of the last update.
  void out_of_plane_stress(const Particles<D>& P, int p0, int p1, double* out) const override {
    if constexpr (D != 2) {
      Material<D>::out_of_plane_stress(P, p0, p1, out);
    } else {
      for (int p = p0; p < p1; ++p) out[p - p0] = ZzLaw(c_, P.F[p]);
    }
  }

private:
  ElasticConstants c_;
};

template <int D> std::unique_ptr<Material<D>> make_linear_elastic(const MaterialParameters& p) {
  return std::make_unique<LinearElastic<D>>(p);
}
template <int D> std::unique_ptr<Material<D>> make_linear_elastic_finite(const MaterialParameters& p) {
  return std::make_unique<FiniteElastic<D, linear_elastic_finite_stress<D>, linear_elastic_finite_out_of_plane,
                                         linear_elastic_finite_wave_modulus<D>>>(p);
}
template <int D> std::unique_ptr<Material<D>> make_neo_hookean(const MaterialParameters& p) {
  return std::make_unique<FiniteElastic<D, neo_hookean_stress<D>, neo_hookean_out_of_plane,
                                         neo_hookean_wave_modulus<D>, NeoHookeanPotential<D>>>(p);
}

} // namespace

/// Steel: the example material of the elastic models.
const std::array<ParameterValue, 3> kSteel{{{"density", 7833.0}, {"young", 200.0e9}, {"poisson", 0.3}}};

const MaterialModel& linear_elastic_model() {
  static const MaterialModel m{"linear_elastic", "small-strain isotropic elasticity (molinos et al.)", {}, {},
                               make_linear_elastic<1>, make_linear_elastic<2>, make_linear_elastic<3>, kSteel, true};
  return m;
}

const MaterialModel& linear_elastic_finite_model() {
  static const MaterialModel m{"linear_elastic_finite", "St. Venant-like law of wobbes et al. eq. 10 (not objective)",
                               {}, {}, make_linear_elastic_finite<1>, make_linear_elastic_finite<2>,
                               make_linear_elastic_finite<3>, kSteel};
  return m;
}

const MaterialModel& neo_hookean_model() {
  static const MaterialModel m{"neo_hookean", "compressible neo-Hookean (wobbes et al. eq. 11)", {}, {},
                               make_neo_hookean<1>, make_neo_hookean<2>, make_neo_hookean<3>, kSteel};
  return m;
}

} // namespace otmpm
