// Tests of the exact solutions of the benchmark scenes (lib/otmpm/reference):
// boundary conditions, known values at the wave fronts, the governing PDEs
// checked by finite differences (or in integral form where the fields jump),
// the manufactured body force, the scene factory and the RMS error.
#include "otmpm/assembly/exact_solutions.hpp"
#include "otmpm/reference/exact.hpp"
#include "otmpm/reference/solutions.hpp"
#include "otmpm/scene/scene.hpp"

#include <doctest/doctest.h>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <string>

using namespace otmpm;

namespace {

constexpr double pi = std::numbers::pi;

// Dyka benchmark (benchmarks.md): L, rho, E, V0 on [0, L/4].
constexpr double kDykaL = 0.1333;
constexpr double kDykaRho = 7833.0;
constexpr double kDykaE = 200.0e9;
constexpr double kDykaV0 = -5.0;
constexpr double kDykaA = kDykaL / 4.0;

DykaBar<1> dyka() { return DykaBar<1>(kDykaL, kDykaE, kDykaRho, kDykaV0, kDykaA); }

/// Fixed bar of wobbes sect. 8.1.
FixedBar<1> fixed_bar() { return FixedBar<1>(FixedBarParameters{1.0, 4.0e3, 1.0, 0.6, 0.0}); }

/// Traction bar of wobbes sect. 8.2 (c = 1 m/s, unit traction amplitude).
TractionBar<1> traction_bar() { return TractionBar<1>(TractionBarParameters{1.0, 100.0, 100.0, 1.0, 0.0}); }

/// Plate of wobbes sect. 8.3.
MmsPlate mms_plate() {
  MmsPlateParameters p;
  p.length = 1.0;
  p.young = 1.0e7;
  p.poisson = 0.3;
  p.density = 1.0e7;
  p.amplitude = 0.005;
  return MmsPlate(p);
}

/// Deterministic, well-spread sample in [0, 1): fractional parts of k times
/// the golden ratio, shifted so that no sample falls on a simple fraction
/// (where the Dyka fronts sit at the times used below).
double sample(int k) {
  const double g = 0.6180339887498949 * (k + 1) + 0.0123456789;
  return g - std::floor(g);
}

Vec<1> at(double x) { return Vec<1>(x); }

// The Dyka fields in 1D at (x, t).
double dv(const DykaBar<1>& b, double x, double t) { return b.state(x, t).v; }
double ds(const DykaBar<1>& b, double x, double t) { return b.state(x, t).sigma; }
double du(const DykaBar<1>& b, double x, double t) { return b.state(x, t).u; }

/// Midpoint rule of f over [a, b] with n cells; also returns the total
/// variation seen between consecutive midpoints (for an error bound on
/// piecewise-constant integrands: |error| <= cell width * variation).
struct Quadrature {
  double integral = 0.0;
  double variation = 0.0;
};
Quadrature midpoint(const std::function<double(double)>& f, double a, double b, int n) {
  Quadrature q;
  const double w = (b - a) / n;
  double previous = f(a + 0.5 * w);
  for (int i = 0; i < n; ++i) {
    const double value = f(a + (i + 0.5) * w);
    q.integral += value * w;
    q.variation += std::abs(value - previous);
    previous = value;
  }
  return q;
}

} // namespace

// ---------------------------------------------------------------------------
// Dyka bar

TEST_CASE("dyka: at t = 0 the fields equal the initial data (v = V0 on [0, L/4], at rest elsewhere, no stress)") {
  const DykaBar<1> b = dyka();
  for (int k = 0; k < 200; ++k) {
    const double x = kDykaL * sample(k);
    const BarState s = b.state(x, 0.0);
    // V is piecewise constant and evaluated at the same point twice: exact.
    CHECK(s.v == (x <= kDykaA ? kDykaV0 : 0.0));
    CHECK(s.sigma == 0.0);
    CHECK(s.u == 0.0);
  }
}

TEST_CASE("dyka: the free end is stress-free and the fixed end neither moves nor has velocity, at all times") {
  const DykaBar<1> b = dyka();
  const double c = b.wave_speed();
  const double sigma_scale = kDykaRho * c * std::abs(kDykaV0);
  const double u_scale = std::abs(kDykaV0) * kDykaA / c;
  // Three periods 4L/c of the reflections. Away from the jumps both ends are
  // exact cancellations of the same piecewise constant: allow only rounding
  // of the folded arguments.
  for (int k = 0; k < 600; ++k) {
    const double t = 12.0 * kDykaL / c * sample(k);
    CHECK(std::abs(ds(b, 0.0, t)) <= 1e-12 * sigma_scale);
    CHECK(std::abs(dv(b, kDykaL, t)) <= 1e-12 * std::abs(kDykaV0));
    CHECK(std::abs(du(b, kDykaL, t)) <= 1e-9 * u_scale);
  }
}

TEST_CASE("dyka: the initial jump at L/4 splits into two waves of half the velocity") {
  const DykaBar<1> b = dyka();
  const double c = b.wave_speed();
  const double rc = kDykaRho * c;
  const double t = kDykaL / 8.0 / c; // fronts at L/4 -+ L/8
  const double eps = 1e-3 * kDykaL;
  // Exact piecewise constants away from the fronts: compare to rounding.
  const double tol_v = 1e-12, tol_s = 1e-12 * rc * 5.0;
  CHECK(dv(b, kDykaA - c * t - eps, t) == doctest::Approx(-5.0).epsilon(tol_v));
  CHECK(dv(b, kDykaA - c * t + eps, t) == doctest::Approx(-2.5).epsilon(tol_v));
  CHECK(dv(b, kDykaA + c * t - eps, t) == doctest::Approx(-2.5).epsilon(tol_v));
  CHECK(std::abs(dv(b, kDykaA + c * t + eps, t)) <= tol_v);
  // Between the fronts the bar is stretched: tension rho c |V0| / 2.
  CHECK(ds(b, kDykaA, t) == doctest::Approx(2.5 * rc).epsilon(tol_v));
  CHECK(std::abs(ds(b, kDykaA - c * t - eps, t)) <= tol_s);
  CHECK(std::abs(ds(b, kDykaA + c * t + eps, t)) <= tol_s);
  // Rankine-Hugoniot across each front: [sigma] = -rho c [v] moving right,
  // [sigma] = +rho c [v] moving left (this fixes the sign convention).
  const double x_right = kDykaA + c * t, x_left = kDykaA - c * t;
  const double jump_v_right = dv(b, x_right + eps, t) - dv(b, x_right - eps, t);
  const double jump_s_right = ds(b, x_right + eps, t) - ds(b, x_right - eps, t);
  CHECK(jump_s_right == doctest::Approx(-rc * jump_v_right).epsilon(tol_v));
  const double jump_v_left = dv(b, x_left + eps, t) - dv(b, x_left - eps, t);
  const double jump_s_left = ds(b, x_left + eps, t) - ds(b, x_left - eps, t);
  CHECK(jump_s_left == doctest::Approx(rc * jump_v_left).epsilon(tol_v));
}

TEST_CASE("dyka: point A (the free end) and the fixed end follow the reflection history") {
  const DykaBar<1> b = dyka();
  const double c = b.wave_speed();
  const double L = kDykaL, a = kDykaA;
  // Free end: v(0, t) = V(ct): -5 until the release wave arrives (ct = a),
  // 0 until the wave reflected at the fixed end returns (ct = 2L - a),
  // +5 for 2a, 0 again from 2L + a, and -5 from 4L - a (period 4L).
  struct Phase {
    double s0, s1, v;
  };
  const Phase phases[] = {{0.0, a, -5.0},        {a, 2 * L - a, 0.0},          {2 * L - a, 2 * L + a, 5.0},
                          {2 * L + a, 4 * L - a, 0.0}, {4 * L - a, 4 * L + a, -5.0}, {4 * L + a, 6 * L - a, 0.0}};
  for (const Phase& p : phases)
    for (double f : {0.1, 0.5, 0.9}) {
      const double t = (p.s0 + f * (p.s1 - p.s0)) / c;
      CHECK(dv(b, 0.0, t) == doctest::Approx(p.v).epsilon(1e-12));
    }
  // Fixed end: the tensile pulse rho c |V0| / 2 doubles on reflection,
  // sigma(L, t) = rho c |V0| for ct in (L - a, L + a), zero before.
  const double rc = kDykaRho * c;
  CHECK(std::abs(ds(b, L, 0.5 * (L - a) / c)) <= 1e-12 * rc);
  CHECK(ds(b, L, (L - 0.5 * a) / c) == doctest::Approx(5.0 * rc).epsilon(1e-12));
  CHECK(ds(b, L, (L + 0.5 * a) / c) == doctest::Approx(5.0 * rc).epsilon(1e-12));
  // Mid-bar while the right-going release front has passed: half velocity.
  CHECK(dv(b, 0.5 * L, 0.5 * L / c) == doctest::Approx(-2.5).epsilon(1e-12));
  // Later, x = L/2 at ct = 1.625 L: V(x - ct) = V(1.125 L) = 0 (outside the
  // images of the region) and V(x + ct) = V(2.125 L) = -V0 = +5 (image of
  // [0, a] reflected at the fixed end, sign flipped): v = +2.5 m/s.
  CHECK(dv(b, 0.5 * L, (1.5 * L + 0.5 * a) / c) == doctest::Approx(2.5).epsilon(1e-12));
}

TEST_CASE("dyka: stress and velocity agree with the displacement (sigma = E u_x, v = u_t) by finite differences") {
  // u is continuous and piecewise linear in x and t. Where the forward and
  // backward differences agree no kink lies within the step, and the central
  // difference is exact up to rounding: |u| ~ 2e-5 m with relative rounding
  // ~1e-15 over a step of 1e-5 L gives ~1e-11 of the strain scale |V0|/c.
  const DykaBar<1> b = dyka();
  const double c = b.wave_speed();
  const double h = 1e-5 * kDykaL, k = h / c;
  const double strain_tol = 1e-8 * std::abs(kDykaV0) / c;
  int tested = 0;
  const int n = 400;
  for (int i = 0; i < n; ++i) {
    const double x = kDykaL * (0.001 + 0.998 * sample(i));
    const double t = 3.0 * kDykaL / c * (0.001 + sample(i + 1000));
    const double fx = (du(b, x + h, t) - du(b, x, t)) / h, bx = (du(b, x, t) - du(b, x - h, t)) / h;
    const double ft = (du(b, x, t + k) - du(b, x, t)) / k, bt = (du(b, x, t) - du(b, x, t - k)) / k;
    if (std::abs(fx - bx) > strain_tol || std::abs(ft - bt) > strain_tol * c) continue; // kink inside the stencil
    ++tested;
    CHECK(std::abs(kDykaE * 0.5 * (fx + bx) - ds(b, x, t)) <= kDykaE * strain_tol);
    CHECK(std::abs(0.5 * (ft + bt) - dv(b, x, t)) <= strain_tol * c);
  }
  // Kinks cover a fraction ~ (number of fronts) * 2h / L ~ 1e-4 of the samples.
  CHECK(tested >= n * 9 / 10);
}

TEST_CASE("dyka: the displacement satisfies the wave equation (exact parallelogram rule of d'Alembert)") {
  // Any u = f(x + ct) + g(x - ct) satisfies, exactly and across kinks,
  // u(x + h, t) + u(x - h, t) = u(x, t + h/c) + u(x, t - h/c). Residual:
  // rounding only, relative to the displacement scale |V0| (L/4) / c.
  const DykaBar<1> b = dyka();
  const double c = b.wave_speed();
  const double u_scale = std::abs(kDykaV0) * kDykaA / c;
  double max_u = 0.0;
  for (int i = 0; i < 400; ++i) {
    const double h = 0.2 * kDykaL * sample(i + 7);
    const double x = h + (kDykaL - 2 * h) * sample(i);
    const double t = h / c + 3.0 * kDykaL / c * sample(i + 500);
    const double residual = du(b, x + h, t) + du(b, x - h, t) - du(b, x, t + h / c) - du(b, x, t - h / c);
    CHECK(std::abs(residual) <= 1e-10 * u_scale);
    max_u = std::max(max_u, std::abs(du(b, x, t)));
  }
  CHECK(max_u > 0.1 * u_scale); // the check is not on a bar at rest
}

TEST_CASE("dyka: momentum balance and the constitutive law hold in integral form across the jumps") {
  // Away from jumps rho v_t = sigma_x and sigma_t = E v_x read 0 = 0 (the
  // fields are piecewise constant), so check them on space-time rectangles:
  //   rho (int v(x,t2) dx - int v(x,t1) dx) = int (sigma(x2,t) - sigma(x1,t)) dt,
  //   int (sigma(x,t2) - sigma(x,t1)) dx  = E int (v(x2,t) - v(x1,t)) dt.
  // Midpoint rule on a piecewise-constant integrand errs by at most the cell
  // width times the variation; the tolerance is that bound (doubled).
  const DykaBar<1> b = dyka();
  const double c = b.wave_speed();
  const int n = 20000;
  struct Box {
    double x1, x2, t1, t2;
  };
  // Boxes chosen so that both balances are far from 0 = 0.
  const Box boxes[] = {{0.1 * kDykaL, 0.7 * kDykaL, 0.2 * kDykaL / c, 1.1 * kDykaL / c},
                       {0.0, 0.6 * kDykaL, 0.3 * kDykaL / c, 2.2 * kDykaL / c},
                       {0.0, kDykaL, 0.1 * kDykaL / c, 2.9 * kDykaL / c},
                       {0.05 * kDykaL, 0.45 * kDykaL, 0.0, 0.6 * kDykaL / c}};
  for (const Box& q : boxes) {
    const double dx = (q.x2 - q.x1) / n, dt = (q.t2 - q.t1) / n;
    const Quadrature v2 = midpoint([&](double x) { return dv(b, x, q.t2); }, q.x1, q.x2, n);
    const Quadrature v1 = midpoint([&](double x) { return dv(b, x, q.t1); }, q.x1, q.x2, n);
    const Quadrature s2 = midpoint([&](double t) { return ds(b, q.x2, t); }, q.t1, q.t2, n);
    const Quadrature s1 = midpoint([&](double t) { return ds(b, q.x1, t); }, q.t1, q.t2, n);
    const double lhs = kDykaRho * (v2.integral - v1.integral);
    const double rhs = s2.integral - s1.integral;
    const double tol = 2.0 * (kDykaRho * dx * (v1.variation + v2.variation) + dt * (s1.variation + s2.variation));
    CHECK(std::abs(lhs - rhs) <= tol);
    CHECK(std::abs(lhs) > 10.0 * tol); // a wrong sign of sigma would fail

    const Quadrature S2 = midpoint([&](double x) { return ds(b, x, q.t2); }, q.x1, q.x2, n);
    const Quadrature S1 = midpoint([&](double x) { return ds(b, x, q.t1); }, q.x1, q.x2, n);
    const Quadrature V2 = midpoint([&](double t) { return dv(b, q.x2, t); }, q.t1, q.t2, n);
    const Quadrature V1 = midpoint([&](double t) { return dv(b, q.x1, t); }, q.t1, q.t2, n);
    const double lhs2 = S2.integral - S1.integral;
    const double rhs2 = kDykaE * (V2.integral - V1.integral);
    const double tol2 = 2.0 * (dx * (S1.variation + S2.variation) + kDykaE * dt * (V1.variation + V2.variation));
    CHECK(std::abs(lhs2 - rhs2) <= tol2);
    CHECK(std::abs(lhs2) > 10.0 * tol2);
  }
}

TEST_CASE("dyka: in 2D and 3D only the x components are set, equal to 1D") {
  const DykaBar<1> b1 = dyka();
  const DykaBar<2> b2(kDykaL, kDykaE, kDykaRho, kDykaV0, kDykaA);
  const DykaBar<3> b3(kDykaL, kDykaE, kDykaRho, kDykaV0, kDykaA);
  const double t = 0.7 * kDykaL / b1.wave_speed();
  for (int i = 0; i < 20; ++i) {
    const double x = kDykaL * sample(i);
    const BarState s = b1.state(x, t);
    const Vec<2> v2 = b2.velocity(Vec<2>(x, 0.3), t);
    const Mat<3> s3 = b3.stress(Vec<3>(x, 0.1, 0.2), t);
    CHECK(v2[0] == s.v);
    CHECK(v2[1] == 0.0);
    CHECK(s3(0, 0) == s.sigma);
    Mat<3> expected = Mat<3>::Zero();
    expected(0, 0) = s.sigma;
    CHECK((s3 - expected).norm() == 0.0); // every other component zero
    CHECK(b3.displacement(Vec<3>(x, 0.1, 0.2), t)[0] == s.u);
  }
}

TEST_CASE("dyka: a shifted bar and a velocity region away from the free end") {
  // Bar [1, 1 + L], V0 on [L/2, 3L/4] (relative), 1 m/s elsewhere: at t = 0
  // the extended data reproduce it; the ends keep their boundary conditions.
  DykaParameters p;
  p.length = kDykaL;
  p.young = kDykaE;
  p.density = kDykaRho;
  p.region_velocity = kDykaV0;
  p.region_begin = 0.5 * kDykaL;
  p.region_end = 0.75 * kDykaL;
  p.rest_velocity = 1.0;
  p.x_free = 1.0;
  const DykaBar<1> b(p);
  for (int i = 0; i < 50; ++i) {
    const double xi = kDykaL * sample(i);
    const bool inside = xi >= p.region_begin && xi <= p.region_end;
    CHECK(b.velocity(at(1.0 + xi), 0.0)[0] == doctest::Approx(inside ? kDykaV0 : 1.0).epsilon(1e-12));
    const double t = 5.0 * kDykaL / b.wave_speed() * sample(i + 100);
    CHECK(std::abs(b.stress(at(1.0), t)(0, 0)) <= 1e-12 * kDykaRho * b.wave_speed() * 6.0);
    CHECK(std::abs(b.velocity(at(1.0 + kDykaL), t)[0]) <= 1e-12 * 6.0);
  }
}

TEST_CASE("dyka: unusable parameters are InputErrors") {
  CHECK_THROWS_AS(DykaBar<1>(0.0, kDykaE, kDykaRho, kDykaV0, 0.0), InputError);
  CHECK_THROWS_AS(DykaBar<1>(kDykaL, -1.0, kDykaRho, kDykaV0, kDykaA), InputError);
  CHECK_THROWS_AS(DykaBar<1>(kDykaL, kDykaE, 0.0, kDykaV0, kDykaA), InputError);
  CHECK_THROWS_AS(DykaBar<1>(kDykaL, kDykaE, kDykaRho, kDykaV0, 2.0 * kDykaL), InputError);
  CHECK_THROWS_AS(DykaBar<1>(kDykaL, kDykaE, kDykaRho, std::nan(""), kDykaA), InputError);
}

// ---------------------------------------------------------------------------
// Fixed bar

TEST_CASE("fixed bar: initial data of wobbes eq. 101 and fixed ends") {
  const FixedBar<1> b = fixed_bar();
  const double w = b.angular_frequency();
  CHECK(w == doctest::Approx(pi * std::sqrt(4.0e3)).epsilon(1e-14));
  for (int i = 0; i < 50; ++i) {
    const double x = sample(i);
    CHECK(b.state(x, 0.0).v == doctest::Approx(0.6 * std::sin(pi * x)).epsilon(1e-14));
    CHECK(b.state(x, 0.0).u == 0.0);
    CHECK(b.state(x, 0.0).sigma == 0.0);
    // sin(pi) ~ 1.2e-16: the ends are zero to rounding of the amplitude.
    const double t = 1e-3 * sample(i + 50);
    CHECK(std::abs(b.state(0.0, t).u) == 0.0);
    CHECK(std::abs(b.state(1.0, t).u) <= 1e-15 * 0.6 / w);
    CHECK(std::abs(b.state(1.0, t).v) <= 1e-15 * 0.6);
  }
}

TEST_CASE("fixed bar: u_tt = c^2 u_xx, v = u_t and sigma = E u_x by finite differences") {
  // Central differences with steps 1e-3 / w and 1e-3 / k: truncation is
  // (step * frequency)^2 / 12 ~ 1e-7 relative (second) or / 6 (first
  // derivative), rounding ~1e-16 / 1e-6 = 1e-10; tolerance 1e-6 of the scale.
  const FixedBar<1> b = fixed_bar();
  const double E = 4.0e3, c = std::sqrt(E), w = b.angular_frequency(), kx = pi;
  const double k = 1e-3 / w, h = 1e-3 / kx;
  const double amp = 0.6;
  auto u = [&](double x, double t) { return b.state(x, t).u; };
  for (int i = 0; i < 100; ++i) {
    const double x = sample(i), t = 2e-3 * sample(i + 200) + k;
    const double utt = (u(x, t + k) - 2 * u(x, t) + u(x, t - k)) / (k * k);
    const double uxx = (u(x + h, t) - 2 * u(x, t) + u(x - h, t)) / (h * h);
    CHECK(std::abs(utt - c * c * uxx) <= 1e-6 * amp * w);
    CHECK(std::abs((u(x, t + k) - u(x, t - k)) / (2 * k) - b.state(x, t).v) <= 1e-6 * amp);
    CHECK(std::abs(E * (u(x + h, t) - u(x - h, t)) / (2 * h) - b.state(x, t).sigma) <= 1e-6 * E * amp / c);
  }
}

// ---------------------------------------------------------------------------
// Traction bar

TEST_CASE("traction bar: fixed end, at rest before the wave arrives, and the free-end stress is the applied traction") {
  const TractionBar<1> b = traction_bar();
  const double l = 1.0, c = b.wave_speed();
  CHECK(c == doctest::Approx(1.0).epsilon(1e-15));
  for (int i = 0; i < 400; ++i) {
    const double t = 8.0 * l / c * sample(i);
    CHECK(b.state(0.0, t).u == 0.0);
    CHECK(b.state(0.0, t).v == 0.0);
    // sin(omega (s + l)) against -sin(omega s): equal up to rounding. In 1D
    // (and in uniaxial motion) the reference area does not change, so the
    // nominal traction equals the Cauchy stress sigma_xx(l, t).
    CHECK(b.state(l, t).sigma == doctest::Approx(b.traction(t)).epsilon(1e-12).scale(1.0));
    const double x = sample(i + 400);
    const double t_arrival = (l - x) / c;
    const BarState before = b.state(x, t_arrival * sample(i + 800));
    CHECK(before.u == 0.0);
    CHECK(before.v == 0.0);
    CHECK(before.sigma == 0.0);
  }
  // wobbes eq. 103: tau(t) = -sin(pi t / l) for c = 1.
  CHECK(b.traction(0.5) == doctest::Approx(-1.0).epsilon(1e-15));
  CHECK(b.traction(1.5) == doctest::Approx(1.0).epsilon(1e-15));
}

TEST_CASE("traction bar: u, v and sigma are continuous across the fronts of eq. 103") {
  // Only the derivatives jump at the fronts s = l -+ x and 3l -+ x. With a
  // gap of 2 eps around a front the fields change by at most 2 eps times
  // their slope (omega * scale), so the tolerance is 4 eps omega * scale.
  const TractionBar<1> b = traction_bar();
  const double l = 1.0, omega = pi, eps = 1e-7;
  const double u_scale = 1.0 / (100.0 * omega), v_scale = 2.0 / 100.0, s_scale = 2.0;
  for (int i = 0; i < 50; ++i) {
    const double x = 0.02 + 0.96 * sample(i);
    for (double front : {l - x, l + x, 3 * l - x, 3 * l + x}) {
      const BarState lo = b.state(x, front - eps), hi = b.state(x, front + eps);
      CHECK(std::abs(hi.u - lo.u) <= 4 * eps * omega * u_scale);
      CHECK(std::abs(hi.v - lo.v) <= 4 * eps * omega * v_scale);
      CHECK(std::abs(hi.sigma - lo.sigma) <= 4 * eps * omega * s_scale);
    }
  }
}

TEST_CASE("traction bar: u_tt = c^2 u_xx, v = u_t and sigma = E u_x by finite differences away from the fronts") {
  // Steps h = 1e-4 l and h / c: truncation (omega h)^2 / 12 ~ 1e-8 relative,
  // rounding ~1e-16 / 1e-8 ~ 1e-8 for the second differences of u ~ 3e-3;
  // tolerance 1e-5 of the scale. Points within 3h of a front are skipped.
  const TractionBar<1> b = traction_bar();
  const double l = 1.0, E = 100.0, c = b.wave_speed(), omega = pi / l;
  const double h = 1e-4 * l, k = h / c;
  const double u_scale = 1.0 / (E * omega);
  auto u = [&](double x, double t) { return b.state(x, t).u; };
  int tested = 0;
  for (int i = 0; i < 300; ++i) {
    const double x = 0.01 + 0.98 * sample(i), t = 4.0 * l / c * sample(i + 300);
    const double s = c * t;
    bool near_front = false;
    for (double front : {l - x, l + x, 3 * l - x, 3 * l + x, 4 * l}) near_front |= std::abs(s - front) < 3 * h;
    if (near_front || s < 3 * h) continue;
    ++tested;
    const double utt = (u(x, t + k) - 2 * u(x, t) + u(x, t - k)) / (k * k);
    const double uxx = (u(x + h, t) - 2 * u(x, t) + u(x - h, t)) / (h * h);
    CHECK(std::abs(utt - c * c * uxx) <= 1e-5 * c * c * omega * omega * u_scale);
    CHECK(std::abs((u(x, t + k) - u(x, t - k)) / (2 * k) - b.state(x, t).v) <= 1e-5 * c * omega * u_scale);
    CHECK(std::abs(E * (u(x + h, t) - u(x - h, t)) / (2 * h) - b.state(x, t).sigma) <= 1e-5 * E * omega * u_scale);
  }
  CHECK(tested >= 250);
}

TEST_CASE("traction bar: the bar is at rest again at t = 4l/c and the motion repeats") {
  const TractionBar<1> b = traction_bar();
  const double period = 4.0 / b.wave_speed();
  for (int i = 0; i < 50; ++i) {
    const double x = sample(i), t = period * sample(i + 50);
    const BarState s0 = b.state(x, t), s1 = b.state(x, t + period);
    CHECK(s1.u == doctest::Approx(s0.u).epsilon(1e-9).scale(1e-3));
    CHECK(s1.sigma == doctest::Approx(s0.sigma).epsilon(1e-9).scale(1.0));
    // At the end of the first period: u = alpha (1 + cos(3 pi)) = 0.
    CHECK(std::abs(b.state(x, period * (1.0 - 1e-12)).u) <= 1e-9);
  }
}

// ---------------------------------------------------------------------------
// Manufactured plate

TEST_CASE("mms plate: displacement of wobbes eqs. 104-105, fixed boundary, F and v consistent with u") {
  const MmsPlate m = mms_plate();
  const double A = 0.005, c = 1.0;
  for (int i = 0; i < 50; ++i) {
    const Vec<2> X(sample(i), sample(i + 50));
    const double t = 3.5e-1 * sample(i + 100);
    const Vec<2> u = m.displacement(X, t);
    CHECK(u[0] == doctest::Approx(A * std::sin(2 * pi * X[0]) * std::sin(c * pi * t)).epsilon(1e-13).scale(A));
    CHECK(u[1] == doctest::Approx(A * std::sin(2 * pi * X[1]) * std::sin(c * pi * t + pi)).epsilon(1e-13).scale(A));
    // Boundary X_k in {0, 1}: sin(2 pi) ~ 2.4e-16.
    CHECK(std::abs(m.displacement(Vec<2>(0.0, X[1]), t)[0]) <= 1e-15 * A);
    CHECK(std::abs(m.displacement(Vec<2>(1.0, X[1]), t)[0]) <= 1e-15 * A);
    CHECK(std::abs(m.displacement(Vec<2>(X[0], 1.0), t)[1]) <= 1e-15 * A);
    // Central differences, step 1e-5: truncation (2 pi 1e-5)^2 / 6 ~ 7e-10 relative.
    const double h = 1e-5;
    const Vec<2> ut = (m.displacement(X, t + h) - m.displacement(X, t - h)) / (2 * h);
    CHECK((ut - m.velocity(X, t)).norm() <= 1e-8 * A * pi);
    Mat<2> F = Mat<2>::Identity();
    for (int j = 0; j < 2; ++j) {
      const Vec<2> e = Vec<2>::Unit(j) * h;
      F.col(j) += (m.displacement(X + e, t) - m.displacement(X - e, t)) / (2 * h);
    }
    CHECK((F - m.deformation_gradient(X, t)).norm() <= 1e-8 * A * 2 * pi);
  }
  CHECK(m.has_body_force());
}

namespace {

/// Neo-Hookean first Piola-Kirchhoff stress (wobbes eq. 11 pulled back),
/// written independently of the library for the checks below.
Mat<2> neo_hookean_P(const Mat<2>& F, double lambda, double mu) {
  const Mat<2> FinvT = F.inverse().transpose();
  return mu * (F - FinvT) + lambda * std::log(F.determinant()) * FinvT;
}

Mat<2> fd_deformation_gradient(const MmsPlate& m, const Vec<2>& X, double t, double h) {
  Mat<2> F = Mat<2>::Identity();
  for (int j = 0; j < 2; ++j) {
    const Vec<2> e = Vec<2>::Unit(j) * h;
    F.col(j) += (m.displacement(X + e, t) - m.displacement(X - e, t)) / (2 * h);
  }
  return F;
}

} // namespace

TEST_CASE("mms plate: the body force balances rho0 u_tt - Div P computed by finite differences") {
  // P from a finite-difference F, then a finite-difference divergence, and
  // u_tt by a central second difference in time. Truncation per nested
  // differentiation is (2 pi h)^2 / 6 ~ 7e-8 relative for h = 1e-4, a few times
  // that after the nonlinear P; rounding ~1e-16 * |u| / h^2 ~ 1e-10 of the
  // scale. Tolerance 1e-5 of the scale (lambda + 2 mu) / rho0 A (2 pi)^2.
  const MmsPlate m = mms_plate();
  const double rho0 = 1.0e7, A = 0.005, h = 1e-4, k = 1e-4;
  const double scale = (m.lambda() + 2 * m.mu()) / rho0 * A * 4 * pi * pi;
  double max_b = 0.0;
  for (int i = 0; i < 60; ++i) {
    const Vec<2> X(0.02 + 0.96 * sample(i), 0.02 + 0.96 * sample(i + 60));
    const double t = 0.1 + 1.5 * sample(i + 120);
    const Vec<2> utt = (m.displacement(X, t + k) - 2 * m.displacement(X, t) + m.displacement(X, t - k)) / (k * k);
    Vec<2> div = Vec<2>::Zero();
    for (int j = 0; j < 2; ++j) {
      const Vec<2> e = Vec<2>::Unit(j) * h;
      const Mat<2> Pp = neo_hookean_P(fd_deformation_gradient(m, X + e, t, h), m.lambda(), m.mu());
      const Mat<2> Pm = neo_hookean_P(fd_deformation_gradient(m, X - e, t, h), m.lambda(), m.mu());
      div += (Pp.col(j) - Pm.col(j)) / (2 * h);
    }
    const Vec<2> b_fd = utt - div / rho0;
    CHECK((b_fd - m.body_force(X, t)).norm() <= 1e-5 * scale);
    max_b = std::max(max_b, m.body_force(X, t).norm());
  }
  CHECK(max_b > 0.1 * scale); // the force is not trivially zero
}

TEST_CASE("mms plate: Cauchy stress is the neo-Hookean stress of wobbes eq. 11 and P = J sigma F^-T") {
  // Compared with eq. 11 evaluated on a finite-difference F (step 1e-5,
  // relative error ~1e-9): tolerance 1e-7 of (lambda + 2 mu) A 2 pi.
  const MmsPlate m = mms_plate();
  const double scale = (m.lambda() + 2 * m.mu()) * 0.005 * 2 * pi;
  for (int i = 0; i < 50; ++i) {
    const Vec<2> X(sample(i), sample(i + 50));
    const double t = 1.5 * sample(i + 100);
    const Mat<2> F = fd_deformation_gradient(m, X, t, 1e-5);
    const double J = F.determinant();
    const Mat<2> sigma =
        m.lambda() * std::log(J) / J * Mat<2>::Identity() + m.mu() / J * (F * F.transpose() - Mat<2>::Identity());
    CHECK((sigma - m.stress(X, t)).norm() <= 1e-7 * scale);
    // Round trip with the exact F: rounding only, a few ulps of mu |F| ~ 4e6 Pa,
    // i.e. ~1e-15 of the scale; 1e-12 leaves a wide margin.
    const Mat<2> Fe = m.deformation_gradient(X, t);
    const Mat<2> P = Fe.determinant() * m.stress(X, t) * Fe.inverse().transpose();
    CHECK((P - m.first_piola(X, t)).norm() <= 1e-12 * scale);
  }
}

TEST_CASE("mms plate: an amplitude that folds the plate (det F <= 0) is an InputError") {
  MmsPlateParameters p;
  p.young = 1e7;
  p.density = 1e7;
  p.poisson = 0.3;
  p.amplitude = 0.2; // 2 pi A = 1.26 > 1
  CHECK_THROWS_AS(MmsPlate{p}, InputError);
  p.amplitude = 0.005;
  p.poisson = 0.5;
  CHECK_THROWS_AS(MmsPlate{p}, InputError);
}

// ---------------------------------------------------------------------------
// Factory

namespace {

Scene bar_scene(int dim, const std::string& solution) {
  Scene s;
  s.file = "bar.toml";
  s.simulation.dimension = dim;
  MaterialSection m;
  m.name = "steel";
  m.density = kDykaRho;
  m.young = kDykaE;
  s.materials.push_back(m);
  BodySection b;
  b.name = "bar";
  b.material = "steel";
  b.lower = {0.0, 0.0, 0.0};
  b.upper = {kDykaL, 0.01, 0.01};
  s.bodies.push_back(b);
  s.reference.solution = solution;
  s.where["reference.solution"] = SourceRef{"bar.toml", 42, "reference.solution"};
  return s;
}

Scene dyka_scene(int dim) {
  Scene s = bar_scene(dim, "dyka");
  InitialVelocitySection iv;
  iv.lower = {-1.0, -1.0, -1.0};
  iv.upper = {kDykaA, 1.0, 1.0};
  iv.velocity = {kDykaV0, 0.0, 0.0};
  s.initial_velocities.push_back(iv);
  return s;
}

template <int D> void check_names_key(const Scene& s) {
  try {
    (void)make_exact_solution<D>(s);
    FAIL("no InputError");
  } catch (const InputError& e) {
    const std::string what = e.what();
    CHECK(what.find("bar.toml:42") != std::string::npos);
    CHECK(what.find("reference.solution") != std::string::npos);
  }
}

} // namespace

TEST_CASE("make_exact_solution: no reference gives no solution") {
  Scene s = bar_scene(1, "");
  CHECK(make_exact_solution<1>(s) == nullptr);
}

TEST_CASE("make_exact_solution: builds each solution with the scene's parameters") {
  {
    const auto e = make_exact_solution<1>(dyka_scene(1));
    REQUIRE(e != nullptr);
    CHECK(e->name() == "dyka");
    CHECK(!e->has_body_force());
    CHECK(e->velocity(at(0.1 * kDykaL), 0.0)[0] == kDykaV0);
    CHECK(e->velocity(at(0.5 * kDykaL), 0.0)[0] == 0.0);
    // Matches the directly constructed bar at a later time.
    const double t = 1.3 * kDykaL / dyka().wave_speed();
    CHECK(e->stress(at(0.6 * kDykaL), t)(0, 0) == dyka().state(0.6 * kDykaL, t).sigma);
  }
  {
    const auto e = make_exact_solution<2>(dyka_scene(2));
    REQUIRE(e != nullptr);
    CHECK(e->velocity(Vec<2>(0.1 * kDykaL, 0.005), 0.0)[0] == kDykaV0);
  }
  {
    Scene s = bar_scene(3, "fixed_bar");
    s.materials[0].young = 4e3;
    s.materials[0].density = 1.0;
    s.bodies[0].upper = {1.0, 0.1, 0.1};
    s.bodies[0].velocity = {0.6, 0.0, 0.0};
    s.bodies[0].velocity_profile = "sin_x";
    const auto e = make_exact_solution<3>(s);
    REQUIRE(e != nullptr);
    CHECK(e->name() == "fixed_bar");
    CHECK(e->velocity(Vec<3>(0.25, 0.05, 0.05), 0.0)[0] == doctest::Approx(0.6 * std::sin(pi / 4)).epsilon(1e-14));
  }
  {
    Scene s = bar_scene(1, "traction_bar");
    s.materials[0].young = 100.0;
    s.materials[0].density = 100.0;
    s.bodies[0].upper = {1.0, 0.0, 0.0};
    TractionSection ts;
    ts.function = "wobbes_traction_bar";
    ts.value = {2.0, 0.0, 0.0}; // amplitude 2 Pa
    s.tractions.push_back(ts);
    const auto e = make_exact_solution<1>(s);
    REQUIRE(e != nullptr);
    const auto* tb = dynamic_cast<const TractionBar<1>*>(e.get());
    REQUIRE(tb != nullptr);
    CHECK(tb->traction(0.5) == doctest::Approx(-2.0).epsilon(1e-15));
    s.tractions[0].value = {0.0, 0.0, 0.0}; // default: wobbes' unit amplitude
    const auto e1 = make_exact_solution<1>(s);
    CHECK(dynamic_cast<const TractionBar<1>&>(*e1).traction(0.5) == doctest::Approx(-1.0).epsilon(1e-15));
  }
  {
    Scene s = bar_scene(2, "mms_plate");
    s.materials[0].young = 1e7;
    s.materials[0].density = 1e7;
    s.materials[0].poisson = 0.3;
    s.bodies[0].upper = {1.0, 1.0, 0.0};
    const auto e = make_exact_solution<2>(s);
    REQUIRE(e != nullptr);
    CHECK(e->has_body_force());
    const Vec<2> X(0.3, 0.8);
    CHECK((e->body_force(X, 0.2) - mms_plate().body_force(X, 0.2)).norm() == 0.0);
  }
}

TEST_CASE("make_exact_solution: scenes that do not fit the solution are InputErrors naming reference.solution") {
  SUBCASE("mms_plate in 1D and 3D") {
    check_names_key<1>(bar_scene(1, "mms_plate"));
    check_names_key<3>(bar_scene(3, "mms_plate"));
  }
  SUBCASE("run dimension differs from the scene") { check_names_key<2>(dyka_scene(1)); }
  SUBCASE("dyka with two materials") {
    Scene s = dyka_scene(1);
    s.materials.push_back(s.materials[0]);
    s.materials[1].name = "other";
    check_names_key<1>(s);
  }
  SUBCASE("dyka with two bodies") {
    Scene s = dyka_scene(1);
    s.bodies.push_back(s.bodies[0]);
    check_names_key<1>(s);
  }
  SUBCASE("dyka without an initial-velocity box") { check_names_key<1>(bar_scene(1, "dyka")); }
  SUBCASE("dyka with a box that does not cover the bar's width") {
    Scene s = dyka_scene(2);
    s.initial_velocities[0].upper[1] = 0.005;
    check_names_key<2>(s);
  }
  SUBCASE("dyka with a transverse initial velocity") {
    Scene s = dyka_scene(2);
    s.initial_velocities[0].velocity[1] = 1.0;
    check_names_key<2>(s);
  }
  SUBCASE("dyka with a box outside the bar") {
    Scene s = dyka_scene(1);
    s.initial_velocities[0].lower = {1.0, 0, 0};
    s.initial_velocities[0].upper = {2.0, 0, 0};
    check_names_key<1>(s);
  }
  SUBCASE("fixed_bar without the sin_x profile") { check_names_key<1>(bar_scene(1, "fixed_bar")); }
  SUBCASE("traction_bar without its traction") { check_names_key<1>(bar_scene(1, "traction_bar")); }
  SUBCASE("mms_plate on a rectangle") {
    Scene s = bar_scene(2, "mms_plate");
    s.bodies[0].upper = {1.0, 0.5, 0.0};
    check_names_key<2>(s);
  }
  SUBCASE("mms_plate with an amplitude too large for the plate") {
    Scene s = bar_scene(2, "mms_plate");
    s.bodies[0].upper = {0.02, 0.02, 0.0}; // 2 pi 0.005 / 0.02 > 1
    check_names_key<2>(s);
  }
  SUBCASE("unknown solution") { check_names_key<1>(bar_scene(1, "kepler")); }
}

// ---------------------------------------------------------------------------
// RMS error

TEST_CASE("rms_error: square root of the mean of the squared errors") {
  CHECK(rms_error({4.0}) == 2.0);
  CHECK(rms_error({1.0, 4.0, 4.0, 7.0}) == doctest::Approx(2.0).epsilon(1e-15));
  CHECK(rms_error({0.0, 0.0}) == 0.0);
  CHECK_THROWS_AS(rms_error({}), InputError);
  CHECK_THROWS_AS(rms_error({1.0, -1.0}), InputError);
  CHECK_THROWS_AS(rms_error({std::nan("")}), InputError);
}
