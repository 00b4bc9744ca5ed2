// The particle-to-node pass (engine/scatter.hpp) on a 3D table in the seeded
// particle order, whose scatter blocks are partial slabs: their node ranges
// overlap too much for the dense blocked scatter, so the sparse one sums them.
// It gives the same bits with 1 and 2 threads and the sums of the column
// gather to round-off.
#include <doctest/doctest.h>

#include "otmpm/engine/scatter.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

using namespace otmpm;

namespace {

/// The trilinear basis table of an n^3-cell unit lattice ((n + 1)^3 nodes,
/// x fastest) with 2 x 2 x 2 particles per cell, seeded in the order of the
/// bench's 3D block: x fastest over the whole block, then y, then z. Only
/// node ids and weights (the sums below use no gradients).
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

Sums sums(const BasisTable<3>& table, int nodes, const Carried& c, int threads, bool blocks) {
#ifdef OTMPM_HAVE_OPENMP
  const int saved = omp_get_max_threads();
  omp_set_num_threads(threads);
#else
  (void)threads;
#endif
  Sums s;
  s.m.assign(static_cast<std::size_t>(nodes), -1.0); // clear() must overwrite
  s.q.assign(static_cast<std::size_t>(nodes), Vec<3>::Constant(-1.0));
  s.updates.assign(static_cast<std::size_t>(table.rows()), 0);
  struct Payload {
    double m;
    Vec<3> mv;
  };
  ParticleToNodes<3> scatter;
  scatter.allow_blocks(blocks);
  scatter.run(
      table, nodes,
      [&](int p0, int p1) {
        for (int p = p0; p < p1; ++p) ++s.updates[p];
      },
      [&](int p) { return Payload{c.m[p], c.m[p] * c.v[p]}; },
      [&](NodeSums<3>& acc, int e, const Payload& w) {
        acc.m += table.N[e] * w.m;
        acc.q += table.N[e] * w.mv;
      },
      [&](int I, const NodeSums<3>& acc) {
        s.m[I] += acc.m;
        s.q[I] += acc.q;
      },
      [&](int I0, int I1) {
        for (int I = I0; I < I1; ++I) s.m[I] = 0.0, s.q[I] = Vec<3>::Zero();
      });
  s.path = scatter.path();
#ifdef OTMPM_HAVE_OPENMP
  omp_set_num_threads(saved);
#endif
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

} // namespace

TEST_CASE("scatter: a 3D slab order takes the sparse blocked path, bitwise identical with 1 and 2 threads") {
  const int n = 40, nodes = (n + 1) * (n + 1) * (n + 1);
  const BasisTable<3> table = seeded_table(n);
  REQUIRE(table.rows() == 8 * n * n * n); // 512 000 particles, 63 blocks
  // the property that rules out the dense path: the ranges overlap
  CHECK(block_ranges(table) > static_cast<long long>(max_block_overlap) * nodes);
  const Carried c = carried(table.rows());
  const Sums one = sums(table, nodes, c, 1, true), two = sums(table, nodes, c, 2, true);
  CHECK(one.path == ScatterPath::sparse);
  CHECK(two.path == ScatterPath::sparse);
  CHECK(std::all_of(one.updates.begin(), one.updates.end(), [](int u) { return u == 1; }));
  CHECK(std::all_of(two.updates.begin(), two.updates.end(), [](int u) { return u == 1; }));
  CHECK(one.m == two.m);
  CHECK(one.q == two.q);
  // Against the column gather (each node's serial sum in particle order): up
  // to 64 terms per node, so any order of the sums is within 64 x 2^-53 of
  // the sum of the terms' magnitudes, which is at most the nodal mass
  // (m >= 1, |v| <= 1). 1e-13 of it leaves a margin of 14.
  const Sums cols = sums(table, nodes, c, 2, false);
  CHECK(cols.path == ScatterPath::columns);
  const Sums cols1 = sums(table, nodes, c, 1, false);
  CHECK(cols1.m == cols.m);
  CHECK(cols1.q == cols.q);
  CHECK(std::all_of(cols.updates.begin(), cols.updates.end(), [](int u) { return u == 1; }));
  REQUIRE(*std::min_element(cols.m.begin(), cols.m.end()) > 0.0); // every node carries mass: the bound is relative to it
  double worst = 0.0;
  bool differs = false;
  for (int I = 0; I < nodes; ++I) {
    worst = std::max(worst, std::abs(one.m[I] - cols.m[I]) / cols.m[I]);
    worst = std::max(worst, (one.q[I] - cols.q[I]).cwiseAbs().maxCoeff() / cols.m[I]);
    differs = differs || one.m[I] != cols.m[I];
  }
  CHECK(worst <= 1e-13);
  MESSAGE("largest difference sparse - columns, relative to the nodal mass: " << worst << "; masses "
                                                                               << std::string(differs ? "differ" : "all equal"));
}

TEST_CASE("scatter: a spatially ordered 3D table below the overlap limit keeps the dense blocked path") {
  const int n = 16, nodes = (n + 1) * (n + 1) * (n + 1);
  const BasisTable<3> table = seeded_table(n);
  CHECK(block_ranges(table) <= static_cast<long long>(max_block_overlap) * nodes);
  const Carried c = carried(table.rows());
  const Sums one = sums(table, nodes, c, 1, true), two = sums(table, nodes, c, 2, true);
  CHECK(one.path == ScatterPath::dense);
  CHECK(one.m == two.m);
  CHECK(one.q == two.q);
}
