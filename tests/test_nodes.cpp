// Node sets: lattice arithmetic, the perturbed layout, clouds, and the
// neighbour search (lattice arithmetic vs R-tree vs brute force).
#include "otmpm/nodes/node_set.hpp"

#include "support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <type_traits>

using namespace otmpm;
using otmpm::test::offset_grid;
using otmpm::test::random_in_box;

namespace {

/// A grid with an offset origin and a different cell count and width per axis.
template <int D> CartesianGrid<D> test_grid() { return offset_grid<D>({7, 5, 4}); }

template <int D> std::vector<int> brute_within(const NodeSet<D>& s, const Vec<D>& x, double r) {
  std::vector<int> ids;
  for (int I = 0; I < s.size(); ++I)
    if ((s.position(I) - x).squaredNorm() <= r * r) ids.push_back(I);
  return ids;
}

template <int D> std::vector<int> sorted_within(const NodeSet<D>& s, const Vec<D>& x, double r) {
  std::vector<int> ids;
  s.within(x, r, ids);
  std::sort(ids.begin(), ids.end());
  return ids;
}

/// Compares within() with brute force at random centres in (and around) the
/// bounding box [lo, hi], for radii from below to above the spacing h.
template <int D> void check_within_matches_brute_force(const NodeSet<D>& s, const Vec<D>& lo, const Vec<D>& hi,
                                                       double h, unsigned seed) {
  std::mt19937 rng(seed);
  const Vec<D> pad = Vec<D>::Constant(h);
  const double radii[] = {0.3 * h, h, 1.7 * h, 3.1 * h};
  for (int n = 0; n < 60; ++n) {
    const Vec<D> x = random_in_box<D>(rng, lo - pad, hi + pad);
    for (double r : radii) CHECK(sorted_within(s, x, r) == brute_within(s, x, r));
  }
  // Radius exactly equal to a node distance: the closed ball includes it.
  const Vec<D> x = s.position(s.size() / 2);
  CHECK(sorted_within(s, x, h) == brute_within(s, x, h));
}

template <int D> AlignedVector<Vec<D>> random_cloud(int n, unsigned seed) {
  std::mt19937 rng(seed);
  AlignedVector<Vec<D>> x;
  for (int i = 0; i < n; ++i) x.push_back(random_in_box<D>(rng, Vec<D>::Zero(), Vec<D>::Ones()));
  return x;
}

template <int D> double brute_nearest(const AlignedVector<Vec<D>>& x) {
  double m = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < x.size(); ++i)
    for (std::size_t j = i + 1; j < x.size(); ++j) m = std::min(m, (x[i] - x[j]).norm());
  return m;
}

template <int D> double brute_edge_min(const NodeSet<D>& s) {
  const CartesianGrid<D>& g = *s.grid();
  double m = std::numeric_limits<double>::infinity();
  for (int I = 0; I < s.size(); ++I)
    for (int J = 0; J < s.size(); ++J) {
      const Index<D> a = g.node_index(I), b = g.node_index(J);
      int diff = 0;
      for (int k = 0; k < D; ++k) diff += std::abs(a[k] - b[k]);
      if (diff == 1) m = std::min(m, (s.position(I) - s.position(J)).norm());
    }
  return m;
}

} // namespace

TEST_CASE_TEMPLATE("grid node id and lattice index round trip", T, std::integral_constant<int, 1>,
                   std::integral_constant<int, 2>, std::integral_constant<int, 3>) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  int expected = 1;
  for (int k = 0; k < D; ++k) expected *= g.cells[k] + 1;
  REQUIRE(g.num_nodes() == expected);
  for (int id = 0; id < g.num_nodes(); ++id) {
    const Index<D> ijk = g.node_index(id);
    CHECK(g.node_id(ijk) == id);
    for (int k = 0; k < D; ++k) CHECK((ijk[k] >= 0 && ijk[k] <= g.cells[k]));
  }
  // Axis 0 runs fastest.
  Index<D> one{};
  one[0] = 1;
  CHECK(g.node_id(one) == 1);
}

TEST_CASE_TEMPLATE("grid node positions span the box exactly", T, std::integral_constant<int, 1>,
                   std::integral_constant<int, 2>, std::integral_constant<int, 3>) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  Index<D> first{}, last{};
  for (int k = 0; k < D; ++k) last[k] = g.cells[k];
  CHECK(g.node_position(first) == g.lower);
  CHECK(g.node_position(last) == g.upper);
  // Neighbouring nodes are h apart (to round-off of lower + i h).
  const Vec<D> h = g.h();
  for (int id = 0; id < g.num_nodes(); ++id) {
    const Index<D> ijk = g.node_index(id);
    for (int k = 0; k < D; ++k) {
      if (ijk[k] == g.cells[k]) continue;
      Index<D> nb = ijk;
      ++nb[k];
      CHECK(g.node_position(nb)[k] - g.node_position(ijk)[k] == doctest::Approx(h[k]).epsilon(1e-12));
    }
  }
}

TEST_CASE_TEMPLATE("cell_of finds the cell containing the point and clamps outside points", T,
                   std::integral_constant<int, 1>, std::integral_constant<int, 2>, std::integral_constant<int, 3>) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  std::mt19937 rng(11);
  const Vec<D> h = g.h();
  for (int n = 0; n < 200; ++n) {
    const Vec<D> x = random_in_box<D>(rng, g.lower, g.upper);
    const Index<D> c = g.cell_of(x);
    Index<D> c1 = c;
    for (int k = 0; k < D; ++k) ++c1[k];
    for (int k = 0; k < D; ++k) {
      // 1e-12 h: the division in cell_of may round a point on a face either way.
      CHECK(x[k] >= g.node_position(c)[k] - 1e-12 * h[k]);
      CHECK(x[k] <= g.node_position(c1)[k] + 1e-12 * h[k]);
    }
  }
  CHECK(g.cell_of(g.upper)[0] == g.cells[0] - 1); // upper boundary: last cell
  const Index<D> below = g.cell_of(g.lower - Vec<D>::Constant(10.0));
  const Index<D> above = g.cell_of(g.upper + Vec<D>::Constant(10.0));
  for (int k = 0; k < D; ++k) {
    CHECK(below[k] == 0);
    CHECK(above[k] == g.cells[k] - 1);
  }
}

TEST_CASE("contains is the closed box and validate rejects bad grids") {
  CartesianGrid<2> g = test_grid<2>();
  CHECK(g.contains(g.lower));
  CHECK(g.contains(g.upper));
  CHECK_FALSE(g.contains(Vec<2>(g.lower[0] - 1e-12, g.lower[1])));
  CHECK_FALSE(g.contains(Vec<2>(g.upper[0], std::nan(""))));
  CHECK_NOTHROW(g.validate());
  CartesianGrid<2> bad = g;
  bad.cells[1] = 0;
  CHECK_THROWS_AS(bad.validate(), InputError);
  bad = g;
  bad.upper[0] = bad.lower[0];
  CHECK_THROWS_AS(bad.validate(), InputError);
  CHECK_THROWS_AS(NodeSet<2>::cartesian(bad), InputError);
}

TEST_CASE_TEMPLATE("cartesian node set sits on its lattice", T, std::integral_constant<int, 1>,
                   std::integral_constant<int, 2>, std::integral_constant<int, 3>) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  const NodeSet<D> s = NodeSet<D>::cartesian(g);
  CHECK(s.layout() == NodeLayout::cartesian);
  CHECK(s.on_lattice());
  REQUIRE(s.size() == g.num_nodes());
  for (int I = 0; I < s.size(); ++I) CHECK(s.position(I) == g.node_position(g.node_index(I)));
  CHECK(s.spacing() == doctest::Approx(g.h().minCoeff()).epsilon(1e-15));
  CHECK(s.initial_positions() == s.positions());
}

TEST_CASE_TEMPLATE("perturbed grid keeps boundary nodes and moves interior nodes by at most fraction*h", T,
                   std::integral_constant<int, 1>, std::integral_constant<int, 2>, std::integral_constant<int, 3>) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  const double fraction = 0.3;
  const NodeSet<D> s = NodeSet<D>::perturbed(g, fraction, 42u);
  CHECK(s.layout() == NodeLayout::perturbed);
  CHECK_FALSE(s.on_lattice());
  REQUIRE(s.grid());
  const Vec<D> h = g.h();
  int moved = 0, interior = 0;
  for (int I = 0; I < s.size(); ++I) {
    const Index<D> ijk = g.node_index(I);
    bool boundary = false;
    for (int k = 0; k < D; ++k) boundary = boundary || ijk[k] == 0 || ijk[k] == g.cells[k];
    const Vec<D> d = s.position(I) - g.node_position(ijk);
    if (boundary) {
      CHECK(d.cwiseAbs().maxCoeff() == 0.0);
    } else {
      ++interior;
      moved += d.cwiseAbs().maxCoeff() > 0.0;
      for (int k = 0; k < D; ++k) CHECK(std::abs(d[k]) <= fraction * h[k] * (1 + 1e-14));
    }
  }
  CHECK(moved == interior); // a continuous random offset is never exactly zero
  CHECK(interior > 0);
  // Reproducible with the same seed, different with another.
  CHECK(NodeSet<D>::perturbed(g, fraction, 42u).positions() == s.positions());
  CHECK(NodeSet<D>::perturbed(g, fraction, 43u).positions() != s.positions());
  CHECK(s.initial_positions() == s.positions());
}

TEST_CASE_TEMPLATE("perturbed_positions gives a box of the perturbed lattice bit for bit", T,
                   std::integral_constant<int, 1>, std::integral_constant<int, 2>, std::integral_constant<int, 3>) {
  // A rank's window of a distributed run draws its nodes' positions without the others'.
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  const NodeSet<D> s = NodeSet<D>::perturbed(g, 0.3, 42u);
  Index<D> lo, hi;
  for (int k = 0; k < D; ++k) lo[k] = 1, hi[k] = g.cells[k]; // an inner box touching no face but the last
  hi[0] = g.cells[0] + 1;                                   // and one that reaches the last face on axis 0
  const AlignedVector<Vec<D>> x = NodeSet<D>::perturbed_positions(g, 0.3, 42u, lo, hi);
  std::size_t n = 0;
  for (int I = 0; I < s.size(); ++I) {
    const Index<D> ijk = g.node_index(I);
    bool inside = true;
    for (int k = 0; k < D; ++k) inside = inside && ijk[k] >= lo[k] && ijk[k] < hi[k];
    if (!inside) continue;
    CHECK(x.at(n) == s.position(I)); // in the box's order (axis 0 fastest), the same bits
    ++n;
  }
  CHECK(n == x.size());
  CHECK(n > 0);
  hi[0] = g.cells[0] + 2;
  CHECK_THROWS_AS(NodeSet<D>::perturbed_positions(g, 0.3, 42u, lo, hi), std::invalid_argument);
}

TEST_CASE("perturbed grid rejects a fraction that could invert elements") {
  const CartesianGrid<2> g = test_grid<2>();
  CHECK_THROWS_AS(NodeSet<2>::perturbed(g, 0.5, 1u), InputError);
  CHECK_THROWS_AS(NodeSet<2>::perturbed(g, -0.1, 1u), InputError);
  CHECK_NOTHROW(NodeSet<2>::perturbed(g, 0.0, 1u));
}

TEST_CASE_TEMPLATE("within on an untouched lattice equals brute force", T, std::integral_constant<int, 1>,
                   std::integral_constant<int, 2>, std::integral_constant<int, 3>) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  const NodeSet<D> s = NodeSet<D>::cartesian(g);
  check_within_matches_brute_force<D>(s, g.lower, g.upper, g.h().maxCoeff(), 5u);
  // Lattice order is ascending ids without sorting.
  std::vector<int> ids;
  s.within(0.5 * (g.lower + g.upper), 2 * g.h().maxCoeff(), ids);
  CHECK(std::is_sorted(ids.begin(), ids.end()));
  // within appends.
  std::vector<int> more{-7};
  s.within(g.lower, 0.0, more);
  CHECK(more == std::vector<int>{-7, 0});
  // Far outside, or not a number: no node, and no out-of-range index.
  const double h = g.h().maxCoeff();
  for (const Vec<D>& far : {Vec<D>(g.upper + Vec<D>::Constant(1e3 * h)), Vec<D>(g.lower - Vec<D>::Constant(1e6 * h)),
                            Vec<D>(Vec<D>::Constant(std::numeric_limits<double>::quiet_NaN()))}) {
    std::vector<int> none;
    s.within(far, 2 * h, none);
    CHECK(none.empty());
  }
}

TEST_CASE_TEMPLATE("within on a perturbed lattice (R-tree) equals brute force", T, std::integral_constant<int, 1>,
                   std::integral_constant<int, 2>, std::integral_constant<int, 3>) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  const NodeSet<D> s = NodeSet<D>::perturbed(g, 0.4, 9u);
  check_within_matches_brute_force<D>(s, g.lower, g.upper, g.h().maxCoeff(), 6u);
}

TEST_CASE_TEMPLATE("within on a random cloud and after advect equals brute force", T, std::integral_constant<int, 1>,
                   std::integral_constant<int, 2>, std::integral_constant<int, 3>) {
  constexpr int D = T::value;
  const int n = 300;
  const double h = std::pow(1.0 / n, 1.0 / D);
  NodeSet<D> s = NodeSet<D>::cloud(random_cloud<D>(n, 3u), h);
  CHECK(s.layout() == NodeLayout::cloud);
  CHECK_FALSE(s.grid());
  check_within_matches_brute_force<D>(s, Vec<D>::Zero(), Vec<D>::Ones(), h, 7u);
  // Move every node; the stale tree must be rebuilt on the next query.
  const AlignedVector<Vec<D>> dx = random_cloud<D>(n, 4u);
  s.advect(dx);
  check_within_matches_brute_force<D>(s, Vec<D>::Zero(), 2.0 * Vec<D>::Ones(), h, 8u);
  CHECK(s.initial_positions() != s.positions());
}

TEST_CASE_TEMPLATE("within after a Cartesian lattice is advected equals brute force", T,
                   std::integral_constant<int, 1>, std::integral_constant<int, 2>, std::integral_constant<int, 3>) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  NodeSet<D> s = NodeSet<D>::cartesian(g);
  const double h = g.h().maxCoeff();
  check_within_matches_brute_force<D>(s, g.lower, g.upper, h, 1u); // before: index arithmetic
  std::mt19937 rng(2);
  AlignedVector<Vec<D>> dx;
  for (int I = 0; I < s.size(); ++I) dx.push_back(random_in_box<D>(rng, Vec<D>::Constant(-h), Vec<D>::Constant(h)));
  s.advect(dx);
  CHECK_FALSE(s.on_lattice());
  check_within_matches_brute_force<D>(s, g.lower, g.upper, h, 2u); // after: R-tree
  // set_positions back onto the lattice still counts as moved (R-tree, same answers).
  s.set_positions(s.initial_positions());
  CHECK_FALSE(s.on_lattice());
  check_within_matches_brute_force<D>(s, g.lower, g.upper, h, 3u);
}

TEST_CASE("a copied node set keeps its own search index") {
  const CartesianGrid<2> g = test_grid<2>();
  NodeSet<2> a = NodeSet<2>::perturbed(g, 0.2, 1u);
  a.prepare_search();
  NodeSet<2> b = a;
  AlignedVector<Vec<2>> dx(static_cast<std::size_t>(b.size()), Vec<2>(10.0, 0.0));
  b.advect(dx);
  const Vec<2> x = a.position(3);
  CHECK(sorted_within(a, x, 0.5) == brute_within(a, x, 0.5));
  CHECK(sorted_within(b, x, 0.5).empty()); // b moved 10 to the right
  NodeSet<2> c;
  c = b;
  CHECK(sorted_within(c, b.position(3), 0.5) == brute_within(b, b.position(3), 0.5));
}

TEST_CASE("parallel queries after prepare_search equal serial ones") {
  NodeSet<3> s = NodeSet<3>::cloud(random_cloud<3>(500, 21u), 0.1);
  s.prepare_search();
  const AlignedVector<Vec<3>> centres = random_cloud<3>(200, 22u);
  std::vector<std::vector<int>> par(centres.size());
#ifdef OTMPM_HAVE_OPENMP
#pragma omp parallel for num_threads(2)
#endif
  for (int i = 0; i < static_cast<int>(centres.size()); ++i) s.within(centres[i], 0.15, par[i]);
  for (std::size_t i = 0; i < centres.size(); ++i) CHECK(par[i] == brute_within(s, centres[i], 0.15));
}

TEST_CASE("min_spacing: grid spacing, lattice edges of a perturbed grid, nearest neighbour of a cloud") {
  const CartesianGrid<3> g = test_grid<3>();
  CHECK(NodeSet<3>::cartesian(g).min_spacing() == doctest::Approx(g.h().minCoeff()).epsilon(1e-12));
  const NodeSet<2> p = NodeSet<2>::perturbed(test_grid<2>(), 0.45, 5u);
  CHECK(p.min_spacing() == doctest::Approx(brute_edge_min(p)).epsilon(1e-15));
  CHECK(p.min_spacing() < test_grid<2>().h().minCoeff());
  for (unsigned seed : {1u, 2u, 3u}) {
    const AlignedVector<Vec<2>> x = random_cloud<2>(150, seed);
    CHECK(NodeSet<2>::cloud(x, 0.1).min_spacing() == doctest::Approx(brute_nearest(x)).epsilon(1e-15));
  }
  const AlignedVector<Vec<1>> x1 = random_cloud<1>(80, 4u);
  CHECK(NodeSet<1>::cloud(x1, 0.1).min_spacing() == doctest::Approx(brute_nearest(x1)).epsilon(1e-15));
}

TEST_CASE("node set input errors") {
  CHECK_THROWS_AS(NodeSet<2>::cloud({}, 0.1), InputError);
  CHECK_THROWS_AS(NodeSet<2>::cloud(random_cloud<2>(5, 1u), 0.0), InputError);
  AlignedVector<Vec<2>> bad = random_cloud<2>(5, 1u);
  bad[2][1] = std::nan("");
  CHECK_THROWS_AS(NodeSet<2>::cloud(bad, 0.1), InputError);
  NodeSet<2> s = NodeSet<2>::cartesian(test_grid<2>());
  CHECK_THROWS_AS(s.set_positions(AlignedVector<Vec<2>>(3)), std::invalid_argument);
  CHECK_THROWS_AS(s.advect(AlignedVector<Vec<2>>(3)), std::invalid_argument);
  CHECK(s.on_lattice()); // a rejected move leaves the set untouched
}
