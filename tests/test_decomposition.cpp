// The decomposition of a distributed run, checked in one process for any
// number of ranks (docs/architecture.md, "Distributed runs"): RCB boxes tile
// the cell lattice and balance the particles; the owned points of the ranks
// tile the point lattice (nodes and B-spline control points); a window holds
// every point its particles reach; the exchange lists of two ranks name the
// same points in the same order.
#include "otmpm/distributed/domain.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <map>
#include <numeric>
#include <random>
#include <set>

using namespace otmpm;
using namespace otmpm::distributed;

namespace {

/// Home cells of `per_cell` particles in every cell of the box [lo, hi).
template <int D> std::vector<Index<D>> particles_in(const IndexBox<D>& box, int per_cell) {
  std::vector<Index<D>> home;
  box.for_each([&](const Index<D>& c) {
    for (int i = 0; i < per_cell; ++i) home.push_back(c);
  });
  return home;
}

/// Every cell of the lattice belongs to exactly one rank's box, and owner() agrees with the boxes.
template <int D> void check_tiling(const Decomposition<D>& d) {
  IndexBox<D> all;
  all.hi = d.cells();
  all.for_each([&](const Index<D>& c) {
    int owners = 0;
    for (int r = 0; r < d.ranks(); ++r) owners += d.box(r).contains(c);
    REQUIRE(owners == 1);
    REQUIRE(d.box(d.owner(c)).contains(c));
  });
}

/// Particles per rank for home cells `home`.
template <int D> std::vector<long long> counts(const Decomposition<D>& d, const std::vector<Index<D>>& home) {
  std::vector<long long> n(static_cast<std::size_t>(d.ranks()), 0);
  for (const Index<D>& c : home) ++n[static_cast<std::size_t>(d.owner(c))];
  return n;
}

/// A 2D lattice of points (nodes: shift 0, 1 extra point; B-splines of degree p: p extra points).
PointLattice<2> lattice(int cells_x, int cells_y, int extra, int shift, int below, int above) {
  PointLattice<2> L;
  L.grid.lower = Vec<2>(0, 0);
  L.grid.upper = Vec<2>(1, 1);
  L.grid.cells = {cells_x, cells_y};
  L.points = {cells_x + extra, cells_y + extra};
  L.shift = shift;
  L.below = {below, below};
  L.above = {above, above};
  return L;
}

} // namespace

TEST_CASE("rcb: the boxes tile the lattice and balance uniform particles within one slab") {
  IndexBox<2> body{{2, 3}, {30, 17}}; // a body inside a 32 x 20 lattice
  const std::vector<Index<2>> home = particles_in<2>(body, 4);
  for (int ranks : {1, 2, 3, 4, 5, 7, 8}) {
    CAPTURE(ranks);
    const auto d = Decomposition<2>::rcb({32, 20}, ranks, home, Comm::self());
    REQUIRE(d.ranks() == ranks);
    check_tiling(d);
    // Each cut moves whole slabs: the worst rank is off its share by at most
    // a slab of the body (17 - 3 = 14 or 30 - 2 = 28 cells of 4 particles)
    // per bisection level.
    const auto n = counts<2>(d, home);
    const double mean = static_cast<double>(home.size()) / ranks;
    int levels = 0;
    while ((1 << levels) < ranks) ++levels;
    for (long long c : n) CHECK(std::abs(c - mean) <= levels * 28 * 4 + 1);
  }
}

TEST_CASE("rcb: the same home cells give the same boxes, too many ranks is an input error") {
  std::mt19937 rng(5);
  std::vector<Index<3>> home;
  for (int i = 0; i < 2000; ++i)
    home.push_back({static_cast<int>(rng() % 10), static_cast<int>(rng() % 6), static_cast<int>(rng() % 9)});
  const auto a = Decomposition<3>::rcb({10, 6, 9}, 6, home, Comm::self());
  std::reverse(home.begin(), home.end());
  const auto b = Decomposition<3>::rcb({10, 6, 9}, 6, home, Comm::self());
  check_tiling(a);
  for (int r = 0; r < 6; ++r) CHECK(a.box(r) == b.box(r));
  CHECK_THROWS_AS(Decomposition<1>::rcb({3}, 4, std::vector<Index<1>>{}, Comm::self()), InputError);
}

TEST_CASE("rcb: the tree kept in a checkpoint gives the same owners, a tree of other ranks or cells is refused") {
  std::mt19937 rng(3);
  std::vector<Index<3>> home;
  for (int i = 0; i < 3000; ++i)
    home.push_back({static_cast<int>(rng() % 12), static_cast<int>(rng() % 7), static_cast<int>(rng() % 9)});
  for (int ranks : {1, 2, 5, 16}) {
    CAPTURE(ranks);
    const auto d = Decomposition<3>::rcb({12, 7, 9}, ranks, home, Comm::self());
    const std::vector<std::int64_t> rows = d.tree_rows();
    const auto back = Decomposition<3>::from_tree({12, 7, 9}, ranks, rows);
    REQUIRE(back.has_value());
    check_tiling(*back);
    for (int r = 0; r < ranks; ++r) CHECK(back->box(r) == d.box(r));
    for (const Index<3>& c : home) CHECK(back->owner(c) == d.owner(c));
    CHECK_FALSE(Decomposition<3>::from_tree({12, 7, 10}, ranks, rows).has_value()); // another lattice
    CHECK_FALSE(Decomposition<3>::from_tree({12, 7, 9}, ranks + 1, rows).has_value());
    std::vector<std::int64_t> damaged = rows;
    damaged.pop_back();
    CHECK_FALSE(Decomposition<3>::from_tree({12, 7, 9}, ranks, damaged).has_value());
  }
}

TEST_CASE("rcb: (cell, count) runs give the same boxes as the cells repeated") {
  // What a rank's seeding gives the bisection (local_parts.cpp): runs of
  // one cell's particles, a cell in several runs and in any order.
  std::mt19937 rng(11);
  std::vector<Index<3>> home, cells;
  std::vector<std::int64_t> weight;
  for (int i = 0; i < 400; ++i) {
    const Index<3> c{static_cast<int>(rng() % 12), static_cast<int>(rng() % 7), static_cast<int>(rng() % 5)};
    const int w = static_cast<int>(rng() % 9) + 1;
    cells.push_back(c), weight.push_back(w);
    for (int k = 0; k < w; ++k) home.push_back(c);
  }
  std::shuffle(home.begin(), home.end(), rng);
  for (int ranks : {2, 3, 5, 8}) {
    CAPTURE(ranks);
    const auto a = Decomposition<3>::rcb({12, 7, 5}, ranks, home, Comm::self());
    const auto b = Decomposition<3>::rcb({12, 7, 5}, ranks, cells, weight, Comm::self());
    check_tiling(b);
    for (int r = 0; r < ranks; ++r) CHECK(a.box(r) == b.box(r));
  }
  CHECK_THROWS_AS(Decomposition<3>::rcb({12, 7, 5}, 4, cells, std::vector<std::int64_t>(3, 1), Comm::self()),
                  std::invalid_argument);
}

TEST_CASE("rcb: runs along axis 0 give the tree of their cells and each rank's particles, merged into boxes or not") {
  // Rows of runs as a rank's counting pass gives them: blocks of rows with
  // one extent and weight (merged into boxes along y, then z), rows cut
  // into pieces, single cells, a cell in several runs, in any order.
  std::mt19937 rng(5);
  const Index<3> L{14, 9, 6};
  std::vector<Index<3>> home, cells;
  std::vector<std::int64_t> weight, cell_weight;
  std::vector<int> length;
  const auto run = [&](Index<3> c, int n, int w) {
    home.push_back(c), weight.push_back(w), length.push_back(n);
    for (int t = 0; t < n; ++t) cells.push_back({c[0] + t, c[1], c[2]}), cell_weight.push_back(w);
  };
  for (int z = 0; z < L[2]; ++z)
    for (int y = 0; y < L[1]; ++y) run({2, y, z}, 9, 8); // one box: every row of x 2..10
  for (int y = 3; y < 7; ++y) run({0, y, 1}, 14, 3);     // a box of whole rows
  for (int i = 0; i < 150; ++i) {
    const int x = static_cast<int>(rng() % 14);
    run({x, static_cast<int>(rng() % 9), static_cast<int>(rng() % 6)}, 1 + static_cast<int>(rng() % (14 - x)),
        1 + static_cast<int>(rng() % 5));
  }
  for (bool shuffled : {false, true}) {
    CAPTURE(shuffled);
    if (shuffled) { // the same runs in another order (fewer merge)
      std::vector<std::size_t> order(home.size());
      std::iota(order.begin(), order.end(), 0);
      std::shuffle(order.begin(), order.end(), rng);
      std::vector<Index<3>> h;
      std::vector<std::int64_t> w;
      std::vector<int> n;
      for (std::size_t i : order) h.push_back(home[i]), w.push_back(weight[i]), n.push_back(length[i]);
      home = h, weight = w, length = n;
    }
    for (int ranks : {1, 2, 3, 7, 16}) {
      CAPTURE(ranks);
      std::vector<std::int64_t> owned;
      const auto a = Decomposition<3>::rcb(L, ranks, home, weight, length, Comm::self(), &owned);
      const auto b = Decomposition<3>::rcb(L, ranks, cells, cell_weight, Comm::self());
      check_tiling(a);
      for (int r = 0; r < ranks; ++r) CHECK(a.box(r) == b.box(r));
      std::vector<std::int64_t> want(static_cast<std::size_t>(ranks), 0);
      for (std::size_t i = 0; i < cells.size(); ++i) want[static_cast<std::size_t>(a.owner(cells[i]))] += cell_weight[i];
      CHECK(owned == want);
    }
  }
}

TEST_CASE("rcb: the cut follows the particles, not the empty lattice") {
  // All particles in the left tenth of a long 1D lattice: two ranks share them.
  std::vector<Index<1>> home = particles_in<1>({{0}, {10}}, 10);
  const auto d = Decomposition<1>::rcb({100}, 2, home, Comm::self());
  const auto n = counts<1>(d, home);
  CHECK(d.box(0).hi[0] < 10); // not the middle of the lattice
  // the weights (particles + kEmptyCellWeight per cell) differ by less than one slab's weight
  auto weight = [&](int r) {
    return static_cast<double>(n[static_cast<std::size_t>(r)]) + kEmptyCellWeight * static_cast<double>(d.box(r).count());
  };
  CHECK(std::abs(weight(0) - weight(1)) <= 10 + kEmptyCellWeight);
}

TEST_CASE("point lattice: owned points tile the points, windows hold every point the particles reach") {
  // linear (1 extra point, reach 0..1), uGIMP (reach -1..2), LME-like (-2..3), B-splines p = 2, 3
  const std::vector<PointLattice<2>> lattices{lattice(13, 9, 1, 0, 0, 1), lattice(13, 9, 1, 0, 1, 2),
                                              lattice(13, 9, 1, 0, 2, 3), lattice(13, 9, 2, 1, 0, 2),
                                              lattice(13, 9, 3, 1, 0, 3)};
  for (const PointLattice<2>& L : lattices) {
    for (int ranks : {2, 3, 5}) {
      CAPTURE(ranks);
      std::vector<Index<2>> home = particles_in<2>({{0, 0}, {13, 9}}, 1);
      const auto d = Decomposition<2>::rcb(L.grid.cells, ranks, home, Comm::self());
      std::map<long long, int> owner;
      for (int r = 0; r < ranks; ++r) {
        L.owned_points(d.box(r)).for_each([&](const Index<2>& i) {
          REQUIRE(owner.count(L.point_id(i)) == 0);
          owner[L.point_id(i)] = r;
        });
        const IndexBox<2> w = L.window(d.box(r));
        d.box(r).for_each([&](const Index<2>& c) {
          for (int k = 0; k < 2; ++k) {
            REQUIRE(w.lo[k] <= std::max(0, c[k] - L.below[k]));
            REQUIRE(w.hi[k] >= std::min(L.points[k], c[k] + L.above[k] + 1));
          }
        });
      }
      CHECK(owner.size() == static_cast<std::size_t>(L.points[0] * L.points[1]));
      // a point belongs to the owner of its cell
      for (const auto& [id, r] : owner) {
        const Index<2> i = L.point_index(id);
        CHECK(d.owner({L.cell_of_point(i[0], 0), L.cell_of_point(i[1], 1)}) == r);
      }
    }
  }
}

TEST_CASE("interior box: a position it holds has its cell in the box, far from the faces it has too") {
  // Grids with an offset origin, an awkward spacing and one far from 0 (the
  // margin's part proportional to the coordinates), and a box at the edge.
  std::mt19937_64 rng(7);
  for (const std::pair<double, double>& range : {std::pair{-0.0123, 0.987}, std::pair{1e6, 1e6 + 3.3}, std::pair{-1.0, 1.0}}) {
    const double lower = range.first, upper = range.second;
    CAPTURE(lower);
    CartesianGrid<2> g;
    g.lower = Vec<2>(lower, lower), g.upper = Vec<2>(upper, upper), g.cells = {33, 17};
    for (const IndexBox<2>& box : {IndexBox<2>{{4, 3}, {20, 11}}, IndexBox<2>{{0, 0}, {33, 17}}, IndexBox<2>{{30, 0}, {33, 5}}}) {
      const PositionBox<2> in = interior_box(g, box);
      const Vec<2> h = (g.upper - g.lower).cwiseQuotient(Vec<2>(33, 17));
      int inside = 0, far_inside = 0;
      std::uniform_real_distribution<double> u(-2.0, 35.0), tiny(-1e-9, 1e-9);
      for (int i = 0; i < 20000; ++i) {
        // Uniform positions, and positions on a cell face up to rounding.
        Vec<2> s(u(rng), u(rng));
        if (i % 2) s = Vec<2>(std::round(s[0]) + tiny(rng), std::round(s[1]) + tiny(rng));
        const Vec<2> x = g.lower + s.cwiseProduct(h);
        if (!in.contains(x)) continue;
        ++inside;
        REQUIRE(box.contains(g.cell_of(x)));
      }
      // Positions 1e-4 of a cell inside the box's faces are all held.
      std::uniform_real_distribution<double> v0(box.lo[0] + 1e-4, box.hi[0] - 1e-4), v1(box.lo[1] + 1e-4, box.hi[1] - 1e-4);
      for (int i = 0; i < 2000; ++i) far_inside += in.contains(g.lower + Vec<2>(v0(rng), v1(rng)).cwiseProduct(h));
      CHECK(inside > 300); // the smallest box holds about 2% of the positions
      CHECK(far_inside == 2000);
    }
  }
  // NaN is never inside: cell_of() decides it.
  CartesianGrid<2> g;
  g.cells = {4, 4};
  CHECK(!interior_box(g, IndexBox<2>{{0, 0}, {4, 4}}).contains(Vec<2>(std::nan(""), 0.5)));
}

TEST_CASE("node exchange: two ranks list the same points in the same order, each ghost has one owner") {
  const PointLattice<2> L = lattice(17, 11, 1, 0, 2, 3);
  std::vector<Index<2>> home = particles_in<2>({{1, 1}, {15, 10}}, 2);
  const auto d = Decomposition<2>::rcb(L.grid.cells, 5, home, Comm::self());
  std::vector<NodeExchange<2>> x;
  for (int r = 0; r < 5; ++r) x.emplace_back(L, d, r);
  auto global = [&](int r, int local) { return L.point_id(x[static_cast<std::size_t>(r)].window().index(local)); };
  for (int a = 0; a < 5; ++a) {
    const auto& A = x[static_cast<std::size_t>(a)];
    std::set<long long> ghosts;
    for (std::size_t i = 0; i < A.neighbours().size(); ++i) {
      const int b = A.neighbours()[i];
      const auto& B = x[static_cast<std::size_t>(b)];
      const auto j = static_cast<std::size_t>(std::find(B.neighbours().begin(), B.neighbours().end(), a) -
                                              B.neighbours().begin());
      REQUIRE(j < B.neighbours().size());
      REQUIRE(A.ghosts()[i].size() == B.shared()[j].size());
      for (std::size_t k = 0; k < A.ghosts()[i].size(); ++k) {
        CHECK(global(a, A.ghosts()[i][k]) == global(b, B.shared()[j][k]));
        CHECK(!A.owned()[static_cast<std::size_t>(A.ghosts()[i][k])]);
        CHECK(B.owned()[static_cast<std::size_t>(B.shared()[j][k])]);
        CHECK(ghosts.insert(global(a, A.ghosts()[i][k])).second);
      }
    }
    // every window point is owned here or a ghost of exactly one neighbour
    int owned = 0;
    for (char o : A.owned()) owned += o;
    CHECK(owned + static_cast<int>(ghosts.size()) == A.window().size());
  }
}

TEST_CASE("node exchange: one rank alone leaves the sums as they are") {
  const PointLattice<1> L = [] {
    PointLattice<1> l;
    l.grid.cells = {8};
    l.points = {9};
    l.above = {1};
    return l;
  }();
  const Decomposition<1> d({8});
  NodeExchange<1> x(L, d, 0);
  std::vector<double> m(9, 1.5);
  NodalArray f{m.data(), 1};
  x.sum(Comm::self(), {&f, 1});
  CHECK(m == std::vector<double>(9, 1.5));
  CHECK(x.neighbours().empty());
}

TEST_CASE("domain: in ul mode a stencil that reaches the outer layer of a rank's nodes stops the run") {
  // 1D lattice of 20 cells on 2 ranks; rank 0 owns cells [0, 10): with a
  // reach of 1 below, 2 above and one guard layer its window is points
  // [0, 13) and point 12 is the guard layer (point 0 is the lattice's end).
  PointLattice<1> L;
  L.grid.cells = {20};
  L.points = {21};
  L.below = {1};
  L.above = {2};
  L.guard = 1;
  std::vector<Index<1>> home;
  for (int c = 0; c < 20; ++c) home.push_back({c});
  Domain<1>::Setup setup;
  setup.lattice = L;
  setup.decomposition = Decomposition<1>::rcb({20}, 2, home, Comm::self());
  setup.nodes_move = true;
  REQUIRE(setup.decomposition.box(0).hi[0] == 10);
  const Domain<1> d(Comm::self(), setup);
  REQUIRE(d.exchange().window().box.hi[0] == 13);
  BasisTable<1> table;
  auto row = [&](std::vector<int> nodes) {
    for (int I : nodes) {
      table.node.push_back(I);
      table.N.push_back(1.0 / static_cast<double>(nodes.size()));
      table.dN.push_back(Vec<1>::Zero());
    }
    table.offset.push_back(static_cast<int>(table.node.size()));
  };
  row({0, 1});   // at the lattice's end: no guard there
  row({10, 11}); // inside
  CHECK_NOTHROW(d.check_support(table));
  row({11, 12}); // particle 2 reaches point 12
  try {
    d.check_support(table);
    FAIL("no ParticleFailure");
  } catch (const ParticleFailure& f) {
    CHECK(f.particle == 2);
    CHECK(f.what.find("outer layer") != std::string::npos);
  }
}
