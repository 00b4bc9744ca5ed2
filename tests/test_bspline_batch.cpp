/// \file test_bspline_batch.cpp
/// The batched B-spline evaluation (BsplineBasis::evaluate_fixed_points, the
/// fixed-stencil path of fill_basis_table) against the per-point path
/// (BsplineBasis::evaluate), bit for bit: N, grad N, node ids and cell hints
/// in 1D/2D/3D, degrees 1..3, on uniform, non-uniform, perturbed and advected
/// knot vectors, at random points, on cell faces, at the domain ends and
/// within round-off of them; and KnotVector::evaluate_on_cell (whose Cox-de
/// Boor kernel the batch shares) against the loop it replaced, kept below as
/// the reference. A point the batch refuses must be one the per-point path
/// rejects (BasisError) or gives a stencil with an entry N = 0 (a point on a
/// knot, where evaluate() drops the entries with N = 0 and grad N = 0).
///
/// No tolerances: every comparison is of the bits (std::bit_cast), which also
/// tells +0 from -0.
#include "otmpm/basis/bspline.hpp"
#include "support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>

using namespace otmpm;
using otmpm::test::ScopedThreads;

namespace {

constexpr unsigned kSeed = 20261125;

std::uint64_t bits(double v) { return std::bit_cast<std::uint64_t>(v); }

/// KnotVector::evaluate_on_cell as it was before the batch (commit ec7dbaa):
/// the triangular Cox-de Boor scheme with the degree a run-time value, each
/// quotient formed where it is used - by a division (divide), or as since the
/// reciprocal knot widths: the product with 1 / (t_{j+d} - t_j), which is the
/// reference of the bit comparisons.
BsplineSpanValues reference_on_cell(const KnotVector& kv, double x, int cell, bool divide = false) {
  const std::vector<double>& t_ = kv.knots();
  const int p_ = kv.degree();
  x = std::clamp(x, kv.lower(), kv.upper());
  const int s = cell + p_;
  std::array<double, kMaxBsplineSpanFunctions> B{};
  std::array<double, kMaxBsplineSpanFunctions> prev{};
  BsplineSpanValues out;
  out.first = cell;
  B[0] = 1.0;
  for (int d = 1; d <= p_; ++d) {
    prev = B;
    for (int r = 0; r <= d; ++r) {
      const int j = s - d + r;
      auto quotient = [&](double b, double width) { return divide ? b / width : b * (1.0 / width); };
      const double left = r >= 1 ? quotient(prev[r - 1], t_[j + d] - t_[j]) : 0.0;
      const double right = r <= d - 1 ? quotient(prev[r], t_[j + d + 1] - t_[j + 1]) : 0.0;
      B[r] = (x - t_[j]) * left + (t_[j + d + 1] - x) * right;
      if (d == p_) out.dN[r] = d * (left - right);
    }
  }
  for (int r = 0; r <= p_; ++r) out.N[r] = B[r];
  return out;
}

/// Vertices of the kinds of knot vectors a run meets, `cells` cells on [a, b]:
/// 0 uniform (mpm mode), 1 strongly non-uniform, 2 uniform with interior
/// vertices moved randomly by up to 0.3 h, 3 uniform advected twice by a
/// smooth non-affine increment (the `unified` integrator).
std::vector<double> vertices(int kind, double a, double b, int cells, int degree, unsigned seed) {
  KnotVector kv = KnotVector::uniform(a, b, cells, degree);
  std::vector<double> v = kv.vertices();
  const double h = (b - a) / cells;
  if (kind == 1)
    for (int j = 1; j < cells; ++j) v[j] = a + (b - a) * std::pow(static_cast<double>(j) / cells, 1.7);
  if (kind == 2) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-0.3, 0.3);
    for (int j = 1; j < cells; ++j) v[j] += u(rng) * h;
  }
  if (kind == 3) {
    for (int step = 0; step < 2; ++step) {
      std::vector<double> d(static_cast<std::size_t>(kv.num_basis()));
      for (int i = 0; i < kv.num_basis(); ++i) d[i] = 0.05 * h * std::sin(3.0 * kv.greville(i)) + 0.01 * h;
      kv = kv.advected(d);
    }
    v = kv.vertices();
  }
  return v;
}

/// Coordinates along one axis: random ones, every vertex and its two
/// neighbouring doubles, points 1e-13 of the length inside the ends and beyond
/// them by half and twice the round-off slack of KnotVector::contains.
std::vector<double> axis_samples(const std::vector<double>& v, int random_count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(v.front(), v.back());
  std::vector<double> x;
  for (int i = 0; i < random_count; ++i) x.push_back(u(rng));
  const double inf = std::numeric_limits<double>::infinity();
  for (double vj : v) {
    x.push_back(vj);
    x.push_back(std::nextafter(vj, inf));
    x.push_back(std::nextafter(vj, -inf));
  }
  const double L = v.back() - v.front(), r = KnotVector::kBoundaryRoundoff * L;
  for (double s : {1e-13 * L, -0.5 * r, -2.0 * r}) {
    x.push_back(v.front() + s);
    x.push_back(v.back() - s);
  }
  return x;
}

/// Random combinations of the axis samples of the basis, then a non-finite
/// point and one far outside.
template <int D> AlignedVector<Vec<D>> sample_points(const BsplineBasis<D>& b, int random_count, unsigned seed) {
  std::array<std::vector<double>, D> axis;
  for (int k = 0; k < D; ++k) axis[k] = axis_samples(b.knot_vector(k).vertices(), random_count, seed + k);
  std::mt19937 rng(seed);
  AlignedVector<Vec<D>> pts;
  for (int i = 0; i < 8 * random_count; ++i) {
    Vec<D> x;
    for (int k = 0; k < D; ++k) {
      std::uniform_int_distribution<std::size_t> pick(0, axis[k].size() - 1);
      x[k] = axis[k][pick(rng)];
    }
    pts.push_back(x);
  }
  Vec<D> bad = pts.front();
  bad[D - 1] = std::numeric_limits<double>::quiet_NaN();
  pts.push_back(bad);
  bad[D - 1] = 1e6;
  pts.push_back(bad);
  return pts;
}

/// Counts of a comparison of the batch with evaluate() over a point set.
struct Tally {
  int accepted = 0; ///< points the batch evaluated (all bits compared)
  int refused = 0;  ///< points it left to evaluate()
  int mismatches = 0;
};

/// The per-point path at x: the stencil and the cell hint it leaves, or false
/// with the BasisError message.
template <int D> bool per_point(const BsplineBasis<D>& b, const Vec<D>& x, Stencil<D>& st, Index<D>& cell,
                                std::string& error) {
  PointQuery<D> q;
  q.x = x;
  q.cell_hint = &cell;
  try {
    b.evaluate(q, st);
    return true;
  } catch (const BasisError& e) {
    error = e.what();
    return false;
  }
}

/// Entries [0, S) of the batch output against the per-point stencil, bitwise.
template <int D> int differences(const Stencil<D>& st, int S, const int* node, const double* N, const Vec<D>* dN) {
  if (st.size() != S) return 1;
  int bad = 0;
  for (int e = 0; e < S; ++e) {
    bad += st.node[e] != node[e] || bits(st.N[e]) != bits(N[e]);
    for (int k = 0; k < D; ++k) bad += bits(st.dN[e][k]) != bits(dN[e][k]);
  }
  return bad;
}

/// Every point alone through the batch (with a stale cell hint and without
/// one), compared with evaluate(): accepted points bit for bit, refused
/// points must be rejected by evaluate() or have an entry N = 0.
template <int D> Tally compare_points(const BsplineBasis<D>& b, const AlignedVector<Vec<D>>& x) {
  const int S = b.fixed_stencil();
  Tally t;
  std::vector<int> node(static_cast<std::size_t>(S));
  std::vector<double> N(static_cast<std::size_t>(S));
  AlignedVector<Vec<D>> dN(static_cast<std::size_t>(S));
  for (std::size_t i = 0; i < x.size(); ++i) {
    Stencil<D> st;
    Index<D> cell;
    cell.fill(0);
    std::string error;
    const bool ok = per_point<D>(b, x[i], st, cell, error);
    for (const bool hinted : {true, false}) {
      Index<D> hint;
      hint.fill(b.knot_vector(0).num_cells() / 2); // usually not the cell
      const int done = b.evaluate_fixed_points(&x[i], 1, hinted ? &hint : nullptr, node.data(), N.data(), dN.data());
      INFO("x = " << format_point<D>(x[i]) << ", hint " << hinted);
      if (done == 1) {
        ++t.accepted;
        REQUIRE(ok);
        t.mismatches += differences<D>(st, S, node.data(), N.data(), dN.data());
        if (hinted) t.mismatches += hint != cell;
      } else {
        ++t.refused;
        const bool has_zero = ok && (st.size() < S || std::find(st.N.begin(), st.N.end(), 0.0) != st.N.end());
        CHECK((!ok || has_zero));
      }
    }
  }
  return t;
}

/// The batch over the whole array, resumed after each refused point (as
/// fill_basis_table does), against evaluate() point by point; the previous
/// point's cell serves as the hint.
template <int D> int compare_runs(const BsplineBasis<D>& b, const AlignedVector<Vec<D>>& x) {
  const int S = b.fixed_stencil(), n = static_cast<int>(x.size());
  std::vector<int> node(static_cast<std::size_t>(n * S));
  std::vector<double> N(node.size());
  AlignedVector<Vec<D>> dN(node.size());
  std::vector<char> done(static_cast<std::size_t>(n), 0);
  for (int p = 0; p < n; ++p) {
    const int k = b.evaluate_fixed_points(&x[p], n - p, nullptr, &node[p * S], &N[p * S], &dN[p * S]);
    std::fill(done.begin() + p, done.begin() + p + k, 1);
    p += k;
  }
  int bad = 0;
  for (int p = 0; p < n; ++p) {
    if (!done[p]) continue;
    Stencil<D> st;
    Index<D> cell;
    std::string error;
    REQUIRE(per_point<D>(b, x[p], st, cell, error));
    bad += differences<D>(st, S, &node[p * S], &N[p * S], &dN[p * S]);
  }
  return bad;
}

/// A basis on the knot-vector kind `kind` per axis (vertices()).
template <int D> BsplineBasis<D> basis_of_kind(int kind, int degree, unsigned seed) {
  std::array<std::vector<double>, D> v;
  const int cells[3] = {9, 6, 5};
  for (int k = 0; k < D; ++k) v[k] = vertices(kind, -0.3 + 0.1 * k, 1.7 - 0.2 * k, cells[k], degree, seed + k);
  return BsplineBasis<D>(v, degree);
}

template <int D> void check_all_kinds(int random_count) {
  for (int p = kMinBsplineDegree; p <= kMaxBsplineDegree; ++p)
    for (int kind = 0; kind < 4; ++kind) {
      const BsplineBasis<D> b = basis_of_kind<D>(kind, p, kSeed + 10 * kind);
      const AlignedVector<Vec<D>> x = sample_points<D>(b, random_count, kSeed + p);
      INFO("D = " << D << ", degree " << p << ", knot vectors of kind " << kind);
      const Tally t = compare_points<D>(b, x);
      CHECK(t.mismatches == 0);
      // points made of random coordinates only are off the knots and the
      // batch takes them all: about 8 random_count f^D with f the random
      // share of an axis' samples (0.7 .. 0.9 here), each tried twice
      CHECK(t.accepted >= 2 * random_count);
      CHECK(t.refused >= 4); // at least the NaN, the far point and the points beyond the slack
      CHECK(compare_runs<D>(b, x) == 0);
    }
}

} // namespace

namespace {

/// f(kv, x, cell, a, divided) at ~300 samples x inside each knot vector of
/// every degree and kind: a = kv.evaluate_on_cell(x, cell), divided =
/// reference_on_cell with divisions.
template <class F> void for_each_span_sample(F&& f) {
  for (int p = kMinBsplineDegree; p <= kMaxBsplineDegree; ++p)
    for (int kind = 0; kind < 4; ++kind) {
      const KnotVector kv(vertices(kind, -0.7, 2.3, 11, p, kSeed + kind), p);
      for (double x : axis_samples(kv.vertices(), 300, kSeed)) {
        if (!kv.contains(x)) continue;
        const int cell = kv.find_cell(x);
        f(kv, x, cell, kv.evaluate_on_cell(x, cell), reference_on_cell(kv, x, cell, true));
      }
    }
}

} // namespace

TEST_CASE("bspline batch: evaluate_on_cell reproduces the reference Cox-de Boor bit for bit") {
  int compared = 0, bad = 0;
  for_each_span_sample([&](const KnotVector& kv, double x, int cell, const BsplineSpanValues& a,
                           const BsplineSpanValues&) {
    const BsplineSpanValues r = reference_on_cell(kv, x, cell);
    ++compared;
    bad += a.first != r.first;
    for (int i = 0; i < kMaxBsplineSpanFunctions; ++i) bad += bits(a.N[i]) != bits(r.N[i]) || bits(a.dN[i]) != bits(r.dN[i]);
  });
  CHECK(compared > 3000);
  CHECK(bad == 0);
}

TEST_CASE("bspline batch: the quotients by reciprocal widths agree with the divisions to round-off") {
  // Each of the p levels rounds a product by the reciprocal (<= 1 ulp more
  // than the division's 0.5), and N, dN are sums of such terms: a few eps of
  // the span's largest value (measured 1.5 and 2.7 eps). 8 eps leaves room
  // for p = 3; a wrong width or index is O(1).
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  double worst_N = 0.0, worst_dN = 0.0;
  for_each_span_sample([&](const KnotVector& kv, double, int, const BsplineSpanValues& a, const BsplineSpanValues& r) {
    const int p = kv.degree();
    double dN_max = 0.0;
    for (int i = 0; i <= p; ++i) dN_max = std::max(dN_max, std::abs(r.dN[i]));
    for (int i = 0; i <= p; ++i) {
      worst_N = std::max(worst_N, std::abs(a.N[i] - r.N[i]));
      worst_dN = std::max(worst_dN, std::abs(a.dN[i] - r.dN[i]) / dN_max);
    }
  });
  MESSAGE("largest difference from the divided form: N " << worst_N / kEps << " eps, dN " << worst_dN / kEps
                                                         << " eps of the span's largest"); // docs/theory.md 4.3
  CHECK(worst_N <= 8 * kEps);
  CHECK(worst_dN <= 8 * kEps);
  CHECK(worst_N > 0.0); // the two forms do differ: the comparison is not of one formula with itself
}

TEST_CASE("bspline batch: the batch equals evaluate() bit for bit in 1D") { check_all_kinds<1>(400); }

TEST_CASE("bspline batch: the batch equals evaluate() bit for bit in 2D") { check_all_kinds<2>(150); }

TEST_CASE("bspline batch: the batch equals evaluate() bit for bit in 3D") { check_all_kinds<3>(60); }

TEST_CASE("bspline batch: knot vectors advected by nodes_moved, the batch equals evaluate()") {
  // The unified integrator's path: the control points move, the basis
  // advects its knot vectors (separable, non-affine motion).
  for (int p = kMinBsplineDegree; p <= kMaxBsplineDegree; ++p) {
    CartesianGrid<2> g;
    g.lower = Vec<2>(-1.0, 0.5);
    g.upper = Vec<2>(1.0, 1.5);
    g.cells = {8, 5};
    BsplineBasis<2> b(g, p);
    for (int step = 0; step < 3; ++step) {
      AlignedVector<Vec<2>> dx(static_cast<std::size_t>(b.nodes().size()));
      for (int I = 0; I < b.nodes().size(); ++I) {
        const Vec<2> xI = b.nodes().position(I);
        dx[I] = Vec<2>(0.01 * std::sin(2.0 * xI[0]) + 0.003, -0.005 * xI[1] * xI[1]);
      }
      b.nodes().advect(dx);
      b.nodes_moved(dx);
    }
    const AlignedVector<Vec<2>> x = sample_points<2>(b, 150, kSeed);
    const Tally t = compare_points<2>(b, x);
    CHECK(t.mismatches == 0);
    CHECK(t.accepted >= 300);
    CHECK(compare_runs<2>(b, x) == 0);
  }
}

TEST_CASE("bspline batch: a window basis refuses the points whose stencil leaves the window") {
  CartesianGrid<2> g;
  g.lower = Vec<2>(0.0, 0.0);
  g.upper = Vec<2>(1.0, 1.0);
  g.cells = {10, 8};
  for (int p = kMinBsplineDegree; p <= kMaxBsplineDegree; ++p) {
    const BsplineBasis<2> b(g, p, Index<2>{2, 1}, Index<2>{9, 7});
    const AlignedVector<Vec<2>> x = sample_points<2>(b, 200, kSeed + 7);
    const Tally t = compare_points<2>(b, x);
    INFO("degree " << p);
    CHECK(t.mismatches == 0);
    CHECK(t.accepted >= 100);
    CHECK(t.refused >= 200); // the window holds only part of the domain
    CHECK(compare_runs<2>(b, x) == 0);
  }
}

TEST_CASE("bspline batch: signed zeros in the vertices and the points give the per-point bits") {
  // The batch leaves out the Cox-de Boor terms that add a zero; that changes
  // only signs of zero values, which matter for a vertex or a point at -0.0.
  const double z = -0.0;
  const std::vector<std::vector<double>> sets{{-1.0, -0.25, z}, {z, 0.4, 1.0}, {-1.0, z, 1.0}, {-1.0, 0.0, 1.0}};
  for (int p = kMinBsplineDegree; p <= kMaxBsplineDegree; ++p)
    for (const auto& v : sets) {
      const BsplineBasis<1> b1(std::array<std::vector<double>, 1>{v}, p);
      const BsplineBasis<2> b2(std::array<std::vector<double>, 2>{v, v}, p);
      AlignedVector<Vec<1>> x1;
      AlignedVector<Vec<2>> x2;
      for (double a : {0.0, z, 1e-300, -1e-300, 0.1, -0.1, 5e-324, -5e-324, 1.0, -1.0})
        for (double c : {0.0, z, 0.3, -0.3, 1e-300}) {
          x1.push_back(Vec<1>(a));
          x2.push_back(Vec<2>(a, c));
        }
      INFO("degree " << p << ", vertices " << v[0] << ", " << v[1] << ", " << v[2]);
      const Tally t1 = compare_points<1>(b1, x1), t2 = compare_points<2>(b2, x2);
      CHECK(t1.mismatches == 0);
      CHECK(t2.mismatches == 0);
      CHECK(t1.accepted > 0);
      CHECK(t2.accepted > 0);
      CHECK(compare_runs<1>(b1, x1) == 0);
      CHECK(compare_runs<2>(b2, x2) == 0);
    }
}

TEST_CASE("bspline batch: a zero count writes nothing") {
  const BsplineBasis<1> b(std::array<std::vector<double>, 1>{std::vector<double>{0.0, 0.5, 1.0}}, 2);
  const Vec<1> x(0.25);
  int node = -7;
  double N = -7.0;
  Vec<1> dN(-7.0);
  CHECK(b.evaluate_fixed_points(&x, 0, nullptr, &node, &N, &dN) == 0);
  CHECK(node == -7);
  CHECK(N == -7.0);
}

namespace {

/// fill_basis_table with `threads` threads and per-point cell hints (reset
/// to 0, as bind_points leaves them) against evaluate() row by row.
template <int D> int table_differences(const BsplineBasis<D>& b, const AlignedVector<Vec<D>>& x, int threads) {
  std::vector<Index<D>> hint(x.size(), Index<D>{});
  BasisTable<D> t;
  {
    const ScopedThreads scope(threads);
    fill_basis_table<D>(b, x, nullptr, &hint, t);
  }
  REQUIRE(t.rows() == static_cast<int>(x.size()));
  int bad = 0;
  for (int p = 0; p < t.rows(); ++p) {
    Stencil<D> st;
    Index<D> cell{};
    std::string error;
    REQUIRE(per_point<D>(b, x[p], st, cell, error));
    bad += t.end(p) - t.begin(p) != st.size() || hint[p] != cell;
    if (t.end(p) - t.begin(p) == st.size())
      bad += differences<D>(st, st.size(), &t.node[t.begin(p)], &t.N[t.begin(p)], &t.dN[t.begin(p)]);
  }
  return bad;
}

/// Particles in lattice order (as a run seeds them), jittered, inside the
/// knot vectors of b.
template <int D> AlignedVector<Vec<D>> particles(const BsplineBasis<D>& b, int per_axis, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  AlignedVector<Vec<D>> x;
  int total = 1;
  for (int k = 0; k < D; ++k) total *= per_axis;
  for (int i = 0; i < total; ++i) {
    Vec<D> p;
    for (int k = 0, rest = i; k < D; ++k, rest /= per_axis) {
      const KnotVector& kv = b.knot_vector(k);
      p[k] = kv.lower() + (kv.upper() - kv.lower()) * (rest % per_axis + u(rng)) / per_axis;
    }
    x.push_back(p);
  }
  return x;
}

} // namespace

TEST_CASE("bspline batch: fill_basis_table equals evaluate() row by row, on and off the knots, 1 and 2 threads") {
  for (int p = kMinBsplineDegree; p <= kMaxBsplineDegree; ++p) {
    const BsplineBasis<1> b1 = basis_of_kind<1>(3, p, kSeed);
    const BsplineBasis<2> b2 = basis_of_kind<2>(2, p, kSeed);
    const BsplineBasis<3> b3 = basis_of_kind<3>(1, p, kSeed);
    AlignedVector<Vec<1>> x1 = particles<1>(b1, 3000, kSeed);
    AlignedVector<Vec<2>> x2 = particles<2>(b2, 60, kSeed);
    AlignedVector<Vec<3>> x3 = particles<3>(b3, 15, kSeed);
    for (int threads : {1, 2}) {
      INFO("degree " << p << ", " << threads << " threads");
      CHECK(table_differences<1>(b1, x1, threads) == 0);
      CHECK(table_differences<2>(b2, x2, threads) == 0);
      CHECK(table_differences<3>(b3, x3, threads) == 0);
    }
    // points on a knot, at an end and within round-off beyond one: rows of
    // another size (p >= 2) send the fill to its general path, degree 1
    // keeps every entry
    x1[10][0] = b1.knot_vector(0).vertices()[3];
    x1[2500][0] = b1.knot_vector(0).upper() + 0.5 * KnotVector::kBoundaryRoundoff * 2.0;
    x2[77][1] = b2.knot_vector(1).lower();
    x3[1000] = Vec<3>(b3.knot_vector(0).vertices()[2], b3.knot_vector(1).vertices()[1], x3[1000][2]);
    for (int threads : {1, 2}) {
      INFO("degree " << p << ", " << threads << " threads, points on knots");
      CHECK(table_differences<1>(b1, x1, threads) == 0);
      CHECK(table_differences<2>(b2, x2, threads) == 0);
      CHECK(table_differences<3>(b3, x3, threads) == 0);
    }
  }
}

TEST_CASE("bspline batch: a point outside stops the batch and gets the per-point error") {
  const BsplineBasis<2> b = basis_of_kind<2>(2, 2, kSeed);
  AlignedVector<Vec<2>> x = particles<2>(b, 60, kSeed + 1);
  const KnotVector& kv = b.knot_vector(0);
  const int bad = 2900; // in the second thread's half
  x[bad][0] = kv.upper() + 2.0 * KnotVector::kBoundaryRoundoff * (kv.upper() - kv.lower());
  std::string expected;
  try {
    PointQuery<2> q;
    q.x = x[bad];
    q.id = bad;
    Stencil<2> st;
    b.evaluate(q, st);
  } catch (const BasisError& e) {
    expected = "particle " + std::to_string(bad) + " at " + format_point<2>(x[bad]) + ": " + e.what();
  }
  REQUIRE(expected.find("outside the knot vectors") != std::string::npos);
  for (int threads : {1, 2}) {
    const ScopedThreads scope(threads);
    std::vector<Index<2>> hint(x.size(), Index<2>{});
    BasisTable<2> t;
    try {
      fill_basis_table<2>(b, x, nullptr, &hint, t);
      FAIL("no BasisError");
    } catch (const BasisError& e) {
      CHECK(std::string(e.what()) == expected);
    }
  }
}
