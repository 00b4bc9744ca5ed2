// Constitutive models (docs/theory.md sect. 9): the
// small-strain increment, the two finite-strain models of wobbes eqs. 10 and
// 11, their small-deformation limit, a hand computation and objectivity; the
// Material interface (batch update, energies, failures) and the model table.
#include "otmpm/materials/hencky_solid_j2.hpp"
#include "otmpm/materials/material.hpp"
#include "otmpm/materials/pore_fluid.hpp"

#include <Eigen/Geometry>
#include <doctest/doctest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <string>
#include <type_traits>

using namespace otmpm;

namespace {

/// The elastic laws under test, by model.
enum class Model { linear_elastic, linear_elastic_finite, neo_hookean };
struct Law {
  Model model;
  ElasticConstants c;
  double young, poisson;
};
Law make(Model model, double young, double poisson) { return {model, {1000.0, young, poisson}, young, poisson}; }
template <int D> Mat<D> cauchy_stress(const Law& m, const Mat<D>& F) {
  return m.model == Model::neo_hookean ? neo_hookean_stress<D>(m.c, F) : linear_elastic_finite_stress<D>(m.c, F);
}
template <int D> Mat<D> elastic_stress_increment(const Law& m, const Mat<D>& d) {
  return otmpm::elastic_stress_increment<D>(m.c, d);
}

constexpr double kE = 10.0, kNu = 0.3;
// Lame parameters of E = 10, nu = 0.3 by hand: lambda = E nu / ((1+nu)(1-2nu))
// = 3 / 0.52, mu = E / (2 (1 + nu)) = 10 / 2.6.
constexpr double kLambda = 3.0 / 0.52, kMu = 10.0 / 2.6;

/// A fixed, non-symmetric, well-conditioned D x D matrix (entries O(1)).
template <int D> Mat<D> sample_matrix() {
  Mat<D> H;
  for (int i = 0; i < D; ++i)
    for (int j = 0; j < D; ++j) H(i, j) = std::sin(1.0 + 3.0 * i + 1.7 * j); // deterministic "random"
  return H;
}

/// A rotation: by angle theta about z (2D: in the plane); 3D: about the axis (1, 2, 3).
template <int D> Mat<D> rotation(double theta) {
  if constexpr (D == 2) {
    Mat<2> R;
    R << std::cos(theta), -std::sin(theta), std::sin(theta), std::cos(theta);
    return R;
  } else {
    return Eigen::AngleAxisd(theta, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  }
}

// Stresses of magnitude E ~ 10 computed from O(1) entries with a few dozen
// operations: round-off is ~1e-15 E; 1e-13 E is the bound used for "exact".
constexpr double kExact = 1e-13 * kE;

} // namespace

TEST_CASE("Lame parameters and P-wave modulus") {
  const ElasticConstants m{1000.0, kE, kNu};
  CHECK(m.lambda() == doctest::Approx(kLambda).epsilon(1e-15));
  CHECK(m.mu() == doctest::Approx(kMu).epsilon(1e-15));
  CHECK(m.p_modulus(1) == kE); // uniaxial stress in 1D
  CHECK(m.p_modulus(2) == doctest::Approx(kLambda + 2 * kMu).epsilon(1e-15));
  CHECK(m.p_modulus(3) == doctest::Approx(kLambda + 2 * kMu).epsilon(1e-15));
}

TEST_CASE("the model table: names, deformation gradient, P-wave modulus of the built material") {
  CHECK(material_model_list() == "linear_elastic, linear_elastic_finite, neo_hookean, j2, drucker_prager or mu_i");
  CHECK(find_material_model("hookean") == nullptr);
  MaterialParameters p{.name = "m", .model = "linear_elastic", .density = 1000.0, .young = kE, .poisson = kNu, .extra = {}};
  CHECK(!make_material<2>(p)->needs_deformation_gradient());
  CHECK(make_material<2>(p)->p_modulus() == doctest::Approx(kLambda + 2 * kMu).epsilon(1e-15));
  CHECK(make_material<1>(p)->p_modulus() == kE);
  for (const char* model : {"linear_elastic_finite", "neo_hookean"}) {
    p.model = model;
    CHECK(make_material<3>(p)->needs_deformation_gradient());
  }
}

TEST_CASE("small-strain increment: lambda tr(d_eps) I + 2 mu d_eps in 2D and 3D, E d_eps in 1D") {
  const Law m = make(Model::linear_elastic, kE, kNu);
  {
    Mat<1> d;
    d << 1e-3;
    CHECK(elastic_stress_increment<1>(m, d)(0, 0) == doctest::Approx(kE * 1e-3).epsilon(1e-15));
  }
  {
    Mat<2> d;
    d << 1e-3, 2e-4, 2e-4, -5e-4;
    const Mat<2> s = elastic_stress_increment<2>(m, d);
    // By hand: tr = 5e-4; plane strain.
    CHECK(s(0, 0) == doctest::Approx(kLambda * 5e-4 + 2 * kMu * 1e-3).epsilon(1e-14));
    CHECK(s(1, 1) == doctest::Approx(kLambda * 5e-4 - 2 * kMu * 5e-4).epsilon(1e-14));
    CHECK(s(0, 1) == doctest::Approx(2 * kMu * 2e-4).epsilon(1e-14));
    CHECK(s(1, 0) == s(0, 1));
  }
  {
    Mat<3> d = 1e-3 * sample_matrix<3>();
    d = (0.5 * (d + d.transpose())).eval();
    const Mat<3> s = elastic_stress_increment<3>(m, d);
    const Mat<3> expected = kLambda * d.trace() * Mat<3>::Identity() + 2 * kMu * d;
    CHECK((s - expected).norm() <= 1e-3 * kExact);
  }
}

TEST_CASE("finite models: F = I gives zero stress (1D, 2D, 3D)") {
  for (auto model : {Model::linear_elastic_finite, Model::neo_hookean}) {
    const Law m = make(model, kE, kNu);
    CHECK(cauchy_stress<1>(m, Mat<1>::Identity()).norm() == 0.0);
    CHECK(cauchy_stress<2>(m, Mat<2>::Identity()).norm() == 0.0);
    CHECK(cauchy_stress<3>(m, Mat<3>::Identity()).norm() == 0.0);
  }
}

namespace {

/// |sigma(I + eps H) - C : sym(eps H)| for the finite model (C: plane strain /
/// 3D isotropic, or E in 1D with the uniaxial modulus).
template <int D> double small_strain_gap(const Law& m, double eps) {
  const Mat<D> H = eps * sample_matrix<D>();
  const Mat<D> F = Mat<D>::Identity() + H;
  const Mat<D> e = 0.5 * (H + H.transpose());
  const Law lin = make(Model::linear_elastic, m.young, D == 1 ? 0.0 : m.poisson);
  return (cauchy_stress<D>(m, F) - elastic_stress_increment<D>(lin, e)).norm();
}

template <int D> void check_small_strain_limit(Model model) {
  INFO("dimension " << D << ", model " << static_cast<int>(model));
  // 1D finite models use the uniaxial modulus lambda + 2 mu -> E only for nu = 0.
  const Law m = make(model, kE, D == 1 ? 0.0 : kNu);
  const double e1 = small_strain_gap<D>(m, 1e-3), e2 = small_strain_gap<D>(m, 5e-4);
  // O(eps^2): the gap is below a few E eps^2 (|H| ~ 2, the quadratic terms of
  // eqs. 10-11 carry factors lambda, mu <= 2 E) ...
  CHECK(e1 <= 20 * kE * 1e-6);
  // ... and halving eps divides it by 4 (third-order terms: 1e-3 relative;
  // round-off 1e-15 E is 1e-9 of the gap).
  CHECK(e1 / e2 == doctest::Approx(4.0).epsilon(0.01));
}

} // namespace

TEST_CASE("finite models reduce to linear elasticity to O(eps^2) (with rotation part)") {
  for (auto model : {Model::linear_elastic_finite, Model::neo_hookean}) {
    check_small_strain_limit<2>(model);
    check_small_strain_limit<3>(model);
  }
  check_small_strain_limit<1>(Model::neo_hookean);
}

TEST_CASE("linear_elastic_finite in 1D is exactly sigma = E (F - 1)") {
  // lambda = 0, mu = E/2: sigma = 2 mu / J F (F - 1) = E (F - 1) for J = F.
  const Law m = make(Model::linear_elastic_finite, kE, 0.0);
  for (double f : {0.8, 1.001, 1.3}) {
    Mat<1> F;
    F << f;
    CHECK(cauchy_stress<1>(m, F)(0, 0) == doctest::Approx(kE * (f - 1)).epsilon(1e-14));
  }
}

TEST_CASE("neo-Hookean (wobbes eq. 11) matches a hand computation in 2D") {
  // F = [[a, b], [0, d]]: J = a d, F F^T = [[a^2 + b^2, b d], [b d, d^2]],
  // sigma = lambda ln J / J I + mu / J (F F^T - I), component by component.
  const double a = 1.2, b = 0.1, d = 0.9, J = a * d;
  Mat<2> F;
  F << a, b, 0.0, d;
  const Mat<2> s = cauchy_stress<2>(make(Model::neo_hookean, kE, kNu), F);
  CHECK(s(0, 0) == doctest::Approx(kLambda * std::log(J) / J + kMu / J * (a * a + b * b - 1)).epsilon(1e-14));
  CHECK(s(0, 1) == doctest::Approx(kMu / J * b * d).epsilon(1e-14));
  CHECK(s(1, 0) == doctest::Approx(kMu / J * b * d).epsilon(1e-14));
  CHECK(s(1, 1) == doctest::Approx(kLambda * std::log(J) / J + kMu / J * (d * d - 1)).epsilon(1e-14));
  // The same numbers evaluated independently (Python, double precision).
  CHECK(s(0, 0) == doctest::Approx(2.013680775299831).epsilon(1e-14));
  CHECK(s(0, 1) == doctest::Approx(0.32051282051282054).epsilon(1e-14));
  CHECK(s(1, 1) == doctest::Approx(-0.26552150390244783).epsilon(1e-14));
}

TEST_CASE("neo-Hookean 1D: uniaxial sigma = E/2 (F^2 - 1) / F") {
  // 1D uses lambda = 0, mu = E/2 (uniaxial modulus E at small strain).
  Mat<1> F;
  F << 1.1;
  const double s = cauchy_stress<1>(make(Model::neo_hookean, kE, 0.0), F)(0, 0);
  CHECK(s == doctest::Approx(kE / 2 * (1.1 * 1.1 - 1) / 1.1).epsilon(1e-14));
}

TEST_CASE("linear_elastic_finite (wobbes eq. 10) matches a hand computation in 2D") {
  // E_s = sym(F) - I = [[a-1, b/2], [b/2, d-1]], sigma = lambda/J tr(E_s) F +
  // 2 mu / J F E_s. Eq. 10 as printed is not symmetric (F E_s is not).
  const double a = 1.2, b = 0.1, d = 0.9, J = a * d, tr = a + d - 2;
  Mat<2> F;
  F << a, b, 0.0, d;
  const Mat<2> s = cauchy_stress<2>(make(Model::linear_elastic_finite, kE, kNu), F);
  const double FE00 = a * (a - 1) + b * b / 2, FE01 = a * b / 2 + b * (d - 1);
  const double FE10 = d * b / 2, FE11 = d * (d - 1);
  CHECK(s(0, 0) == doctest::Approx(kLambda / J * tr * a + 2 * kMu / J * FE00).epsilon(1e-14));
  CHECK(s(0, 1) == doctest::Approx(kLambda / J * tr * b + 2 * kMu / J * FE01).epsilon(1e-14));
  CHECK(s(1, 0) == doctest::Approx(2 * kMu / J * FE10).epsilon(1e-14));
  CHECK(s(1, 1) == doctest::Approx(kLambda / J * tr * d + 2 * kMu / J * FE11).epsilon(1e-14));
  CHECK(s(0, 0) == doctest::Approx(2.3860398860398857).epsilon(1e-14));
  CHECK(s(0, 1) == doctest::Approx(0.40954415954415957).epsilon(1e-14));
}

namespace {

template <int D> void check_objectivity(const Law& m) {
  INFO("dimension " << D);
  const Mat<D> F = Mat<D>::Identity() + 0.2 * sample_matrix<D>();
  REQUIRE(F.determinant() > 0.0);
  const Mat<D> s = cauchy_stress<D>(m, F);
  for (double theta : {0.3, 1.0, 2.5}) {
    const Mat<D> R = rotation<D>(theta);
    const Mat<D> sR = cauchy_stress<D>(m, Mat<D>(R * F));
    CHECK((sR - R * s * R.transpose()).norm() <= kExact);
    // A rigid rotation alone is stress free.
    CHECK(cauchy_stress<D>(m, R).norm() <= kExact);
  }
}

} // namespace

TEST_CASE("neo-Hookean is objective: sigma(R F) = R sigma(F) R^T (2D, 3D)") {
  const Law m = make(Model::neo_hookean, kE, kNu);
  check_objectivity<2>(m);
  check_objectivity<3>(m);
}

TEST_CASE("linear_elastic_finite is objective only to first order: a rotation by theta gives O(theta^2) stress") {
  // Eq. 10 uses sym(F) - I, which a rigid rotation R does not leave at zero:
  // sym(R) - I = (cos theta - 1) I in 2D, so sigma(R) = O(E theta^2). That is
  // the model of the paper (used there for axis-aligned motion only); the
  // neo-Hookean model is the objective one.
  const Law m = make(Model::linear_elastic_finite, kE, kNu);
  for (double theta : {1e-2, 1e-3}) {
    const double s = cauchy_stress<2>(m, rotation<2>(theta)).norm();
    // By hand: E_s = (cos theta - 1) I, J = 1, sigma = (cos theta - 1)(2 lambda + 2 mu) R:
    // |sigma|_F = sqrt(2) (1 - cos theta) 2 (lambda + mu).
    CHECK(s == doctest::Approx(std::sqrt(2.0) * (1 - std::cos(theta)) * 2 * (kLambda + kMu)).epsilon(1e-6));
  }
}

namespace {

/// Two particles of a 2D plane-strain body at rest: V = 1, m = rho V.
Particles<2> two_particles() {
  Particles<2> P;
  P.resize(2);
  for (int p = 0; p < 2; ++p) {
    P.V[p] = P.V0[p] = 1.0;
    P.rho[p] = 1000.0;
    P.m[p] = 1000.0;
  }
  return P;
}

} // namespace

TEST_CASE("Material::update: a batch gives each particle the stress of its own H (linear_elastic, neo_hookean)") {
  const Mat<2> H[2] = {1e-3 * sample_matrix<2>(), -2e-3 * sample_matrix<2>().transpose()};
  {
    auto m = make_material<2>({.name = "m", .model = "linear_elastic", .density = 1000.0, .young = kE, .poisson = kNu, .extra = {}});
    Particles<2> P = two_particles();
    m->update(P, 0, 2, H, 1e-3);
    for (int p = 0; p < 2; ++p) {
      const Mat<2> e = 0.5 * (H[p] + H[p].transpose());
      CHECK((P.sigma[p] - elastic_stress_increment<2>(make(Model::linear_elastic, kE, kNu), e)).norm() <= kExact);
      CHECK(P.eps[p] == e);
      CHECK(P.rho[p] == doctest::Approx(1000.0 / (1.0 + e.trace())).epsilon(1e-15));
      CHECK(P.V[p] * P.rho[p] == doctest::Approx(P.m[p]).epsilon(1e-15));
    }
  }
  {
    auto m = make_material<2>({.name = "m", .model = "neo_hookean", .density = 1000.0, .young = kE, .poisson = kNu, .extra = {}});
    Particles<2> P = two_particles();
    P.allocate_optional(false, true);
    m->update(P, 0, 2, H, 1e-3);
    for (int p = 0; p < 2; ++p) {
      const Mat<2> F = Mat<2>::Identity() + H[p];
      CHECK(P.F[p] == F);
      CHECK((P.sigma[p] - cauchy_stress<2>(make(Model::neo_hookean, kE, kNu), F)).norm() <= kExact);
      CHECK(P.V[p] == doctest::Approx(F.determinant()).epsilon(1e-15));
    }
  }
}

TEST_CASE("Material::update: det F <= 0 is a ParticleFailure naming the first failing particle") {
  auto m = make_material<2>({.name = "m", .model = "neo_hookean", .density = 1000.0, .young = kE, .poisson = kNu, .extra = {}});
  Particles<2> P = two_particles();
  P.allocate_optional(false, true);
  Mat<2> H[2] = {Mat<2>::Zero(), Mat<2>::Zero()};
  H[1](0, 0) = -1.5; // F = diag(-0.5, 1): det F = -0.5
  try {
    m->update(P, 0, 2, H, 1e-3);
    FAIL("no ParticleFailure");
  } catch (const ParticleFailure& f) {
    CHECK(f.particle == 1);
    CHECK(f.what.find("det F = -0.5") != std::string::npos);
    CHECK(P.F[0] == Mat<2>::Identity()); // the particle before it was updated
  } catch (...) {
    FAIL("another exception");
  }
}

TEST_CASE("linear_elastic's stored energy: V (phi1 sigma0 : eps + phi2 eps : C : eps), from rest or an initial stress") {
  // Particle 0 starts unstressed (sigma = C : eps); particle 1 starts from
  // sigma0 (a geostatic start), V = 3. tr eps = 7e-4: phi1 = 1 - a/2 + a^2/6,
  // phi2 = 1/2 - a/6 + a^2/24 (theory.md eq. 11.1a) to 1e-13.
  auto m = make_material<2>({.name = "m", .model = "linear_elastic", .density = 1000.0, .young = kE, .poisson = kNu, .extra = {}});
  Particles<2> P = two_particles();
  Mat<2> eps, sigma0;
  eps << 1e-3, 2e-4, 2e-4, -3e-4;
  sigma0 << -2.0, 0.0, 0.0, -5.0;
  const Mat<2> c_eps = otmpm::elastic_stress_increment<2>({1000.0, kE, kNu}, eps);
  P.eps[0] = P.eps[1] = eps;
  P.sigma[0] = c_eps, P.sigma[1] = sigma0 + c_eps;
  P.V[1] = 3.0;
  double stored = 0.0, dissipated = 0.0;
  m->add_energies(P, 0, 2, stored, dissipated);
  const double a = eps.trace(), phi1 = 1 - a / 2 + a * a / 6, phi2 = 0.5 - a / 6 + a * a / 24;
  const double elastic = phi2 * c_eps.cwiseProduct(eps).sum(), initial = phi1 * sigma0.cwiseProduct(eps).sum();
  CHECK(stored == doctest::Approx(elastic + 3.0 * (initial + elastic)).epsilon(1e-13));
  CHECK(dissipated == 0.0);
}

template <int D> void check_energy_batches() {
  // 150 particles (two batches of the weights and a remainder) whose
  // tr eps runs from about -0.3 to 0.3, on both sides of the series' bound
  // |a| = 0.1, every seventh next to it (at it where the perturbation is
  // zero): the sum over the range has the bits of the particles added one
  // call at a time, and the value of eq. 11.1a to round-off.
  auto m = make_material<D>({.name = "m", .model = "linear_elastic", .density = 1000.0, .young = kE, .poisson = kNu,
                             .extra = {}});
  Particles<D> P;
  const int n = 150;
  P.resize(n);
  for (int p = 0; p < n; ++p) {
    const double a = -0.3 + 0.6 * p / (n - 1);
    P.eps[p] = (p % 7 == 0 ? 0.1 : a) / D * Mat<D>::Identity() + 1e-3 * (p % 5) * sample_matrix<D>();
    P.sigma[p] = (-1e4 * (1 + p % 3)) * Mat<D>::Identity() + 10.0 * p * sample_matrix<D>();
    P.V[p] = 1.0 + 0.01 * p;
  }
  double range = 0.0, single = 0.0, dissipated = 0.0;
  m->add_energies(P, 0, n, range, dissipated);
  for (int p = 0; p < n; ++p) m->add_energies(P, p, p + 1, single, dissipated);
  CHECK(std::isfinite(range));
  CHECK(range == single);
  // The weights' series in AVX2 lanes where the processor has them: the
  // portable loop gives the same bits.
  otmpm::plasticity::point::set_wide_lanes(false);
  double portable = 0.0;
  m->add_energies(P, 0, n, portable, dissipated);
  otmpm::plasticity::point::set_wide_lanes(true);
  CHECK(portable == range);
  // eq. 11.1a term by term: phi_1 = (1 - e^-a) / a, phi_2 = (a - 1 + e^-a) / a^2, by
  // their series to a^7 (Horner) below |a| = 0.1, its factorials formed here.
  double expected = 0.0;
  for (int p = 0; p < n; ++p) {
    const double a = P.eps[p].trace();
    double phi1 = -std::expm1(-a) / a, phi2 = (a + std::expm1(-a)) / (a * a);
    if (std::abs(a) < 0.1) {
      phi1 = phi2 = 0.0;
      double factorial = 40320.0; // 8!
      for (int k = 7; k >= 0; --k) {
        phi1 = 1.0 / factorial - a * phi1; // 1 / (k + 1)!
        phi2 = 1.0 / (factorial * (k + 2)) - a * phi2; // 1 / (k + 2)!
        factorial /= (k + 1);
      }
    }
    const Mat<D> c_eps = otmpm::elastic_stress_increment<D>({1000.0, kE, kNu}, P.eps[p]);
    expected += P.V[p] * (phi1 * (P.sigma[p] - c_eps).cwiseProduct(P.eps[p]).sum() +
                          phi2 * c_eps.cwiseProduct(P.eps[p]).sum());
  }
  CHECK(range == doctest::Approx(expected).epsilon(1e-15));
}

TEST_CASE("linear_elastic's stored energy over a range has the bits of one particle at a time (its weights in "
          "batches, both sides of the series' bound)") {
  check_energy_batches<1>();
  check_energy_batches<2>();
  check_energy_batches<3>();
}

namespace {

/// Drives one particle (V0 = 1) of `model` along the straight path F(s) = I
/// + s G in n increments (linear_elastic: eps(s) = s sym(G), from the stress
/// sigma0) and returns the stored energy the material reports at the end and
/// the work its stress did, the stress power V sigma : L dt summed with the
/// trapezoidal rule, L dt = (F_k+1 - F_k) ((F_k + F_k+1) / 2)^-1 (sym(G) / n
/// for linear_elastic): both second order in 1/n.
template <int D> std::pair<double, double> straight_path_energy(const std::string& model, const Mat<D>& G,
                                                                const Mat<D>& sigma0, int n) {
  auto m = make_material<D>({.name = "m", .model = model, .density = 1000.0, .young = kE, .poisson = kNu, .extra = {}});
  Particles<D> P;
  P.resize(1);
  P.allocate_optional(false, true);
  P.V[0] = P.V0[0] = 1.0, P.m[0] = P.rho[0] = 1000.0;
  P.sigma[0] = sigma0;
  const bool small_strain = model == "linear_elastic";
  const Mat<D> I = Mat<D>::Identity();
  double work = 0.0;
  for (int k = 0; k < n; ++k) {
    const Mat<D> F0 = I + (double(k) / n) * G, F1 = I + (double(k + 1) / n) * G;
    const Mat<D> H = small_strain ? Mat<D>(0.5 * (G + G.transpose()) / n) : Mat<D>((F1 - F0) * F0.inverse());
    const Mat<D> L_dt = small_strain ? H : Mat<D>((F1 - F0) * (0.5 * (F0 + F1)).inverse());
    const Mat<D> before = P.V[0] * P.sigma[0];
    m->update(P, 0, 1, &H, 1e-3);
    work += 0.5 * (before + P.V[0] * P.sigma[0]).cwiseProduct(L_dt).sum();
  }
  double stored = 0.0, dissipated = 0.0;
  m->add_energies(P, 0, 1, stored, dissipated);
  return {stored, work};
}

template <int D> void check_straight_path_energy() {
  // A stretch of 8 % with shear and rotation (sample_matrix is not
  // symmetric), from rest and (linear_elastic) from an initial stress.
  // 1/2 sigma : eps V, the stored energy counted before, is off by about
  // tr(eps) / 3 of it on this path (5e-3 to 3e-2): the bound 2e-5 takes the
  // work's O(1/n^2) and linear_elastic's volume, prod (1 + tr d_eps), against
  // exp(tr eps): O(tr(eps)^2 / n).
  const Mat<D> G = 0.08 * sample_matrix<D>();
  Mat<D> sigma0 = -0.3 * Mat<D>::Identity();
  sigma0(0, 0) = -0.5;
  for (const std::string model : {"linear_elastic", "linear_elastic_finite", "neo_hookean"})
    for (const bool prestressed : {false, true}) {
      if (prestressed && model != "linear_elastic") continue;
      INFO(D << "D " << model << std::string(prestressed ? ", from sigma0" : ""));
      const auto [stored, work] = straight_path_energy<D>(model, G, prestressed ? sigma0 : Mat<D>::Zero(), 2000);
      CHECK(std::abs(work) > 1e-3);
      CHECK(stored == doctest::Approx(work).epsilon(2e-5));
    }
}

} // namespace

TEST_CASE("the elastic laws store the work their stress does along a straight path, 1D to 3D") {
  check_straight_path_energy<1>();
  check_straight_path_energy<2>();
  check_straight_path_energy<3>();
}

TEST_CASE("linear_elastic in plane strain: sigma_zz = lambda tr(eps) plus the particle's initial out-of-plane stress") {
  auto m = make_material<2>({.name = "m", .model = "linear_elastic", .density = 1000.0, .young = kE, .poisson = kNu, .extra = {}});
  Particles<2> P = two_particles();
  P.eps[0] << 1e-3, 0.0, 0.0, -3e-4;
  P.eps[1] = P.eps[0];
  double zz[2];
  m->out_of_plane_stress(P, 0, 2, zz);
  CHECK(zz[0] == doctest::Approx(kLambda * 7e-4).epsilon(1e-14));
  const double zero = 0.0;
  P.add_state(std::string(kInitialOutOfPlaneStressField), 1, &zero).values[1] = -4.0;
  m->out_of_plane_stress(P, 0, 2, zz);
  CHECK(zz[0] == doctest::Approx(kLambda * 7e-4).epsilon(1e-14));
  CHECK(zz[1] == doctest::Approx(kLambda * 7e-4 - 4.0).epsilon(1e-14));
}

namespace {

/// The model parameters of an example material of each model in the table
/// (a model added to the table must be added here: the loops below check it).
std::map<std::string, double> example_parameters(std::string_view model) {
  if (model == "j2") return {{"yield_stress", 1e6}};
  if (model == "drucker_prager") return {{"friction_angle", 30.0}};
  if (model == "mu_i")
    return {{"mu_s", 0.38}, {"mu_2", 0.64}, {"I_0", 0.28}, {"grain_diameter", 1e-3}, {"grain_density", 2500.0},
            {"critical_packing", 0.38}};
  return {};
}

/// One particle of a 2D plane-strain body with F, its reference volume V0 =
/// 1 and mass 1000 (rho0 = 1000), and the material's state.
Particles<2> particle_with_F(Material<2>& m, const Mat<2>& F) {
  Particles<2> P;
  P.resize(1);
  P.allocate_optional(false, true);
  P.F[0] = F;
  P.V0[0] = 1.0;
  P.m[0] = 1000.0;
  P.V[0] = F.determinant();
  P.rho[0] = P.m[0] / P.V[0];
  for (const StateSpec& st : m.state()) P.add_state(std::string(st.name), st.width, st.initial.data());
  m.bind(P);
  return P;
}

double wave_speed2(const Material<2>& m, const Particles<2>& P) {
  double c2 = 0.0;
  m.max_wave_speed2(P, 0, 1, c2);
  return c2;
}

} // namespace

TEST_CASE("every model's wave speed: M / rho at rest, a dilated stress-free particle does not raise it") {
  // At rest (F = I) every model's tangent is its P-wave modulus: c^2 = M /
  // rho0. A particle dilated to J = 4 (F = 2 I) without stress - the state
  // the Hencky models reach by plastic dilation or below the critical
  // packing (b_e = I) - has rho = rho0 / 4: its c^2 stays M / rho0 (Kirchhoff
  // tangent M, Cauchy tangent M / J), where M / rho_p would be 4 M / rho0 and
  // cut the step by 2.
  for (const MaterialModel* model : material_models()) {
    CAPTURE(model->name);
    MaterialParameters p{.name = "m", .model = std::string(model->name), .density = 1000.0, .young = kE,
                         .poisson = kNu, .extra = example_parameters(model->name)};
    auto m = make_material<2>(p);
    Particles<2> rest = particle_with_F(*m, Mat<2>::Identity());
    CHECK(wave_speed2(*m, rest) == doctest::Approx(m->p_modulus() / 1000.0).epsilon(1e-15));
    if (m->state().empty() || m->state()[0].name != "elastic_left_cauchy_green") continue;
    Particles<2> dilated = particle_with_F(*m, 2.0 * Mat<2>::Identity()); // b_e = I: stress-free
    CHECK(wave_speed2(*m, dilated) == wave_speed2(*m, rest));
  }
}

TEST_CASE("finite elastic wave speeds: the tangent along the principal stretches (1D exact, 2D by hand)") {
  // 1D: sigma = P of a bar; the spatial wave speed is F times the
  // Lagrangian sqrt(dP/dF / rho0): neo_hookean P = E/2 (F^2 - 1)/F gives c^2
  // = E/2 (F^2 + 1) / rho0, linear_elastic_finite P = E (F - 1) gives E F^2
  // / rho0.
  for (const double f : {0.7, 1.3}) {
    Mat<1> F;
    F << f;
    const ElasticConstants c{1000.0, kE, 0.0};
    CHECK(neo_hookean_wave_modulus<1>(c, F) == doctest::Approx(kE / 2 * (f * f + 1)).epsilon(1e-15));
    CHECK(linear_elastic_finite_wave_modulus<1>(c, F) == doctest::Approx(kE * f * f).epsilon(1e-15));
    // The same from finite differences of P(F): rho0 c^2 = F^2 dP/dF.
    const double d = 1e-6;
    auto P_neo = [&](double x) { return kE / 2 * (x * x - 1) / x; };
    CHECK(neo_hookean_wave_modulus<1>(c, F) ==
          doctest::Approx(f * f * (P_neo(f + d) - P_neo(f - d)) / (2 * d)).epsilon(1e-8));
  }
  // 2D, stretches u = (1.2, 0.9) along the axes: neo_hookean lambda (1 - ln
  // J) + mu (u_max^2 + 1), linear_elastic_finite (lambda + 2 mu) u_max^2.
  Mat<2> F;
  F << 1.2, 0.0, 0.0, 0.9;
  const ElasticConstants c{1000.0, kE, kNu};
  CHECK(neo_hookean_wave_modulus<2>(c, F) ==
        doctest::Approx(kLambda * (1 - std::log(1.08)) + kMu * (1.44 + 1)).epsilon(1e-14));
  CHECK(linear_elastic_finite_wave_modulus<2>(c, F) == doctest::Approx((kLambda + 2 * kMu) * 1.44).epsilon(1e-14));
  // Rotated stretches: the bound (largest row sum of F F^T) is at least the
  // largest eigenvalue 1.44 and within the row's spread of it.
  const Mat<2> RF = rotation<2>(0.4) * F;
  CHECK(linear_elastic_finite_wave_modulus<2>(c, RF) >= (kLambda + 2 * kMu) * 1.44 * (1 - 1e-15));
  CHECK(linear_elastic_finite_wave_modulus<2>(c, RF) <= (kLambda + 2 * kMu) * (1.44 + (1.44 - 0.81)));
}

TEST_CASE("neo_hookean: the stored energy is the potential of the stress, J sigma F^-T = dW/dF, in 1D, 2D and 3D") {
  // Central differences of W at a finite stretch with shear; their error is
  // O(e^2 W'''), about 1e-9 of the stress at e = 1e-6.
  const ElasticConstants c{1000.0, kE, kNu};
  auto check = [&](auto dim) {
    constexpr int D = decltype(dim)::value;
    Mat<D> F = Mat<D>::Identity();
    for (int i = 0; i < D; ++i)
      for (int j = 0; j < D; ++j) F(i, j) += (i == j ? 0.6 : 0.1 * (i + 2 * j + 1));
    const Mat<D> P = F.determinant() * neo_hookean_stress<D>(c, F) * F.inverse().transpose();
    const double e = 1e-6;
    for (int i = 0; i < D; ++i)
      for (int j = 0; j < D; ++j) {
        Mat<D> Fp = F, Fm = F;
        Fp(i, j) += e, Fm(i, j) -= e;
        const double dW = (neo_hookean_energy<D>(c, Fp) - neo_hookean_energy<D>(c, Fm)) / (2.0 * e);
        CHECK(dW == doctest::Approx(P(i, j)).epsilon(1e-6).scale(kE));
      }
    CHECK(neo_hookean_energy<D>(c, Mat<D>::Identity()) == 0.0);
    // Near F = I, W -> lambda/2 tr(eps)^2 + mu |eps|^2 (eps = sym(F) - I, to
    // O(|eps|^3) and O(|skew|^2 |eps|)), to all digits where tr(F F^T) - D
    // and ln J in double would cancel to noise of 1e-16 mu (1e-6 of W at
    // |eps| = 1e-5, all of it at 1e-9: a gravity ramp's first steps read as
    // energy created).
    for (const double size : {1e-5, 1e-9, 1e-13}) {
      const Mat<D> H = size * sample_matrix<D>(), eps = 0.5 * (H + H.transpose());
      const double lambda = D == 1 ? 0.0 : c.lambda(), mu = D == 1 ? 0.5 * c.young : c.mu(); // 1D: uniaxial stress
      const double small = 0.5 * lambda * eps.trace() * eps.trace() + mu * eps.squaredNorm();
      CHECK(neo_hookean_energy<D>(c, Mat<D>::Identity() + H) == doctest::Approx(small).epsilon(1e-4));
    }
  };
  check(std::integral_constant<int, 1>{});
  check(std::integral_constant<int, 2>{});
  check(std::integral_constant<int, 3>{});
}
