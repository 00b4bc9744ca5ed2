// Tests of the Taylor-predicted warm start of the max-ent solve
// (MultiplierSlope, docs/theory.md sect. 4.4, eq. 4.7a): the slope G = d lambda / d x
// stored at each converged solve, and the prediction lambda + G (x - x0).
//
// Tolerances (h = nodal spacing; lambda ~ 1/h, G ~ beta ~ 1/h^2):
// * G against central differences of lambda with step 2e-5 h, lambda solved
//   to |r| <= 1e-14 h: the truncation error (step^2) was measured at up to
//   1.6e-6 |G| with step 1e-4 h (deformation metric), 6.5e-6 with 2e-4 h,
//   so ~7e-8 here; Newton noise ~ (1e-14 h / J) / (4e-5 h) ~ 1e-9 relative.
//   Bound 1e-6 |G|.
// * The prediction error is second order: halving the displacement divides
//   it by 4 (asserted between 3 and 5, displacements 1e-2 h and 5e-3 h,
//   where the third-order term is ~1% of the second).
// * N from the predicted start agree with a cold solve to 1e-11: both
//   converge to |r| <= 1e-12 h, and J^{-1} r moves N by less than ~1e-11.
// * With the second-order term (eq. 4.7b) along a straight path of equal
//   steps the prediction error is third order: halving the step divides it
//   by 8 (asserted between 6 and 10, steps 2e-2 h and 1e-2 h; measured
//   7.9-8.1: the solves' noise, |r| <= 1e-14 h, moves lambda by ~1e-14 / h
//   against errors above ~1e-8 / h), so its ratio to the first-order
//   start's error halves with the step (asserted <= 0.6 of the ratio at
//   twice the step).
#include "otmpm/basis/families.hpp"
#include "otmpm/basis/lme.hpp"
#include "otmpm/state.hpp"
#include "support.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <random>
#include <vector>
#include <string>

using namespace otmpm;
using namespace otmpm::test;

namespace {

BasisOptions options(const std::string& kind, const std::string& metric = "isotropic") {
  BasisOptions opt;
  opt.kind = kind;
  opt.values["gamma_lme"] = 3.0;
  opt.metric = metric;
  opt.values["newton_tolerance"] = 1e-14;
  return opt;
}

/// The converged multiplier at x from a cold start; G of that solve into *G.
template <int D>
Vec<D> converged_lambda(const Basis<D>& b, const Vec<D>& x, const Mat<D>* F = nullptr, Mat<D>* G = nullptr) {
  Vec<D> lambda = Vec<D>::Zero();
  MultiplierSlope<D> slope;
  PointQuery<D> q;
  q.x = x;
  q.lambda = &lambda;
  q.slope = &slope;
  q.deformation = F;
  Stencil<D> st;
  b.evaluate(q, st);
  if (G) *G = slope.G;
  CHECK(slope.x0 == x);
  return lambda;
}

/// max over the axes of |G e_k - (lambda(x + d e_k) - lambda(x - d e_k)) / 2d| / |G|.
template <int D> double slope_fd_error(const Basis<D>& b, const Vec<D>& x, const Mat<D>* F = nullptr) {
  Mat<D> G;
  converged_lambda<D>(b, x, F, &G);
  const double d = 2e-5 * b.nodes().spacing();
  double err = 0.0;
  for (int k = 0; k < D; ++k) {
    const Vec<D> e = Vec<D>::Unit(k) * d;
    const Vec<D> fd = (converged_lambda<D>(b, x + e, F) - converged_lambda<D>(b, x - e, F)) / (2 * d);
    err = std::max(err, (G.col(k) - fd).norm() / G.norm());
  }
  return err;
}

/// `count` random points of [0.2, 0.8]^D (inside the unit box, away from its
/// boundary, where lambda grows without bound).
template <int D> AlignedVector<Vec<D>> interior_points(int count, unsigned seed) {
  std::mt19937 rng(seed);
  AlignedVector<Vec<D>> x;
  for (int i = 0; i < count; ++i) x.push_back(random_in_box<D>(rng, Vec<D>::Constant(0.2), Vec<D>::Constant(0.8)));
  return x;
}

template <int D> void check_slopes(const Basis<D>& b, unsigned seed, const Mat<D>* F = nullptr) {
  for (const Vec<D>& x : interior_points<D>(8, seed)) {
    CAPTURE(x.transpose());
    CHECK(slope_fd_error<D>(b, x, F) <= 1e-6);
  }
}

} // namespace

TEST_CASE("lme slope: G = d lambda / d x against central differences, every prior and metric") {
  const auto g2 = unit_grid<2>(8);
  SUBCASE("lme on a lattice (closed form 2 beta I - J^-1)") {
    check_slopes<2>(*make_basis<2>(options("lme"), NodeSet<2>::cartesian(g2)), 3);
  }
  SUBCASE("lme on perturbed nodes, 3D") {
    check_slopes<3>(*make_basis<3>(options("lme"), NodeSet<3>::perturbed(unit_grid<3>(5), 0.3, 2)), 4);
  }
  SUBCASE("lme, metric node_spacing on perturbed nodes (general form, beta_I by node)") {
    check_slopes<2>(*make_basis<2>(options("lme", "node_spacing"), NodeSet<2>::perturbed(g2, 0.3, 5)), 5);
  }
  SUBCASE("lme, metric deformation (closed form with B = beta M)") {
    Mat<2> F;
    F << 1.3, 0.2, -0.1, 0.8;
    check_slopes<2>(*make_basis<2>(options("lme", "deformation"), NodeSet<2>::cartesian(g2)), 6, &F);
  }
  SUBCASE("max-ent, cubic spline prior (general form)") {
    check_slopes<2>(*make_basis<2>(options("maxent"), NodeSet<2>::perturbed(g2, 0.2, 7)), 7);
  }
}

TEST_CASE("lme slope: the predicted start is second-order accurate and saves Newton iterations") {
  const auto b = make_basis<2>(options("lme"), NodeSet<2>::perturbed(unit_grid<2>(8), 0.3, 12));
  const double h = b->nodes().spacing();
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> angle(0.0, 6.283185307179586);
  int plain_total = 0, predicted_total = 0;
  double worst_N = 0.0;
  for (const Vec<2>& x : interior_points<2>(20, 21)) {
    const double a = angle(rng);
    const Vec<2> dir(std::cos(a), std::sin(a));
    Mat<2> G;
    const Vec<2> lambda0 = converged_lambda<2>(*b, x, nullptr, &G);
    // second order: the error of lambda0 + G dx falls 4-fold per halving of dx
    double err[2];
    for (int i = 0; i < 2; ++i) {
      const Vec<2> dx = dir * (i == 0 ? 1e-2 : 5e-3) * h;
      err[i] = (lambda0 + G * dx - converged_lambda<2>(*b, Vec<2>(x + dx))).norm();
    }
    CAPTURE(x.transpose());
    CHECK(err[0] / err[1] >= 3.0);
    CHECK(err[0] / err[1] <= 5.0);
    // one step of a particle (1e-3 h): the plain and the predicted warm start
    const Vec<2> x1 = x + dir * 1e-3 * h;
    Stencil<2> cold, plain, predicted;
    evaluate_at<2>(*b, x1, cold);
    for (const bool with_slope : {false, true}) {
      Vec<2> lambda = lambda0;
      MultiplierSlope<2> slope{x, G};
      int it = -1;
      b->evaluate(stateful_query<2>(x1, &lambda, with_slope ? &slope : nullptr, &it), with_slope ? predicted : plain);
      (with_slope ? predicted_total : plain_total) += it;
    }
    REQUIRE(predicted.node == cold.node);
    for (int i = 0; i < cold.size(); ++i) worst_N = std::max(worst_N, std::abs(predicted.N[i] - cold.N[i]));
  }
  CHECK(predicted_total < plain_total);
  CHECK(worst_N <= 1e-11);
}

TEST_CASE("lme slope: kept per point only while the nodes stay fixed, and saved in checkpoints") {
  const auto b = make_basis<2>(options("lme"), NodeSet<2>::cartesian(unit_grid<2>(8)));
  CHECK(b->point_state_use(false).slope);
  CHECK_FALSE(b->point_state_use(true).slope);
  CHECK_FALSE(make_basis<2>(options("linear"), NodeSet<2>::cartesian(unit_grid<2>(8)))->point_state_use(false).slope);
  b->bind_points(3, true);
  CHECK(b->point_state().slope.empty());
  b->bind_points(3, false);
  REQUIRE(b->point_state().slope.size() == 3);
  const AlignedVector<Vec<2>> x{Vec<2>(0.31, 0.42), Vec<2>(0.55, 0.61), Vec<2>(0.72, 0.27)};
  BasisTable<2> table;
  b->evaluate_points(x, table);
  for (int p = 0; p < 3; ++p) {
    CHECK(b->point_state().slope[p].x0 == x[p]);
    CHECK(b->point_state().slope[p].G.norm() > 0.0);
  }
  StateGroup saved;
  b->save_state(saved);
  const auto restored = make_basis<2>(options("lme"), NodeSet<2>::cartesian(unit_grid<2>(8)));
  restored->bind_points(3, false);
  restored->restore_state(saved);
  for (int p = 0; p < 3; ++p) {
    CHECK(restored->point_state().slope[p].x0 == x[p]);
    CHECK(restored->point_state().slope[p].G == b->point_state().slope[p].G);
    CHECK(restored->point_state().lambda[p] == b->point_state().lambda[p]);
  }
  // a checkpoint without slopes (older otmpm): the plain warm start, G = 0
  saved.real_arrays.erase("lambda_slope");
  restored->bind_points(3, false);
  restored->restore_state(saved);
  CHECK(restored->point_state().slope[0].G.isZero(0.0));
  CHECK(restored->point_state().lambda[0] == b->point_state().lambda[0]);
}

namespace {

using Lme2 = maxent::MaxEntBasis<2, maxent::GaussianPrior<2>>;

/// Solves at each of `path` in turn from the state (lambda, slope) of the
/// solve before (the first from a cold start); Newton iterations of each
/// solve into *iterations when given. Returns the stencil of the last point.
Stencil<2> walk(const Basis<2>& b, const std::vector<Vec<2>>& path, Vec<2>& lambda, MultiplierSlope<2>& slope,
                std::vector<int>* iterations = nullptr) {
  Stencil<2> st;
  for (const Vec<2>& x : path) {
    int it = -1;
    b.evaluate(stateful_query<2>(x, &lambda, &slope, &it), st);
    if (iterations) iterations->push_back(it);
  }
  return st;
}

/// The start warm_start predicts at x from (lambda, slope).
Vec<2> predicted_start(const Basis<2>& b, const Vec<2>& x, Vec<2> lambda, MultiplierSlope<2> slope) {
  return dynamic_cast<const Lme2&>(b).warm_start(stateful_query<2>(x, &lambda, &slope, nullptr));
}

} // namespace

TEST_CASE("lme slope: along a straight path the second-order start is third-order accurate") {
  const auto b = make_basis<2>(options("lme"), NodeSet<2>::perturbed(unit_grid<2>(8), 0.3, 12));
  const double h = b->nodes().spacing();
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> angle(0.0, 6.283185307179586);
  for (const Vec<2>& x : interior_points<2>(12, 29)) {
    const double a = angle(rng);
    const Vec<2> dir(std::cos(a), std::sin(a));
    CAPTURE(x.transpose());
    double err[2], first_order[2];
    for (int i = 0; i < 2; ++i) {
      const Vec<2> d = dir * (i == 0 ? 2e-2 : 1e-2) * h;
      Vec<2> lambda = Vec<2>::Zero();
      MultiplierSlope<2> slope;
      walk(*b, {Vec<2>(x - d), x}, lambda, slope);
      REQUIRE(slope.e.isApprox(d, 1e-12));
      const Vec<2> exact = converged_lambda<2>(*b, Vec<2>(x + d));
      err[i] = (predicted_start(*b, x + d, lambda, slope) - exact).norm();
      first_order[i] = (lambda + slope.G * d - exact).norm();
    }
    CHECK(err[0] / err[1] >= 6.0);
    CHECK(err[0] / err[1] <= 10.0);
    // and below the first-order start's error, by a factor that halves with the step
    // (measured 0.016-0.35 at the smaller step over these points)
    CHECK(err[1] < 0.5 * first_order[1]);
    CHECK(err[1] / first_order[1] <= 0.6 * (err[0] / first_order[0]));
  }
}

TEST_CASE("lme slope: the second-order term only along the last displacement, |alpha| <= 4") {
  const auto b = make_basis<2>(options("lme"), NodeSet<2>::cartesian(unit_grid<2>(8)));
  const double h = b->nodes().spacing();
  const Vec<2> x(0.43, 0.51), d = Vec<2>(1.0, 0.3).normalized() * 1e-2 * h;
  Vec<2> lambda = Vec<2>::Zero();
  MultiplierSlope<2> slope;
  walk(*b, {Vec<2>(x - d)}, lambda, slope);
  CHECK(slope.e.isZero(0.0)); // one solve: no displacement before it yet
  walk(*b, {x}, lambda, slope);
  REQUIRE(slope.e.isApprox(d, 1e-12));
  REQUIRE((slope.G - slope.G_prev).norm() > 0.0);
  const auto first_order = [&](const Vec<2>& to) { return Vec<2>(lambda + slope.G * (to - x)); };
  const Vec<2> turned = x + Vec<2>(-d[1], d[0]);                    // 90 degrees
  const Vec<2> slightly = x + d + Vec<2>(-d[1], d[0]) * 0.02;        // 0.02 rad
  CHECK(predicted_start(*b, turned, lambda, slope) == first_order(turned));
  CHECK(predicted_start(*b, slightly, lambda, slope) == first_order(slightly));
  CHECK(predicted_start(*b, x + 4.5 * d, lambda, slope) == first_order(x + 4.5 * d));
  CHECK(predicted_start(*b, x + d, lambda, slope) != first_order(x + d));
  CHECK(predicted_start(*b, x - 3.0 * d, lambda, slope) != first_order(x - 3.0 * d)); // back along e
}

TEST_CASE("lme slope: steady motion converges in fewer Newton steps, to the same N") {
  BasisOptions opt = options("lme");
  opt.values["newton_tolerance"] = 1e-12; // the default
  const auto b = make_basis<2>(opt, NodeSet<2>::perturbed(unit_grid<2>(8), 0.3, 31));
  const double h = b->nodes().spacing();
  int with_total = 0, without_total = 0;
  for (const Vec<2>& x0 : interior_points<2>(10, 37)) {
    std::vector<Vec<2>> path;
    const Vec<2> v = Vec<2>(0.6, -0.8) * 2e-3 * h; // constant velocity, slowly accelerating
    for (int n = 0; n < 8; ++n) path.push_back(x0 + v * (n + 0.05 * n * n));
    Vec<2> lambda = Vec<2>::Zero();
    MultiplierSlope<2> slope;
    std::vector<int> with;
    const Stencil<2> warm = walk(*b, path, lambda, slope, &with);
    Vec<2> lambda1 = Vec<2>::Zero();
    MultiplierSlope<2> first;
    std::vector<int> without;
    for (const Vec<2>& x : path) { // e cleared before each solve: the first-order start
      first.e.setZero();
      walk(*b, {x}, lambda1, first, &without);
    }
    for (std::size_t n = 2; n < path.size(); ++n) with_total += with[n], without_total += without[n];
    // the stencil solved from the second-order start against a cold solve
    Stencil<2> cold;
    evaluate_at<2>(*b, path.back(), cold);
    REQUIRE(warm.node == cold.node);
    for (int i = 0; i < cold.size(); ++i) CHECK(std::abs(warm.N[i] - cold.N[i]) <= 1e-11);
  }
  CHECK(with_total < without_total);
}

TEST_CASE("lme slope: the second-order state is saved in checkpoints") {
  const auto b = make_basis<2>(options("lme"), NodeSet<2>::cartesian(unit_grid<2>(8)));
  b->bind_points(2, false);
  AlignedVector<Vec<2>> x{Vec<2>(0.31, 0.42), Vec<2>(0.55, 0.61)};
  BasisTable<2> table;
  b->evaluate_points(x, table);
  for (Vec<2>& p : x) p += Vec<2>(1e-3, -2e-3);
  b->evaluate_points(x, table);
  REQUIRE(b->point_state().slope[1].e.isApprox(Vec<2>(1e-3, -2e-3), 1e-9));
  StateGroup saved;
  b->save_state(saved);
  const auto restored = make_basis<2>(options("lme"), NodeSet<2>::cartesian(unit_grid<2>(8)));
  restored->bind_points(2, false);
  restored->restore_state(saved);
  for (int p = 0; p < 2; ++p) {
    CHECK(restored->point_state().slope[p].e == b->point_state().slope[p].e);
    CHECK(restored->point_state().slope[p].G_prev == b->point_state().slope[p].G_prev);
    CHECK(restored->point_state().slope[p].G == b->point_state().slope[p].G);
  }
  // a checkpoint of an otmpm before the second-order term: the first-order start
  saved.real_arrays.erase("lambda_curvature");
  restored->restore_state(saved);
  CHECK(restored->point_state().slope[1].e.isZero(0.0));
  CHECK(restored->point_state().slope[1].G == b->point_state().slope[1].G);
}
