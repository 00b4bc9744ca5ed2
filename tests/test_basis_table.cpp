// The per-step basis table (fill_basis_table) and the basis factory
// (make_basis).
#include "otmpm/basis/basis.hpp"
#include "support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <random>
#include <stdexcept>
#include <string>


using namespace otmpm;
using otmpm::test::ScopedThreads;

namespace {

CartesianGrid<2> test_grid() {
  CartesianGrid<2> g;
  g.lower = Vec<2>(-0.3, 1.2);
  g.upper = Vec<2>(0.9, 2.0);
  g.cells = {6, 4};
  return g;
}

AlignedVector<Vec<2>> random_points(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const CartesianGrid<2> g = test_grid();
  AlignedVector<Vec<2>> x;
  for (int i = 0; i < n; ++i) x.emplace_back(g.lower[0] + u(rng) * 1.2, g.lower[1] + u(rng) * 0.8);
  return x;
}

std::unique_ptr<Basis<2>> basis(const std::string& kind, NodeSet<2> nodes) {
  BasisOptions opt;
  opt.kind = kind;
  opt.particle_half_width[0] = 0.25 * test_grid().h()[0];
  opt.particle_half_width[1] = 0.25 * test_grid().h()[1];
  return make_basis<2>(opt, std::move(nodes));
}

bool same_table(const BasisTable<2>& a, const BasisTable<2>& b) {
  return a.offset == b.offset && a.node == b.node && a.N == b.N && a.dN == b.dN;
}

/// Runs fill_basis_table with `threads` OpenMP threads (1 without OpenMP).
void fill_with_threads(int threads, const Basis<2>& b, const AlignedVector<Vec<2>>& x,
                       std::vector<Index<2>>* hint, BasisTable<2>& t) {
  const ScopedThreads scope(threads);
  fill_basis_table(b, x, nullptr, hint, t);
}

} // namespace

TEST_CASE("basis table rows equal per-point evaluation") {
  for (const auto& b : {basis("linear", NodeSet<2>::cartesian(test_grid())),
                        basis("linear", NodeSet<2>::perturbed(test_grid(), 0.3, 2u)),
                        basis("ugimp", NodeSet<2>::cartesian(test_grid()))}) {
    const AlignedVector<Vec<2>> x = random_points(101, 1u);
    BasisTable<2> t;
    fill_basis_table(*b, x, nullptr, nullptr, t);
    REQUIRE(t.rows() == 101);
    CHECK(t.entries() == t.N.size());
    CHECK(t.entries() == t.dN.size());
    for (int p = 0; p < t.rows(); ++p) {
      Stencil<2> st;
      PointQuery<2> q;
      q.x = x[p];
      b->evaluate(q, st);
      REQUIRE(t.end(p) - t.begin(p) == st.size());
      for (int a = 0; a < st.size(); ++a) {
        CHECK(t.node[t.begin(p) + a] == st.node[a]);
        CHECK(t.N[t.begin(p) + a] == st.N[a]);
        CHECK(t.dN[t.begin(p) + a] == st.dN[a]);
      }
    }
  }
}

TEST_CASE("basis table is identical with 1 and 2 threads") {
  const auto b = basis("linear", NodeSet<2>::perturbed(test_grid(), 0.3, 3u));
  // more than 2 x 512 points, so that fill_basis_table really uses two threads
  const AlignedVector<Vec<2>> x = random_points(2049, 4u);
  BasisTable<2> one, two;
  std::vector<Index<2>> hint1(x.size(), Index<2>{0, 0}), hint2 = hint1;
  fill_with_threads(1, *b, x, &hint1, one);
  fill_with_threads(2, *b, x, &hint2, two);
  CHECK(same_table(one, two));
  CHECK(hint1 == hint2);
  // Refilling reuses the table (and gives the same rows).
  fill_with_threads(2, *b, x, &hint2, two);
  CHECK(same_table(one, two));
}

TEST_CASE("basis table updates the cell hints to the containing cells") {
  const CartesianGrid<2> g = test_grid();
  const auto b = basis("linear", NodeSet<2>::cartesian(g));
  const AlignedVector<Vec<2>> x = random_points(50, 5u);
  std::vector<Index<2>> hint(x.size(), Index<2>{-1, -1});
  BasisTable<2> t;
  fill_basis_table(*b, x, nullptr, &hint, t);
  for (std::size_t p = 0; p < x.size(); ++p) CHECK(hint[p] == g.cell_of(x[p]));
}

TEST_CASE("basis table error names the particle with the lowest index") {
  const auto b = basis("linear", NodeSet<2>::cartesian(test_grid()));
  AlignedVector<Vec<2>> x = random_points(2048, 6u);
  x[7] = Vec<2>(5.0, 1.5);
  x[2000] = Vec<2>(-5.0, 1.5); // in the second thread's half
  for (int threads : {1, 2}) {
    BasisTable<2> t;
    try {
      fill_with_threads(threads, *b, x, nullptr, t);
      FAIL("no BasisError");
    } catch (const BasisError& e) {
      const std::string what = e.what();
      CHECK(what.find("particle 7 at " + format_point<2>(x[7]) + ": ") == 0);
    }
  }
}

TEST_CASE("basis table of linear: the batched fill equals per-point evaluation, also around a refused point") {
  // The lattice family fills rows in batches (evaluate_fixed_points); a point
  // just beyond the round-off slack stops the batch and is reported by the
  // per-point path with the message evaluate() gives.
  const CartesianGrid<2> g = test_grid();
  const auto b = basis("linear", NodeSet<2>::cartesian(g));
  AlignedVector<Vec<2>> x = random_points(3001, 12u);
  x[5] = g.upper; // on the boundary: last cell
  x[6] = g.lower;
  BasisTable<2> t;
  std::vector<Index<2>> hint(x.size(), Index<2>{-1, -1});
  for (int threads : {1, 2}) {
    fill_with_threads(threads, *b, x, &hint, t);
    REQUIRE(t.rows() == static_cast<int>(x.size()));
    int bad = 0;
    for (int p = 0; p < t.rows(); ++p) {
      Stencil<2> st;
      Index<2> cell{-1, -1};
      PointQuery<2> q;
      q.x = x[p];
      q.cell_hint = &cell;
      b->evaluate(q, st);
      bad += t.end(p) - t.begin(p) != st.size() || hint[p] != cell;
      for (int a = 0; a < st.size(); ++a)
        bad += t.node[t.begin(p) + a] != st.node[a] || t.N[t.begin(p) + a] != st.N[a] ||
               t.dN[t.begin(p) + a] != st.dN[a];
    }
    CHECK(bad == 0);
  }
  x[1700] = Vec<2>(g.upper[0], g.upper[1] + 1e-9 * g.h()[1]);
  std::string expected;
  try {
    PointQuery<2> q;
    q.x = x[1700];
    q.id = 1700;
    Stencil<2> st;
    b->evaluate(q, st);
  } catch (const BasisError& e) {
    expected = "particle 1700 at " + format_point<2>(x[1700]) + ": " + e.what();
  }
  REQUIRE(!expected.empty());
  for (int threads : {1, 2}) {
    try {
      fill_with_threads(threads, *b, x, nullptr, t);
      FAIL("no BasisError");
    } catch (const BasisError& e) {
      CHECK(std::string(e.what()) == expected);
    }
  }
}

TEST_CASE("basis table: empty input and mismatched side arrays") {
  const auto b = basis("linear", NodeSet<2>::cartesian(test_grid()));
  BasisTable<2> t;
  fill_basis_table(*b, AlignedVector<Vec<2>>{}, nullptr, nullptr, t);
  CHECK(t.rows() == 0);
  CHECK(t.entries() == 0u);
  const AlignedVector<Vec<2>> x = random_points(5, 7u);
  AlignedVector<Vec<2>> lambda(3);
  CHECK_THROWS_AS(fill_basis_table(*b, x, &lambda, nullptr, t), std::invalid_argument);
  std::vector<Index<2>> hint(2);
  CHECK_THROWS_AS(fill_basis_table(*b, x, nullptr, &hint, t), std::invalid_argument);
  // Empty side arrays mean "none".
  AlignedVector<Vec<2>> no_lambda;
  std::vector<Index<2>> no_hint;
  CHECK_NOTHROW(fill_basis_table(*b, x, &no_lambda, &no_hint, t));
  CHECK(t.rows() == 5);
}

namespace {

/// The rows of a per-point evaluation of each point (no per-point state).
BasisTable<2> rows_one_by_one(const Basis<2>& b, const AlignedVector<Vec<2>>& x) {
  BasisTable<2> t;
  for (std::size_t p = 0; p < x.size(); ++p) {
    Stencil<2> st;
    PointQuery<2> q;
    q.x = x[p];
    b.evaluate(q, st);
    t.node.insert(t.node.end(), st.node.begin(), st.node.end());
    t.N.insert(t.N.end(), st.N.begin(), st.N.end());
    t.dN.insert(t.dN.end(), st.dN.begin(), st.dN.end());
    t.offset.push_back(static_cast<int>(t.node.size()));
  }
  return t;
}

std::unique_ptr<Basis<2>> lme(double gamma) {
  BasisOptions opt;
  opt.kind = "lme";
  opt.values["gamma_lme"] = gamma;
  return make_basis<2>(opt, NodeSet<2>::cartesian(test_grid()));
}

} // namespace

TEST_CASE("basis table: two threads place each chunk's rows where they were in the last fill - the same rows") {
  // From the second fill on, two threads write each chunk of rows in place
  // where the chunk's rows were; rows that moved (larger or smaller) are
  // gathered after. Points that stay and points that move by up to 0.3 h
  // (rows of new sizes): every fill gives the rows of one thread and of
  // each point.
  const auto b = lme(3.0);
  AlignedVector<Vec<2>> x = random_points(3001, 21u);
  std::mt19937 rng(5u);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  BasisTable<2> two;
  for (int fill = 0; fill < 4; ++fill) {
    CAPTURE(fill);
    if (fill == 2) // the points move: the rows change size in every chunk
      for (Vec<2>& p : x)
        for (int k = 0; k < 2; ++k)
          p[k] = std::clamp(p[k] + u(rng) * test_grid().h()[k], test_grid().lower[k], test_grid().upper[k]);
    BasisTable<2> one;
    fill_with_threads(1, *b, x, nullptr, one);
    fill_with_threads(2, *b, x, nullptr, two);
    CHECK(same_table(one, two));
    CHECK(same_table(one, rows_one_by_one(*b, x)));
  }
}

TEST_CASE("basis table: a table holding another fill of as many points changes the cost, never the rows") {
  const AlignedVector<Vec<2>> x = random_points(3001, 22u);
  const auto b = lme(3.0);
  const BasisTable<2> expected = rows_one_by_one(*b, x);
  BasisTable<2> wider, narrower, empty, short_arrays;
  fill_with_threads(1, *lme(1.5), x, nullptr, wider);   // larger rows: gaps to close
  fill_with_threads(1, *lme(8.0), x, nullptr, narrower); // smaller rows: rows beyond their place
  empty.offset.assign(x.size() + 1, 0); // every row empty (a fill that failed)
  short_arrays = wider;
  short_arrays.N.resize(10); // not a fill: ignored
  for (BasisTable<2>* t : {&wider, &narrower, &empty, &short_arrays}) {
    fill_with_threads(2, *b, x, nullptr, *t);
    CHECK(same_table(*t, expected));
  }
}

TEST_CASE("basis table: the error of rows placed in the last fill's places names the particle with the lowest index") {
  AlignedVector<Vec<2>> x = random_points(3001, 23u);
  const auto b = lme(3.0);
  BasisTable<2> t;
  fill_with_threads(2, *b, x, nullptr, t);
  x[2500] = Vec<2>(-5.0, 1.5); // outside the nodes' hull, in the second thread's half
  x[1800] = Vec<2>(5.0, 1.5);
  try {
    fill_with_threads(2, *b, x, nullptr, t);
    FAIL("no BasisError");
  } catch (const BasisError& e) {
    CHECK(std::string(e.what()).find("particle 1800 at " + format_point<2>(x[1800]) + ": ") == 0);
  }
  x[1800] = x[1799];
  x[2500] = x[2499];
  fill_with_threads(2, *b, x, nullptr, t); // after a failure the table fills again
  CHECK(same_table(t, rows_one_by_one(*b, x)));
}

TEST_CASE("make_basis dispatches on the kind name") {
  const CartesianGrid<2> g = test_grid();
  for (const char* kind : {"linear", "ugimp", "bspline2", "bspline3", "lme", "maxent"})
    CHECK(basis(kind, NodeSet<2>::cartesian(g))->kind() == kind);
}

TEST_CASE("make_basis rejects unknown kinds and layouts a family cannot use") {
  const CartesianGrid<2> g = test_grid();
  CHECK_THROWS_WITH_AS(basis("quintic", NodeSet<2>::cartesian(g)), doctest::Contains("quintic"), InputError);
  CHECK_THROWS_WITH_AS(basis("ugimp", NodeSet<2>::perturbed(g, 0.2, 1u)),
                       doctest::Contains("ugimp needs an unperturbed Cartesian grid"), InputError);
  AlignedVector<Vec<2>> x{Vec<2>(0, 0), Vec<2>(1, 0), Vec<2>(0, 1), Vec<2>(1, 1)};
  for (const char* kind : {"linear", "ugimp", "bspline2", "bspline3"})
    CHECK_THROWS_AS(basis(kind, NodeSet<2>::cloud(x, 1.0)), InputError);
}

TEST_CASE("linear_row_width: 2^D only when every row holds the linear stencil, and row_entries agrees with the offsets") {
  // The linear basis on its grid: every point inside a cell has 4 entries.
  const auto lin = basis("linear", NodeSet<2>::cartesian(test_grid()));
  BasisTable<2> t;
  fill_basis_table(*lin, random_points(57, 3u), nullptr, nullptr, t);
  REQUIRE(linear_row_width(t) == 4);
  for (int p = 0; p < t.rows(); ++p) {
    const auto [e0, e1] = row_entries<4>(t.offset.data(), p);
    const auto [f0, f1] = row_entries<0>(t.offset.data(), p);
    CHECK(e0 == t.begin(p));
    CHECK(e1 == t.end(p));
    CHECK(f0 == t.begin(p));
    CHECK(f1 == t.end(p));
  }
  // uGIMP rows differ in length: no fixed width.
  const auto ugimp = basis("ugimp", NodeSet<2>::cartesian(test_grid()));
  BasisTable<2> u;
  fill_basis_table(*ugimp, random_points(57, 3u), nullptr, nullptr, u);
  CHECK(linear_row_width(u) == 0);
  // Equal row lengths other than 2^D, and one short row among linear ones.
  BasisTable<2> three;
  three.offset = {0, 3, 6, 9};
  CHECK(linear_row_width(three) == 0);
  BasisTable<2> ragged;
  ragged.offset = {0, 4, 8, 11, 15};
  CHECK(linear_row_width(ragged) == 0);
  BasisTable<2> empty; // no particle: trivially fixed
  CHECK(linear_row_width(empty) == 4);
}

TEST_CASE("uniform_row_width: the common row size when every row has it and 0 otherwise") {
  CHECK(uniform_row_width({0, 3, 6, 9}) == 3);
  CHECK(uniform_row_width({0, 9}) == 9);
  CHECK(uniform_row_width({0, 3, 6, 8}) == 0);      // a short last row
  CHECK(uniform_row_width({0, 2, 5, 8}) == 0);      // a short first row
  CHECK(uniform_row_width({0, 4, 8, 11, 15}) == 0); // one short row between
  CHECK(uniform_row_width({0, 0, 0}) == 0);         // rows without entries
  CHECK(uniform_row_width({0}) == 0);               // no rows
  CHECK(uniform_row_width({}) == 0);
  // Offsets that would agree with p S only modulo 2^32 are uneven rows too.
  CHECK(uniform_row_width({0, 1 << 30, 1 << 30, 1 << 30, 1 << 30, 1 << 30}) == 0);
}
