// Verlet (skin) lists (lib/otmpm/nodes/neighbour_lists.hpp): the candidates
// followed by the exact distance test must give exactly NodeSet::within, in
// the same order, while points and nodes move; lists must be reused while
// valid and rebuilt when not; and a basis table filled with them must be
// the table filled without them, bit for bit.
#include "otmpm/basis/basis.hpp"
#include "otmpm/nodes/neighbour_lists.hpp"
#include "support.hpp"

#include <doctest/doctest.h>

#include <random>
#include <stdexcept>

using namespace otmpm;
using namespace otmpm::test;

namespace {

/// The ids within r of x among the candidates, in candidate order.
template <int D>
std::vector<int> filtered(const NodeSet<D>& nodes, std::span<const int> candidates, const Vec<D>& x,
                          double r) {
  std::vector<int> out;
  for (int I : candidates)
    if ((nodes.position(I) - x).squaredNorm() <= r * r) out.push_back(I);
  return out;
}

template <int D> std::vector<int> direct(const NodeSet<D>& nodes, const Vec<D>& x, double r) {
  std::vector<int> out;
  nodes.within(x, r, out);
  return out;
}

/// Random points inside [0.2, 0.8]^D.
template <int D> AlignedVector<Vec<D>> inner_points(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.2, 0.8);
  AlignedVector<Vec<D>> x(static_cast<std::size_t>(n));
  for (auto& p : x)
    for (int k = 0; k < D; ++k) p[k] = u(rng);
  return x;
}

/// Moves every point by a random vector of length <= step.
template <int D> void jiggle(AlignedVector<Vec<D>>& x, double step, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (auto& p : x) {
    Vec<D> d;
    for (int k = 0; k < D; ++k) d[k] = u(rng);
    p += step * d / std::sqrt(double(D));
  }
}

/// Runs `rounds` rounds of queries with the points moving by up to step h
/// and, when move_nodes, the nodes by `drift` plus up to jitter h (the points
/// by `drift` too); checks every answer against the direct search and
/// returns the number of lists rebuilt after the first two rounds.
template <int D>
long long check_rounds(NodeSet<D> nodes, double r, double step, bool move_nodes, const Vec<D>& drift,
                       int rounds, double jitter = 0.02) {
  const double h = nodes.spacing();
  AlignedVector<Vec<D>> x = inner_points<D>(200, 17);
  NeighbourLists<D> lists;
  std::mt19937 rng(4);
  std::vector<int> scratch;
  long long rebuilt = 0;
  for (int round = 0; round < rounds; ++round) {
    lists.prepare(nodes, static_cast<int>(x.size()), r);
    for (int p = 0; p < static_cast<int>(x.size()); ++p)
      REQUIRE(filtered(nodes, lists.candidates(nodes, p, x[p], scratch), x[p], r) == direct(nodes, x[p], r));
    if (round >= 2) rebuilt += lists.rebuilt();
    jiggle(x, step * h, rng);
    if (move_nodes) {
      AlignedVector<Vec<D>> dx(static_cast<std::size_t>(nodes.size()));
      std::uniform_real_distribution<double> u(-1.0, 1.0);
      for (auto& d : dx)
        for (int k = 0; k < D; ++k) d[k] = drift[k] + jitter * h * u(rng);
      nodes.advect(dx);
      for (auto& p : x) p += drift;
    }
  }
  return rebuilt;
}

} // namespace

TEST_CASE("neighbour lists: exactly the direct search on a fixed lattice, lists reused while valid") {
  const auto nodes = NodeSet<2>::cartesian(unit_grid<2>(16));
  const double h = nodes.spacing();
  // 30 rounds of moves of at most 0.004 h: far below the skin (0.25 h), so
  // after the round that sizes the lists and the round that fills them no
  // list is rebuilt.
  CHECK(check_rounds<2>(nodes, 2.1 * h, 0.004, false, Vec<2>::Zero(), 30) == 0);
  // moves of 0.2 h: lists go stale and are rebuilt, answers stay exact
  CHECK(check_rounds<2>(nodes, 2.1 * h, 0.2, false, Vec<2>::Zero(), 10) > 0);
}

TEST_CASE("neighbour lists: exactly the direct search on moving nodes (R-tree), 1D to 3D") {
  // The assertions are the REQUIREs of check_rounds (every answer equals the
  // direct search); how many lists get rebuilt is not asserted here.
  check_rounds<1>(NodeSet<1>::perturbed(unit_grid<1>(20), 0.3, 2), 0.15, 0.01, true, Vec<1>(0.003), 20);
  check_rounds<2>(NodeSet<2>::perturbed(unit_grid<2>(12), 0.3, 3), 0.2, 0.01, true, Vec<2>(0.01, -0.02), 15);
  check_rounds<3>(NodeSet<3>::perturbed(unit_grid<3>(6), 0.3, 4), 0.35, 0.02, true, Vec<3>(0.01, 0.0, 0.02), 8);
}

TEST_CASE("neighbour lists: a rigid translation of nodes and points rebuilds nothing") {
  // Both move by 0.22 h per round, 10 rounds (2.2 h in all): relative to the
  // common translation nothing moves but the 0.002 h jitter of the nodes
  // (a random walk of 10 steps, far below half the skin, 0.125 h).
  const auto nodes = NodeSet<2>::cartesian(unit_grid<2>(12));
  const double h = nodes.spacing();
  CHECK(check_rounds<2>(nodes, 2.0 * h, 0.0, true, Vec<2>(0.2 * h, 0.1 * h), 10, 0.002) == 0);
}

TEST_CASE("neighbour lists: capacity grows after the first round, bad arguments throw") {
  const auto nodes = NodeSet<2>::cartesian(unit_grid<2>(10));
  NeighbourLists<2> lists;
  CHECK(lists.capacity() == 0);
  std::vector<int> scratch;
  const Vec<2> x(0.5, 0.5);
  lists.prepare(nodes, 1, 0.25);
  const auto first = lists.candidates(nodes, 0, x, scratch);
  CHECK(first.data() == scratch.data()); // did not fit: the caller's scratch
  lists.prepare(nodes, 1, 0.25);
  CHECK(lists.capacity() >= static_cast<int>(first.size()));
  const auto second = lists.candidates(nodes, 0, x, scratch);
  CHECK(second.data() != scratch.data()); // stored
  CHECK(lists.rebuilt() == 1);
  lists.candidates(nodes, 0, x, scratch);
  CHECK(lists.rebuilt() == 1); // reused
  CHECK_THROWS_AS(lists.prepare(nodes, -1, 0.25), std::invalid_argument);
  CHECK_THROWS_AS(lists.prepare(nodes, 1, 0.0), std::invalid_argument);
  CHECK_THROWS_AS(lists.candidates(nodes, 1, x, scratch), std::invalid_argument);
}

TEST_CASE(
    "neighbour lists: LME basis tables with and without lists are identical while particles and nodes move") {
  BasisOptions opt;
  opt.kind = "lme";
  opt.values["gamma_lme"] = 3.0;
  auto basis = make_basis<2>(opt, NodeSet<2>::cartesian(unit_grid<2>(12)));
  AlignedVector<Vec<2>> x = inner_points<2>(300, 8);
  AlignedVector<Vec<2>> lambda_a(x.size(), Vec<2>::Zero()), lambda_b = lambda_a;
  NeighbourLists<2> lists;
  std::mt19937 rng(6);
  const double h = basis->nodes().spacing();
  for (int step = 0; step < 12; ++step) {
    BasisTable<2> with, without;
    fill_basis_table<2>(*basis, x, &lambda_a, nullptr, with, &lists);
    fill_basis_table<2>(*basis, x, &lambda_b, nullptr, without, nullptr);
    REQUIRE(with.offset == without.offset);
    REQUIRE(with.node == without.node);
    REQUIRE(with.N == without.N);
    REQUIRE(with.dN == without.dN);
    jiggle(x, 0.05 * h, rng);
    if (step >= 6) { // ul-like: the nodes move too
      AlignedVector<Vec<2>> dx(static_cast<std::size_t>(basis->nodes().size()), Vec<2>(0.01 * h, -0.03 * h));
      basis->nodes().advect(dx);
      basis->nodes_moved(dx);
    }
  }
}
