// The plane-strain J2 step in lanes (lib/otmpm/materials/hencky_plane_j2.hpp):
// two particles per SSE2 register give each particle the bits of the
// one-particle form; the form agrees with the general update (j2_general,
// library functions) to round-off where it covers the step and hands every
// other step to it; the material's batch update gives a particle the same
// bits whether it is updated in a pair or alone (thread chunks start
// anywhere), and still names the first failing particle.
#include "otmpm/materials/hencky_plane_j2.hpp"
#include "otmpm/materials/material.hpp"
#include "j2_batch.hpp"

#include <doctest/doctest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

using namespace otmpm;
using namespace otmpm::plasticity;
using point::Lanes2;
using point::PlaneJ2;

namespace {

using test::parameters;

/// A random step of a particle: dF = I + H with |H| ~ scale, b_e a small
/// elastic stretch (|b_e - I| ~ 1e-3, b_zz too), eps_p in [0, 0.1).
struct Step {
  Mat<2> H;
  Mat3 be;
  double eps_p;
};
Step random_step(std::mt19937_64& rng, double scale) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Step s;
  s.H << scale * u(rng), scale * u(rng), scale * u(rng), scale * u(rng);
  Mat<2> A;
  A << 1e-3 * u(rng), 1e-3 * u(rng), 1e-3 * u(rng), 1e-3 * u(rng);
  const Mat<2> Fe = Mat<2>::Identity() + A;
  s.be = Mat3::Identity();
  s.be.topLeftCorner<2, 2>() = Fe * Fe.transpose();
  s.be(2, 2) = 1.0 + 1e-3 * u(rng);
  s.eps_p = 0.05 * (u(rng) + 1.0);
  return s;
}

/// The input of a step in a one-particle form.
void set_input(PlaneJ2<double>& x, const Step& a) {
  x.f00 = 1.0 + a.H(0, 0), x.f01 = 0.0 + a.H(0, 1), x.f10 = 0.0 + a.H(1, 0), x.f11 = 1.0 + a.H(1, 1);
  x.b00 = a.be(0, 0), x.b01 = a.be(0, 1), x.b11 = a.be(1, 1), x.bzz = a.be(2, 2), x.eps_p = a.eps_p;
}
/// The inputs of two steps in the two lanes.
void set_input(PlaneJ2<Lanes2>& x, const Step& a, const Step& b) {
  const auto two = [](double u, double v) { return Lanes2{u, v}; };
  x.f00 = 1.0 + two(a.H(0, 0), b.H(0, 0)), x.f01 = 0.0 + two(a.H(0, 1), b.H(0, 1));
  x.f10 = 0.0 + two(a.H(1, 0), b.H(1, 0)), x.f11 = 1.0 + two(a.H(1, 1), b.H(1, 1));
  x.b00 = two(a.be(0, 0), b.be(0, 0)), x.b01 = two(a.be(0, 1), b.be(0, 1));
  x.b11 = two(a.be(1, 1), b.be(1, 1)), x.bzz = two(a.be(2, 2), b.be(2, 2));
  x.eps_p = two(a.eps_p, b.eps_p);
}

using test::bits;

/// Every output of lane l of v equals the one-particle output s, bit for bit.
bool same_lane(const PlaneJ2<Lanes2>& v, int l, const PlaneJ2<double>& s) {
  const double vs[] = {v.tau00[l], v.tau11[l], v.tau01[l], v.tau22[l], v.be00[l],      v.be11[l],
                       v.be01[l],  v.bezz[l],  v.eps_p_new[l], v.energy[l], v.work[l]};
  const double ss[] = {s.tau00, s.tau11, s.tau01, s.tau22, s.be00, s.be11, s.be01, s.bezz, s.eps_p_new, s.energy, s.work};
  for (int i = 0; i < 11; ++i)
    if (bits(vs[i]) != bits(ss[i])) return false;
  return (v.plastic[l] != 0) == s.plastic;
}

double rel(double a, double b, double scale) { return std::abs(a - b) / scale; }

} // namespace

TEST_CASE("plane J2 in two lanes: each lane has the bits of the one-particle form (elastic, plastic, uncovered)") {
  const J2Parameters p = parameters();
  std::mt19937_64 rng(7);
  int plastic = 0, elastic = 0, uncovered = 0;
  // Increments from 1e-6 (elastic) to 1e-1 (beyond the covered range).
  for (double scale : {1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1})
    for (int i = 0; i < 200; ++i) {
      const Step a = random_step(rng, scale), b = random_step(rng, scale);
      PlaneJ2<Lanes2> v{};
      set_input(v, a, b);
      const point::Mask2 cv = point::plane_j2(p, v);
      for (int l = 0; l < 2; ++l) {
        PlaneJ2<double> s{};
        set_input(s, l == 0 ? a : b);
        const bool cs = point::plane_j2(p, s);
        CHECK((cv[l] != 0) == cs);
        if (cs) CHECK(same_lane(v, l, s));
        uncovered += !cs;
        plastic += cs && s.plastic;
        elastic += cs && !s.plastic;
      }
    }
  // The samples reach every branch.
  CHECK(plastic > 100);
  CHECK(elastic > 100);
  CHECK(uncovered > 100);
}

TEST_CASE("plane J2 form agrees with the general update to round-off where it covers the step") {
  const J2Parameters p = parameters();
  const double scale_tau = p.elastic.bulk + p.elastic.shear; // stresses are O(1e-3) of it: round-off 1e-16 of it
  std::mt19937_64 rng(11);
  int covered = 0;
  for (double scale : {1e-6, 1e-5, 1e-4, 1e-3, 3e-3})
    for (int i = 0; i < 300; ++i) {
      const Step st = random_step(rng, scale);
      const Mat<2> dF = Mat<2>::Identity() + st.H;
      HenckyState fast{st.be, st.eps_p, 0.0}, general{st.be, st.eps_p, 0.0};
      PointUpdate uf;
      if (!point::plane_j2_point(p, dF, fast, uf)) continue;
      ++covered;
      const PointUpdate ug = point::j2_general<2>(p, dF, 1.0, general);
      CHECK(uf.plastic == ug.plastic);
      CHECK((uf.kirchhoff - ug.kirchhoff).norm() <= 1e-14 * scale_tau);
      CHECK((fast.be - general.be).norm() <= 1e-15);
      CHECK(rel(fast.eps_p, general.eps_p, 1.0) <= 1e-16);
      CHECK(rel(uf.elastic_energy, ug.elastic_energy, 1e-6 * scale_tau) <= 1e-12);
      CHECK(rel(uf.plastic_work, ug.plastic_work, 1e-6 * scale_tau) <= 1e-12);
      CHECK(rel(uf.return_work, ug.return_work, 1e-6 * scale_tau) <= 1e-12);
    }
  CHECK(covered > 1000);
}

TEST_CASE("j2_update in plane strain falls back to the general update outside the form's range") {
  const J2Parameters p = parameters();
  // A 10% stretch: |det b - 1| > 1/32, not covered.
  Mat<2> dF;
  dF << 1.1, 0.0, 0.0, 1.0;
  HenckyState a, b;
  PointUpdate probe;
  CHECK_FALSE(point::plane_j2_point(p, dF, a, probe));
  const PointUpdate u = j2_update<2>(p, dF, 1.0, a);
  const PointUpdate g = point::j2_general<2>(p, dF, 1.0, b);
  CHECK(u.kirchhoff == g.kirchhoff);
  CHECK(a.be == b.be);
  CHECK(a.eps_p == b.eps_p);
  CHECK(u.plastic);
}

namespace {

/// n plane-strain particles of a j2 material, random elastic states and
/// random increments H (one of them far outside the plane form's range).
test::J2Batch<2> make_batch(int n) {
  test::J2Batch<2> b = test::j2_batch<2>(n);
  std::mt19937_64 rng(3);
  double* be = b.P.find_state("elastic_left_cauchy_green")->values.data();
  for (int p = 0; p < n; ++p) {
    const Step s = random_step(rng, p % 3 == 0 ? 1e-6 : 2e-3);
    be[6 * p + 0] = s.be(0, 0), be[6 * p + 1] = s.be(1, 1), be[6 * p + 2] = s.be(2, 2), be[6 * p + 3] = s.be(0, 1);
    b.P.find_state("plastic_strain")->values[static_cast<std::size_t>(p)] = s.eps_p;
    b.H[static_cast<std::size_t>(p)] = s.H;
  }
  if (n > 5) b.H[5] << 0.2, 0.05, -0.03, 0.1; // outside the covered range: the general path inside a pair
  return b;
}

} // namespace

TEST_CASE("j2 material in plane strain: a particle's result does not depend on whether it is updated in a pair") {
  CHECK(test::check_pairings<2>(make_batch, 9) >= 3);
}

TEST_CASE("j2 material in plane strain: det F <= 0 inside a pair names that particle, the one before is updated") {
  constexpr int n = 4;
  test::J2Batch<2> b = make_batch(n);
  b.H[1] << -1.5, 0.0, 0.0, 0.0; // F = diag(-0.5, 1) for particle 1, paired with particle 0
  const Mat<2> F0 = (Mat<2>::Identity() + b.H[0]) * b.P.F[0];
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
