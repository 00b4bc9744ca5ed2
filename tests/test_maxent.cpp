// Tests of the max-ent basis with a cubic-spline prior (wobbes sect. 6.3,
// docs/theory.md sect. 4).
//
// Tolerances (h = nodal spacing):
// * partition of unity |sum N - 1| <= 1e-12 and |sum grad N| <= 1e-12 sum |grad N|:
//   exact up to summation round-off by construction.
// * linear completeness |sum N_I x_I - x| <= 2e-12 h: |r| <= newton_tolerance h
//   (1e-12 h) plus round-off.
// * gradient consistency |sum x_I (x) grad N_I - I| <= 1e-10: exact identity of
//   the implicit-differentiation gradient, up to round-off times cond(J).
// * gradients vs central differences with step 2e-6 h: truncation error
//   step^2 / 6 |d^3 N| <= ~1e-9 / h here (measured to fall 100-fold per decade of
//   the step), Newton solved to 1e-14 h so that its noise (/ 4e-6 h) stays below
//   ~1e-9 / h; tolerance 2e-8 / h. A gradient that ignores the x-dependence of
//   the prior is off by O(1 / h) (checked below).
#include "otmpm/basis/families.hpp"
#include "otmpm/basis/lme.hpp"
#include "support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

using namespace otmpm;
using namespace otmpm::test;

namespace {

constexpr double kPartitionTol = 1e-12;
constexpr double kGradientSumTol = 1e-12;
constexpr double kCompletenessTol = 2e-12; // times h
constexpr double kGradientConsistencyTol = 1e-10;
constexpr double kFdStep = 2e-6; // times h
constexpr double kFdTol = 2e-8;  // times 1/h

constexpr IdentityTolerances kIdentityTol{kPartitionTol, kGradientSumTol, kCompletenessTol, kGradientConsistencyTol};

BasisOptions maxent_options(double d_max = 2.0) {
  BasisOptions opt;
  opt.kind = "maxent";
  opt.values["d_max"] = d_max;
  return opt;
}

/// Checks every basis identity at every point; reports the worst violations.
template <int D> void require_identities(const Basis<D>& basis, const AlignedVector<Vec<D>>& pts) {
  const Identities<D> id = check_identities(basis, pts);
  test::require_identities(id, id.worst_consistency_point, kIdentityTol);
}

template <int D> void identities_on(const NodeSet<D>& nodes, unsigned seed, double d_max = 2.0) {
  const auto basis = make_maxent_basis<D>(nodes, maxent_options(d_max));
  require_identities<D>(*basis, unit_box_points<D>(basis->nodes(), 60, seed));
}

template <int D> void fd_on(const NodeSet<D>& nodes, unsigned seed) {
  BasisOptions opt = maxent_options();
  opt.values["newton_tolerance"] = 1e-14;
  const auto basis = make_maxent_basis<D>(nodes, opt);
  const double err = max_fd_gradient_error<D>(*basis, seed, kFdStep);
  INFO("layout " << int(nodes.layout()) << ", D = " << D);
  CHECK(err <= kFdTol);
}

} // namespace

TEST_CASE("maxent: cubic spline prior (wobbes eq. 89)") {
  using maxent::cubic_spline;
  using maxent::cubic_spline_derivative;
  CHECK(cubic_spline(0.0) == doctest::Approx(2.0 / 3.0).epsilon(1e-15));
  CHECK(cubic_spline(0.5) == doctest::Approx(1.0 / 6.0).epsilon(1e-15));
  CHECK(cubic_spline(1.0) == 0.0);
  CHECK(cubic_spline(1.5) == 0.0);
  // C^2 at r = 1/2: both pieces agree in value and slope (-1)
  const double e = 1e-9;
  CHECK(cubic_spline(0.5 - e) == doctest::Approx(cubic_spline(0.5 + e)).epsilon(1e-8));
  CHECK(cubic_spline_derivative(0.5) == doctest::Approx(-1.0).epsilon(1e-15));
  CHECK(cubic_spline_derivative(0.5 + 1e-12) == doctest::Approx(-1.0).epsilon(1e-10));
  // derivative vs central differences (step 1e-6: truncation ~1e-12, round-off ~1e-10)
  double err = 0;
  for (double r = 0.013; r < 1.0; r += 0.0611)
    err = std::max(err, std::abs((cubic_spline(r + 1e-6) - cubic_spline(r - 1e-6)) / 2e-6 - cubic_spline_derivative(r)));
  CHECK(err <= 1e-8);
}

TEST_CASE("maxent: gradient of the log-prior matches finite differences") {
  const maxent::CubicSplinePrior<2> prior(0.3);
  double err = 0;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  for (int i = 0; i < 50; ++i) {
    const Vec<2> dx(u(rng), u(rng));
    double a = 0;
    if (!prior.log_weight(dx, a)) continue;
    const Vec<2> g = prior.grad_log_weight(dx);
    for (int k = 0; k < 2; ++k) {
      Vec<2> e = Vec<2>::Zero();
      e[k] = 1e-7;
      double ap = 0, am = 0;
      REQUIRE(prior.log_weight(dx + e, ap));
      REQUIRE(prior.log_weight(dx - e, am));
      err = std::max(err, std::abs((ap - am) / 2e-7 - g[k]) / (1.0 + std::abs(g[k])));
    }
  }
  CHECK(err <= 1e-6); // step 1e-7 on |dx| ~ 0.1: truncation ~1e-12, round-off ~1e-9
  double a = 0;
  CHECK_FALSE(prior.log_weight(Vec<2>(0.3, 0.0), a)); // r = 1: w = 0, not in the support
  CHECK(prior.grad_log_weight(Vec<2>::Zero()).norm() == 0.0); // regular at the node
}

namespace {

/// CubicSplinePrior::weight against cubic_spline, log_weight and
/// grad_log_weight: the basis uses it in place of them, so it must give
/// their bits (same r, same w, same factor).
template <int D> void weight_matches_log_form(unsigned seed) {
  const maxent::CubicSplinePrior<D> prior(0.3);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  int inside = 0;
  for (int i = 0; i < 2000; ++i) {
    Vec<D> dx;
    for (int k = 0; k < D; ++k) dx[k] = u(rng);
    if (i == 0) dx.setZero(); // at the node
    double log_w = 0, w = 0, c = 0;
    const bool in = prior.log_weight(dx, log_w);
    REQUIRE(prior.weight(dx, w, c) == in);
    if (!in) continue;
    ++inside;
    const double r = prior.normalised_radius(dx);
    CHECK(w == maxent::cubic_spline(r));
    // |dx| / d as |dx| (1 / d): within an ulp of the quotient (two roundings)
    CHECK(std::abs(r - dx.norm() / 0.3) <= 2.0 * std::numeric_limits<double>::epsilon() * r);
    if constexpr (D == 1) CHECK(std::abs(dx[0]) == dx.norm()); // 1D: |dx_0| is sqrt(dx_0^2) exactly
    CHECK(std::log(w) == log_w);
    const Vec<D> g = prior.grad_log_weight(dx);
    for (int k = 0; k < D; ++k) CHECK(c * dx[k] == g[k]);
  }
  CHECK(inside > 100);
}

/// N_I against the log form exp(log w_I + lambda . dx_I - max) / sum at the
/// basis' own converged lambda, and linear completeness. Returns |lambda| R.
/// `warm`: N of a second evaluation started from the converged lambda,
/// which must end without a Newton step (its N from the start's weights).
template <int D>
double check_log_form(const Basis<D>& basis, double d, const Vec<D>& x, double tol_N, double tol_completeness,
                      bool warm = false) {
  Stencil<D> st;
  Vec<D> lambda = Vec<D>::Zero();
  PointQuery<D> q;
  q.x = x;
  q.lambda = &lambda;
  basis.evaluate(q, st);
  if (warm) {
    int iterations = -1;
    q.iterations = &iterations;
    basis.evaluate(q, st);
    REQUIRE(iterations == 0);
  }
  std::vector<double> f;
  double f_max = -std::numeric_limits<double>::infinity();
  for (int a = 0; a < st.size(); ++a) {
    const Vec<D> dx = x - basis.nodes().position(st.node[a]);
    f.push_back(std::log(maxent::cubic_spline(dx.norm() / d)) + lambda.dot(dx));
    f_max = std::max(f_max, f.back());
  }
  double Z = 0;
  for (const double v : f) Z += std::exp(v - f_max);
  double err = 0, sum = 0;
  Vec<D> xbar = Vec<D>::Zero();
  for (int a = 0; a < st.size(); ++a) {
    err = std::max(err, std::abs(st.N[a] - std::exp(f[a] - f_max) / Z));
    sum += st.N[a];
    xbar += st.N[a] * basis.nodes().position(st.node[a]);
  }
  INFO("x = " << x.transpose() << ", lambda = " << lambda.transpose());
  CHECK(err <= tol_N);
  CHECK(std::abs(sum - 1.0) <= kPartitionTol);
  CHECK((xbar - x).norm() <= tol_completeness);
  return lambda.norm() * d;
}

} // namespace

TEST_CASE("maxent: the prior's weight and gradient factor are the bits of the log form") {
  weight_matches_log_form<1>(3);
  weight_matches_log_form<2>(4);
  weight_matches_log_form<3>(5);
}

TEST_CASE("maxent: N from w_I exp(lambda . dx_I) equals the log form, also with shifted exponents") {
  // The solver forms p_I = w_I exp(lambda . dx_I) (no log per node); the
  // reference is exp(log w_I + lambda . dx_I) normalised, at the same lambda:
  // they differ by round-off of the exponents, |lambda . dx| eps <~ 1e-13.
  const auto b2 = make_maxent_basis<2>(NodeSet<2>::perturbed(unit_grid<2>(6), 0.3, 8), maxent_options());
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(0.1, 0.9);
  const double h2 = b2->nodes().spacing();
  for (int i = 0; i < 20; ++i)
    check_log_form<2>(*b2, 2.0 * h2, Vec<2>(u(rng), u(rng)), 1e-13, kCompletenessTol * h2);
  // 1D, two nodes 1e-3 apart next to a lattice of spacing 0.1: at x = 1e-4
  // lambda ~ ln(9) / 1e-3 ~ 2e3, |lambda| R > 300, so the exponents are
  // shifted by their maximum (log w_I formed there) and the line search
  // compares log Z values (its round-off bound needs log w_I too).
  AlignedVector<Vec<1>> x{Vec<1>(0.0), Vec<1>(1e-3)};
  for (int I = 1; I <= 10; ++I) x.push_back(Vec<1>(0.1 * I));
  const auto b1 = make_maxent_basis<1>(NodeSet<1>::cloud(x, 0.1), maxent_options());
  // exponents up to |lambda| R ~ 440: their round-off ~1e-13 relative in N
  const double lambda_R = check_log_form<1>(*b1, 0.2, Vec<1>(1e-4), 1e-12, kCompletenessTol * 0.1);
  CHECK(lambda_R > 300.0);
}

TEST_CASE("maxent: N near lambda = 0 (the Taylor exponential) equals the log form to round-off") {
  // On evenly spaced nodes the cubic-spline prior of d_max = 2 (the cubic
  // B-spline of spacing h) reproduces x by itself (lambda = 0); nodes moved
  // by a smooth stretch give |lambda| R up to 2^-8 at 0.25% of h, where the
  // solver takes e^u by its degree-5 Taylor polynomial (within an ulp), and
  // beyond 2^-8 at 2%, where it takes the full exponential. N against
  // exp(log w_I + lambda . dx_I) normalised with std::exp, at the same
  // lambda, from a start at the converged lambda (as in `ul` mode, where
  // that start ends the solve): two ulp of N <= 1 on both sides of 2^-8
  // (measured 2.2e-16; a cubic polynomial below 2^-8, or the degree-5 one
  // up to 2^-4, fails).
  const double h = 0.1;
  const auto largest_lambda_R = [&](double amplitude) {
    AlignedVector<Vec<1>> x;
    for (int I = 0; I <= 20; ++I) x.push_back(Vec<1>(h * I + amplitude * h * std::sin(0.9 * I)));
    const auto b = make_maxent_basis<1>(NodeSet<1>::cloud(x, h), maxent_options());
    double largest = 0.0;
    for (int i = 0; i < 40; ++i) {
      const double xi = 0.5 + 1.0 * i / 40.0; // interior: full supports
      largest = std::max(largest, check_log_form<1>(*b, 2.0 * h, Vec<1>(xi), 4.5e-16, kCompletenessTol * h, true));
    }
    MESSAGE("stretch " << amplitude << " h: largest |lambda| R " << largest);
    return largest;
  };
  const double taylor = largest_lambda_R(0.0025);
  CHECK(taylor <= 0x1p-8); // every point on the Taylor path
  CHECK(taylor > 0x1p-9);  // and its exponents reach half its range
  const double beyond = largest_lambda_R(0.02);
  CHECK(beyond > 0x1p-8); // some points past it
  CHECK(beyond <= 0x1p-4);
}

TEST_CASE("maxent: kind, flags and option checks") {
  const auto nodes = NodeSet<2>::cartesian(unit_grid<2>(4));
  const auto b = make_maxent_basis<2>(nodes, maxent_options());
  CHECK(b->kind() == "maxent");
  CHECK(b->linearly_complete());
  CHECK_THROWS_AS(make_maxent_basis<2>(nodes, maxent_options(0.0)), InputError);
  CHECK_THROWS_AS(make_maxent_basis<2>(nodes, maxent_options(-1.0)), InputError);
}

TEST_CASE("maxent: symmetric 1D values match the closed form (lambda = 0)") {
  // Uniform 1D grid, d_max = 2: at a node the neighbours at +-h have r = 1/2,
  // w = 1/6, against w(0) = 2/3: N = 2/3 and 1/6. At a midpoint, r = 1/4 and 3/4:
  // w = 23/48 and 1/48, which already sum to 1 over the four nodes.
  const auto b = make_maxent_basis<1>(NodeSet<1>::cartesian(unit_grid<1>(10)), maxent_options());
  std::vector<double> N;
  dense_eval<1>(*b, Vec<1>(0.5), N);
  CHECK(N[5] == doctest::Approx(2.0 / 3.0).epsilon(1e-13));
  CHECK(N[6] == doctest::Approx(1.0 / 6.0).epsilon(1e-13));
  CHECK(N[7] == 0.0);
  dense_eval<1>(*b, Vec<1>(0.45), N);
  CHECK(N[4] == doctest::Approx(23.0 / 48.0).epsilon(1e-13));
  CHECK(N[6] == doctest::Approx(1.0 / 48.0).epsilon(1e-13));
}

TEST_CASE("maxent: identities on Cartesian grids (1D, 2D, 3D)") {
  identities_on<1>(NodeSet<1>::cartesian(unit_grid<1>(cells_for<1>())), 11);
  identities_on<2>(NodeSet<2>::cartesian(unit_grid<2>(cells_for<2>())), 12);
  identities_on<2>(NodeSet<2>::cartesian(unit_grid<2>(cells_for<2>())), 14, 3.0);
  identities_on<3>(NodeSet<3>::cartesian(unit_grid<3>(cells_for<3>())), 13);
}

TEST_CASE("maxent: identities on perturbed grids (1D, 2D, 3D)") {
  identities_on<1>(NodeSet<1>::perturbed(unit_grid<1>(cells_for<1>()), 0.3, 5), 21);
  identities_on<2>(NodeSet<2>::perturbed(unit_grid<2>(cells_for<2>()), 0.3, 6), 22);
  identities_on<3>(NodeSet<3>::perturbed(unit_grid<3>(cells_for<3>()), 0.3, 7), 23);
}

TEST_CASE("maxent: identities on random clouds (1D, 2D, 3D)") {
  identities_on<1>(random_cloud<1>(cells_for<1>(), 8), 31);
  identities_on<2>(random_cloud<2>(cells_for<2>(), 9), 32);
  identities_on<3>(random_cloud<3>(cells_for<3>(), 10), 33);
}

TEST_CASE("maxent: gradients agree with central differences") {
  fd_on<1>(NodeSet<1>::perturbed(unit_grid<1>(10), 0.3, 1), 51);
  fd_on<2>(NodeSet<2>::cartesian(unit_grid<2>(8)), 52);
  fd_on<2>(NodeSet<2>::perturbed(unit_grid<2>(8), 0.3, 2), 53);
  fd_on<2>(random_cloud<2>(8, 4), 54);
  fd_on<3>(NodeSet<3>::perturbed(unit_grid<3>(5), 0.3, 3), 55);
}

TEST_CASE("maxent: the prior's dependence on x contributes to the gradient") {
  // The closed LME form -N_I J^{-1} (x - x_I) is wrong for this prior: at
  // generic points it differs from the (finite-difference checked) gradient by O(1/h).
  const auto nodes = NodeSet<2>::perturbed(unit_grid<2>(8), 0.3, 2);
  const auto b = make_maxent_basis<2>(nodes, maxent_options());
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(0.1, 0.9);
  double diff = 0, fd = 0;
  for (int i = 0; i < 10; ++i) {
    Stencil<2> st;
    PointQuery<2> q;
    q.x = Vec<2>(u(rng), u(rng));
    b->evaluate(q, st);
    Vec<2> r = Vec<2>::Zero();
    for (int a = 0; a < st.size(); ++a) r += st.N[a] * (q.x - nodes.position(st.node[a]));
    Mat<2> J = Mat<2>::Zero();
    for (int a = 0; a < st.size(); ++a) {
      const Vec<2> c = q.x - nodes.position(st.node[a]) - r;
      J += st.N[a] * c * c.transpose();
    }
    for (int a = 0; a < st.size(); ++a) {
      const Vec<2> naive = -st.N[a] * J.inverse() * (q.x - nodes.position(st.node[a]) - r);
      diff = std::max(diff, (naive - st.dN[a]).norm() * nodes.spacing());
    }
    fd = std::max(fd, fd_gradient_error<2>(*b, q.x, kFdStep));
  }
  CHECK(diff >= 0.05);
  CHECK(fd <= kFdTol);
}

TEST_CASE("maxent: support is the ball of radius d_max h") {
  for (double d_max : {2.0, 3.0}) {
    const auto nodes = NodeSet<2>::perturbed(unit_grid<2>(8), 0.25, 9);
    const auto b = make_maxent_basis<2>(nodes, maxent_options(d_max));
    const double d = d_max * nodes.spacing();
    Stencil<2> st;
    int mismatches = 0;
    int largest = 0;
    for (const Vec<2>& x : unit_box_points<2>(nodes, 40, 61)) {
      PointQuery<2> q;
      q.x = x;
      b->evaluate(q, st);
      largest = std::max(largest, st.size());
      std::vector<int> kept(st.node.begin(), st.node.end());
      std::sort(kept.begin(), kept.end());
      std::vector<int> expected;
      for (int I = 0; I < nodes.size(); ++I)
        if ((nodes.position(I) - x).norm() < d * (1 - 1e-12)) expected.push_back(I);
      for (int I : kept) // on the cut-off w ~ (1 - r)^3 ~ 1e-36: either answer is right
        if (std::abs((nodes.position(I) - x).norm() - d) <= 1e-12 * d) expected.push_back(I);
      std::sort(expected.begin(), expected.end());
      if (kept != expected) ++mismatches;
    }
    CAPTURE(d_max);
    CHECK(mismatches == 0);
    CHECK(largest <= b->max_stencil());
  }
}

TEST_CASE("maxent: warm start gives the same answer in fewer iterations") {
  const auto nodes = NodeSet<3>::perturbed(unit_grid<3>(5), 0.3, 12);
  const auto b = make_maxent_basis<3>(nodes, maxent_options());
  const double h = nodes.spacing();
  std::mt19937 rng(91);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  Stencil<3> cold, warm;
  int cold_total = 0, warm_total = 0;
  double diff = 0;
  for (int i = 0; i < 20; ++i) {
    Vec<3> lambda = Vec<3>::Zero();
    int it = -1;
    PointQuery<3> q;
    q.x = Vec<3>(u(rng), u(rng), u(rng));
    q.lambda = &lambda;
    q.iterations = &it;
    b->evaluate(q, cold);
    b->evaluate(q, warm);
    CHECK(it == 0); // already converged at the same point
    q.x += Vec<3>(0.01 * h, -0.02 * h, 0.005 * h);
    b->evaluate(q, warm);
    warm_total += it;
    PointQuery<3> qc;
    qc.x = q.x;
    qc.iterations = &it;
    b->evaluate(qc, cold);
    cold_total += it;
    REQUIRE(warm.node == cold.node);
    for (int a = 0; a < cold.size(); ++a) diff = std::max(diff, std::abs(warm.N[a] - cold.N[a]));
  }
  CHECK(warm_total < cold_total);
  CHECK(diff <= 1e-11); // both within |r| <= 1e-12 h of the same lambda
}

TEST_CASE("maxent: points outside the convex hull are a BasisError naming the point") {
  const auto b = make_maxent_basis<2>(NodeSet<2>::cartesian(unit_grid<2>(8)), maxent_options());
  for (const Vec<2>& x : {Vec<2>(-0.02, 0.5), Vec<2>(0.3, 1.001), Vec<2>(5.0, 5.0)}) {
    PointQuery<2> q;
    q.x = x;
    q.id = 42;
    Stencil<2> st;
    CAPTURE(x.transpose());
    const std::string named = "point 42 at " + format_point<2>(x);
    CHECK_THROWS_WITH_AS(b->evaluate(q, st), doctest::Contains(named.c_str()), BasisError);
    CHECK_THROWS_WITH_AS(b->evaluate(q, st), doctest::Contains("convex hull"), BasisError);
  }
  // outside a slanted face, inside the bounding box: detected by the Newton solve
  const auto g = unit_grid<2>(8);
  const auto lattice = NodeSet<2>::cartesian(g);
  AlignedVector<Vec<2>> x;
  for (int id = 0; id < lattice.size(); ++id) {
    const auto ijk = g.node_index(id);
    if (ijk[0] + ijk[1] <= 8) x.push_back(lattice.position(id));
  }
  const auto tri = make_maxent_basis<2>(NodeSet<2>::cloud(x, 0.125), maxent_options());
  PointQuery<2> q;
  q.x = Vec<2>(0.51, 0.51);
  Stencil<2> st;
  CHECK_THROWS_WITH_AS(tri->evaluate(q, st), doctest::Contains("convex hull"), BasisError);
}

TEST_CASE("maxent: moved nodes keep the initial support radius") {
  auto b = make_maxent_basis<2>(NodeSet<2>::perturbed(unit_grid<2>(8), 0.2, 4), maxent_options());
  const Vec<2> x(0.37, 0.61);
  std::vector<double> before, after;
  dense_eval<2>(*b, x, before);
  const Vec<2> shift(-0.21, 0.4);
  AlignedVector<Vec<2>> dx(static_cast<std::size_t>(b->nodes().size()), shift);
  b->nodes().advect(dx);
  b->nodes_moved(dx);
  dense_eval<2>(*b, Vec<2>(x + shift), after);
  double diff = 0;
  for (std::size_t I = 0; I < before.size(); ++I) diff = std::max(diff, std::abs(before[I] - after[I]));
  CHECK(diff <= 1e-11); // translation invariance (round-off of the shifted coordinates only)
}
