// Tests of the factorised LME path on an untouched Cartesian lattice
// (lme_lattice.hpp, docs/theory.md sect. 4.7): the same basis as the general
// solver on the same node positions given as a cloud, and the cases that it
// leaves to the general solver.
//
// Tolerances (h = nodal spacing; newton_tolerance 1e-14, so both solves stop
// at |r| <= 1e-14 h):
// * N_I of the two paths agree to 1e-12: the converged multipliers differ
//   by at most ~J^{-1} (r_1 - r_2) ~ 1e-14 / h (J ~ h^2 / gamma), which
//   moves N_I by ~1e-14 h |lambda diff| ~ 1e-14 relative; the weights
//   themselves differ by the rounding of a product of D exponentials
//   against one exponential of a sum and by the lattice spacing standing
//   for the stored coordinates' differences (a few 1e-16 relative, D = 3:
//   up to ~30 roundings of the recurrence, 1e-14).
// * grad N_I agree to 1e-10 / h: grad N_I = -N_I J^{-1} (dx_I - r), J^{-1}
//   ~ gamma / h^2 (larger next to the boundary) amplifies the differences
//   of N_I and r.
// * The multipliers: J (lambda_1 - lambda_2) <= 1e-12 h (both residuals
//   are below 1e-14 h; lambda itself is ill-determined next to the hull's
//   boundary, where J is small along the normal).
// Measured over the points below: N 1.2e-14, h grad N 1.5e-11 (gamma_lme =
// 8, 9e-14 otherwise), J (lambda_1 - lambda_2) 1.1e-14 h.
// * The identities on the lattice path's own stencils: sum N_I = 1 to 1e-13
//   (normalisation), sum N_I x_I = x to 1e-13 h (|r| <= 1e-14 h plus the
//   rounding of the sums), sum grad N_I = 0 to 1e-10 / h and sum x_I (x)
//   grad N_I = I to 1e-10 (the closed form with xbar; round-off of ~15-45
//   terms of size gamma).
#include "otmpm/basis/families.hpp"
#include "otmpm/basis/lme_lattice.hpp"
#include "support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

using namespace otmpm;
using namespace otmpm::maxent;
using namespace otmpm::test;

namespace {

BasisOptions lme_options(double gamma = 3.0) {
  BasisOptions opt;
  opt.kind = "lme";
  opt.values["gamma_lme"] = gamma;
  opt.values["newton_tolerance"] = 1e-14;
  return opt;
}

/// The lattice path's inputs for an lme basis with options `opt` on `nodes`
/// (as make_lme_basis sets them up).
template <int D> struct LatticeSetup {
  LatticeAxes<D> axes;
  GaussianPrior<D> prior;
  NewtonSettings set;
  LatticeSetup(const NodeSet<D>& nodes, const BasisOptions& opt) {
    const double h = nodes.spacing();
    prior.beta = opt.value("gamma_lme") / (h * h);
    prior.max_exponent = -std::log(opt.value("tolerance"));
    set.h = h;
    set.residual_tolerance = opt.value("newton_tolerance") * h;
    set.max_iterations = opt.value("max_newton_iterations");
    set.support_radius = prior.support_radius();
    axes = LatticeAxes<D>::from(nodes, prior.beta);
  }
  bool solve(const Vec<D>& x, const Vec<D>& lambda0, Stencil<D>& out, LatticeSolve<D>& res) const {
    return lattice_solve<D>(axes, prior, set, x, lambda0, out, res);
  }
};

/// The general solver's stencil and multiplier at x (cold start).
template <int D> Vec<D> general_at(const Basis<D>& b, const Vec<D>& x, Stencil<D>& st) {
  Vec<D> lambda = Vec<D>::Zero();
  PointQuery<D> q;
  q.x = x;
  q.lambda = &lambda;
  b.evaluate(q, st);
  return lambda;
}

/// Largest differences of N and h grad N between two stencils with the same
/// nodes (false when the nodes differ).
template <int D> bool compare(const Stencil<D>& a, const Stencil<D>& b, double h, double& dN, double& dG) {
  if (a.node != b.node) return false;
  dN = dG = 0.0;
  for (int i = 0; i < a.size(); ++i) {
    dN = std::max(dN, std::abs(a.N[i] - b.N[i]));
    dG = std::max(dG, (a.dN[i] - b.dN[i]).norm() * h);
  }
  return true;
}

/// The lattice path against the general solver on the same positions as a
/// cloud, at `count` points of the unit box (uniform and next to faces,
/// edges and nodes), warm-started from the general solver's multiplier
/// moved a little (as a step's Taylor start would be). Returns the share of
/// the points that the lattice path took.
template <int D> double agreement(int cells, double gamma, int count, unsigned seed) {
  const NodeSet<D> lattice = NodeSet<D>::cartesian(unit_grid<D>(cells));
  const NodeSet<D> cloud = NodeSet<D>::cloud(lattice.positions(), lattice.spacing());
  const BasisOptions opt = lme_options(gamma);
  const auto general = make_lme_basis<D>(cloud, opt);
  const LatticeSetup<D> fast(lattice, opt);
  const double h = lattice.spacing();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-1e-3, 1e-3);
  int taken = 0;
  const AlignedVector<Vec<D>> points = unit_box_points<D>(lattice, count, seed);
  for (const Vec<D>& x : points) {
    Stencil<D> ref, st;
    const Vec<D> lambda = general_at<D>(*general, x, ref);
    Vec<D> start = lambda;
    for (int k = 0; k < D; ++k) start[k] += jitter(rng) / h;
    LatticeSolve<D> res;
    if (!fast.solve(x, start, st, res)) continue;
    ++taken;
    double dN = 0, dG = 0;
    INFO("x = " << x.transpose() << ", support " << st.size() << " against " << ref.size());
    REQUIRE(compare<D>(st, ref, h, dN, dG));
    CHECK(dN <= 1e-12);
    CHECK(dG <= 1e-10);
    // lambda itself is ill-determined next to the hull's boundary: what
    // the solve fixes is r, and r moves by J (lambda difference)
    CHECK((res.J_inv.inverse() * (res.lambda - lambda)).norm() <= 1e-12 * h);
  }
  return double(taken) / double(points.size());
}

/// The largest |N_I - prod_k N1_{i_k}(x_k)| over `count` random points of
/// the middle of the unit box: the D-dimensional LME of a lattice against
/// the product of the 1D LME of its axes (same gamma_lme and cut-off), a
/// node of either support missing from the other counted with its value.
template <int D> double product_difference(int cells, int count, unsigned seed) {
  const BasisOptions opt = lme_options();
  const auto full = make_lme_basis<D>(NodeSet<D>::cartesian(unit_grid<D>(cells)), opt);
  const auto line = make_lme_basis<1>(NodeSet<1>::cartesian(unit_grid<1>(cells)), opt);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.3, 0.7);
  double worst = 0.0;
  for (int p = 0; p < count; ++p) {
    Vec<D> x;
    for (int k = 0; k < D; ++k) x[k] = u(rng);
    Stencil<D> st;
    general_at<D>(*full, x, st);
    Stencil<1> axis[D];
    for (int k = 0; k < D; ++k) general_at<1>(*line, Vec<1>(x[k]), axis[k]);
    // every node of the product's box: its product weight against the D-dim weight (0 when absent)
    int idx[D] = {};
    for (bool more = true; more;) {
      double product = 1.0;
      int id = 0, stride = 1;
      for (int k = 0; k < D; ++k) {
        product *= axis[k].N[static_cast<std::size_t>(idx[k])];
        id += axis[k].node[static_cast<std::size_t>(idx[k])] * stride;
        stride *= cells + 1;
      }
      const auto it = std::find(st.node.begin(), st.node.end(), id);
      const double N = it == st.node.end() ? 0.0 : st.N[static_cast<std::size_t>(it - st.node.begin())];
      worst = std::max(worst, std::abs(N - product));
      more = false;
      for (int k = 0; k < D && !more; ++k) {
        more = ++idx[k] < axis[k].size();
        if (!more) idx[k] = 0;
      }
    }
  }
  return worst;
}

} // namespace

TEST_CASE("lme lattice path: the general solver's N and grad N on the same positions (1D, 2D, 3D)") {
  // most points are taken (measured: 85% in 1D, 81% in 2D, 69% in 3D);
  // the rest lie within 1e-3 h of a face of the box, where |lambda| R
  // exceeds kLatticeMaxExponent or this start needs the line search (the
  // identities case below asserts that interior points are all taken)
  CHECK(agreement<1>(20, 3.0, 200, 1) >= 0.6);
  CHECK(agreement<2>(12, 3.0, 200, 2) >= 0.6);
  CHECK(agreement<3>(6, 3.0, 120, 3) >= 0.6);
}

TEST_CASE("lme lattice path: other localities (gamma_lme 1.5 and 8) agree as well") {
  CHECK(agreement<2>(12, 1.5, 100, 4) >= 0.6); // measured 67%
  CHECK(agreement<2>(12, 8.0, 100, 5) >= 0.6); // measured 96%
}

TEST_CASE("lme lattice path: the isotropic LME is not the product of 1D LME functions (its support is a ball)") {
  // The weights p_I factorise over the axes, but the support (|x - x_I| <=
  // R) cuts the corners of the box of lines within R, nodes of weight up to
  // tolerance 1e-6: a product of 1D functions, tabulated or not, differs
  // from the basis by far more than the Newton tolerance (newton_tolerance
  // 1e-14 here). Measured: 5.2e-6 (2D), 1.8e-5 (3D).
  const double d2 = product_difference<2>(20, 2000, 5), d3 = product_difference<3>(12, 300, 6);
  MESSAGE("max |N - product of 1D N|: 2D " << d2 << ", 3D " << d3);
  CHECK(d2 > 1e-7);
  CHECK(d3 > 1e-7);
  CHECK(d2 < 1e-4); // of the order of the nodes cut off (weight <= tolerance 1e-6, a few of them)
  CHECK(d3 < 1e-4);
}

TEST_CASE("lme lattice path: an anisotropic lattice (different spacing per axis) agrees") {
  const CartesianGrid<2> g = offset_grid<2>({10, 8, 1}); // h = 0.12 and 0.1
  const NodeSet<2> lattice = NodeSet<2>::cartesian(g);
  const NodeSet<2> cloud = NodeSet<2>::cloud(lattice.positions(), lattice.spacing());
  const BasisOptions opt = lme_options();
  const auto general = make_lme_basis<2>(cloud, opt);
  const LatticeSetup<2> fast(lattice, opt);
  std::mt19937 rng(6);
  int taken = 0;
  for (int i = 0; i < 100; ++i) {
    const Vec<2> x = random_in_box<2>(rng, g.lower + 0.05 * (g.upper - g.lower), g.upper - 0.05 * (g.upper - g.lower));
    Stencil<2> ref, st;
    const Vec<2> lambda = general_at<2>(*general, x, ref);
    LatticeSolve<2> res;
    if (!fast.solve(x, lambda, st, res)) continue;
    ++taken;
    double dN = 0, dG = 0;
    REQUIRE(compare<2>(st, ref, lattice.spacing(), dN, dG));
    CHECK(dN <= 1e-12);
    CHECK(dG <= 1e-10);
  }
  CHECK(taken >= 90);
}

TEST_CASE("lme lattice path: its stencils satisfy the basis identities, node ids ascending") {
  const NodeSet<3> lattice = NodeSet<3>::cartesian(unit_grid<3>(7));
  const LatticeSetup<3> fast(lattice, lme_options());
  // the warm start from the general solver (the same positions as a cloud)
  const auto general = make_lme_basis<3>(NodeSet<3>::cloud(lattice.positions(), lattice.spacing()), lme_options());
  const double h = lattice.spacing();
  std::mt19937 rng(7);
  int taken = 0;
  for (int i = 0; i < 60; ++i) {
    const Vec<3> x = random_in_box<3>(rng, Vec<3>::Constant(0.1), Vec<3>::Constant(0.9));
    Stencil<3> st;
    const Vec<3> lambda = general_at<3>(*general, x, st);
    LatticeSolve<3> res;
    if (!fast.solve(x, lambda, st, res)) continue;
    ++taken;
    double sum = 0;
    Vec<3> xs = Vec<3>::Zero(), gs = Vec<3>::Zero();
    Mat<3> xg = Mat<3>::Zero();
    for (int e = 0; e < st.size(); ++e) {
      if (e > 0) CHECK(st.node[e] > st.node[e - 1]);
      const Vec<3> xI = lattice.position(st.node[e]);
      sum += st.N[e];
      xs += st.N[e] * xI;
      gs += st.dN[e];
      xg += xI * st.dN[e].transpose();
    }
    CHECK(std::abs(sum - 1.0) <= 1e-13);
    CHECK((xs - x).norm() <= 1e-13 * h);
    CHECK(gs.norm() * h <= 1e-10);
    CHECK((xg - Mat<3>::Identity()).norm() <= 1e-10);
  }
  CHECK(taken == 60);
}

TEST_CASE("lme lattice path: left to the general solver") {
  const NodeSet<2> lattice = NodeSet<2>::cartesian(unit_grid<2>(10));
  const LatticeSetup<2> fast(lattice, lme_options());
  const double h = lattice.spacing();
  Stencil<2> st;
  LatticeSolve<2> res;
  SUBCASE("outside the lattice's box, or not finite") {
    CHECK_FALSE(fast.solve(Vec<2>(-1e-9, 0.5), Vec<2>::Zero(), st, res));
    CHECK_FALSE(fast.solve(Vec<2>(0.5, 1.0 + 1e-9), Vec<2>::Zero(), st, res));
    CHECK_FALSE(fast.solve(Vec<2>(std::nan(""), 0.5), Vec<2>::Zero(), st, res));
  }
  SUBCASE("a start far from the solution (a step that needs the line search)") {
    CHECK_FALSE(fast.solve(Vec<2>(0.5, 0.5), Vec<2>(3.0 / h, 0.0), st, res));
  }
  SUBCASE("|lambda| R beyond kLatticeMaxExponent, even at the converged lambda") {
    // next to a face lambda grows without bound; from its own converged
    // value (no Newton step needed) the bound alone refuses the point
    const auto general = make_lme_basis<2>(NodeSet<2>::cloud(lattice.positions(), h), lme_options());
    const Vec<2> x(1e-10 * h, 0.5);
    Stencil<2> ref;
    const Vec<2> lambda = general_at<2>(*general, x, ref);
    REQUIRE(lambda.norm() * fast.set.support_radius > kLatticeMaxExponent);
    CHECK_FALSE(fast.solve(x, lambda, st, res));
  }
  SUBCASE("a support wider than kLatticeMaxSpan lines") {
    const NodeSet<2> fine = NodeSet<2>::cartesian(unit_grid<2>(40));
    const LatticeSetup<2> wide(fine, lme_options(0.2)); // R = h sqrt(13.8 / 0.2) = 8.3 h: 17 lines
    CHECK_FALSE(wide.solve(Vec<2>(0.5, 0.5), Vec<2>::Zero(), st, res));
    const LatticeSetup<2> narrower(fine, lme_options(0.3)); // R = 6.8 h: 13 lines
    CHECK(narrower.solve(Vec<2>(0.5, 0.5), Vec<2>::Zero(), st, res));
  }
  SUBCASE("nodes off their lattice: no axes") {
    NodeSet<2> moved = lattice;
    AlignedVector<Vec<2>> dx(static_cast<std::size_t>(moved.size()), Vec<2>::Zero());
    moved.advect(dx);
    CHECK(LatticeAxes<2>::from(moved, fast.prior.beta).empty());
    CHECK_FALSE(LatticeAxes<2>::from(lattice, fast.prior.beta).empty());
  }
  SUBCASE("the basis evaluates such points through the general solver: the cloud's answer") {
    const auto basis = make_lme_basis<2>(lattice, lme_options());
    const auto general = make_lme_basis<2>(NodeSet<2>::cloud(lattice.positions(), h), lme_options());
    for (const Vec<2>& x : {Vec<2>(0.5, 0.5), Vec<2>(0.37, 0.61), Vec<2>(1e-10 * h, 0.5)}) {
      Vec<2> far(3.0 / h, -2.0 / h), lambda = far; // a start the factorised path refuses
      PointQuery<2> q;
      q.x = x;
      q.lambda = &lambda;
      basis->evaluate(q, st);
      Stencil<2> ref;
      Vec<2> lambda_ref = far;
      q.lambda = &lambda_ref;
      general->evaluate(q, ref);
      double dN = 0, dG = 0;
      REQUIRE(compare<2>(st, ref, h, dN, dG));
      CHECK(dN == 0.0); // the same solver from the same start: the same bits
      CHECK(dG == 0.0);
    }
  }
}

namespace {

/// Three table fills of an lme basis on a lattice over points that move a
/// little between them (a step's pattern: the multipliers and slopes carried
/// from fill to fill), with `threads` threads; the tables and the per-point
/// state after the last fill.
template <int D> struct Fills {
  BasisTable<D> table;
  AlignedVector<Vec<D>> lambda;
  AlignedVector<MultiplierSlope<D>> slope;
};

/// The points' move before each fill: 1e-3 h along a pattern that differs
/// from point to point, kept within the unit box.
template <int D> void move_points(AlignedVector<Vec<D>>& x, double h) {
  for (std::size_t p = 0; p < x.size(); ++p)
    for (int k = 0; k < D; ++k) x[p][k] = std::clamp(x[p][k] + 1e-3 * h * ((p + k) % 3 - 1.0), 0.0, 1.0);
}

template <int D> Fills<D> three_fills(const Basis<D>& basis, AlignedVector<Vec<D>> x, int threads) {
  const ScopedThreads scope(threads);
  Fills<D> f;
  f.lambda.assign(x.size(), Vec<D>::Zero());
  f.slope.assign(x.size(), MultiplierSlope<D>{});
  PointArrays<D> a;
  a.lambda = &f.lambda;
  a.slope = &f.slope;
  const double h = basis.nodes().spacing();
  for (int fill = 0; fill < 3; ++fill) {
    move_points<D>(x, h);
    fill_basis_table<D>(basis, x, a, f.table);
  }
  return f;
}

/// The same three steps point by point through evaluate().
template <int D> Fills<D> three_evaluations(const Basis<D>& basis, AlignedVector<Vec<D>> x) {
  Fills<D> f;
  f.lambda.assign(x.size(), Vec<D>::Zero());
  f.slope.assign(x.size(), MultiplierSlope<D>{});
  const double h = basis.nodes().spacing();
  for (int fill = 0; fill < 3; ++fill) {
    f.table = BasisTable<D>{};
    f.table.offset.assign(1, 0);
    move_points<D>(x, h);
    for (std::size_t p = 0; p < x.size(); ++p) {
      PointQuery<D> q;
      q.x = x[p];
      q.id = static_cast<int>(p);
      q.lambda = &f.lambda[p];
      q.slope = &f.slope[p];
      Stencil<D> st;
      basis.evaluate(q, st);
      f.table.node.insert(f.table.node.end(), st.node.begin(), st.node.end());
      f.table.N.insert(f.table.N.end(), st.N.begin(), st.N.end());
      f.table.dN.insert(f.table.dN.end(), st.dN.begin(), st.dN.end());
      f.table.offset.push_back(static_cast<int>(f.table.node.size()));
    }
  }
  return f;
}

template <int D> bool same_fills(const Fills<D>& a, const Fills<D>& b) {
  bool slopes = a.slope.size() == b.slope.size();
  for (std::size_t p = 0; slopes && p < a.slope.size(); ++p)
    slopes = a.slope[p].x0 == b.slope[p].x0 && a.slope[p].G == b.slope[p].G && a.slope[p].G_prev == b.slope[p].G_prev &&
             a.slope[p].e == b.slope[p].e;
  return a.table.offset == b.table.offset && a.table.node == b.table.node && a.table.N == b.table.N &&
         a.table.dN == b.table.dN && a.lambda == b.lambda && slopes;
}

template <int D> void table_path_agrees(int cells) {
  const auto basis = make_lme_basis<D>(NodeSet<D>::cartesian(unit_grid<D>(cells)), lme_options());
  // points everywhere, the faces and corners included (the general solver
  // takes those next to a face: a table mixes rows of both paths)
  AlignedVector<Vec<D>> x = unit_box_points<D>(basis->nodes(), 1500, 5u);
  const Fills<D> by_point = three_evaluations<D>(*basis, x);
  const Fills<D> one = three_fills<D>(*basis, x, 1), two = three_fills<D>(*basis, x, 2);
  CHECK(same_fills<D>(one, by_point));
  CHECK(same_fills<D>(two, by_point));
}

} // namespace

TEST_CASE("lme lattice path: table rows written in place equal evaluate() bit for bit, also the point state") {
  // fill_basis_table writes the factorised path's rows straight into the
  // table (Basis::evaluate_into) while max_stencil() entries are left, the
  // other rows through evaluate(); 1 and 2 threads, 2D and 3D
  table_path_agrees<2>(12);
  table_path_agrees<3>(6);
}

TEST_CASE("lme lattice path: evaluate_into writes in place only what fits, else into the stencil, with evaluate()'s state") {
  const auto basis = make_lme_basis<2>(NodeSet<2>::cartesian(unit_grid<2>(10)), lme_options());
  const AlignedVector<Vec<2>> pts = unit_box_points<2>(basis->nodes(), 40, 9u);
  int in_place = 0;
  for (const Vec<2>& x : pts) {
    // evaluate() twice from a slope, as a step would: the reference
    Vec<2> lambda_ref = Vec<2>::Zero();
    MultiplierSlope<2> slope_ref;
    int it_ref = -1;
    PointQuery<2> q = stateful_query<2>(x, &lambda_ref, &slope_ref, &it_ref);
    Stencil<2> ref;
    basis->evaluate(q, ref);
    const Vec<2> lambda0 = lambda_ref;
    const MultiplierSlope<2> slope0 = slope_ref;
    q.x = (x + Vec<2>(1e-3, -2e-3) * basis->nodes().spacing()).cwiseMax(0.0).cwiseMin(1.0);
    basis->evaluate(q, ref);
    const int n = ref.size();
    bool placed[3] = {false, false, false};
    for (int r = 0; r < 3; ++r) {
      const int room = n - 1 + (r == 0 ? 0 : r == 1 ? 1 : 4);
      Vec<2> lambda = lambda0;
      MultiplierSlope<2> slope = slope0;
      int it = -1;
      const PointQuery<2> qi = stateful_query<2>(q.x, &lambda, &slope, &it);
      std::vector<int> node(static_cast<std::size_t>(n + 3), -7);
      std::vector<double> N(node.size(), -7.0);
      AlignedVector<Vec<2>> dN(node.size(), Vec<2>::Constant(-7.0));
      Stencil<2> st;
      const int m = basis->evaluate_into(qi, room, node.data(), N.data(), dN.data(), st);
      INFO("x = " << qi.x.transpose() << ", support " << n << ", room " << room);
      // the same per-point state as evaluate() whichever way the row went
      CHECK(lambda == lambda_ref);
      CHECK(slope.x0 == slope_ref.x0);
      CHECK(slope.G == slope_ref.G);
      CHECK(slope.G_prev == slope_ref.G_prev);
      CHECK(slope.e == slope_ref.e);
      CHECK(it == it_ref);
      if (m < 0) { // in the stencil, nothing written to the row
        CHECK(st.node == ref.node);
        CHECK(st.N == ref.N);
        CHECK(st.dN == ref.dN);
        CHECK(std::all_of(node.begin(), node.end(), [](int v) { return v == -7; }));
        CHECK(std::all_of(N.begin(), N.end(), [](double v) { return v == -7.0; }));
        continue;
      }
      placed[r] = true;
      CHECK(room >= n); // a row written in place fits
      REQUIRE(m == n);
      for (int e = 0; e < n; ++e) {
        CHECK(node[static_cast<std::size_t>(e)] == ref.node[static_cast<std::size_t>(e)]);
        CHECK(N[static_cast<std::size_t>(e)] == ref.N[static_cast<std::size_t>(e)]);
        CHECK(dN[static_cast<std::size_t>(e)] == ref.dN[static_cast<std::size_t>(e)]);
      }
      for (std::size_t e = static_cast<std::size_t>(n); e < node.size(); ++e) CHECK(node[e] == -7); // nothing beyond
    }
    // a point the factorised path takes goes in place whenever its row fits
    CHECK_FALSE(placed[0]);
    CHECK(placed[1] == placed[2]);
    in_place += placed[2] ? 1 : 0;
  }
  // the others (next to a face) go through the general solver, into the stencil
  MESSAGE(in_place << " of " << pts.size() << " points written in place");
  CHECK(3 * in_place >= static_cast<int>(pts.size()));
}

TEST_CASE("lme lattice path: rows are written in place only while the nodes are on their lattice") {
  // Basis::writes_in_place, asked once per table fill: the Gaussian prior on
  // an untouched lattice; false once the nodes moved, for the cubic-spline
  // prior and for a cloud
  const NodeSet<2> lattice = NodeSet<2>::cartesian(unit_grid<2>(10));
  const auto basis = make_lme_basis<2>(lattice, lme_options());
  CHECK(basis->writes_in_place());
  AlignedVector<Vec<2>> dx(static_cast<std::size_t>(lattice.size()), Vec<2>(1e-3, 0.0));
  basis->nodes().advect(dx);
  basis->nodes_moved(dx);
  CHECK_FALSE(basis->writes_in_place());
  BasisOptions spline;
  spline.kind = "maxent";
  CHECK_FALSE(make_basis<2>(spline, lattice)->writes_in_place());
  CHECK_FALSE(make_lme_basis<2>(NodeSet<2>::cloud(lattice.positions(), lattice.spacing()), lme_options())->writes_in_place());
}
