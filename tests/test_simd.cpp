// The short-vector kernels of the max-ent solver (lib/otmpm/basis/simd.hpp):
// the lane-wise exponential must be the scalar maxent::exp_shifted bit for
// bit (so the solver's results do not depend on how points fall into lanes),
// and the Taylor exponential of the Newton updates within 1 ulp of std::exp
// over the range it is used on.
#include "otmpm/basis/lme.hpp"
#include "otmpm/basis/simd.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <random>

using namespace otmpm;

namespace {

/// |a - b| in units of the spacing of doubles at b.
double ulps(double a, double b) { return std::abs(a - b) / (std::nextafter(b, INFINITY) - b); }

/// The lanes of f applied to x, x + dx, ... (one value per lane).
template <class F> simd::vd lanes_of(F&& f, double x, double dx) {
  double in[simd::lanes];
  for (int i = 0; i < simd::lanes; ++i) in[i] = f(x + i * dx);
  return simd::load(in);
}

} // namespace

TEST_CASE("simd: exp_shifted equals the scalar exp_shifted bit for bit on [-708, 0]") {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> wide(-708.0, 0.0), narrow(-20.0, 0.0);
  for (int i = 0; i < 100000; ++i) {
    double x[simd::lanes];
    for (double& v : x) v = i % 2 ? wide(rng) : narrow(rng);
    const simd::vd e = simd::exp_shifted(simd::load(x));
    for (int l = 0; l < simd::lanes; ++l) REQUIRE(double(e[l]) == maxent::exp_shifted(x[l]));
  }
  CHECK(double(simd::exp_shifted(simd::broadcast(0.0))[0]) == 1.0);
}

TEST_CASE("simd: exp_shifted is 0 below -708 and for -inf, NaN for NaN") {
  double x[simd::lanes];
  x[0] = -708.0 - 1e-9;
  x[1] = -std::numeric_limits<double>::infinity();
  if constexpr (simd::lanes > 2) x[2] = -1e300, x[3] = -800.0;
  simd::vd e = simd::exp_shifted(simd::load(x));
  for (int l = 0; l < simd::lanes; ++l) CHECK(double(e[l]) == 0.0);
  e = simd::exp_shifted(simd::broadcast(std::nan("")));
  CHECK(std::isnan(double(e[0])));
  CHECK(double(simd::exp_shifted(simd::broadcast(-708.0))[0]) == maxent::exp_shifted(-708.0));
}

TEST_CASE("simd: the Taylor exponentials are within 1 ulp of exp on their ranges") {
  // degree 5 on |u| <= 2^-8, degree 8 on |u| <= 2^-4 (maxent kTaylorSmall/Large)
  std::mt19937_64 rng(5);
  double worst5 = 0, worst8 = 0;
  for (int i = 0; i < 200000; ++i) {
    const double u5 = std::uniform_real_distribution<double>(-0x1p-8, 0x1p-8)(rng);
    const double u8 = std::uniform_real_distribution<double>(-0x1p-4, 0x1p-4)(rng);
    worst5 = std::max(worst5, ulps(simd::exp_small<5>(simd::broadcast(u5))[0], std::exp(u5)));
    worst8 = std::max(worst8, ulps(simd::exp_small<8>(simd::broadcast(u8))[0], std::exp(u8)));
  }
  MESSAGE("worst ulps: degree 5 " << worst5 << ", degree 8 " << worst8);
  CHECK(worst5 <= 1.0);
  CHECK(worst8 <= 1.0);
  // and not beyond: degree 5 at 2^-4 is visibly truncated (the ranges matter)
  CHECK(ulps(simd::exp_small<5>(simd::broadcast(0x1p-4))[0], std::exp(0x1p-4)) > 100.0);
}

TEST_CASE("simd: lane sums, maxima, selection and padding") {
  const simd::vd v = lanes_of([](double x) { return x * x; }, 1.0, 1.0); // 1, 4, (9, 16)
  double expected = 0, largest = 0;
  for (int i = 0; i < simd::lanes; ++i) expected += (1.0 + i) * (1.0 + i), largest = (1.0 + i) * (1.0 + i);
  CHECK(simd::sum(v) == expected);
  CHECK(simd::max_lane(v) == largest);
  const simd::vd m = simd::max(v, simd::broadcast(2.0));
  CHECK(double(m[0]) == 2.0);
  CHECK(double(m[1]) == 4.0);
  const simd::vd s = simd::select(simd::less(v, simd::broadcast(2.0)), simd::broadcast(-1.0), v);
  CHECK(double(s[0]) == -1.0);
  CHECK(double(s[1]) == 4.0);
  CHECK(simd::padded(0) == 0);
  CHECK(simd::padded(1) == simd::lanes);
  CHECK(simd::padded(simd::lanes + 1) == 2 * simd::lanes);
}
