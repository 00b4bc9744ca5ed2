// Reused buffers of the max-ent evaluation and of the basis-table fill give
// the same bits as fresh ones: MaxEntBasis::evaluate no longer clears the
// Stencil (its arrays keep their size from the last point, the scratch arrays
// only grow) and fill_basis_table writes the rows through a cursor into
// arrays kept from the last fill. Each check compares a reused buffer with a
// fresh one bit for bit (exact equality), over points with stencils of
// different sizes (interior, edges, corners), a point that fails in between,
// and tables of growing and shrinking point counts.
#include "otmpm/basis/families.hpp"
#include "otmpm/basis/lme.hpp"
#include "support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <memory>
#include <random>
#include <string>
#include <vector>

using namespace otmpm;
using namespace otmpm::test;

namespace {

BasisOptions options(const std::string& kind) {
  BasisOptions opt;
  opt.kind = kind;
  opt.values["gamma_lme"] = 3.0;
  opt.values["d_max"] = 2.0;
  return opt;
}

template <int D> std::unique_ptr<Basis<D>> make(const std::string& kind, const NodeSet<D>& nodes) {
  return kind == "lme" ? make_lme_basis<D>(nodes, options(kind)) : make_maxent_basis<D>(nodes, options(kind));
}

template <int D> void require_same(const Stencil<D>& a, const Stencil<D>& b) {
  REQUIRE(a.size() == b.size());
  REQUIRE(a.N.size() == a.node.size());
  REQUIRE(a.dN.size() == a.node.size());
  for (int i = 0; i < a.size(); ++i) {
    CHECK(a.node[i] == b.node[i]);
    CHECK(a.N[i] == b.N[i]);
    for (int k = 0; k < D; ++k) CHECK(a.dN[i][k] == b.dN[i][k]);
  }
}

/// Points of the unit box with stencils of different sizes (random interior
/// points, points next to faces and edges, corners), in an order where the
/// stencil size goes up and down.
template <int D> AlignedVector<Vec<D>> mixed_points(const NodeSet<D>& nodes, unsigned seed) {
  AlignedVector<Vec<D>> pts = unit_box_points<D>(nodes, 20, seed);
  std::mt19937 rng(seed);
  std::shuffle(pts.begin(), pts.end(), rng);
  pts.push_back(Vec<D>::Zero());
  pts.push_back(Vec<D>::Constant(0.5));
  pts.push_back(Vec<D>::Ones());
  return pts;
}

template <int D> void reused_stencil(const std::string& kind, const NodeSet<D>& nodes) {
  const auto basis = make<D>(kind, nodes);
  const AlignedVector<Vec<D>> pts = mixed_points<D>(basis->nodes(), 11);
  Stencil<D> reused;
  int sizes_differ = 0, last = -1;
  for (std::size_t p = 0; p < pts.size(); ++p) {
    INFO(kind << " D = " << D << " point " << p);
    evaluate_at<D>(*basis, pts[p], reused);
    Stencil<D> fresh;
    evaluate_at<D>(*basis, pts[p], fresh);
    require_same<D>(reused, fresh);
    sizes_differ += last >= 0 && last != reused.size();
    last = reused.size();
    if (p == pts.size() / 2) { // a failing point in between leaves nothing behind
      CHECK_THROWS_AS(evaluate_at<D>(*basis, Vec<D>::Constant(3.0), reused), BasisError);
    }
  }
  CHECK(sizes_differ > 0); // the sequence did change the stencil size
}

template <int D> void require_same_table(const BasisTable<D>& a, const BasisTable<D>& b) {
  REQUIRE(a.offset == b.offset);
  REQUIRE(a.node == b.node);
  REQUIRE(a.N == b.N);
  REQUIRE(a.dN.size() == b.dN.size());
  for (std::size_t e = 0; e < a.dN.size(); ++e)
    for (int k = 0; k < D; ++k) CHECK(a.dN[e][k] == b.dN[e][k]);
}

template <int D> void reused_table(const std::string& kind, const NodeSet<D>& nodes) {
  const auto basis = make<D>(kind, nodes);
  const AlignedVector<Vec<D>> all = mixed_points<D>(basis->nodes(), 5);
  BasisTable<D> reused;
  // many points, few, then all again: the arrays shrink and grow
  for (const std::size_t count : {all.size(), std::size_t{3}, std::size_t{0}, all.size() / 2, all.size()}) {
    INFO(kind << " D = " << D << " points " << count);
    const AlignedVector<Vec<D>> x(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(count));
    fill_basis_table<D>(*basis, x, nullptr, nullptr, reused);
    BasisTable<D> fresh;
    fill_basis_table<D>(*basis, x, nullptr, nullptr, fresh);
    require_same_table<D>(reused, fresh);
    CHECK(reused.rows() == static_cast<int>(count));
    CHECK(reused.entries() == static_cast<std::size_t>(reused.offset.back()));
  }
  // a failing point: the error names it, and the next fill is whole again
  AlignedVector<Vec<D>> bad = all;
  bad[bad.size() / 2] = Vec<D>::Constant(3.0);
  CHECK_THROWS_AS(fill_basis_table<D>(*basis, bad, nullptr, nullptr, reused), BasisError);
  fill_basis_table<D>(*basis, all, nullptr, nullptr, reused);
  BasisTable<D> fresh;
  fill_basis_table<D>(*basis, all, nullptr, nullptr, fresh);
  require_same_table<D>(reused, fresh);
}

template <int D> void both(const NodeSet<D>& nodes) {
  for (const char* kind : {"lme", "maxent"}) {
    reused_stencil<D>(kind, nodes);
    reused_table<D>(kind, nodes);
  }
}

} // namespace

TEST_CASE("basis reuse: a reused Stencil and table give the bits of fresh ones for lme and maxent on lattices in 1D 2D and 3D") {
  both<1>(NodeSet<1>::cartesian(unit_grid<1>(cells_for<1>())));
  both<2>(NodeSet<2>::cartesian(unit_grid<2>(cells_for<2>())));
  both<3>(NodeSet<3>::cartesian(unit_grid<3>(cells_for<3>())));
}

TEST_CASE("basis reuse: the same for lme and maxent on perturbed nodes and after the nodes moved") {
  both<2>(NodeSet<2>::perturbed(unit_grid<2>(cells_for<2>()), 0.3, 4));
  auto moved = NodeSet<2>::cartesian(unit_grid<2>(cells_for<2>()));
  AlignedVector<Vec<2>> x = moved.positions();
  for (std::size_t I = 0; I < x.size(); ++I) x[I] += Vec<2>(1e-3 * static_cast<double>(I % 3), 0.0);
  moved.set_positions(x);
  both<2>(moved);
}
