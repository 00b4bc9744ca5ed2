// Plane strain's out-of-plane stress sigma_zz (Material::out_of_plane_stress,
// docs/theory.md sect. 9, "Out-of-plane stress"): for every material model,
// the sigma_zz a 2D material derives at output time from its state equals
// the sigma_zz the 3D model computes itself for the same motion (F with
// F_zz = 1, F_xz = F_yz = 0), along a path of many steps, elastic and - for
// j2 (linear hardening, Johnson-Cook) and drucker_prager - yielding. The 3D
// stress is an independent computation: its own update (3x3 increments,
// the 3D eigen-decomposition of the Hencky models) and no formula of the 2D
// derivation.
#include "otmpm/materials/material.hpp"
#include "otmpm/materials/hencky_plasticity.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

using namespace otmpm;

namespace {

constexpr double kE = 200e9, kNu = 0.3;
constexpr int kParticles = 3; // an odd count: J2's plane update takes pairs and one particle alone
constexpr int kSteps = 400;

/// A material of `model` with young = kE, poisson = kNu and `extra` parameters.
MaterialParameters parameters(const std::string& model, std::map<std::string, double> extra = {}) {
  return {.name = "m", .model = model, .density = 7800.0, .young = kE, .poisson = kNu, .extra = std::move(extra)};
}

/// n particles of unit volume at rest, with F = I and the material's state.
template <int D> Particles<D> particles(Material<D>& m, int n) {
  Particles<D> P;
  P.resize(n);
  P.allocate_optional(false, true);
  for (int p = 0; p < n; ++p) {
    P.V[p] = P.V0[p] = 1.0;
    P.m[p] = P.rho[p] = 7800.0;
  }
  for (const StateSpec& s : m.state()) P.add_state(std::string(s.name), s.width, s.initial.data());
  m.bind(P);
  return P;
}

/// The in-plane deformation gradient of particle p at time t in [0, 1]:
/// stretches and shear of magnitude `amplitude` (strain), different per
/// particle, compressive on average when `compress` (Drucker-Prager: a soil
/// without cohesion carries no tension).
Mat<2> path(double t, int p, double amplitude, bool compress) {
  const double s = std::sin(3.0 * t + p), c = std::cos(2.0 * t - 0.5 * p);
  const double bias = compress ? -0.3 : 0.0;
  Mat<2> F;
  F << 1.0 + amplitude * t * (bias + 0.6 * s), amplitude * t * (0.8 + 0.3 * p) * c,
      0.4 * amplitude * t * s, 1.0 + amplitude * t * (bias - 0.5 * c + 0.2 * p);
  return F;
}

/// The 3D gradient of an in-plane one (F_zz = 1).
Mat<3> embed(const Mat<2>& a) {
  Mat<3> m = Mat<3>::Identity();
  m.topLeftCorner<2, 2>() = a;
  return m;
}

/// What a model is driven through and how close its 2D and 3D sigma_zz must agree.
struct Case {
  const char* name;
  MaterialParameters parameters;
  double amplitude; ///< the largest strain of the path
  bool compress;
  bool plastic; ///< the path must yield (plastic_strain > 0 at the end)
};

/// Drives a 2D and a 3D material of `c` through the same motion in kSteps
/// increments (H = F_{k+1} F_k^-1 - I) and checks after every step: the 2D
/// sigma_zz (out_of_plane_stress) equals the 3D model's sigma_zz, and the
/// in-plane stresses agree, within `tol` (Pa). Returns the largest |sigma_zz|
/// seen and the largest difference.
struct Agreement {
  double largest = 0.0, worst = 0.0, worst_in_plane = 0.0, plastic_strain = 0.0;
};
Agreement drive(const Case& c) {
  auto m2 = make_material<2>(c.parameters);
  auto m3 = make_material<3>(c.parameters);
  Particles<2> P2 = particles<2>(*m2, kParticles);
  Particles<3> P3 = particles<3>(*m3, kParticles);
  const double dt = 1e-6;
  Agreement a;
  std::vector<Mat<2>> H2(kParticles);
  std::vector<Mat<3>> H3(kParticles);
  std::vector<double> zz(kParticles);
  for (int k = 1; k <= kSteps; ++k) {
    for (int p = 0; p < kParticles; ++p) {
      const double t0 = double(k - 1) / kSteps, t1 = double(k) / kSteps;
      H2[static_cast<std::size_t>(p)] = path(t1, p, c.amplitude, c.compress) * path(t0, p, c.amplitude, c.compress).inverse() -
                                        Mat<2>::Identity();
      H3[static_cast<std::size_t>(p)] = embed(H2[static_cast<std::size_t>(p)] + Mat<2>::Identity()) - Mat<3>::Identity();
    }
    m2->update(P2, 0, kParticles, H2.data(), dt);
    m3->update(P3, 0, kParticles, H3.data(), dt);
    m2->out_of_plane_stress(P2, 0, kParticles, zz.data());
    for (int p = 0; p < kParticles; ++p) {
      const Mat<3>& s3 = P3.sigma[p];
      a.largest = std::max(a.largest, std::abs(s3(2, 2)));
      a.worst = std::max(a.worst, std::abs(zz[static_cast<std::size_t>(p)] - s3(2, 2)));
      a.worst_in_plane = std::max(a.worst_in_plane, (P2.sigma[p] - s3.topLeftCorner<2, 2>()).norm());
    }
  }
  if (const StateField* e = P2.find_state("plastic_strain"))
    for (double v : e->values) a.plastic_strain = std::max(a.plastic_strain, v);
  return a;
}

} // namespace

TEST_CASE("out_of_plane_stress: every model's 2D sigma_zz equals its 3D sigma_zz under the same motion") {
  // Round-off of a stress along a path of n steps: each step rounds at
  // ~1e-16 of (K + G) |e| with |e| <= 1 (the bound of test_plasticity.cpp,
  // 5e-16 n (K + G)); the 2D and 3D updates are different code (closed-form
  // 2x2 against 3x3 products and eigen-decompositions), so they drift apart
  // by at most that. (K + G = 2.4e11 Pa here: tol = 4.8e-2 Pa for 400 steps,
  // i.e. 1e-10 of the ~5e8 Pa stresses.)
  const plasticity::ElasticModuli el = plasticity::ElasticModuli::from_young_poisson(kE, kNu);
  const double tol = 5e-16 * kSteps * (el.bulk + el.shear);
  const std::vector<Case> cases{
      {"linear_elastic", parameters("linear_elastic"), 2e-3, false, false},
      {"linear_elastic_finite", parameters("linear_elastic_finite"), 2e-3, false, false},
      {"neo_hookean", parameters("neo_hookean"), 0.3, false, false}, // large strain
      {"j2 elastic", parameters("j2", {{"yield_stress", 1e12}}), 2e-3, false, false},
      {"j2 linear hardening", parameters("j2", {{"yield_stress", 250e6}, {"hardening_modulus", 1e9}}), 0.05, false,
       true},
      {"j2 Johnson-Cook", parameters("j2", {{"yield_stress", 250e6}, {"johnson_cook.B", 300e6},
                                             {"johnson_cook.n", 0.4}, {"johnson_cook.C", 0.02},
                                             {"johnson_cook.reference_strain_rate", 1.0}}),
       0.05, false, true},
      {"drucker_prager", parameters("drucker_prager", {{"friction_angle", 30.0}, {"dilation_angle", 10.0},
                                                        {"cohesion", 1e6}}),
       0.05, true, true},
      {"mu_i", parameters("mu_i", {{"mu_s", 0.4}, {"mu_2", 0.65}, {"I_0", 0.28}, {"grain_diameter", 1e-3},
                                    {"grain_density", 8000.0}, {"critical_packing", 0.9}}),
       0.05, true, true},
  };
  for (const Case& c : cases) {
    INFO(c.name);
    const Agreement a = drive(c);
    MESSAGE(std::string(c.name), ": largest |sigma_zz| ", a.largest, " Pa, 2D - 3D ", a.worst, " Pa (in plane ", a.worst_in_plane,
            " Pa), plastic strain ", a.plastic_strain);
    CHECK(a.largest > 1e6 * tol); // not a comparison of zeros
    CHECK(a.worst <= tol);
    CHECK(a.worst_in_plane <= tol); // the motions are the same (the 2D in-plane stress is the 3D one)
    if (c.plastic) CHECK(a.plastic_strain > 1e-3);
  }
}

TEST_CASE("out_of_plane_stress: linear_elastic's sigma_zz is nu (sigma_xx + sigma_yy) of its own stress") {
  // Plane strain of Hooke's law: eps_zz = 0 gives sigma_zz = nu (sigma_xx +
  // sigma_yy), a relation between the stress the update accumulates and the
  // sigma_zz = lambda tr(eps) derived from the accumulated strain.
  auto m = make_material<2>(parameters("linear_elastic"));
  Particles<2> P = particles<2>(*m, 1);
  std::vector<double> zz(1);
  double worst = 0.0;
  for (int k = 1; k <= kSteps; ++k) {
    Mat<2> H = path(double(k) / kSteps, 0, 2e-3, false) * path(double(k - 1) / kSteps, 0, 2e-3, false).inverse() -
               Mat<2>::Identity();
    m->update(P, 0, 1, &H, 1e-6);
    m->out_of_plane_stress(P, 0, 1, zz.data());
    worst = std::max(worst, std::abs(zz[0] - kNu * (P.sigma[0](0, 0) + P.sigma[0](1, 1))));
  }
  CHECK(std::abs(zz[0]) > 1e6);
  CHECK(worst <= 5e-16 * kSteps * kE);
}

TEST_CASE("out_of_plane_stress: a rest state has sigma_zz = 0, 1D and 3D materials refuse") {
  for (const char* model : {"linear_elastic", "linear_elastic_finite", "neo_hookean", "j2", "drucker_prager", "mu_i"}) {
    INFO(model);
    std::map<std::string, double> extra;
    if (std::string(model) == "j2") extra = {{"yield_stress", 1e8}};
    if (std::string(model) == "drucker_prager") extra = {{"friction_angle", 30.0}, {"cohesion", 1e5}};
    if (std::string(model) == "mu_i")
      extra = {{"mu_s", 0.4}, {"mu_2", 0.65}, {"I_0", 0.28}, {"grain_diameter", 1e-3}, {"grain_density", 8000.0},
               {"critical_packing", 0.9}};
    auto m2 = make_material<2>(parameters(model, extra));
    Particles<2> P = particles<2>(*m2, 2);
    std::vector<double> zz(2, 1.0);
    m2->out_of_plane_stress(P, 0, 2, zz.data());
    CHECK(zz == std::vector<double>{0.0, 0.0});
    auto m3 = make_material<3>(parameters(model, extra));
    Particles<3> P3 = particles<3>(*m3, 1);
    CHECK_THROWS_AS(m3->out_of_plane_stress(P3, 0, 1, zz.data()), std::logic_error);
    auto m1 = make_material<1>(parameters(model, extra));
    Particles<1> P1 = particles<1>(*m1, 1);
    CHECK_THROWS_AS(m1->out_of_plane_stress(P1, 0, 1, zz.data()), std::logic_error);
  }
}
