// The 3D J2 step in lanes (lib/otmpm/materials/hencky_solid_j2.hpp): each
// lane of the two-particle form, and the one-particle form, has the bits of
// the general update (j2_general: update3 with j2_return) wherever the form
// covers the step - elastic steps, returns to the von Mises cylinder, elastic
// unloading from it - and hands every other step to it; the material's
// batch update gives a particle the same bits in a pair, alone or in another
// pairing, names the first failing particle, and a 3D j2 run gives the same
// bits on 1 and 2 threads.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/materials/hencky_solid_j2.hpp"
#include "otmpm/materials/material.hpp"
#include "otmpm/scene/scene.hpp"
#include "j2_batch.hpp"
#include "support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

using namespace otmpm;
using namespace otmpm::plasticity;
using point::Lanes2;
using point::SolidJ2;

namespace {

using test::parameters;

/// A random step of a particle: dF = I + H with |H| ~ scale, b_e = Fe Fe^T
/// with |Fe - I| ~ stretch (q from 0.01 to 40 sigma_y: elastic and plastic),
/// eps_p in [0, 0.1).
struct Step {
  Mat3 H;
  Mat3 be;
  double eps_p;
};
Step random_step(std::mt19937_64& rng, double scale) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double stretch = std::pow(10.0, -6.0 + 3.0 * (u(rng) + 1.0) / 2.0);
  Step s;
  Mat3 A;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) s.H(i, j) = scale * u(rng), A(i, j) = stretch * u(rng);
  const Mat3 Fe = Mat3::Identity() + A;
  s.be = Fe * Fe.transpose();
  s.eps_p = 0.05 * (u(rng) + 1.0);
  return s;
}

/// The inputs of a step in lane l of x (T = Lanes2) or in x (T = double).
template <class T> void set_lane(SolidJ2<T>& x, int l, const Step& a) {
  const auto put = [l](T& v, double d) {
    if constexpr (std::is_same_v<T, double>) v = d, (void)l;
    else v[l] = d;
  };
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) put(x.f[i][j], (i == j ? 1.0 : 0.0) + a.H(i, j));
  const double b[6] = {a.be(0, 0), a.be(1, 1), a.be(2, 2), a.be(0, 1), a.be(1, 2), a.be(0, 2)};
  for (int k = 0; k < 6; ++k) put(x.b[k], b[k]);
  put(x.eps_p, a.eps_p);
}

using test::bits;
double lane(double v, int) { return v; }
double lane(Lanes2 v, int l) { return v[l]; }
#ifdef OTMPM_WIDE_LANES
using point::Lanes4;
double lane(Lanes4 v, int l) { return v[l]; }
#endif

/// Every output of lane l of x has the bits of the general update u, st of
/// the same step (b_e in the state's order xx, yy, zz, xy, yz, xz).
template <class T> bool same_as_general(const SolidJ2<T>& x, int l, const PointUpdate& u, const HenckyState& st) {
  const double tau[6] = {u.kirchhoff(0, 0), u.kirchhoff(1, 1), u.kirchhoff(2, 2),
                         u.kirchhoff(0, 1), u.kirchhoff(1, 2), u.kirchhoff(0, 2)};
  const double be[6] = {st.be(0, 0), st.be(1, 1), st.be(2, 2), st.be(0, 1), st.be(1, 2), st.be(0, 2)};
  for (int k = 0; k < 6; ++k)
    if (bits(lane(x.tau[k], l)) != bits(tau[k]) || bits(lane(x.be[k], l)) != bits(be[k])) return false;
  bool plastic;
  if constexpr (std::is_same_v<T, double>) plastic = x.plastic;
  else plastic = x.plastic[l] != 0;
  return plastic == u.plastic && bits(lane(x.eps_p_new, l)) == bits(st.eps_p) &&
         bits(lane(x.energy, l)) == bits(u.elastic_energy) && bits(lane(x.work, l)) == bits(u.plastic_work);
}

/// Counts of what the samples reached.
struct Reached {
  int elastic = 0, plastic = 0, unloading = 0, uncovered = 0;
};

/// The W-lane (lane type L) and one-lane forms against j2_general for the
/// steps s[0 .. W - 1].
template <class L, int W> void check_lanes(const J2Parameters& p, const Step* steps, Reached& reached, bool unloading) {
  SolidJ2<L> v{};
  for (int l = 0; l < W; ++l) set_lane(v, l, steps[l]);
  const auto cv = point::solid_j2(p, v);
  for (int l = 0; l < W; ++l) {
    const Step& s = steps[l];
    SolidJ2<double> one{};
    set_lane(one, 0, s);
    const bool c1 = point::solid_j2(p, one);
    CHECK((cv[l] != 0) == c1);
    HenckyState st{s.be, s.eps_p, 0.0};
    PointUpdate u;
    try {
      u = point::j2_general<3>(p, Mat3::Identity() + s.H, 1.0, st);
    } catch (const InstabilityError&) {
      CHECK_FALSE(c1); // the general path refuses it: the form must not take it
      ++reached.uncovered;
      continue;
    }
    if (!c1) {
      ++reached.uncovered;
      continue;
    }
    CHECK(same_as_general(v, l, u, st));
    CHECK(same_as_general(one, 0, u, st));
    if (u.plastic) ++reached.plastic;
    else if (unloading) ++reached.unloading;
    else ++reached.elastic;
  }
}

/// check_lanes for the two-lane form and steps a, b.
void check_pair(const J2Parameters& p, const Step& a, const Step& b, Reached& reached, bool unloading) {
  const Step steps[2] = {a, b};
  check_lanes<Lanes2, 2>(p, steps, reached, unloading);
}

} // namespace

TEST_CASE("3D J2 in two lanes: each lane has the bits of the general update (elastic, return, unloading, uncovered)") {
  const J2Parameters p = parameters();
  std::mt19937_64 rng(17);
  Reached reached;
  // Increments from 1e-7 (elastic) to 3e-1 (beyond the series radius), and
  // a few non-invertible ones.
  for (double scale : {1e-7, 1e-5, 1e-4, 1e-3, 1e-2, 3e-2, 3e-1})
    for (int i = 0; i < 300; ++i) {
      Step a = random_step(rng, scale), b = random_step(rng, scale);
      if (i == 0) b.H = -Mat3::Identity(); // det dF = 0
      if (i == 1) a.H(0, 0) = std::nan("");
      check_pair(p, a, b, reached, false);
      // Elastic unloading: a returned state driven back by the inverse increment.
      HenckyState sa{a.be, a.eps_p, 0.0}, sb{b.be, b.eps_p, 0.0};
      try {
        if (!point::j2_general<3>(p, Mat3::Identity() + a.H, 1.0, sa).plastic) continue;
        point::j2_general<3>(p, Mat3::Identity() + b.H, 1.0, sb);
      } catch (const InstabilityError&) {
        continue;
      }
      const Step ua{(Mat3::Identity() + a.H).inverse() - Mat3::Identity(), sa.be, sa.eps_p};
      const Step ub{(Mat3::Identity() + b.H).inverse() - Mat3::Identity(), sb.be, sb.eps_p};
      check_pair(p, ua, ub, reached, true);
    }
  // The samples reach every branch.
  CHECK(reached.elastic > 300);
  CHECK(reached.plastic > 300);
  CHECK(reached.unloading > 100);
  CHECK(reached.uncovered > 300);
}

TEST_CASE("3D J2 form: the series takes as many terms per lane as update3 (a small and a large strain side by side)") {
  const J2Parameters p = parameters();
  std::mt19937_64 rng(5);
  for (int i = 0; i < 200; ++i) {
    Step a = random_step(rng, 1e-3), b = random_step(rng, 1e-3);
    a.be = Mat3::Identity() + 1e-9 * (a.be - Mat3::Identity()); // a few terms
    b.be = Mat3::Identity() + 20.0 * (b.be - Mat3::Identity()); // many terms (if still in the radius)
    Reached reached;
    check_pair(p, a, b, reached, false);
    check_pair(p, b, a, reached, false);
  }
}

#ifdef OTMPM_WIDE_LANES
TEST_CASE("3D J2 in four lanes: each lane has the bits of the general update (elastic, return, uncovered)") {
  const J2Parameters p = parameters();
  std::mt19937_64 rng(29);
  Reached reached;
  for (double scale : {1e-7, 1e-4, 1e-3, 1e-2, 3e-2, 3e-1})
    for (int i = 0; i < 200; ++i) {
      Step s[4];
      for (Step& a : s) a = random_step(rng, scale);
      if (i == 0) s[2].H = -Mat3::Identity(); // det dF = 0 in one lane
      if (i == 1) s[3].be = Mat3::Identity() + 20.0 * (s[3].be - Mat3::Identity()); // many series terms in one lane
      check_lanes<Lanes4, 4>(p, s, reached, false);
    }
  CHECK(reached.elastic > 300);
  CHECK(reached.plastic > 300);
  CHECK(reached.uncovered > 300);
}
#endif

namespace {

/// n 3D particles of a j2 material, random states and increments H (one of
/// them far outside the form's range).
test::J2Batch<3> make_batch(int n) {
  test::J2Batch<3> b = test::j2_batch<3>(n);
  std::mt19937_64 rng(3);
  double* be = b.P.find_state("elastic_left_cauchy_green")->values.data();
  for (int p = 0; p < n; ++p) {
    const Step s = random_step(rng, p % 3 == 0 ? 1e-6 : 2e-3);
    b.P.F[p] = Mat3::Identity() + 0.1 * s.H.transpose();
    const double v[6] = {s.be(0, 0), s.be(1, 1), s.be(2, 2), s.be(0, 1), s.be(1, 2), s.be(0, 2)};
    for (int k = 0; k < 6; ++k) be[6 * p + k] = v[k];
    b.P.find_state("plastic_strain")->values[static_cast<std::size_t>(p)] = s.eps_p;
    b.H[static_cast<std::size_t>(p)] = s.H;
  }
  if (n > 5) b.H[5] << 0.2, 0.05, -0.03, 0.1, 0.0, 0.02, 0.0, 0.01, -0.1; // the general path inside a pair
  return b;
}

} // namespace

TEST_CASE("j2 material in 3D: a particle's result does not depend on whether it is updated in a pair") {
  const int grown = test::check_pairings<3>(make_batch, 41);
  CHECK(grown >= 10);
  CHECK(grown < 41);
}

TEST_CASE("j2 material in 3D: the four-lane path (AVX2) gives every particle the bits of the two-lane path") {
  if (!point::wide_lanes()) {
    MESSAGE("this processor has no AVX2: the four-lane path is not taken");
    return;
  }
  constexpr int n = 203; // 50 quads, then a pair and one
  test::J2Batch<3> wide = make_batch(n), pairs = make_batch(n);
  wide.material->update(wide.P, 0, n, wide.H.data(), 1e-3);
  point::set_wide_lanes(false);
  pairs.material->update(pairs.P, 0, n, pairs.H.data(), 1e-3);
  point::set_wide_lanes(true);
  CHECK(test::same_particles(wide.P, pairs.P));
  const test::J2Batch<3> before = make_batch(n);
  int grown = 0;
  for (std::size_t q = 0; q < static_cast<std::size_t>(n); ++q)
    grown += wide.P.find_state("plastic_strain")->values[q] > before.P.find_state("plastic_strain")->values[q];
  CHECK(grown > 20); // lanes in plastic flow among them
  CHECK(grown < n);  // and elastic ones
}

TEST_CASE("j2 material in 3D: det F <= 0 inside a pair names that particle, the one before is updated") {
  constexpr int n = 4;
  test::J2Batch<3> b = make_batch(n);
  b.H[1] = Mat3::Zero();
  b.H[1](0, 0) = -1.5; // dF = diag(-0.5, 1, 1) for particle 1, paired with particle 0
  double J0 = 0.0;
  const Mat3 F0 = point::mul3(Mat3::Identity() + b.H[0], b.P.F[0], J0); // the material's order of the product
  try {
    b.material->update(b.P, 0, n, b.H.data(), 1e-3);
    FAIL("no ParticleFailure");
  } catch (const ParticleFailure& f) {
    CHECK(f.particle == 1);
    CHECK(b.P.F[0] == F0);
  } catch (...) {
    FAIL("another exception");
  }
}

namespace {

/// A copper cylinder (R = 3.2 mm, L = 8 mm, 2 x 2 x 2 particles per cell of
/// h = 0.8 mm) hitting a frictionless wall at 227 m/s: j2 returns at the
/// foot, elastic particles above; `steps` steps on `threads` threads.
Particles<3> impact(int threads, int steps) {
  const test::ScopedThreads scoped(threads);
  const Scene s = parse_scene(R"(
[simulation]
dimension = 3
integrator = "npc"
t_end = 1.0
cfl = 0.2
[basis]
kind = "linear"
[grid]
lower = [-0.0064, -0.0064, -0.0016]
upper = [0.0064, 0.0064, 0.0096]
cells = [16, 16, 14]
[[material]]
name = "copper"
model = "j2"
density = 8930.0
young = 117.0e9
poisson = 0.35
yield_stress = 400.0e6
hardening_modulus = 100.0e6
[[body]]
name = "bar"
material = "copper"
shape = "cylinder"
center = [0.0, 0.0, 0.0]
radius = 0.0032
axis = [0.0, 0.0, 1.0]
length = 0.008
velocity = [0.0, 0.0, -227.0]
[[wall]]
name = "target"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
)",
                              "impact.toml");
  Engine<3> e = assemble<3>(s);
  for (int i = 0; i < steps; ++i) e.step();
  return e.particles();
}

} // namespace

TEST_CASE("j2 impact in 3D: bitwise identical with 1 and 2 threads, plastic state included") {
  const Particles<3> one = impact(1, 40), two = impact(2, 40);
  REQUIRE(one.size() == two.size());
  CHECK(test::same_particles(one, two));
  const std::vector<double>& eps_p = one.find_state("plastic_strain")->values;
  const long yielded = std::count_if(eps_p.begin(), eps_p.end(), [](double v) { return v > 0.0; });
  CHECK(yielded > 100);
  CHECK(yielded < one.size());
}
