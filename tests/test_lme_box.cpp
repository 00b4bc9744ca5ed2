// Tests of LME with the box support (lme_box.hpp, docs/theory.md sect. 4.9):
// the table of the 1D functions against the Newton solve, and the basis on
// a lattice (the table) against the general solver with the same box
// cut-off on the same positions given as a cloud.
//
// Tolerances (h = nodal spacing):
// * The table against the 1D Newton solve (solved to round-off): |N| within
//   kBoxTableError = 1e-12 and |dN/du| within kBoxTableGradientError =
//   1e-11 at 10^6 random positions for the benchmark's and the default
//   gamma_lme (3 and 4), 2e5 for the others, every interval of the cell;
//   the same for every configuration of the cells near the lattice's end
//   (10^6 each at gamma_lme 3). The table's spacing is refined until its quarter points agree to 1e-13
//   (N) and 1e-12 (dN/du); measured (MESSAGE): N 1.1e-15 - 6.3e-14, dN/du
//   5.4e-14 - 8.1e-13, lambda h (relative) up to 5.3e-13.
// * The basis against the general solver (newton_tolerance 1e-14): N within
//   1e-11 (the table's error per axis, D factors, plus the solver's), h
//   grad N within 1e-9 (J^{-1} ~ gamma / h^2 amplifies the general solver's
//   residual).
// * The identities on the table's stencils: sum N_I = 1, sum N_I x_I = x,
//   sum grad N_I = 0 and sum x_I (x) grad N_I = I to 1e-13 (h): the
//   interpolant of a partition of unity (zero derivatives) is 1 and that of
//   the coordinates is u, in N and in dN/du alike, up to the rounding of
//   sums of ~20 - 80 terms (measured 4e-16 - 2.5e-14, the latter next to
//   the hull's boundary).
#include "otmpm/basis/families.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/basis/lme_box.hpp"
#include "support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

using namespace otmpm;
using namespace otmpm::maxent;
using namespace otmpm::test;

namespace {

BasisOptions box_options(double gamma = 3.0) {
  BasisOptions opt;
  opt.kind = "lme_box";
  opt.values["gamma_lme"] = gamma;
  opt.values["newton_tolerance"] = 1e-14;
  return opt;
}

/// The largest errors of the table of (gamma, tol) against the 1D solve at
/// `count` random positions of a cell.
struct TableError {
  double N = 0.0, dN = 0.0, L = 0.0;
};

TableError table_error(double gamma, double tol, int count, unsigned seed,
                       BoxEnds ends = BoxAxisTable::interior_ends) {
  const double cut = -std::log(tol), r = std::sqrt(cut / gamma);
  const BoxAxisTable table(gamma, cut, ends);
  REQUIRE_FALSE(table.empty());
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pick(0.0, 1.0);
  TableError e;
  double Nt[kBoxLanes], dNt[kBoxLanes], dx[kBoxMaxLines];
  for (int p = 0; p < count; ++p) {
    const double u = pick(rng);
    int first;
    double Lt;
    const int m = table.evaluate(u, first, Nt, dNt, Lt);
    if (m == 0) { // declined: only within kBoxHullGap of a side that is the hull's boundary
      REQUIRE(((ends.below == 0 && u < kBoxHullGap) || (ends.above == 0 && u > 1.0 - kBoxHullGap)));
      continue;
    }
    // the lines within r of u, as the cut-off beta dx^2 <= -ln(tol) keeps
    // them, that exist beyond the cell
    const int lo = std::max(static_cast<int>(std::ceil(u - r)), -ends.below);
    const int hi = std::min(static_cast<int>(std::floor(u + r)), 1 + ends.above);
    REQUIRE(first == lo);
    REQUIRE(m == hi - lo + 1);
    for (int i = 0; i < m; ++i) dx[i] = u - (first + i);
    Lme1d f;
    REQUIRE(solve_lme_1d(gamma, dx, m, f));
    for (int i = 0; i < m; ++i) {
      e.N = std::max(e.N, std::abs(Nt[i] - f.f[i][0]));
      e.dN = std::max(e.dN, std::abs(dNt[i] - f.f[i][1]));
    }
    e.L = std::max(e.L, std::abs(Lt - f.L[0]) / (1.0 + std::abs(f.L[0])));
  }
  return e;
}

/// The general solver's stencil at x (cold start), or the table's.
template <int D> int stencil_at(const Basis<D>& b, const Vec<D>& x, Stencil<D>& st) {
  Vec<D> lambda = Vec<D>::Zero();
  int iterations = -1;
  PointQuery<D> q;
  q.x = x;
  q.lambda = &lambda;
  q.iterations = &iterations;
  b.evaluate(q, st);
  return iterations;
}

/// The table path against the general solver on the same positions as a
/// cloud at `count` points of the unit box; returns the share of the
/// points the tables cover (all but those within kBoxHullGap h of the
/// lattice's ends) that the table took (no Newton step).
template <int D> double agreement(int cells, double gamma, int count, unsigned seed) {
  const NodeSet<D> lattice = NodeSet<D>::cartesian(unit_grid<D>(cells));
  const NodeSet<D> cloud = NodeSet<D>::cloud(lattice.positions(), lattice.spacing());
  const auto fast = make_lme_box_basis<D>(lattice, box_options(gamma));
  const auto general = make_lme_box_basis<D>(cloud, box_options(gamma));
  const double h = lattice.spacing();
  int taken = 0, covered = 0;
  for (const Vec<D>& x : unit_box_points<D>(lattice, count, seed)) {
    Stencil<D> a, b;
    bool inner = true; // off the hull's boundary by kBoxHullGap h on every axis
    for (int k = 0; k < D; ++k) {
      const double u = x[k] / h; // the lattice starts at 0
      inner = inner && u >= kBoxHullGap && u <= cells - kBoxHullGap;
    }
    const bool table = stencil_at<D>(*fast, x, a) == 0;
    covered += inner;
    taken += inner && table;
    CHECK((table <= inner)); // next to the hull's boundary the general solver
    stencil_at<D>(*general, x, b);
    INFO("x = " << x.transpose());
    REQUIRE(a.node == b.node);
    double dN = 0.0, dG = 0.0;
    for (int i = 0; i < a.size(); ++i) {
      dN = std::max(dN, std::abs(a.N[i] - b.N[i]));
      dG = std::max(dG, (a.dN[i] - b.dN[i]).norm() * h);
    }
    CHECK(dN <= 1e-11);
    CHECK(dG <= 1e-9);
  }
  REQUIRE(covered > 0);
  return double(taken) / covered;
}

/// The largest departures from the reproducing identities over the table's
/// stencils at `count` points of [lo, 1 - lo]^D (lo = 0.35: interior cells;
/// kBoxHullGap h: every cell, those within R of the ends among them).
template <int D> void check_identities(int cells, double gamma, int count, unsigned seed, double lo = 0.35) {
  const NodeSet<D> nodes = NodeSet<D>::cartesian(unit_grid<D>(cells));
  const auto basis = make_lme_box_basis<D>(nodes, box_options(gamma));
  const double h = nodes.spacing();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(lo, 1.0 - lo);
  double pu = 0, lin = 0, grad = 0, dlin = 0;
  for (int p = 0; p < count; ++p) {
    Vec<D> x;
    for (int k = 0; k < D; ++k) x[k] = u(rng);
    Stencil<D> st;
    REQUIRE(stencil_at<D>(*basis, x, st) == 0); // the table took it
    double sum = 0.0;
    Vec<D> first = Vec<D>::Zero(), g = Vec<D>::Zero();
    Mat<D> second = Mat<D>::Zero();
    for (int i = 0; i < st.size(); ++i) {
      const Vec<D> xi = nodes.position(st.node[static_cast<std::size_t>(i)]);
      sum += st.N[i];
      first += st.N[i] * xi;
      g += st.dN[i];
      second += xi * st.dN[i].transpose();
      CHECK(st.N[i] > 0.0);
    }
    pu = std::max(pu, std::abs(sum - 1.0));
    lin = std::max(lin, (first - x).norm() / h);
    grad = std::max(grad, g.norm() * h);
    dlin = std::max(dlin, (second - Mat<D>::Identity()).norm());
  }
  MESSAGE(D << "D gamma_lme " << gamma << " on [" << lo << ", " << 1.0 - lo << "]: |sum N - 1| " << pu
            << ", |sum N x - x| / h " << lin << ", h |sum grad N| " << grad << ", |sum x grad N - I| "
            << dlin);
  CHECK(pu <= 1e-13);
  CHECK(lin <= 1e-13);
  CHECK(grad <= 1e-13);
  CHECK(dlin <= 1e-13);
}

} // namespace

TEST_CASE("lme_box table: the 1D functions within kBoxTableError of the Newton solve at 10^6 random points") {
  struct Case {
    double gamma, tol;
    int count;
  };
  const Case cases[] = {{3.0, 1e-6, 1000000}, {4.0, 1e-6, 1000000}, {0.8, 1e-6, 200000},
                        {1.5, 1e-6, 200000},  {6.0, 1e-6, 200000},  {4.0, 1e-10, 200000}};
  unsigned seed = 1;
  for (const Case& c : cases) {
    const TableError e = table_error(c.gamma, c.tol, c.count, seed++);
    MESSAGE("gamma_lme " << c.gamma << ", tolerance " << c.tol << ": |N| " << e.N << ", |dN/du| " << e.dN
                         << ", lambda h (relative) " << e.L);
    CHECK(e.N <= kBoxTableError);
    CHECK(e.dN <= kBoxTableGradientError);
    CHECK(e.L <= kBoxTableGradientError);
  }
}

TEST_CASE(
    "lme_box table: the cells near the lattice's end within kBoxTableError, 10^6 points per configuration") {
  // every configuration of lines beyond the cell (BoxEnds) that an axis has
  // - at gamma_lme 3 (r = 2.15) none, one or two lines below and above (none:
  // the outermost cell, the hull's boundary at u = 0 or 1) - and the
  // interior; 10^6 points each for the benchmark's gamma_lme, 10^5 for the
  // wider supports
  struct Case {
    double gamma;
    int count;
  };
  const double tol = 1e-6, cut = -std::log(tol);
  unsigned seed = 20;
  for (const Case c : {Case{3.0, 1000000}, Case{1.5, 100000}, Case{0.8, 50000}}) {
    const BoxAxisTables axis(c.gamma, cut, 40);
    const int reach = BoxAxisTable(c.gamma, cut).reach();
    const std::vector<const BoxAxisTable*> tables = axis.tables();
    // the interior and the (below, reach), (reach, above), below, above < reach, of an axis of 40 cells
    CHECK(tables.size() == static_cast<std::size_t>(2 * reach + 1));
    for (const BoxAxisTable* t : tables) {
      if (t->ends() == BoxEnds{reach, reach}) continue; // the interior: the case above
      const TableError e = table_error(c.gamma, tol, c.count, seed++, t->ends());
      MESSAGE("gamma_lme " << c.gamma << ", lines beyond the cell " << t->ends().below << " below, "
                           << t->ends().above << " above: |N| " << e.N << ", |dN/du| " << e.dN
                           << ", lambda h (relative) " << e.L);
      CHECK(e.N <= kBoxTableError);
      CHECK(e.dN <= kBoxTableGradientError);
      CHECK(e.L <= kBoxTableGradientError);
    }
  }
  // a short axis (3 cells at reach 2): its middle cell has one line on each
  // side; a single cell none on either (two lines: N = 1 - u, u)
  const BoxAxisTables short_axis(3.0, cut, 3);
  REQUIRE(short_axis.at(1));
  CHECK(short_axis.at(1)->ends() == BoxEnds{1, 1});
  for (const BoxEnds e : {BoxEnds{1, 1}, BoxEnds{0, 1}, BoxEnds{0, 0}}) {
    const TableError err = table_error(3.0, tol, 100000, seed++, e);
    CHECK(err.N <= kBoxTableError);
    CHECK(err.dN <= kBoxTableGradientError);
    CHECK(err.L <= kBoxTableGradientError);
  }
}

TEST_CASE("lme_box table: which cells of an axis have a table") {
  const double cut = -std::log(1e-6);
  const BoxAxisTables axis(3.0, cut, 10); // reach 2
  REQUIRE(axis.at(0));                    // the outermost cells: the hull's boundary on one side
  CHECK(axis.at(0)->ends() == BoxEnds{0, 2});
  REQUIRE(axis.at(9));
  CHECK(axis.at(9)->ends() == BoxEnds{2, 0});
  REQUIRE(axis.at(1));
  CHECK(axis.at(1)->ends() == BoxEnds{1, 2});
  REQUIRE(axis.at(8));
  CHECK(axis.at(8)->ends() == BoxEnds{2, 1});
  for (int c = 2; c <= 7; ++c) CHECK(axis.at(c)->ends() == BoxEnds{2, 2});
  // gamma_lme 4 and 6 (reach 1): one line beyond is the interior; the outermost cells
  CHECK(BoxAxisTables(4.0, cut, 10).tables().size() == 3);
  CHECK(BoxAxisTables(6.0, cut, 10).tables().size() == 3);
  // the lines of the cell next to the lower end at u = 0.1: -1 .. 2 (line -2 is missing)
  double N[kBoxLanes], dN[kBoxLanes], L;
  int first;
  CHECK(axis.at(1)->evaluate(0.1, first, N, dN, L) == 4);
  CHECK(first == -1);
  // the outermost cell: lines 0 .. 2; nearer the hull's boundary than
  // kBoxHullGap the table declines (the general solver takes the point)
  CHECK(axis.at(0)->evaluate(0.1, first, N, dN, L) == 3);
  CHECK(first == 0);
  CHECK(axis.at(0)->evaluate(0.5 * kBoxHullGap, first, N, dN, L) == 0);
  CHECK(axis.at(0)->evaluate(2.0 * kBoxHullGap, first, N, dN, L) == 3);
  CHECK(N[0] > 0.99);
  CHECK(axis.at(9)->evaluate(1.0 - 0.5 * kBoxHullGap, first, N, dN, L) == 0);
  // an axis of the same spacing and another cell count takes the tables it
  // shares with the first instead of building them; a configuration the
  // first lacks ({1, 1} of a 3-cell axis) it builds
  const BoxAxisTables longer(3.0, cut, 20, &axis), short_axis(3.0, cut, 3, &axis);
  CHECK(longer.at(10) == axis.at(5));
  CHECK(longer.at(0) == axis.at(0));
  CHECK(longer.at(19) == axis.at(9));
  REQUIRE(short_axis.at(1));
  CHECK(short_axis.at(1)->ends() == BoxEnds{1, 1});
  CHECK(short_axis.at(0) == axis.at(0));
}

TEST_CASE("lme_box table: refuses a support wider than it holds, and the intervals follow the cut-off") {
  // r = sqrt(-ln tol / gamma) > 7.5: more than kBoxMaxLines lines
  CHECK(BoxAxisTable(0.2, -std::log(1e-6)).empty());
  // gamma_lme 8: the functions turn within ~2 exp(-8) of a node, more
  // samples than kBoxMaxSamples; 6 is the largest integer that is built
  CHECK(BoxAxisTable(8.0, -std::log(1e-6)).empty());
  CHECK_FALSE(BoxAxisTable(6.0, -std::log(1e-6)).empty());
  // gamma 3, tol 1e-6: r = 2.145, 5 lines for u < 0.145 or u > 0.855, else 4
  const BoxAxisTable t(3.0, -std::log(1e-6));
  // small enough to stay in a core's L2 cache (docs/theory.md sect. 4.9
  // quotes these figures)
  MESSAGE("gamma_lme 3, tolerance 1e-6: " << t.samples() << " samples, " << t.bytes() << " bytes");
  CHECK(t.bytes() <= 65536);
  double N[kBoxLanes], dN[kBoxLanes], L;
  int first;
  CHECK(t.evaluate(0.1, first, N, dN, L) == 5);
  CHECK(first == -2);
  CHECK(t.evaluate(0.5, first, N, dN, L) == 4);
  CHECK(first == -1);
  CHECK(t.evaluate(0.9, first, N, dN, L) == 5);
  CHECK(first == -1);
  // symmetry of the interior: N_o(u) = N_{1-o}(1 - u)
  double M[kBoxLanes], dM[kBoxLanes];
  int first2;
  t.evaluate(0.3, first, N, dN, L);
  const int m = t.evaluate(0.7, first2, M, dM, L);
  for (int i = 0; i < m; ++i) CHECK(N[i] == doctest::Approx(M[m - 1 - i]).epsilon(1e-13));
  // dN_scale multiplies the interpolated derivative (per unit length: 1 / h)
  const double inv_h = 1.0 / 0.37;
  double L1, L2;
  const int m1 = t.evaluate(0.3, first, N, dN, L1);
  CHECK(t.evaluate(0.3, first2, M, dM, L2, inv_h) == m1);
  CHECK(L2 == L1);
  for (int i = 0; i < m1; ++i) {
    CHECK(M[i] == N[i]);
    CHECK(dM[i] == dN[i] * inv_h);
  }
}

TEST_CASE("lme_box: the table's stencil is the general solver's on the same positions (1D, 2D, 3D)") {
  // every point takes a table (interior cells and those within R of the
  // ends) but those within kBoxHullGap h of the lattice's end, which take
  // the general solver, with the box cut-off as on the cloud (the points of
  // unit_box_points at 1e-3 h from a face take the table, those at 1e-6 h
  // and 1e-10 h the solver)
  CHECK(agreement<1>(20, 3.0, 300, 1) == 1.0);
  CHECK(agreement<2>(12, 3.0, 200, 2) == 1.0);
  CHECK(agreement<3>(8, 3.0, 60, 3) == 1.0);
  CHECK(agreement<2>(12, 1.5, 100, 4) == 1.0);
  CHECK(agreement<2>(12, 6.0, 100, 5) == 1.0);
  CHECK(agreement<2>(5, 3.0, 100, 7) == 1.0); // a short lattice: cells with one line beyond on both sides
  // no table at gamma_lme 8: every point is the general solver's
  CHECK(agreement<2>(12, 8.0, 50, 6) == 0.0);
}

TEST_CASE("lme_box: partition of unity and linear completeness of the table's stencils") {
  check_identities<1>(20, 3.0, 2000, 6);
  check_identities<2>(16, 3.0, 1000, 7);
  check_identities<3>(12, 3.0, 200, 8);
  check_identities<2>(16, 6.0, 500, 9);
  // over every cell, those within R of the ends included, up to kBoxHullGap h of the ends
  check_identities<1>(20, 3.0, 2000, 11, kBoxHullGap / 20);
  check_identities<2>(16, 3.0, 1000, 12, kBoxHullGap / 16);
  check_identities<2>(16, 1.5, 500, 13, kBoxHullGap / 16);
  check_identities<3>(8, 3.0, 200, 14, kBoxHullGap / 8);
}

TEST_CASE("lme_box: N_I is the product of the 1D functions, and the box holds the ball of lme") {
  const int cells = 16;
  const auto box2 = make_lme_box_basis<2>(NodeSet<2>::cartesian(unit_grid<2>(cells)), box_options());
  const auto box1 = make_lme_box_basis<1>(NodeSet<1>::cartesian(unit_grid<1>(cells)), box_options());
  BasisOptions lme = box_options();
  lme.kind = "lme";
  const auto ball = make_lme_basis<2>(NodeSet<2>::cartesian(unit_grid<2>(cells)), lme);
  std::mt19937 rng(10);
  std::uniform_real_distribution<double> u(0.35, 0.65);
  for (int p = 0; p < 200; ++p) {
    const Vec<2> x(u(rng), u(rng));
    Stencil<2> st, b;
    Stencil<1> ax[2];
    stencil_at<2>(*box2, x, st);
    for (int k = 0; k < 2; ++k) stencil_at<1>(*box1, Vec<1>(x[k]), ax[k]);
    REQUIRE(st.size() == ax[0].size() * ax[1].size());
    int q = 0;
    for (int j = 0; j < ax[1].size(); ++j)
      for (int i = 0; i < ax[0].size(); ++i, ++q) {
        CHECK(st.node[q] == ax[0].node[i] + ax[1].node[j] * (cells + 1));
        CHECK(st.N[q] == ax[0].N[i] * ax[1].N[j]);
        CHECK(st.dN[q][0] == ax[0].dN[i][0] * ax[1].N[j]);
        CHECK(st.dN[q][1] == ax[0].N[i] * ax[1].dN[j][0]);
      }
    stencil_at<2>(*ball, x, b);
    for (const int I : b.node) CHECK(std::find(st.node.begin(), st.node.end(), I) != st.node.end());
    CHECK(st.size() >= b.size());
  }
}

namespace {
/// `count` random points of [lo, 1 - lo]^D (fixed seed).
template <int D> AlignedVector<Vec<D>> random_points(int count, double lo, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(lo, 1.0 - lo);
  AlignedVector<Vec<D>> x(static_cast<std::size_t>(count));
  for (Vec<D>& p : x)
    for (int k = 0; k < D; ++k) p[k] = u(rng);
  return x;
}

/// The product rows of lme_box at points over every cell of an n^D lattice
/// (those within R of its ends among them) against the table the same
/// family fills at the same points: the same entries, bits and multipliers.
template <int D> void check_product_rows(int cells, double gamma, unsigned seed) {
  const NodeSet<D> nodes = NodeSet<D>::cartesian(unit_grid<D>(cells));
  const auto by_table = make_lme_box_basis<D>(nodes, box_options(gamma));
  const auto by_rows = make_lme_box_basis<D>(nodes, box_options(gamma));
  // off the hull's boundary by more than kBoxHullGap h on every axis
  const AlignedVector<Vec<D>> x = random_points<D>(400, 2.0 * kBoxHullGap / cells, seed);
  const int n = static_cast<int>(x.size());
  by_table->bind_points(n, false);
  by_rows->bind_points(n, false);
  BasisTable<D> table, expanded;
  by_table->evaluate_points(x, table);
  ProductRows<D> rows;
  REQUIRE(by_rows->evaluate_product_rows(x, rows));
  expand_product_rows(rows, expanded);
  CHECK(expanded.offset == table.offset);
  CHECK(expanded.node == table.node);
  CHECK(expanded.N == table.N);
  CHECK(expanded.dN == table.dN);
  CHECK(by_rows->point_state().lambda == by_table->point_state().lambda);
  // what the memory estimate counts per row (lme_box_row_bytes): the rows'
  // arrays and the multiplier, exact or at most one pair of lanes per axis over
  const double held = static_cast<double>(rows.f.size() * sizeof(double)) / n +
                      static_cast<double>((D + 2) * sizeof(int) + D * sizeof(double));
  CHECK(held <= lme_box_row_bytes(box_options(gamma), D));
  CHECK(held >= lme_box_row_bytes(box_options(gamma), D) - 32.0 * D);
  bool same = true; // entry by entry (the column gather's access), and each row's node range
  for (int p = 0; p < n; ++p) {
    const auto [lo, hi] =
        std::minmax_element(table.node.begin() + table.begin(p), table.node.begin() + table.end(p));
    same = same && rows.lowest(p) == *lo && rows.highest(p) == *hi;
    for (int e = table.begin(p); e < table.end(p); ++e) {
      int I;
      double N;
      Vec<D> dN;
      rows.entry(p, e, I, N, dN);
      same = same && I == table.node[e] && N == table.N[e] && dN == table.dN[e];
    }
    int e = table.begin(p); // the node ids alone, in the table's order
    rows.visit_nodes(p, [&](int I) { same = same && e < table.end(p) && I == table.node[e++]; });
    same = same && e == table.end(p);
  }
  CHECK(same);
}
} // namespace

TEST_CASE(
    "lme_box: the product rows hold the table's entries bit for bit, and its multipliers (1D, 2D, 3D)") {
  for (const double gamma : {1.5, 3.0, 6.0}) {
    INFO("gamma_lme " << gamma);
    check_product_rows<1>(9, gamma, 3);
    check_product_rows<2>(9, gamma, 4);
    check_product_rows<3>(7, gamma, 5);
  }
}

TEST_CASE("lme_box: no product rows where a point's table does not reach, nor for another family") {
  const NodeSet<2> nodes = NodeSet<2>::cartesian(unit_grid<2>(8));
  const auto basis = make_lme_box_basis<2>(nodes, box_options());
  AlignedVector<Vec<2>> x = random_points<2>(50, 0.01, 6);
  basis->bind_points(static_cast<int>(x.size()), false);
  ProductRows<2> rows;
  REQUIRE(basis->evaluate_product_rows(x, rows));
  const double h = 1.0 / 8;
  for (const Vec<2>& off : {Vec<2>(0.5 * kBoxHullGap * h, 0.5), Vec<2>(0.5, 1.0 - 0.5 * kBoxHullGap * h),
                            Vec<2>(-0.1, 0.5), Vec<2>(0.5, std::nan("")), Vec<2>(INFINITY, 0.5)}) {
    AlignedVector<Vec<2>> y = x;
    y[25] = off; // next to the hull's boundary (the Newton solve's), outside, not finite
    INFO("x = " << off.transpose());
    CHECK_FALSE(basis->evaluate_product_rows(y, rows));
  }
  BasisOptions lme = box_options();
  lme.kind = "lme"; // the ball support is no product
  const auto ball = make_basis<2>(lme, nodes);
  ball->bind_points(static_cast<int>(x.size()), false);
  CHECK_FALSE(ball->evaluate_product_rows(x, rows));
  // the points of a run whose nodes move keep more state than the multiplier
  const auto moving = make_lme_box_basis<2>(nodes, box_options());
  moving->bind_points(static_cast<int>(x.size()), true);
  CHECK_FALSE(moving->evaluate_product_rows(x, rows));
}

TEST_CASE("lme_box: a distributed run's window holds the lines within R per axis, not sqrt(D) R") {
  // The window's reach (BasisKind::reach, from the search radius sqrt(D) R
  // of the ball around the box) is lme's at R: R / h rounded up below and
  // one more above, at least the lines a cell's stencil takes beyond it
  // (floor(R / h) below, BoxAxisTable::reach; that the stencils hold no
  // more: test_contracts' basis_reach), where the ball around the box would
  // add about (sqrt(D) - 1) R / h lines on each side
  const BasisKind* kind = find_basis_kind("lme_box");
  REQUIRE(kind);
  const double cut = -std::log(1e-6);
  for (const double gamma : {0.8, 1.5, 3.0, 6.0})
    for (const int D : {2, 3}) {
      CAPTURE(gamma);
      CAPTURE(D);
      const double R = std::sqrt(cut / gamma); // in units of h
      const LatticeReach r = kind->reach(std::sqrt(static_cast<double>(D)) * R, 1.0, D);
      const int lines = BoxAxisTable(gamma, cut).reach();
      const LatticeReach ball = find_basis_kind("lme")->reach(R, 1.0, D);
      CHECK(r.below == ball.below);
      CHECK(r.above == ball.above);
      CHECK(r.below == lines + 1); // R / h is no integer at these gamma_lme
      CHECK(r.above == r.below + 1);
    }
  // gamma_lme 3 in 3D: R = 2.15 h, 3 lines below and 4 above; the ball
  // around the box, radius 3.72 h, would take 4 and 5
  const double R3 = std::sqrt(cut / 3.0);
  CHECK(kind->reach(std::sqrt(3.0) * R3, 1.0, 3).below == 3);
  CHECK(find_basis_kind("lme")->reach(std::sqrt(3.0) * R3, 1.0, 3).below == 4);
  // an integer R / h that sqrt(D) R / sqrt(D) may leave an ulp short still reaches its R / h lines
  for (const int D : {2, 3})
    for (const double R : {1.0, 2.0, 3.0, 5.0})
      CHECK(kind->reach(std::sqrt(double(D)) * R, 1.0, D).below >= int(R));
}
