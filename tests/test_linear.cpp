// The `linear` family: tensor-product hats on a Cartesian lattice and
// isoparametric multilinear elements on perturbed / moved lattices.
#include "otmpm/basis/families.hpp"

#include "support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cmath>
#include <cstring>
#include <map>
#include <random>
#include <type_traits>

using namespace otmpm;
using namespace otmpm::test;

namespace {

using Dims = std::tuple<std::integral_constant<int, 1>, std::integral_constant<int, 2>, std::integral_constant<int, 3>>;

// Round-off tolerance for the identities below. A sum of n terms a_I has a
// floating error of about n * eps * sum |a_I| (eps = 2.2e-16, n <= 8), so
// 1e-12 * sum |a_I| is ~500 times that bound and still far below any error a
// wrong basis would make.
constexpr double kRelTol = 1e-12;

template <int D> CartesianGrid<D> test_grid() { return offset_grid<D>({6, 4, 3}); }

/// Random points of the box plus the awkward ones: nodes, points one ulp
/// inside the boundary or next to a node, face and edge midpoints, corners.
template <int D> AlignedVector<Vec<D>> sample_points(const CartesianGrid<D>& g, unsigned seed) {
  std::mt19937 rng(seed);
  AlignedVector<Vec<D>> pts;
  for (int n = 0; n < 150; ++n) pts.push_back(random_in_box<D>(rng, g.lower, g.upper));
  const Vec<D> h = g.h();
  for (int id = 0; id < g.num_nodes(); id += 3) {
    const Vec<D> xn = g.node_position(g.node_index(id));
    pts.push_back(xn);
    Vec<D> near = xn;
    for (int k = 0; k < D; ++k)
      near[k] = std::nextafter(xn[k], xn[k] < 0.5 * (g.lower[k] + g.upper[k]) ? g.upper[k] : g.lower[k]);
    pts.push_back(near);
    Vec<D> mid = xn;
    mid[0] = std::min(g.upper[0], xn[0] + 0.5 * h[0]);
    pts.push_back(mid);
  }
  for (int n = 0; n < 40; ++n) {
    Vec<D> x = random_in_box<D>(rng, g.lower, g.upper);
    const int k = n % D;
    x[k] = (n / D) % 2 ? g.upper[k] : std::nextafter(g.lower[k], g.upper[k]);
    pts.push_back(x);
  }
  pts.push_back(g.lower);
  pts.push_back(g.upper);
  return pts;
}

/// Partition of unity, sum grad N = 0, linear completeness (sum N_I x_I = x,
/// sum x_I (x) grad N_I = I), non-negativity, at one point.
template <int D> void check_identities(const Basis<D>& b, const Vec<D>& x) {
  Stencil<D> st;
  evaluate_at(b, x, st);
  REQUIRE(st.size() > 0);
  CHECK(st.size() <= b.max_stencil());
  for (int a = 0; a < st.size(); ++a) CHECK(st.N[a] >= 0.0);
  const StencilSums<D> s = stencil_sums(b, st);
  INFO("point ", format_point<D>(x));
  CHECK(std::abs(s.sumN - 1.0) <= kRelTol * s.absN);
  for (int k = 0; k < D; ++k) CHECK(std::abs(s.sumG[k]) <= kRelTol * s.absG[k]);
  check_linear_completeness(s, x, kRelTol);
}

/// grad N against central differences with step delta = 1e-6 h. Points are
/// images of natural coordinates in [-0.9, 0.9]^D of random elements, so
/// x +- delta stays inside one element where N is smooth (multilinear in xi).
/// Error: O(delta^2 |N'''|) ~ 1e-12 / h truncation plus eps / delta ~ 1e-10 / h
/// cancellation; the tolerance 1e-7 / h leaves a wide margin.
template <int D> void check_fd_gradient(const Basis<D>& b, const CartesianGrid<D>& g, unsigned seed) {
  std::mt19937 rng(seed);
  const double h = g.h().minCoeff();
  const double delta = 1e-6 * h;
  const double tol = 1e-7 / h;
  for (int n = 0; n < 40; ++n) {
    Index<D> c;
    for (int k = 0; k < D; ++k) c[k] = static_cast<int>(rng() % static_cast<unsigned>(g.cells[k]));
    const Vec<D> xi = random_in_box<D>(rng, Vec<D>::Constant(-0.9), Vec<D>::Constant(0.9));
    Vec<D> x = Vec<D>::Zero();
    for (int a = 0; a < (1 << D); ++a) {
      Index<D> ijk = c;
      double w = 1;
      for (int k = 0; k < D; ++k) {
        const int bit = (a >> k) & 1;
        ijk[k] += bit;
        w *= 0.5 * (1 + (bit ? xi[k] : -xi[k]));
      }
      x += w * b.nodes().position(g.node_id(ijk));
    }
    Stencil<D> st;
    PointQuery<D> q;
    q.x = x;
    b.evaluate(q, st);
    for (int k = 0; k < D; ++k) {
      Vec<D> e = Vec<D>::Zero();
      e[k] = delta;
      const auto plus = values_at(b, Vec<D>(x + e));
      const auto minus = values_at(b, Vec<D>(x - e));
      for (int a = 0; a < st.size(); ++a) {
        const int I = st.node[a];
        const double fd = (plus.at(I) - minus.at(I)) / (2 * delta);
        INFO("point ", format_point<D>(x), " node ", I, " axis ", k);
        CHECK(std::abs(fd - st.dN[a][k]) <= tol);
      }
    }
  }
}

template <int D> void check_outside_names_point(const Basis<D>& b, const Vec<D>& x) {
  Stencil<D> st;
  PointQuery<D> q;
  q.x = x;
  try {
    b.evaluate(q, st);
    FAIL("no BasisError for ", format_point<D>(x));
  } catch (const BasisError& e) {
    CHECK(std::string(e.what()).find(format_point<D>(x)) != std::string::npos);
  }
}

/// The lattice hats by the generic formula of the first implementation (one
/// loop over corners, N and each component of grad N formed as products in
/// axis order starting from 1): the bits every faster form must keep.
template <int D> void reference_hats(const CartesianGrid<D>& g, const Vec<D>& x, int* node, double* N, Vec<D>* dN) {
  const Vec<D> h = g.h();
  std::array<double, D> t, inv_h;
  int base = 0, stride[D];
  for (int k = 0, s = 1; k < D; s *= g.cells[k] + 1, ++k) {
    const double u = (x[k] - g.lower[k]) / h[k];
    const int c = std::clamp(static_cast<int>(u), 0, g.cells[k] - 1);
    t[k] = std::clamp(u - c, 0.0, 1.0);
    inv_h[k] = 1.0 / h[k];
    stride[k] = s;
    base += s * c;
  }
  for (int a = 0; a < (1 << D); ++a) {
    double w[D];
    int id = base;
    for (int k = 0; k < D; ++k) {
      const bool upper = (a >> k) & 1;
      w[k] = upper ? t[k] : 1.0 - t[k];
      id += upper ? stride[k] : 0;
    }
    double n = 1.0;
    Vec<D> grad;
    for (int k = 0; k < D; ++k) {
      n *= w[k];
      double gk = 1.0;
      for (int j = 0; j < D; ++j) gk *= j != k ? w[j] : (((a >> k) & 1) ? inv_h[k] : -inv_h[k]);
      grad[k] = gk;
    }
    node[a] = id;
    N[a] = n;
    dN[a] = grad;
  }
}

/// Same bits (memcmp, so that 0 and -0 differ too).
template <class T> bool same_bits(const T& a, const T& b) { return std::memcmp(&a, &b, sizeof(T)) == 0; }

} // namespace

namespace {
/// sample_points and, on each axis, a point below and above the box within
/// the 1e-12-cell slack (u < 0 and u > cells): clamped onto it.
template <int D> AlignedVector<Vec<D>> points_and_slack(const CartesianGrid<D>& g, unsigned seed) {
  AlignedVector<Vec<D>> x = sample_points(g, seed);
  for (int k = 0; k < D; ++k) {
    Vec<D> below = g.lower, above = g.upper;
    below[k] -= 1e-14 * g.h()[k];
    above[k] += 1e-14 * g.h()[k];
    x.push_back(below);
    x.push_back(above);
  }
  return x;
}
} // namespace

TEST_CASE_TEMPLATE_DEFINE(
    "linear on a lattice: evaluate, evaluate_fixed, the batch and the lattice rows give the reference bits",
    T, batch_id) {
  constexpr int D = T::value;
  constexpr int S = 1 << D;
  const CartesianGrid<D> g = test_grid<D>();
  const auto b = make_linear_basis<D>(NodeSet<D>::cartesian(g));
  REQUIRE(b->fixed_stencil() == S);
  AlignedVector<Vec<D>> x = points_and_slack(g, 11u);
  const int n = static_cast<int>(x.size());
  std::vector<int> node(static_cast<std::size_t>(n * S), -1);
  std::vector<double> N(node.size(), -1.0);
  AlignedVector<Vec<D>> dN(node.size(), Vec<D>::Constant(-1.0));
  std::vector<Index<D>> hint(static_cast<std::size_t>(n));
  for (Index<D>& c : hint) c.fill(-7);
  REQUIRE(b->evaluate_fixed_points(x.data(), n, hint.data(), node.data(), N.data(), dN.data()) == n);
  int mismatches = 0;
  for (int p = 0; p < n; ++p) {
    int rn[S];
    double rN[S];
    Vec<D> rdN[S];
    reference_hats<D>(g, x[p], rn, rN, rdN);
    Stencil<D> st;
    Index<D> cell;
    cell.fill(-7);
    PointQuery<D> q;
    q.x = x[p];
    q.cell_hint = &cell;
    b->evaluate(q, st);
    REQUIRE(st.size() == S);
    int fn[S];
    double fN[S];
    Vec<D> fdN[S];
    REQUIRE(b->evaluate_fixed(q, fn, fN, fdN));
    CHECK(hint[static_cast<std::size_t>(p)] == cell);
    CHECK(cell == g.cell_of(x[p]));
    for (int a = 0; a < S; ++a) {
      const std::size_t e = static_cast<std::size_t>(p * S + a);
      const bool ok = node[e] == rn[a] && st.node[a] == rn[a] && fn[a] == rn[a] && same_bits(N[e], rN[a]) &&
                      same_bits(st.N[a], rN[a]) && same_bits(fN[a], rN[a]) && same_bits(dN[e], rdN[a]) &&
                      same_bits(st.dN[a], rdN[a]) && same_bits(fdN[a], rdN[a]);
      if (!ok) ++mismatches;
    }
  }
  CHECK(mismatches == 0);
  // Without hints: the same rows.
  std::vector<int> node2(node.size());
  std::vector<double> N2(N.size());
  AlignedVector<Vec<D>> dN2(dN.size());
  REQUIRE(b->evaluate_fixed_points(x.data(), n, nullptr, node2.data(), N2.data(), dN2.data()) == n);
  CHECK(node2 == node);
  CHECK(std::memcmp(N2.data(), N.data(), N.size() * sizeof(double)) == 0);
  CHECK(std::memcmp(dN2.data(), dN.data(), dN.size() * sizeof(Vec<D>)) == 0);
  // The compact lattice rows (LatticeRows): every entry rebuilt the same,
  // and lowest / highest the row's extreme node ids.
  LatticeRows<D> rows;
  REQUIRE(b->evaluate_lattice_rows(x, rows));
  REQUIRE(rows.rows() == n);
  BasisTable<D> expanded;
  expand_lattice_rows(rows, expanded);
  CHECK(expanded.offset.back() == n * S);
  CHECK(expanded.node == node);
  CHECK(std::memcmp(expanded.N.data(), N.data(), N.size() * sizeof(double)) == 0);
  CHECK(std::memcmp(expanded.dN.data(), dN.data(), dN.size() * sizeof(Vec<D>)) == 0);
  int wrong_range = 0;
  for (int p = 0; p < n; ++p) {
    const auto [lo, hi] = std::minmax_element(node.begin() + p * S, node.begin() + (p + 1) * S);
    wrong_range += *lo != rows.lowest(p) || *hi != rows.highest(p);
  }
  CHECK(wrong_range == 0);
}
TEST_CASE_TEMPLATE_APPLY(batch_id, Dims);

TEST_CASE_TEMPLATE_DEFINE("linear batch stops before a point it cannot evaluate and off the lattice", T, stop_id) {
  constexpr int D = T::value;
  constexpr int S = 1 << D;
  const CartesianGrid<D> g = test_grid<D>();
  auto b = make_linear_basis<D>(NodeSet<D>::cartesian(g));
  AlignedVector<Vec<D>> x(6, 0.5 * (g.lower + g.upper));
  std::vector<int> node(x.size() * S, -1);
  std::vector<double> N(node.size(), -1.0);
  AlignedVector<Vec<D>> dN(node.size(), Vec<D>::Zero());
  Vec<D> out = g.upper;
  out[D - 1] += 1e-9 * g.h()[D - 1]; // beyond the round-off slack
  for (const Vec<D>& bad : {out, Vec<D>(Vec<D>::Constant(std::nan(""))), Vec<D>(Vec<D>::Constant(-INFINITY))}) {
    x[3] = bad;
    std::fill(N.begin(), N.end(), -1.0);
    CHECK(b->evaluate_fixed_points(x.data(), 6, nullptr, node.data(), N.data(), dN.data()) == 3);
    CHECK(N[3 * S - 1] >= 0.0);  // rows 0..2 written
    CHECK(N[3 * S] == -1.0);     // row 3 not
    CHECK(b->evaluate_fixed_points(x.data(), 3, nullptr, node.data(), N.data(), dN.data()) == 3);
    CHECK(b->evaluate_fixed_points(x.data() + 4, 2, nullptr, node.data(), N.data(), dN.data()) == 2);
    // The per-point path reports it (the error the table fill prefixes).
    PointQuery<D> q;
    q.x = bad;
    CHECK_THROWS_AS(b->evaluate_fixed(q, node.data(), N.data(), dN.data()), BasisError);
  }
  CHECK(b->evaluate_fixed_points(x.data(), 0, nullptr, node.data(), N.data(), dN.data()) == 0);
  // Once the nodes moved: the elements (segments in 1D) of the points' cells (below).
  AlignedVector<Vec<D>> dx(static_cast<std::size_t>(b->nodes().size()), Vec<D>::Constant(1e-3 * g.h()[0]));
  b->nodes().advect(dx);
  b->nodes_moved(dx);
  x[3] = x[0];
  for (Vec<D>& p : x) p += 0.25 * g.h(); // inside the cells of their Cartesian guess (a node before)
  CHECK(b->evaluate_fixed_points(x.data(), 6, nullptr, node.data(), N.data(), dN.data()) == 6);
}
TEST_CASE_TEMPLATE_APPLY(stop_id, Dims);

TEST_CASE_TEMPLATE_DEFINE("linear lattice rows: none for a point outside, a non-finite one or moved nodes", T,
                          rows_refused_id) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  auto b = make_linear_basis<D>(NodeSet<D>::cartesian(g));
  AlignedVector<Vec<D>> x(6, 0.5 * (g.lower + g.upper));
  LatticeRows<D> rows;
  CHECK(b->evaluate_lattice_rows(x, rows));
  Vec<D> out = g.upper;
  out[D - 1] += 1e-9 * g.h()[D - 1]; // beyond the round-off slack
  for (const Vec<D>& bad :
       {out, Vec<D>(Vec<D>::Constant(std::nan(""))), Vec<D>(Vec<D>::Constant(-INFINITY))}) {
    x[3] = bad;
    CHECK_FALSE(b->evaluate_lattice_rows(x, rows));
  }
  x[3] = x[0];
  AlignedVector<Vec<D>> dx(static_cast<std::size_t>(b->nodes().size()), Vec<D>::Constant(1e-3 * g.h()[0]));
  b->nodes().advect(dx);
  b->nodes_moved(dx);
  CHECK_FALSE(b->evaluate_lattice_rows(x, rows));
  // the other families keep no lattice rows
  BasisOptions lme;
  lme.kind = "lme";
  CHECK_FALSE(make_basis<D>(lme, NodeSet<D>::cartesian(g))->evaluate_lattice_rows(x, rows));
}
TEST_CASE_TEMPLATE_APPLY(rows_refused_id, Dims);

TEST_CASE_TEMPLATE_DEFINE("linear on a Cartesian grid: partition of unity and linear completeness", T, cart_id) {
  constexpr int D = T::value;
  const auto b = make_linear_basis<D>(NodeSet<D>::cartesian(test_grid<D>()));
  CHECK(b->kind() == "linear");
  CHECK(b->linearly_complete());
  for (const Vec<D>& x : sample_points(test_grid<D>(), 1u)) check_identities(*b, x);
}
TEST_CASE_TEMPLATE_APPLY(cart_id, Dims);

TEST_CASE_TEMPLATE_DEFINE("linear on a perturbed grid: partition of unity and linear completeness", T, pert_id) {
  constexpr int D = T::value;
  const auto b = make_linear_basis<D>(NodeSet<D>::perturbed(test_grid<D>(), 0.35, 17u));
  for (const Vec<D>& x : sample_points(test_grid<D>(), 2u)) check_identities(*b, x);
}
TEST_CASE_TEMPLATE_APPLY(pert_id, Dims);

TEST_CASE_TEMPLATE_DEFINE("linear stencil on a Cartesian grid is the 2^D vertices of the containing cell", T, st_id) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  const auto b = make_linear_basis<D>(NodeSet<D>::cartesian(g));
  // At a node every other hat vanishes: N is the Kronecker delta.
  const int I = g.num_nodes() / 2;
  const Vec<D> xI = g.node_position(g.node_index(I));
  const auto m = values_at(*b, xI);
  CHECK(static_cast<int>(m.size()) == (1 << D));
  // 1e-15: x_I - lower divided by h is an integer only to round-off.
  for (const auto& [J, N] : m) CHECK(std::abs(N - (J == I ? 1.0 : 0.0)) <= 1e-15);
  // Hat value at a generic point: prod_k (1 - |x_k - x_Ik| / h_k).
  std::mt19937 rng(3);
  const Vec<D> x = random_in_box<D>(rng, g.lower, g.upper);
  for (const auto& [J, N] : values_at(*b, x)) {
    const Vec<D> d = (x - g.node_position(g.node_index(J))).cwiseAbs().cwiseQuotient(g.h());
    double expect = 1;
    for (int k = 0; k < D; ++k) expect *= 1 - d[k];
    CHECK(N == doctest::Approx(expect).epsilon(1e-13));
  }
}
TEST_CASE_TEMPLATE_APPLY(st_id, Dims);

TEST_CASE_TEMPLATE_DEFINE("linear gradients equal central differences", T, fd_id) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  check_fd_gradient(*make_linear_basis<D>(NodeSet<D>::cartesian(g)), g, 4u);
  check_fd_gradient(*make_linear_basis<D>(NodeSet<D>::perturbed(g, 0.35, 5u)), g, 6u);
}
TEST_CASE_TEMPLATE_APPLY(fd_id, Dims);

TEST_CASE_TEMPLATE_DEFINE("linear after an affine motion of the nodes equals the mapped Cartesian basis", T, aff_id) {
  // x' = A x + b maps every multilinear element to an element whose inverse
  // map is exact, so N'_I(A x + b) = N_I(x) and grad N'_I = A^{-T} grad N_I.
  // The strong shear moves points several cells away from their Cartesian
  // guess, which exercises the element walk.
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  auto ref = make_linear_basis<D>(NodeSet<D>::cartesian(g));
  auto moved = make_linear_basis<D>(NodeSet<D>::cartesian(g));
  Mat<D> A = Mat<D>::Identity();
  for (int k = 0; k < D; ++k) A(k, k) = 1.0 + 0.1 * (k + 1);
  if constexpr (D > 1) A(0, D - 1) = 2.5;
  const Vec<D> shift = Vec<D>::Constant(0.37);
  AlignedVector<Vec<D>> dx;
  for (const Vec<D>& x : moved->nodes().positions()) dx.push_back(A * x + shift - x);
  moved->nodes().advect(dx);
  moved->nodes_moved(dx);
  CHECK_FALSE(moved->nodes().on_lattice());
  const Mat<D> AinvT = A.inverse().transpose();
  for (const Vec<D>& x : sample_points(g, 7u)) {
    Stencil<D> s0, s1;
    PointQuery<D> q;
    q.x = x;
    ref->evaluate(q, s0);
    q.x = A * x + shift;
    moved->evaluate(q, s1);
    check_identities(*moved, q.x);
    std::map<int, std::pair<double, Vec<D>>> m0;
    for (int a = 0; a < s0.size(); ++a) m0[s0.node[a]] = {s0.N[a], s0.dN[a]};
    for (int a = 0; a < s1.size(); ++a) {
      INFO("point ", format_point<D>(x), " node ", s1.node[a]);
      // Nodes with N = 0 on a face may differ between the two cells sharing it.
      if (!m0.count(s1.node[a])) {
        CHECK(std::abs(s1.N[a]) <= 1e-12);
        continue;
      }
      CHECK(std::abs(s1.N[a] - m0[s1.node[a]].first) <= 1e-12);
      // Gradients only where both picked the same cell (not on faces).
      if (s0.N[a] > 1e-9 && s1.N[a] > 1e-9 && s0.node == s1.node)
        CHECK((s1.dN[a] - AinvT * m0[s1.node[a]].second).norm() <= 1e-10 * m0[s1.node[a]].second.norm() + 1e-10);
    }
  }
}
TEST_CASE_TEMPLATE_APPLY(aff_id, Dims);

namespace {

/// A 1D linear basis on the nodes 0, 2.5, 2, 3: the second segment runs backwards.
std::unique_ptr<Basis<1>> inverted_segment() {
  CartesianGrid<1> g;
  g.lower[0] = 0;
  g.upper[0] = 3;
  g.cells[0] = 3;
  auto b = make_linear_basis<1>(NodeSet<1>::cartesian(g));
  AlignedVector<Vec<1>> dx(4, Vec<1>::Zero());
  dx[1][0] = 1.5;
  b->nodes().advect(dx);
  b->nodes_moved(dx);
  return b;
}

/// Rows of points x filled as the table fill does (the batch, and each
/// point it stops at through evaluate(), then the batch again), against
/// evaluate() point by point with the same hints: the same bits, the same
/// hints after, and the batch wrote exactly the points that lie in their
/// start cell (the hint when valid, else the Cartesian guess). Returns the
/// points the batch wrote.
template <int D>
int batch_against_evaluate(const Basis<D>& b, const CartesianGrid<D>& g, const AlignedVector<Vec<D>>& x,
                           const std::vector<Index<D>>& hints) {
  constexpr int S = 1 << D;
  const int n = static_cast<int>(x.size());
  std::vector<int> node(S * x.size());
  std::vector<double> N(node.size());
  AlignedVector<Vec<D>> dN(node.size());
  std::vector<Index<D>> hint_batch = hints, hint_point = hints;
  int batched = 0;
  for (int p = 0; p < n; ++p) {
    const int done =
        b.evaluate_fixed_points(&x[p], n - p, &hint_batch[p], &node[S * p], &N[S * p], &dN[S * p]);
    batched += done;
    p += done;
    if (p == n) break;
    Stencil<D> st;
    PointQuery<D> q;
    q.x = x[p];
    q.cell_hint = &hint_batch[p];
    b.evaluate(q, st);
    REQUIRE(st.size() == S);
    for (int a = 0; a < S; ++a)
      node[S * p + a] = st.node[a], N[S * p + a] = st.N[a], dN[S * p + a] = st.dN[a];
  }
  int in_start_cell = 0;
  for (int p = 0; p < n; ++p) {
    bool valid = true;
    for (int k = 0; k < D; ++k) valid = valid && hint_point[p][k] >= 0 && hint_point[p][k] < g.cells[k];
    const Index<D> start = valid ? hint_point[p] : g.cell_of(x[p]);
    Stencil<D> st;
    PointQuery<D> q;
    q.x = x[p];
    q.cell_hint = &hint_point[p];
    b.evaluate(q, st);
    in_start_cell += hint_point[p] == start ? 1 : 0;
    INFO("point " << p << " at " << x[p].transpose());
    for (int a = 0; a < S; ++a) {
      CHECK(node[S * p + a] == st.node[a]);
      CHECK(std::bit_cast<std::uint64_t>(N[S * p + a]) == std::bit_cast<std::uint64_t>(st.N[a]));
      for (int k = 0; k < D; ++k)
        CHECK(std::bit_cast<std::uint64_t>(dN[S * p + a][k]) == std::bit_cast<std::uint64_t>(st.dN[a][k]));
    }
    CHECK(hint_batch[p] == hint_point[p]);
  }
  CHECK(batched == in_start_cell);
  return batched;
}

} // namespace

TEST_CASE("linear 1D off the lattice: the batch gives evaluate()'s bits and leaves the walk to it") {
  const CartesianGrid<1> g = test_grid<1>();
  const auto b = make_linear_basis<1>(NodeSet<1>::perturbed(g, 0.3, 4u));
  std::mt19937 rng(21);
  AlignedVector<Vec<1>> x;
  std::vector<Index<1>> hints;
  for (int i = 0; i < 400; ++i) {
    x.push_back(random_in_box<1>(rng, g.lower, g.upper));
    // the cell of the Cartesian guess, a neighbour (often not the element:
    // the walk), invalid hints (ignored: -5 and one past the last cell), the
    // last cell
    const int c = g.cell_of(x.back())[0];
    const int pick = i % 5;
    hints.push_back(Index<1>{pick == 0   ? c
                             : pick == 1 ? std::min(c + 1, g.cells[0] - 1)
                             : pick == 2 ? -5
                             : pick == 3 ? g.cells[0]
                                         : g.cells[0] - 1});
  }
  // the ends of the node set, and just beyond them within the round-off
  // slack (|xi| a little above 1: clamped)
  const double h = g.h()[0];
  x[7] = g.lower, x[8] = g.upper;
  x[9] = g.lower - Vec<1>(1e-13 * h), x[10] = g.upper + Vec<1>(1e-13 * h);
  hints[9] = Index<1>{0}, hints[10] = Index<1>{g.cells[0] - 1};
  // interior nodes, from the cells on either side (xi = +-1 up to round-off)
  for (int I = 1; I < g.cells[0]; ++I)
    for (const int side : {I - 1, I}) {
      x.push_back(b->nodes().position(I));
      hints.push_back(Index<1>{side});
    }
  const int batched = batch_against_evaluate<1>(*b, g, x, hints);
  MESSAGE("points written by the batch: " << batched << " of " << x.size());
  CHECK(batched > 100);
  CHECK(batched < static_cast<int>(x.size())); // the walks went through evaluate()
  // a point that is not finite, and one in an inverted element: the batch
  // stops before them (evaluate() reports them)
  std::vector<int> node(4);
  std::vector<double> N(4);
  AlignedVector<Vec<1>> dN(4);
  const AlignedVector<Vec<1>> bad{Vec<1>(std::nan("")), x[0]};
  CHECK(b->evaluate_fixed_points(bad.data(), 2, nullptr, node.data(), N.data(), dN.data()) == 0);
  const auto inverted = inverted_segment();
  Index<1> hint{1};
  const Vec<1> x_in(2.2);
  CHECK(inverted->evaluate_fixed_points(&x_in, 1, &hint, node.data(), N.data(), dN.data()) == 0);
  CHECK(hint[0] == 1);
}

TEST_CASE_TEMPLATE_DEFINE(
    "linear 2D and 3D off the lattice: the batch gives evaluate()'s bits and leaves the walk to it", T,
    iso_batch_id) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  const auto b = make_linear_basis<D>(NodeSet<D>::perturbed(g, 0.3, 4u));
  std::mt19937 rng(22);
  AlignedVector<Vec<D>> x;
  std::vector<Index<D>> hints;
  for (int i = 0; i < 400; ++i) {
    // runs of points in one cell (the batch forms the element once), the
    // cell of the Cartesian guess, a neighbour (often not the element: the
    // walk), an invalid hint (ignored)
    x.push_back(i % 4 == 1 ? Vec<D>((x.back() + 0.01 * g.h()).cwiseMin(g.upper))
                           : random_in_box<D>(rng, g.lower, g.upper));
    Index<D> c = g.cell_of(x.back());
    const int pick = i % 5;
    if (pick == 1) c[0] = std::min(c[0] + 1, g.cells[0] - 1);
    if (pick == 2) c[D - 1] = -5;
    hints.push_back(c);
  }
  const int batched = batch_against_evaluate<D>(*b, g, x, hints);
  MESSAGE("points written by the batch: " << batched << " of " << x.size());
  CHECK(batched > 100);
  CHECK(batched < static_cast<int>(x.size())); // the walks went through evaluate()
  // a point that is not finite: the batch stops before it
  constexpr int S = 1 << D;
  std::vector<int> node(2 * S);
  std::vector<double> N(2 * S);
  AlignedVector<Vec<D>> dN(2 * S);
  const AlignedVector<Vec<D>> bad{Vec<D>::Constant(std::nan("")), x[0]};
  CHECK(b->evaluate_fixed_points(bad.data(), 2, nullptr, node.data(), N.data(), dN.data()) == 0);
}
TEST_CASE_TEMPLATE_APPLY(iso_batch_id,
                         std::tuple<std::integral_constant<int, 2>, std::integral_constant<int, 3>>);

TEST_CASE("linear uses and updates the cell hint") {
  const CartesianGrid<2> g = test_grid<2>();
  const auto b = make_linear_basis<2>(NodeSet<2>::perturbed(g, 0.3, 8u));
  std::mt19937 rng(9);
  for (int n = 0; n < 50; ++n) {
    const Vec<2> x = random_in_box<2>(rng, g.lower, g.upper);
    Stencil<2> cold, warm;
    PointQuery<2> q;
    q.x = x;
    b->evaluate(q, cold);
    Index<2> hint{g.cells[0] - 1, 0}; // a far corner: the walk must get there
    q.cell_hint = &hint;
    b->evaluate(q, warm);
    CHECK(cold.node == warm.node);
    for (int a = 0; a < cold.size(); ++a) CHECK(cold.N[a] == doctest::Approx(warm.N[a]).epsilon(1e-12));
    // The hint now names the element whose vertices are the stencil.
    CHECK(warm.node[0] == g.node_id(hint));
    Index<2> bogus{-5, 99}; // invalid hints are ignored
    q.cell_hint = &bogus;
    b->evaluate(q, warm);
    CHECK(cold.node == warm.node);
  }
}

TEST_CASE_TEMPLATE_DEFINE("linear: a point outside the grid is a BasisError naming the point", T, out_id) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  const Vec<D> below = g.lower - 0.01 * g.h();
  // Just beyond the round-off slack of 1e-12 cells that counts as inside.
  Vec<D> beside = 0.5 * (g.lower + g.upper);
  beside[D - 1] = g.upper[D - 1] + 1e-9 * g.h()[D - 1];
  for (const auto& b : {make_linear_basis<D>(NodeSet<D>::cartesian(g)),
                        make_linear_basis<D>(NodeSet<D>::perturbed(g, 0.3, 1u))}) {
    check_outside_names_point<D>(*b, below);
    check_outside_names_point<D>(*b, beside);
    check_outside_names_point<D>(*b, Vec<D>::Constant(1e6));
  }
}
TEST_CASE_TEMPLATE_APPLY(out_id, Dims);

TEST_CASE("linear: a point in an inverted element is a BasisError") {
  const auto b = inverted_segment();
  Stencil<1> st;
  PointQuery<1> q;
  q.x = Vec<1>(2.6);
  CHECK_NOTHROW(b->evaluate(q, st)); // only in the last element
  Index<1> hint{1};                  // start the search in the inverted element
  q.x = Vec<1>(2.2);
  q.cell_hint = &hint;
  CHECK_THROWS_WITH_AS(b->evaluate(q, st), doctest::Contains("inverted"), BasisError);
}

TEST_CASE("linear needs a structured grid") {
  AlignedVector<Vec<2>> x{Vec<2>(0, 0), Vec<2>(1, 0), Vec<2>(0, 1)};
  CHECK_THROWS_AS(make_linear_basis<2>(NodeSet<2>::cloud(x, 1.0)), InputError);
}

TEST_CASE_TEMPLATE_DEFINE("linear: a point within round-off outside the grid is clamped onto it", T, clamp_id) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  Vec<D> x = g.upper;
  x[0] += 1e-14 * g.h()[0];
  for (const auto& b : {make_linear_basis<D>(NodeSet<D>::cartesian(g)),
                        make_linear_basis<D>(NodeSet<D>::perturbed(g, 0.3, 1u))}) {
    const auto m = values_at(*b, x);
    Index<D> last;
    for (int k = 0; k < D; ++k) last[k] = g.cells[k];
    // The corner node carries everything (to the 1e-14 offset).
    CHECK(m.at(g.node_id(last)) == doctest::Approx(1.0).epsilon(1e-12));
  }
}
TEST_CASE_TEMPLATE_APPLY(clamp_id, Dims);

TEST_CASE_TEMPLATE_DEFINE("linear finds the containing element from any start cell on a strongly perturbed grid", T,
                          walk_id) {
  // A random (mostly wrong) hint makes the search walk, and on a strongly
  // distorted lattice the walk may cycle and hand over to the ring search.
  // Completeness sum N_I x_I = x can only hold in the element that contains x.
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  const auto b = make_linear_basis<D>(NodeSet<D>::perturbed(g, 0.4, 23u));
  std::mt19937 rng(24);
  for (int n = 0; n < 400; ++n) {
    const Vec<D> x = random_in_box<D>(rng, g.lower, g.upper);
    Index<D> hint;
    for (int k = 0; k < D; ++k) hint[k] = static_cast<int>(rng() % static_cast<unsigned>(g.cells[k]));
    Stencil<D> st;
    PointQuery<D> q;
    q.x = x;
    q.cell_hint = &hint;
    b->evaluate(q, st);
    Vec<D> sumX = Vec<D>::Zero();
    for (int a = 0; a < st.size(); ++a) sumX += st.N[a] * b->nodes().position(st.node[a]);
    // 1e-12 of the coordinate scale (|x| <= 2): see kRelTol.
    CHECK((sumX - x).cwiseAbs().maxCoeff() <= 2e-12);
  }
}
TEST_CASE_TEMPLATE_APPLY(walk_id, Dims);
