// The particle-to-node pass (engine/scatter.hpp) on 3D tables whose scatter
// blocks' node ranges overlap (more than max_block_overlap times the nodes):
// in the seeded particle order the blocks are partial slabs and the dense
// blocked scatter sums them; with the particles shuffled the sparse one does.
// Both give the same bits with 1 and 2 threads, the same bits as each other
// on one table, and the sums of the column gather to round-off.
#include <doctest/doctest.h>

#include "otmpm/basis/families.hpp"
#include "otmpm/engine/scatter.hpp"
#include "support.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>
#include <random>
#include <string>
#include <tuple>

using namespace otmpm;
using otmpm::test::ScopedThreads;

namespace {

/// The trilinear basis table of an n^3-cell unit lattice ((n + 1)^3 nodes,
/// x fastest) with 2 x 2 x 2 particles per cell, seeded in the order of the
/// bench's 3D block: x fastest over the whole block, then y, then z. Node
/// ids and weights; the gradients zero (the sums below use none, but a pass
/// hands each entry's to its add).
BasisTable<3> seeded_table(int n) {
  BasisTable<3> t;
  const int rows = 2 * n, nn = n + 1;
  for (int k = 0; k < rows; ++k)
    for (int j = 0; j < rows; ++j)
      for (int i = 0; i < rows; ++i) {
        const int c[3] = {i / 2, j / 2, k / 2};
        const double f[3] = {0.5 * i + 0.25 - c[0], 0.5 * j + 0.25 - c[1], 0.5 * k + 0.25 - c[2]};
        for (int dz = 0; dz < 2; ++dz)
          for (int dy = 0; dy < 2; ++dy)
            for (int dx = 0; dx < 2; ++dx) {
              t.node.push_back((c[0] + dx) + nn * ((c[1] + dy) + nn * (c[2] + dz)));
              t.N.push_back((dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]));
              t.dN.push_back(Vec<3>::Zero());
            }
        t.offset.push_back(static_cast<int>(t.node.size()));
      }
  return t;
}

/// Per-particle mass in [1, 2) and velocity in [-1, 1]^3 (fixed seed).
struct Carried {
  std::vector<double> m;
  std::vector<Vec<3>> v;
};

Carried carried(int particles) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> mass(1.0, 2.0), vel(-1.0, 1.0);
  Carried c;
  for (int p = 0; p < particles; ++p) {
    c.m.push_back(mass(rng));
    c.v.push_back(Vec<3>(vel(rng), vel(rng), vel(rng)));
  }
  return c;
}

/// Nodal mass and momentum from one ParticleToNodes pass, the path it took,
/// and how often each particle was updated.
struct Sums {
  std::vector<double> m;
  std::vector<Vec<3>> q;
  ScatterPath path = ScatterPath::columns;
  std::vector<int> updates;
};

template <class Rows>
Sums sums(const Rows& table, int nodes, const Carried& c, int threads,
          std::optional<ScatterPath> forced = std::nullopt, int row_width = 0) {
  const ScopedThreads scope(threads);
  Sums s;
  s.m.assign(static_cast<std::size_t>(nodes), -1.0); // clear() must overwrite
  s.q.assign(static_cast<std::size_t>(nodes), Vec<3>::Constant(-1.0));
  s.updates.assign(static_cast<std::size_t>(table.rows()), 0);
  struct Payload {
    double m;
    Vec<3> mv;
  };
  ParticleToNodes<3> scatter;
  scatter.force(forced);
  scatter.invalidate(row_width);
  scatter.run(
      table, nodes,
      [&](int p0, int p1) {
        for (int p = p0; p < p1; ++p) ++s.updates[p];
      },
      [&](int p) {
        return Payload{c.m[p], c.m[p] * c.v[p]};
      },
      [&](NodeSums<3>& acc, double N, const Vec<3>&, const Payload& w) {
        acc.m += N * w.m;
        acc.q += N * w.mv;
      },
      [&](int I, const NodeSums<3>& acc) {
        s.m[I] += acc.m;
        s.q[I] += acc.q;
      },
      [&](int I0, int I1) {
        for (int I = I0; I < I1; ++I) s.m[I] = 0.0, s.q[I] = Vec<3>::Zero();
      });
  s.path = scatter.path();
  return s;
}

/// The total of the blocks' node-index ranges (what the dense path would
/// allocate), from the table.
long long block_ranges(const BasisTable<3>& table) {
  long long total = 0;
  for (int p0 = 0; p0 < table.rows(); p0 += scatter_block) {
    const int e0 = table.begin(p0), e1 = table.end(std::min(table.rows(), p0 + scatter_block) - 1);
    const auto [lo, hi] = std::minmax_element(table.node.begin() + e0, table.node.begin() + e1);
    total += *hi - *lo + 1;
  }
  return total;
}

/// The table with its rows (particles) in a fixed random order.
BasisTable<3> shuffled(const BasisTable<3>& t) {
  std::vector<int> perm(static_cast<std::size_t>(t.rows()));
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), std::mt19937(42));
  BasisTable<3> out;
  for (const int p : perm) {
    out.node.insert(out.node.end(), t.node.begin() + t.begin(p), t.node.begin() + t.end(p));
    out.N.insert(out.N.end(), t.N.begin() + t.begin(p), t.N.begin() + t.end(p));
    out.dN.insert(out.dN.end(), t.dN.begin() + t.begin(p), t.dN.begin() + t.end(p));
    out.offset.push_back(static_cast<int>(out.node.size()));
  }
  return out;
}

/// The largest difference of a and b per node, relative to the nodal mass
/// of b (mass and each momentum component).
double largest_difference(const Sums& a, const Sums& b) {
  double worst = 0.0;
  for (std::size_t I = 0; I < b.m.size(); ++I) {
    worst = std::max(worst, std::abs(a.m[I] - b.m[I]) / b.m[I]);
    worst = std::max(worst, (a.q[I] - b.q[I]).cwiseAbs().maxCoeff() / b.m[I]);
  }
  return worst;
}

} // namespace

TEST_CASE("scatter: 3D tables whose block ranges overlap take a blocked path, bitwise identical with 1 and 2 threads") {
  const int n = 40, nodes = (n + 1) * (n + 1) * (n + 1);
  const BasisTable<3> seeded = seeded_table(n), mixed = shuffled(seeded);
  REQUIRE(seeded.rows() == 8 * n * n * n); // 512 000 particles, 63 blocks
  const Carried c = carried(seeded.rows());
  for (const bool shuffle : {false, true}) {
    CAPTURE(shuffle);
    const BasisTable<3>& table = shuffle ? mixed : seeded;
    // the property that rules out the dense path's first test: the ranges overlap
    CHECK(block_ranges(table) > static_cast<long long>(max_block_overlap) * nodes);
    const Sums one = sums(table, nodes, c, 1), two = sums(table, nodes, c, 2);
    CHECK(one.path == (shuffle ? ScatterPath::sparse : ScatterPath::dense));
    CHECK(two.path == one.path);
    CHECK(std::all_of(one.updates.begin(), one.updates.end(), [](int u) { return u == 1; }));
    CHECK(std::all_of(two.updates.begin(), two.updates.end(), [](int u) { return u == 1; }));
    CHECK(one.m == two.m);
    CHECK(one.q == two.q);
    // Against the column gather (each node's serial sum in particle order):
    // up to 64 terms per node, so any order of the sums is within 64 x 2^-53
    // of the sum of the terms' magnitudes, which is at most the nodal mass
    // (m >= 1, |v| <= 1). 1e-13 of it leaves a margin of 14.
    const Sums cols = sums(table, nodes, c, 2, ScatterPath::columns), cols1 = sums(table, nodes, c, 1, ScatterPath::columns);
    CHECK(cols.path == ScatterPath::columns);
    CHECK(std::all_of(cols.updates.begin(), cols.updates.end(), [](int u) { return u == 1; }));
    CHECK(cols1.m == cols.m);
    CHECK(cols1.q == cols.q);
    REQUIRE(*std::min_element(cols.m.begin(), cols.m.end()) > 0.0); // the bound is relative to the mass
    const double worst = largest_difference(one, cols);
    CHECK(worst <= 1e-13);
    MESSAGE("largest difference blocked - columns, relative to the nodal mass: " << worst);
  }
}

// On one table the sparse path adds, per node, the same block sums in the same
// order as the dense path (a node a block does not touch only gets +0 there).
TEST_CASE("scatter: the sparse and the dense blocked path give the same bits on one table") {
  const int n = 40, nodes = (n + 1) * (n + 1) * (n + 1);
  const BasisTable<3> table = seeded_table(n);
  const Carried c = carried(table.rows());
  const Sums dense = sums(table, nodes, c, 2, ScatterPath::dense), sparse = sums(table, nodes, c, 2, ScatterPath::sparse);
  CHECK(dense.path == ScatterPath::dense);
  CHECK(sparse.path == ScatterPath::sparse);
  CHECK(std::all_of(sparse.updates.begin(), sparse.updates.end(), [](int u) { return u == 1; }));
  CHECK(dense.m == sparse.m);
  CHECK(dense.q == sparse.q);
}

TEST_CASE("scatter: a spatially ordered 3D table below the overlap limit keeps the dense blocked path") {
  const int n = 16, nodes = (n + 1) * (n + 1) * (n + 1);
  const BasisTable<3> table = seeded_table(n);
  CHECK(block_ranges(table) <= static_cast<long long>(max_block_overlap) * nodes);
  const Carried c = carried(table.rows());
  const Sums one = sums(table, nodes, c, 1), two = sums(table, nodes, c, 2);
  CHECK(one.path == ScatterPath::dense);
  CHECK(one.m == two.m);
  CHECK(one.q == two.q);
}

TEST_CASE("scatter: rows of the fixed linear width give the bits of rows read from the offsets, on both blocked paths") {
  const int n = 12, nodes = (n + 1) * (n + 1) * (n + 1);
  const BasisTable<3> table = seeded_table(n);
  REQUIRE(linear_row_width(table) == 8);
  const Carried c = carried(table.rows());
  for (const ScatterPath path : {ScatterPath::dense, ScatterPath::sparse}) {
    const Sums any = sums(table, nodes, c, 2, path, 0), fixed = sums(table, nodes, c, 2, path, 8);
    CHECK(any.m == fixed.m);
    CHECK(any.q == fixed.q);
    CHECK(fixed.updates == std::vector<int>(static_cast<std::size_t>(table.rows()), 1));
  }
}

namespace {
/// The lattice rows of `linear` on an n^D-cell unit lattice at 2^D particles
/// per cell (a fixed random order when `shuffle`), and their full table.
template <int D> std::pair<LatticeRows<D>, BasisTable<D>> lattice_rows(int n, bool shuffle) {
  CartesianGrid<D> g;
  g.lower = Vec<D>::Zero(), g.upper = Vec<D>::Ones();
  g.cells.fill(n);
  AlignedVector<Vec<D>> x;
  for (int i = 0; i < (2 * n) * (D > 1 ? 2 * n : 1) * (D > 2 ? 2 * n : 1); ++i) {
    Vec<D> p;
    for (int k = 0, r = i; k < D; ++k, r /= 2 * n) p[k] = (r % (2 * n) + 0.25 + 0.5 * (k % 2)) / (2.0 * n);
    x.push_back(p);
  }
  if (shuffle) std::shuffle(x.begin(), x.end(), std::mt19937(42));
  std::pair<LatticeRows<D>, BasisTable<D>> out;
  REQUIRE(make_linear_basis<D>(NodeSet<D>::cartesian(g))->evaluate_lattice_rows(x, out.first));
  expand_lattice_rows(out.first, out.second);
  return out;
}

/// Every entry (I, N, grad N) a view visits, in order.
template <int D, class View>
std::vector<std::pair<int, Eigen::Matrix<double, D + 1, 1>>> visited(const View& v, int rows) {
  std::vector<std::pair<int, Eigen::Matrix<double, D + 1, 1>>> out;
  for (int p = 0; p < rows; ++p)
    v.visit_row(p, [&](int I, double N, const Vec<D>& dN) {
      Eigen::Matrix<double, D + 1, 1> w;
      w << N, dN;
      out.emplace_back(I, w);
    });
  return out;
}
} // namespace

TEST_CASE_TEMPLATE("lattice rows: a pass visits the table's entries in the table's order, bit for bit", T,
                   std::integral_constant<int, 1>, std::integral_constant<int, 2>,
                   std::integral_constant<int, 3>) {
  constexpr int D = T::value;
  const auto [rows, table] = lattice_rows<D>(5, true);
  const auto lattice = visited<D>(LatticeView<D>(rows), rows.rows());
  CHECK(lattice == visited<D>(TableView<D, (1 << D)>(table), table.rows()));
  CHECK(lattice == visited<D>(TableView<D, 0>(table), table.rows()));
  // entry by entry (the column gather's access) the same bits
  bool same = true;
  for (int e = 0; e < static_cast<int>(table.entries()); ++e) {
    double N;
    Vec<D> dN;
    rows.entry(e, N, dN);
    same = same && rows.node(e) == table.node[e] && N == table.N[e] && dN == table.dN[e];
  }
  CHECK(same);
}

namespace {
/// The compact rows `rows` (lattice or product rows) sum to the bits of
/// their full `table` on every scatter path with 1 and 2 threads, each
/// particle updated once, and their plan is the table's.
template <class Rows>
void check_same_sums(const Rows& rows, const BasisTable<3>& table, int nodes, int width) {
  const Carried c = carried(table.rows());
  for (const ScatterPath path : {ScatterPath::dense, ScatterPath::sparse, ScatterPath::columns})
    for (const int threads : {1, 2}) {
      const Sums a = sums(rows, nodes, c, threads, path, width),
                 b = sums(table, nodes, c, threads, path, width);
      CHECK(a.path == path);
      CHECK(a.m == b.m);
      CHECK(a.q == b.q);
      CHECK(a.updates == std::vector<int>(static_cast<std::size_t>(table.rows()), 1));
    }
  ParticleToNodes<3> plan;
  CHECK(plan.plan_for(rows, nodes) == ParticleToNodes<3>().plan_for(table, nodes));
}
} // namespace

TEST_CASE("lattice rows: the scatter sums them to the bits of their table on every path, 1 and 2 threads") {
  const int n = 12, nodes = (n + 1) * (n + 1) * (n + 1);
  for (const bool shuffle : {false, true}) {
    const auto [rows, table] = lattice_rows<3>(n, shuffle);
    check_same_sums(rows, table, nodes, 8);
  }
}

namespace {
/// The product rows of lme_box (gamma_lme 3: 4 - 5 lines per axis) on an
/// n^3-cell unit lattice at 2 x 2 x 2 points per cell (a fixed random order
/// when `shuffle`), and their full table.
std::pair<ProductRows<3>, BasisTable<3>> product_rows(int n, bool shuffle) {
  CartesianGrid<3> g;
  g.lower = Vec<3>::Zero(), g.upper = Vec<3>::Ones();
  g.cells.fill(n);
  BasisOptions opt;
  opt.kind = "lme_box";
  opt.values["gamma_lme"] = 3.0;
  AlignedVector<Vec<3>> x;
  for (int i = 0; i < 8 * n * n * n; ++i)
    x.push_back(Vec<3>((i % (2 * n) + 0.5) / (2.0 * n), (i / (2 * n) % (2 * n) + 0.5) / (2.0 * n),
                       (i / (4 * n * n) + 0.5) / (2.0 * n)));
  if (shuffle) std::shuffle(x.begin(), x.end(), std::mt19937(42));
  const auto basis = make_lme_box_basis<3>(NodeSet<3>::cartesian(g), opt);
  basis->bind_points(static_cast<int>(x.size()), false);
  std::pair<ProductRows<3>, BasisTable<3>> out;
  REQUIRE(basis->evaluate_product_rows(x, out.first));
  expand_product_rows(out.first, out.second);
  return out;
}
} // namespace

TEST_CASE("product rows: the scatter sums them to the bits of their table on every path, 1 and 2 threads") {
  const int n = 8, nodes = (n + 1) * (n + 1) * (n + 1);
  for (const bool shuffle : {false, true}) {
    const auto [rows, table] = product_rows(n, shuffle);
    check_same_sums(rows, table, nodes, 0);
  }
}

namespace {
/// StepRows::node_range of the rows in `r` over particle ranges of every
/// length (single rows, the summing blocks' 1 024, all of them) is the
/// smallest and the largest node of those rows in `table` (their entries).
void check_node_ranges(const StepRows<3>& r, const BasisTable<3>& table) {
  const int n = table.rows();
  std::mt19937 rng(5);
  for (int len : {1, 7, 1024, n}) {
    for (int trial = 0; trial < 20; ++trial) {
      const int p0 = std::uniform_int_distribution<int>(0, n - len)(rng), p1 = p0 + len;
      const auto first = table.node.begin() + table.begin(p0), last = table.node.begin() + table.end(p1 - 1);
      int lo = -1, hi = -1;
      r.node_range(p0, p1, lo, hi);
      CHECK(lo == *std::min_element(first, last));
      CHECK(hi == *std::max_element(first, last));
    }
  }
}
} // namespace

TEST_CASE(
    "step rows: the node range of a run of particles is the least and the greatest node of their rows") {
  for (const bool shuffle : {false, true}) {
    StepRows<3> lattice, product, table;
    BasisTable<3> lattice_table, product_table;
    std::tie(lattice.lattice, lattice_table) = lattice_rows<3>(8, shuffle);
    lattice.compact = true;
    std::tie(product.product, product_table) = product_rows(6, shuffle);
    product.factored = true;
    table.table = product_table; // the table's own rows: their entries
    check_node_ranges(lattice, lattice_table);
    check_node_ranges(product, product_table);
    check_node_ranges(table, product_table);
  }
}

namespace {
/// A particle's payload for the engine's sums (NodeSumsAdd): m, m w, f_ext
/// and V sigma, random with both signs and several magnitudes (fixed seed).
struct Loads {
  double m;
  Vec<3> mw, fext;
  Mat<3> Vs;
};

std::vector<Loads> random_loads(int n) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Loads> out(static_cast<std::size_t>(n));
  for (Loads& w : out) {
    w.m = 1.0 + std::abs(u(rng));
    w.mw = Vec<3>(u(rng), u(rng), u(rng)) * 3.0;
    w.fext = Vec<3>(u(rng), u(rng), u(rng)) * 0.1;
    for (int i = 0; i < 9; ++i) w.Vs(i) = u(rng) * std::pow(10.0, 3 * u(rng));
  }
  return out;
}

/// The nodal sums of one ParticleToNodes pass with the engine's NodeSumsAdd.
template <bool Mass, bool Momentum, bool Forces, class Rows>
std::vector<NodeSums<3>> engine_sums(const Rows& rows, int nodes, const std::vector<Loads>& loads,
                                     int threads, ScatterPath path) {
  const ScopedThreads scope(threads);
  std::vector<NodeSums<3>> out(static_cast<std::size_t>(nodes));
  ParticleToNodes<3> scatter;
  scatter.force(path);
  scatter.invalidate(8);
  scatter.run(
      rows, nodes, [](int, int) {}, [&](int p) { return loads[static_cast<std::size_t>(p)]; },
      NodeSumsAdd<3, Mass, Momentum, Forces, false>{},
      [&](int I, const NodeSums<3>& acc) { out[I].m += acc.m, out[I].q += acc.q, out[I].f += acc.f; },
      [&](int I0, int I1) { std::fill(out.begin() + I0, out.begin() + I1, NodeSums<3>{}); });
  return out;
}

/// True when a and b hold the same bits in every node's m, q and f.
bool same_sums(const std::vector<NodeSums<3>>& a, const std::vector<NodeSums<3>>& b) {
  bool same = a.size() == b.size();
  for (std::size_t I = 0; same && I < a.size(); ++I)
    same = a[I].m == b[I].m && a[I].q == b[I].q && a[I].f == b[I].f;
  return same;
}

template <bool Mass, bool Momentum, bool Forces> void check_pairs_against_table() {
  const int n = 9, nodes = (n + 1) * (n + 1) * (n + 1);
  for (const bool shuffle : {false, true}) {
    const auto [rows, table] = lattice_rows<3>(n, shuffle);
    const std::vector<Loads> loads = random_loads(rows.rows());
    for (const ScatterPath path : {ScatterPath::dense, ScatterPath::sparse})
      for (const int threads : {1, 2}) {
        const auto a = engine_sums<Mass, Momentum, Forces>(rows, nodes, loads, threads, path);
        const auto b = engine_sums<Mass, Momentum, Forces>(table, nodes, loads, threads, path);
        CHECK(same_sums(a, b));
        double largest = 0.0; // the forces are not trivially zero
        for (const NodeSums<3>& s : a) largest = std::max(largest, s.f.cwiseAbs().maxCoeff());
        CHECK(largest > 1.0);
      }
  }
}
} // namespace

TEST_CASE(
    "lattice rows: the engine's sums with forces, two corners of a 3D row at a time, give the table's bits") {
  static_assert(NodeSumsAdd<3, false, false, true, false>::pairs && LatticeView<3>::pairs);
  check_pairs_against_table<false, false, true>(); // the stress update's pass
  check_pairs_against_table<true, true, true>();   // fe's and musl's first
  check_pairs_against_table<true, false, true>();
}

TEST_CASE("lattice rows: two 3D rows' node-to-particle sums at a time give the bits of each row's own") {
  const auto [rows, table] = lattice_rows<3>(7, true);
  const int nodes = 8 * 8 * 8;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec<3>> rate(nodes), kick(nodes), move(nodes), field(nodes);
  for (int I = 0; I < nodes; ++I)
    for (auto* a : {&rate, &kick, &move, &field})
      (*a)[I] = Vec<3>(u(rng), u(rng), u(rng)) * std::pow(10.0, 2 * u(rng));
  const LatticeView<3> view(rows);
  int checked = 0;
  for (int p = 0; p + 1 < rows.rows(); p += 2) {
    TwoRowSums<3, true, true, true, true> s{
        .rate = rate.data(), .kick = kick.data(), .move = move.data(), .field = field.data()};
    view.visit_two_rows(p, [&s](int I, int J, CornerPair N, const CornerPair* dN) { s.add(I, J, N, dN); });
    for (int l = 0; l < 2; ++l) { // the engine's one-row sums (Engine::to_particles_rows)
      Vec<3> r = Vec<3>::Zero(), k = Vec<3>::Zero(), m = Vec<3>::Zero();
      Mat<3> G = Mat<3>::Zero();
      view.visit_row(p + l, [&](int I, double N, const Vec<3>& dN) {
        r += N * rate[I];
        k += N * kick[I];
        m += N * move[I];
        G.noalias() += field[I] * dN.transpose();
      });
      const bool same =
          r == s.lane(s.r, l) && k == s.lane(s.k, l) && m == s.lane(s.u, l) && G == s.gradient(l);
      checked += same;
      CHECK(same);
    }
  }
  CHECK(checked == rows.rows());
}
