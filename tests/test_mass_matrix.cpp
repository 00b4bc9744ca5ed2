// The consistent mass matrix M_IJ = sum_p N_Ip m_p N_Jp (docs/theory.md
// sect. 8) assembled from a basis table: row sums are the lumped masses, it
// is symmetric, the sparse solve is accurate, and constrained components and
// inactive nodes return the value the caller put there.
#include "otmpm/basis/basis.hpp"
#include "otmpm/engine/mass_matrix.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>

#include <doctest/doctest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

using namespace otmpm;

namespace {

/// A basis on a Cartesian grid, particles at 2 points per cell and axis
/// (offset so that they are not symmetric), masses that vary from particle
/// to particle, and the basis table. `fill` says which part of the grid (per
/// axis, in cells from the lower end) holds particles.
template <int D> struct Setup {
  std::unique_ptr<Basis<D>> basis;
  AlignedVector<Vec<D>> x;
  std::vector<double> m;
  BasisTable<D> table;
  std::vector<double> lumped; ///< m_I = sum_p N_Ip m_p

  Setup(const std::string& kind, int cells, int filled_cells) {
    CartesianGrid<D> grid;
    grid.lower = Vec<D>::Zero();
    grid.upper = Vec<D>::Constant(cells * 0.5);
    grid.cells.fill(cells);
    BasisOptions opt;
    opt.kind = kind;
    basis = make_basis<D>(opt, NodeSet<D>::cartesian(grid));
    const int per_axis = 2 * filled_cells;
    int count = 1;
    for (int k = 0; k < D; ++k) count *= per_axis;
    for (int i = 0; i < count; ++i) {
      Vec<D> p;
      int rest = i;
      for (int k = 0; k < D; ++k) {
        const int j = rest % per_axis;
        rest /= per_axis;
        p[k] = 0.5 * (j / 2 + (j % 2 ? 0.73 : 0.19)); // cell j/2, two offsets
      }
      x.push_back(p);
      m.push_back(1.0 + 0.5 * std::sin(1.0 + i)); // in [0.5, 1.5]
    }
    refill();
  }

  /// The table and the lumped masses of the current positions x.
  void refill() {
    fill_basis_table<D>(*basis, x, nullptr, nullptr, table);
    lumped.assign(basis->nodes().size(), 0.0);
    for (int p = 0; p < table.rows(); ++p)
      for (int a = table.begin(p); a < table.end(p); ++a) lumped[table.node[a]] += table.N[a] * m[p];
  }

  int nodes() const { return basis->nodes().size(); }
  std::vector<char> active() const {
    std::vector<char> a(lumped.size());
    for (std::size_t I = 0; I < a.size(); ++I) a[I] = lumped[I] > 0.0;
    return a;
  }
};

/// A deterministic right-hand side with entries O(1).
template <int D> AlignedVector<Vec<D>> rhs(int n) {
  AlignedVector<Vec<D>> r(n);
  for (int I = 0; I < n; ++I)
    for (int k = 0; k < D; ++k) r[I][k] = std::cos(0.7 * I + 2.1 * k);
  return r;
}

/// max over free rows and components of |(M y)_I - r_I| / max |r|.
template <int D>
double free_row_residual(const Eigen::SparseMatrix<double>& M, const AlignedVector<Vec<D>>& y,
                         const AlignedVector<Vec<D>>& r, const std::vector<char>& active,
                         const std::vector<char>& constrained) {
  const int n = static_cast<int>(y.size());
  double worst = 0.0, scale = 0.0;
  for (int k = 0; k < D; ++k) {
    Eigen::VectorXd yk(n), rk(n);
    for (int I = 0; I < n; ++I) {
      yk[I] = y[I][k];
      rk[I] = r[I][k];
    }
    const Eigen::VectorXd res = M * yk - rk;
    for (int I = 0; I < n; ++I) {
      scale = std::max(scale, std::abs(rk[I]));
      if (active[I] && !constrained[I * D + k]) worst = std::max(worst, std::abs(res[I]));
    }
  }
  return worst / scale;
}

// Row sums and symmetry: each entry is a sum of a few products m_p N_a N_b
// (relative round-off ~1e-16 each, tens of terms per entry), so 1e-14 of the
// largest mass is a round-off bound; a missing or doubled term is O(1e-2).
constexpr double kAssemblyRoundOff = 1e-14;
// The solve: the mass matrix of these bases is well conditioned (condition
// number ~10-100), so an LDL^T solve leaves ~1e-14 relative residual; the
// header promises < 1e-10.
constexpr double kSolveResidual = 1e-10;

template <int D> void check_row_sums_and_symmetry(const std::string& kind) {
  INFO("dimension " << D << ", basis " << kind);
  Setup<D> s(kind, 4, 4);
  MassMatrix<D> M;
  const int n = s.nodes();
  M.assemble(s.table, s.m, s.active(), std::vector<char>(n * D, 0), n);
  const Eigen::SparseMatrix<double>& A = M.matrix();
  REQUIRE(A.rows() == n);
  const double m_max = *std::max_element(s.lumped.begin(), s.lumped.end());
  const Eigen::VectorXd row_sums = A * Eigen::VectorXd::Ones(n);
  for (int I = 0; I < n; ++I) CHECK(std::abs(row_sums[I] - s.lumped[I]) <= kAssemblyRoundOff * m_max);
  const Eigen::SparseMatrix<double> At = A.transpose();
  CHECK((A - At).norm() <= kAssemblyRoundOff * m_max);
  // Off-diagonal coupling is really there (else it would be the lumped matrix).
  CHECK(A.nonZeros() > n);
}

template <int D> void check_solve(const std::string& kind) {
  INFO("dimension " << D << ", basis " << kind);
  Setup<D> s(kind, 4, 4);
  MassMatrix<D> M;
  const int n = s.nodes();
  const std::vector<char> none(n * D, 0), active = s.active();
  M.assemble(s.table, s.m, active, none, n);
  const AlignedVector<Vec<D>> r = rhs<D>(n);
  AlignedVector<Vec<D>> y(n, Vec<D>::Zero());
  M.solve(r, y);
  CHECK(M.residual(r, y) < kSolveResidual);
  CHECK(free_row_residual<D>(M.matrix(), y, r, active, none) < kSolveResidual);
}

template <int D> void check_constraints(const std::string& kind) {
  INFO("dimension " << D << ", basis " << kind);
  // Particles fill only 2 of the 4 cells per axis: the far nodes have no
  // mass and are inactive.
  Setup<D> s(kind, 4, 2);
  MassMatrix<D> M;
  const int n = s.nodes();
  const std::vector<char> active = s.active();
  int inactive = 0;
  for (char a : active) inactive += !a;
  REQUIRE(inactive > 0);
  // Constrain component 0 of every third active node (a different pattern per
  // component in 2D/3D, so that each component has its own factor).
  std::vector<char> constrained(n * D, 0);
  for (int I = 0; I < n; ++I)
    for (int k = 0; k < D; ++k)
      if (active[I] && (I + k) % 3 == 0) constrained[I * D + k] = 1;
  M.assemble(s.table, s.m, active, constrained, n);
  const AlignedVector<Vec<D>> r = rhs<D>(n);
  AlignedVector<Vec<D>> y(n, Vec<D>::Zero());
  for (int I = 0; I < n; ++I)
    for (int k = 0; k < D; ++k)
      if (constrained[I * D + k]) y[I][k] = 0.25 + 0.01 * I; // prescribed values
  const AlignedVector<Vec<D>> y0 = y;
  M.solve(r, y);
  const double residual = M.residual(r, y);
  for (int I = 0; I < n; ++I)
    for (int k = 0; k < D; ++k) {
      // Identity rows: the prescribed value (and zero on inactive nodes),
      // exactly or to round-off of the sparse LDL^T.
      if (constrained[I * D + k]) CHECK(y[I][k] == doctest::Approx(y0[I][k]).epsilon(1e-14));
      if (!active[I]) CHECK(std::abs(y[I][k]) <= 1e-14);
    }
  CHECK(residual < kSolveResidual);
  // The free rows solve M y = r with the prescribed values moved to the right.
  CHECK(free_row_residual<D>(M.matrix(), y, r, active, constrained) < kSolveResidual);
}

} // namespace

TEST_CASE("consistent mass: row sums equal the lumped masses and M is symmetric") {
  for (const char* kind : {"linear", "bspline2", "bspline3", "lme"}) {
    check_row_sums_and_symmetry<1>(kind);
    check_row_sums_and_symmetry<2>(kind);
  }
  check_row_sums_and_symmetry<3>("linear");
}

TEST_CASE("consistent mass: the solve residual is below 1e-10") {
  for (const char* kind : {"linear", "bspline2", "lme"}) {
    check_solve<1>(kind);
    check_solve<2>(kind);
  }
  check_solve<3>("bspline2");
}

TEST_CASE("consistent mass: constrained components and inactive nodes return the prescribed value") {
  for (const char* kind : {"linear", "bspline2"}) {
    check_constraints<1>(kind);
    check_constraints<2>(kind);
    check_constraints<3>(kind);
  }
}

TEST_CASE("consistent mass: an active node without mass is a singular matrix, reported as InstabilityError") {
  Setup<1> s("linear", 4, 2);
  MassMatrix<1> M;
  const int n = s.nodes();
  const std::vector<char> all_active(n, 1);
  CHECK_THROWS_AS(M.assemble(s.table, s.m, all_active, std::vector<char>(n, 0), n), InstabilityError);
  // No factor is left behind: a solve is refused until the next assembly.
  AlignedVector<Vec<1>> r(n, Vec<1>::Ones()), y(n, Vec<1>::Zero());
  CHECK_THROWS_AS(M.solve(r, y), std::invalid_argument);
}

namespace {

/// The node a failed factorisation names: with every node flagged active, a
/// node of the unfilled cells (no mass: its row of M is empty, its pivot zero).
template <int D> void check_singular_node(bool band) {
  INFO("dimension " << D << ", band " << band);
  Setup<D> s("linear", 4, 2);
  MassMatrix<D> M(band);
  const int n = s.nodes();
  int node = -2;
  try {
    M.assemble(s.table, s.m, std::vector<char>(n, 1), std::vector<char>(n * D, 0), n);
  } catch (const SingularMassError& e) {
    node = e.node;
    CHECK(std::string(e.what()).find("at node " + std::to_string(e.node)) != std::string::npos);
  }
  REQUIRE(node >= 0);
  REQUIRE(node < n);
  CHECK(s.lumped[static_cast<std::size_t>(node)] == 0.0);
  if (band) CHECK(M.band() == 1); // the band path was taken (1D)
}

} // namespace

TEST_CASE("consistent mass: a failed factorisation names the node whose pivot is zero, on both paths") {
  check_singular_node<1>(false);
  check_singular_node<1>(true);
  check_singular_node<2>(false);
  check_singular_node<3>(false);
}

namespace {

/// The matrices (signed zeros included) and the solves of a and b have the same bits.
template <int D> bool same_bits(const MassMatrix<D>& a, const MassMatrix<D>& b, int n) {
  const Eigen::SparseMatrix<double>&A = a.matrix(), &B = b.matrix();
  if (A.nonZeros() != B.nonZeros()) return false;
  for (Eigen::Index i = 0; i < A.nonZeros(); ++i)
    if (std::bit_cast<std::uint64_t>(A.valuePtr()[i]) != std::bit_cast<std::uint64_t>(B.valuePtr()[i]) ||
        A.innerIndexPtr()[i] != B.innerIndexPtr()[i])
      return false;
  const AlignedVector<Vec<D>> r = rhs<D>(n);
  AlignedVector<Vec<D>> ya(n, Vec<D>::Zero()), yb(n, Vec<D>::Zero());
  a.solve(r, ya);
  b.solve(r, yb);
  return ya == yb;
}

template <int D> void check_reuse(const std::string& kind) {
  INFO("dimension " << D << ", basis " << kind);
  Setup<D> s(kind, 4, 2);
  const int n = s.nodes();
  const std::vector<char> active = s.active();
  std::vector<char> constrained(n * D, 0);
  for (int I = 0; I < n; I += 3) constrained[I * D] = 1;
  if (kind != std::string("lme")) // a fixed stencil: the unrolled loop of its size is the one tested
    CHECK(s.table.offset[1] * s.table.rows() == s.table.offset.back());
  MassMatrix<D> kept;
  kept.assemble(s.table, s.m, active, constrained, n);
  // The next step: the same node lists with other weights and masses (the
  // particles moved inside their supports).
  for (double& N : s.table.N) N *= 1.0 + 0.01 * std::sin(17.0 * N);
  for (double& m : s.m) m *= 1.1;
  // Signed zeros: a particle without mass (its products are +0) and a
  // weight of -0 (products -0) - the places they start must keep the sign
  // the triplet assembly gives them. Every node keeps other particles' mass.
  s.m[0] = 0.0;
  s.table.N[static_cast<std::size_t>(s.table.begin(1))] = -0.0;
  kept.assemble(s.table, s.m, active, constrained, n);
  CHECK(kept.pattern_reuses() == 1);
  CHECK(kept.analysis_reuses() >= 1);
  MassMatrix<D> fresh;
  fresh.assemble(s.table, s.m, active, constrained, n);
  CHECK(fresh.pattern_reuses() == 0);
  CHECK(same_bits(kept, fresh, n));
  // A changed node list (one particle drops its last node): assembled afresh.
  Setup<D> t(kind, 4, 2);
  BasisTable<D>& tb = t.table;
  const int last = tb.end(0) - 1;
  tb.node.erase(tb.node.begin() + last), tb.N.erase(tb.N.begin() + last), tb.dN.erase(tb.dN.begin() + last);
  for (std::size_t p = 1; p < tb.offset.size(); ++p) --tb.offset[p];
  kept.assemble(tb, t.m, active, constrained, n);
  CHECK(kept.pattern_reuses() == 1);
  MassMatrix<D> fresh2;
  fresh2.assemble(tb, t.m, active, constrained, n);
  CHECK(same_bits(kept, fresh2, n));
}

} // namespace

TEST_CASE("consistent mass: a step with the last step's node lists reuses the pattern and gives the bits of a fresh assembly") {
  // Rows of 2, 3, 4 (1D), 4, 9, 16 (2D), 8, 27, 64 (3D) entries take the unrolled
  // loops of MassMatrix::sum_into_slots, LME's rows of varying size the general one.
  for (const char* kind : {"linear", "bspline2", "bspline3", "lme"}) {
    check_reuse<1>(kind);
    check_reuse<2>(kind);
  }
  check_reuse<3>("linear");
  check_reuse<3>("bspline2");
  check_reuse<3>("bspline3");
}

namespace {

/// Assembles s's table after `kept` assembled the last one; checks the path
/// taken (pattern_kept() grew by `kept_pattern`; not checked when < 0) and
/// the bits of a fresh assembly on the same path (band or not).
template <int D> void assemble_moved(MassMatrix<D>& kept, bool band, const Setup<D>& s, int kept_pattern) {
  const int n = s.nodes(), before = kept.pattern_kept(), reuses = kept.pattern_reuses();
  const std::vector<char> active = s.active(), constrained(static_cast<std::size_t>(n) * D, 0);
  kept.assemble(s.table, s.m, active, constrained, n);
  if (kept_pattern >= 0) CHECK(kept.pattern_kept() - before == kept_pattern);
  CHECK(kept.pattern_reuses() == reuses); // the node lists changed
  MassMatrix<D> fresh(band);
  fresh.assemble(s.table, s.m, active, constrained, n);
  CHECK(kept.band() == fresh.band());
  CHECK(same_bits(kept, fresh, n));
}

/// `mpm` mode: particles cross cells, so the node lists change while the
/// pattern mostly does not.
template <int D> void check_moved(const std::string& kind, bool band) {
  INFO("dimension " << D << ", basis " << kind << ", band " << band);
  Setup<D> s(kind, 4, 2); // 2^D particles in each of the first two cells per axis
  const int n = s.nodes();
  MassMatrix<D> kept(band);
  kept.assemble(s.table, s.m, s.active(), std::vector<char>(static_cast<std::size_t>(n) * D, 0), n);
  // the particles of the corner cell (every coordinate below 0.5) moved by dx along axis 0
  const auto shift_corner = [&](double from, double dx) {
    for (Vec<D>& x : s.x)
      if ((x.array() < 0.5).tail(D - 1).all() && x[0] >= from && x[0] < from + 0.5) x[0] += dx;
    s.refill();
  };
  // particles 0 and the last one (another cell of the block) swap places:
  // two rows change their lists, the products fill the pattern
  std::swap(s.x[0], s.x.back());
  s.refill();
  assemble_moved(kept, band, s, 1);
  // the same particles in the reverse order: every row's list changes and
  // the sums run in another order - looked up, the bits of a fresh assembly
  std::reverse(s.x.begin(), s.x.end());
  std::reverse(s.m.begin(), s.m.end());
  s.refill();
  assemble_moved(kept, band, s, 1);
  // the corner cell's particles two cells on, past the block: new pairs
  // (and pairs left without a particle), assembled afresh (LME's wide
  // supports may keep their pattern in the steps below: the bits are checked)
  const int afresh = kind == std::string("lme") ? -1 : 0;
  shift_corner(0.0, 1.0);
  assemble_moved(kept, band, s, afresh);
  // back: the pattern of two assemblies ago, not the last one - afresh
  shift_corner(1.0, -1.0);
  assemble_moved(kept, band, s, afresh);
  // the corner cell's particles into the next cell: every product falls on
  // the pattern, but the pairs of the corner cell alone are left without
  // a particle (the lookup would keep them as stored -0) - afresh
  shift_corner(0.0, 0.5);
  assemble_moved(kept, band, s, afresh);
}

} // namespace

TEST_CASE("consistent mass: particles that cross cells keep the pattern when their products fill it, with the bits of a fresh assembly") {
  for (const char* kind : {"linear", "bspline2", "lme"}) {
    check_moved<1>(kind, false);
    check_moved<1>(kind, true);
    check_moved<2>(kind, false);
  }
  check_moved<3>("linear", false);
}

TEST_CASE("consistent mass: new node lists that couple two nodes of the pattern not coupled before are assembled afresh") {
  // The first M couples 0-1, 1-2, 0-3 and 2-3; then the first row couples 0
  // and 2 instead, both in the pattern and every other place still filled:
  // column 2 holds rows 1, 2, 3 and column 0 rows 0, 1, 3 - no place for
  // (0, 2) or (2, 0), though each column has a row below and above.
  const auto table_of = [](std::vector<int> node, std::vector<double> N) {
    BasisTable<1> t;
    t.offset = {0, 2, 4, 6, 8, 10};
    t.node = std::move(node);
    t.N = std::move(N);
    t.dN.assign(10, Vec<1>::Zero());
    return t;
  };
  const std::vector<double> m = {1.0, 2.0, 3.0, 1.5, 2.5};
  const std::vector<char> active(4, 1), constrained(4, 0);
  const std::vector<double> N = {0.25, 0.75, 0.5, 0.5, 0.8, 0.2, 0.4, 0.6, 0.7, 0.3};
  const BasisTable<1> first = table_of({0, 1, 1, 2, 0, 3, 2, 3, 0, 1}, N);
  const BasisTable<1> coupled = table_of({0, 2, 1, 2, 0, 3, 2, 3, 0, 1}, N);
  const BasisTable<1> reordered = table_of({1, 2, 0, 1, 0, 3, 0, 1, 2, 3}, N);
  // `next` assembled after `first`: the pattern kept or not, the bits of a fresh assembly
  const auto after_first = [&](const BasisTable<1>& next, int kept_pattern) {
    MassMatrix<1> kept, fresh;
    kept.assemble(first, m, active, constrained, 4);
    kept.assemble(next, m, active, constrained, 4);
    CHECK(kept.pattern_kept() == kept_pattern);
    fresh.assemble(next, m, active, constrained, 4);
    CHECK(same_bits(kept, fresh, 4));
  };
  after_first(coupled, 0);
  after_first(reordered, 1); // the first lists in another order fill the first pattern: looked up
}

TEST_CASE("consistent mass: a place whose only products are -0 keeps -0 when the pattern is reused") {
  // Particle 0 weighs node 0 by -0: its products at (0, 1) and (1, 0) are
  // -0, the only ones there; node 0 is inactive (no mass), so the solve
  // replaces its row. The triplet assembly stores -0 at those places; the
  // reused pattern must too (it starts every place at -0 and adds).
  BasisTable<1> table;
  table.offset = {0, 2, 4};
  table.node = {0, 1, 1, 2};
  table.N = {-0.0, 1.0, 0.5, 0.5};
  table.dN.assign(4, Vec<1>::Zero());
  const std::vector<double> m = {1.0, 2.0};
  const std::vector<char> active = {0, 1, 1}, constrained(3, 0);
  MassMatrix<1> kept, fresh;
  kept.assemble(table, m, active, constrained, 3);
  kept.assemble(table, m, active, constrained, 3);
  fresh.assemble(table, m, active, constrained, 3);
  REQUIRE(kept.pattern_reuses() == 1);
  CHECK(std::signbit(fresh.matrix().coeff(0, 1)));
  CHECK(same_bits(kept, fresh, 3));
}

namespace {

/// The solve as the first implementation formed it, with Eigen alone: A = M
/// with identity rows at the fixed components, a fresh LDL^T of A, b = r -
/// M y0 (y0: the values in y at fixed components, +0 elsewhere), b = y0 at
/// the fixed rows.
template <int D>
AlignedVector<Vec<D>> reference_solve(const Eigen::SparseMatrix<double>& M, const AlignedVector<Vec<D>>& r,
                                      AlignedVector<Vec<D>> y, const std::vector<char>& active,
                                      const std::vector<char>& constrained) {
  const int n = static_cast<int>(M.rows());
  for (int k = 0; k < D; ++k) {
    std::vector<char> fixed(n);
    for (int I = 0; I < n; ++I) fixed[I] = !active[I] || constrained[I * D + k];
    Eigen::SparseMatrix<double> A = M;
    for (int col = 0; col < A.outerSize(); ++col)
      for (Eigen::SparseMatrix<double>::InnerIterator it(A, col); it; ++it)
        if (fixed[it.row()] || fixed[it.col()]) it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
    for (int I = 0; I < n; ++I)
      if (fixed[I]) A.coeffRef(I, I) = 1.0;
    A.prune(0.0);
    A.makeCompressed();
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(A);
    REQUIRE(ldlt.info() == Eigen::Success);
    Eigen::VectorXd y0 = Eigen::VectorXd::Zero(n), rk(n);
    for (int I = 0; I < n; ++I) {
      rk[I] = r[I][k];
      if (fixed[I]) y0[I] = y[I][k];
    }
    Eigen::VectorXd b = rk - M * y0;
    for (int I = 0; I < n; ++I)
      if (fixed[I]) b[I] = y0[I];
    const Eigen::VectorXd sol = ldlt.solve(b);
    for (int I = 0; I < n; ++I) y[I][k] = sol[I];
  }
  return y;
}

template <int D> bool same_bits(const AlignedVector<Vec<D>>& a, const AlignedVector<Vec<D>>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t I = 0; I < a.size(); ++I)
    for (int k = 0; k < D; ++k)
      if (std::bit_cast<std::uint64_t>(a[I][k]) != std::bit_cast<std::uint64_t>(b[I][k])) return false;
  return true;
}

/// A reused factorisation (the permuted matrix gathered from M's values)
/// solves with prescribed values (of both signs, +0 and -0) to the bits of
/// reference_solve; negative_zero: a weight of -0 puts a -0 into M.
template <int D> void check_solve_bits(const std::string& kind, bool negative_zero) {
  INFO("dimension " << D << ", basis " << kind << ", a -0 weight: " << negative_zero);
  Setup<D> s(kind, 4, 2);
  const int n = s.nodes();
  const std::vector<char> active = s.active();
  std::vector<char> constrained(n * D, 0);
  for (int I = 0; I < n; I += 3) constrained[I * D + (I / 3) % D] = 1;
  MassMatrix<D> M;
  M.assemble(s.table, s.m, active, constrained, n);
  for (double& N : s.table.N) N *= 1.0 + 0.01 * std::cos(11.0 * N);
  if (negative_zero) s.table.N[static_cast<std::size_t>(s.table.begin(1))] = -0.0;
  M.assemble(s.table, s.m, active, constrained, n);
  REQUIRE(M.pattern_reuses() == 1);
  REQUIRE(M.analysis_reuses() >= 1);
  const AlignedVector<Vec<D>> r = rhs<D>(n);
  AlignedVector<Vec<D>> y(n, Vec<D>::Zero());
  for (int I = 0; I < n; ++I)
    for (int k = 0; k < D; ++k)
      if (constrained[I * D + k]) y[I][k] = I % 2 ? 0.3 - 0.02 * I : (I % 4 ? -0.0 : 0.0);
  const AlignedVector<Vec<D>> expected = reference_solve<D>(M.matrix(), r, y, active, constrained);
  M.solve(r, y);
  CHECK(same_bits<D>(y, expected));
}

/// w with its first entry replaced by v.
std::vector<double> with_first(std::vector<double> w, double v) {
  w[0] = v;
  return w;
}

/// A 1D table of linear rows: runs of particles with the same two nodes.
BasisTable<1> runs_table(const std::vector<std::vector<int>>& nodes, const std::vector<double>& left_weight) {
  BasisTable<1> t;
  t.offset = {0};
  for (std::size_t p = 0; p < nodes.size(); ++p) {
    t.node.insert(t.node.end(), nodes[p].begin(), nodes[p].end());
    t.N.push_back(left_weight[p]);
    t.N.push_back(1.0 - left_weight[p]);
    t.offset.push_back(static_cast<int>(t.node.size()));
  }
  t.dN.assign(t.node.size(), Vec<1>::Zero());
  return t;
}

} // namespace

TEST_CASE("consistent mass: a reused factorisation solves with prescribed values to the bits of a fresh Eigen solve") {
  for (const bool negative_zero : {false, true}) {
    for (const char* kind : {"linear", "bspline2", "lme"}) {
      check_solve_bits<1>(kind, negative_zero);
      check_solve_bits<2>(kind, negative_zero);
    }
    check_solve_bits<3>("linear", negative_zero);
    check_solve_bits<3>("bspline2", negative_zero);
  }
}

TEST_CASE("consistent mass: an entry of M that becomes zero, or nonzero again, changes the factorised pattern") {
  // Particle 0 alone couples nodes 0 and 1; runs of equal node lists follow.
  const std::vector<std::vector<int>> nodes = {{0, 1}, {1, 2}, {1, 2}, {1, 2}, {2, 3}, {2, 3}, {3, 4}};
  const std::vector<double> m = {1.0, 2.0, 1.5, 0.7, 1.2, 0.9, 1.1};
  const std::vector<double> w1 = {0.5, 0.9, 0.6, 0.2, 0.35, 0.8, 0.45};
  const std::vector<double> w2 = with_first(w1, 1.0); // N = (1, 0): the product at (0, 1) is 0, the entry drops out
  const std::vector<char> active(5, 1), constrained(5, 0);
  const AlignedVector<Vec<1>> r = rhs<1>(5);
  MassMatrix<1> kept;
  int step = 0;
  for (const std::vector<double>* w : {&w2, &w1, &w2, &w1}) {
    INFO("step " << step++);
    const BasisTable<1> t = runs_table(nodes, *w);
    kept.assemble(t, m, active, constrained, 5);
    MassMatrix<1> fresh;
    fresh.assemble(t, m, active, constrained, 5);
    CHECK(same_bits(kept, fresh, 5));
    AlignedVector<Vec<1>> y(5, Vec<1>::Zero());
    kept.solve(r, y);
    CHECK(kept.residual(r, y) < kSolveResidual);
    CHECK(same_bits<1>(y, reference_solve<1>(fresh.matrix(), r, AlignedVector<Vec<1>>(5, Vec<1>::Zero()), active,
                                             constrained)));
  }
  CHECK(kept.pattern_reuses() == 3);
}

TEST_CASE("consistent mass: a row that names a node twice is summed as the triplet assembly sums it") {
  // Row 1 names node 1 twice: its two weights add into one place.
  const BasisTable<1> t = runs_table({{0, 1}, {1, 1}, {1, 1}, {1, 2}}, {0.5, 0.3, 0.4, 0.6});
  const std::vector<double> m = {1.0, 2.0, 0.5, 1.5};
  const std::vector<char> active(3, 1), constrained(3, 0);
  MassMatrix<1> kept, fresh;
  kept.assemble(t, m, active, constrained, 3);
  kept.assemble(t, m, active, constrained, 3); // the pattern reused
  fresh.assemble(t, m, active, constrained, 3);
  REQUIRE(kept.pattern_reuses() == 1);
  CHECK(same_bits(kept, fresh, 3));
  // new node lists on the same pattern, one naming node 1 twice: looked up
  // (pattern_kept), each product into its place in the triplets' order
  const BasisTable<1> moved = runs_table({{1, 2}, {0, 1}, {1, 1}, {0, 1}}, {0.7, 0.2, 0.45, 0.35});
  kept.assemble(moved, m, active, constrained, 3);
  MassMatrix<1> fresh_moved;
  fresh_moved.assemble(moved, m, active, constrained, 3);
  CHECK(kept.pattern_kept() == 1);
  CHECK(same_bits(kept, fresh_moved, 3));
}

TEST_CASE("consistent mass: another node count is assembled afresh, not looked up in the last pattern") {
  const std::vector<double> m = {1.0, 2.0, 0.5, 1.5};
  const std::vector<char> constrained(4, 0);
  MassMatrix<1> M;
  M.assemble(runs_table({{0, 1}, {1, 2}, {0, 1}, {1, 2}}, {0.5, 0.3, 0.4, 0.6}), m, std::vector<char>(3, 1),
             std::vector<char>(3, 0), 3);
  // the lists in another order (their products fill the last pattern) with
  // a fourth node, inactive: M is 4 x 4 now
  const BasisTable<1> t = runs_table({{1, 2}, {0, 1}, {1, 2}, {0, 1}}, {0.5, 0.3, 0.4, 0.6});
  const std::vector<char> active = {1, 1, 1, 0};
  M.assemble(t, m, active, constrained, 4);
  CHECK(M.pattern_kept() == 0);
  CHECK(M.matrix().rows() == 4);
  MassMatrix<1> fresh;
  fresh.assemble(t, m, active, constrained, 4);
  CHECK(same_bits(M, fresh, 4));
}

TEST_CASE("consistent mass: a negative entry of M and r = -0 give the signed zeros of the first implementation") {
  // Weights 1.2 and 0.9 (outside [0, 1]) make M_01 < 0: the first
  // implementation's b = r - M 0 adds +0 there, turning r's -0 into +0.
  const BasisTable<1> t = runs_table({{0, 1}, {0, 1}}, {1.2, 0.9});
  const std::vector<double> m = {1.0, 1.0};
  const std::vector<char> active(2, 1), constrained(2, 0);
  MassMatrix<1> M;
  M.assemble(t, m, active, constrained, 2);
  REQUIRE(M.matrix().coeff(0, 1) < 0.0);
  const AlignedVector<Vec<1>> r(2, Vec<1>::Constant(-0.0));
  AlignedVector<Vec<1>> y(2, Vec<1>::Zero());
  const AlignedVector<Vec<1>> expected = reference_solve<1>(M.matrix(), r, y, active, constrained);
  M.solve(r, y);
  CHECK(same_bits<1>(y, expected));
}

// ---------------------------------------------------------------------------
// The band path (MassMatrix(true), 1D): L D L^T in node order.
// ---------------------------------------------------------------------------

namespace {

/// max_I |a_I - b_I| / max_I |b_I| over all components.
template <int D> double relative_difference(const AlignedVector<Vec<D>>& a, const AlignedVector<Vec<D>>& b) {
  double num = 0.0, den = 0.0;
  for (std::size_t I = 0; I < a.size(); ++I) {
    num = std::max(num, (a[I] - b[I]).cwiseAbs().maxCoeff());
    den = std::max(den, b[I].cwiseAbs().maxCoeff());
  }
  return num / den;
}

// The band and the sparse LDL^T solve the same well conditioned system
// (condition number ~10-100 for these bases, below) in another order: their
// solutions differ by a few eps times the condition number.
constexpr double kBandAgreement = 1e-13;

/// The band path on a 1D basis of half bandwidth b: the solve with
/// constraints and inactive nodes agrees with the sparse path's, the fixed
/// rows return their prescribed values exactly, and the residual is at
/// round-off.
void check_band(const std::string& kind, int b) {
  INFO("basis " << kind);
  Setup<1> s(kind, 8, 5);
  const int n = s.nodes();
  const std::vector<char> active = s.active();
  REQUIRE(std::count(active.begin(), active.end(), 0) > 0);
  std::vector<char> constrained(n, 0);
  for (int I = 1; I < n; I += 4) constrained[I] = active[I];
  MassMatrix<1> band(true), sparse;
  band.assemble(s.table, s.m, active, constrained, n);
  sparse.assemble(s.table, s.m, active, constrained, n);
  CHECK(band.band() == b);
  CHECK(sparse.band() == -1);
  const AlignedVector<Vec<1>> r = rhs<1>(n);
  AlignedVector<Vec<1>> y(n, Vec<1>::Zero());
  for (int I = 0; I < n; ++I)
    if (constrained[I]) y[I][0] = 0.4 - 0.03 * I;
  AlignedVector<Vec<1>> y_sparse = y;
  const AlignedVector<Vec<1>> y0 = y;
  band.solve(r, y);
  sparse.solve(r, y_sparse);
  CHECK(relative_difference<1>(y, y_sparse) < kBandAgreement);
  CHECK(band.residual(r, y) < kBandAgreement);
  for (int I = 0; I < n; ++I) {
    if (constrained[I]) CHECK(y[I][0] == y0[I][0]);
    if (!active[I]) CHECK(y[I][0] == 0.0);
  }
}

} // namespace

TEST_CASE("consistent mass, band path: the 1D mass matrices of linear elements and B-splines are well conditioned") {
  // The premise of kBandAgreement: condition numbers of 4.2, 11.5 and 32 (64
  // uniform cells, 4 particles per cell; mass_matrix.hpp, docs/theory.md sect. 5);
  // max-ent and LME, which keep the sparse path, measure 18 and 4.2 (as the
  // header says: conditioning is not why they keep it).
  for (const auto& kind_bound : {std::pair{"linear", 5.0}, {"bspline2", 15.0}, {"bspline3", 40.0}, {"maxent", 25.0},
                                 {"lme", 5.0}}) {
    const std::string kind = kind_bound.first;
    const double bound = kind_bound.second;
    INFO("basis " << kind);
    CartesianGrid<1> grid;
    grid.lower = Vec<1>::Zero();
    grid.upper = Vec<1>::Ones();
    grid.cells = {64};
    BasisOptions opt;
    opt.kind = kind;
    const auto basis = make_basis<1>(opt, NodeSet<1>::cartesian(grid));
    AlignedVector<Vec<1>> x;
    for (int q = 0; q < 256; ++q) x.push_back(Vec<1>::Constant((q + 0.5) / 256.0));
    BasisTable<1> table;
    fill_basis_table<1>(*basis, x, nullptr, nullptr, table);
    const int n = basis->nodes().size();
    MassMatrix<1> M(true);
    M.assemble(table, std::vector<double>(x.size(), 1.0 / 256), std::vector<char>(n, 1), std::vector<char>(n, 0), n);
    const Eigen::MatrixXd dense(M.matrix());
    const Eigen::VectorXd lambda = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(dense).eigenvalues();
    MESSAGE(kind << ": condition number " << lambda.maxCoeff() / lambda.minCoeff()); // docs/theory.md sect. 5
    CHECK(lambda.minCoeff() > 0.0);
    CHECK(lambda.maxCoeff() / lambda.minCoeff() < bound);
  }
}

TEST_CASE("consistent mass, band path: linear and B-splines in 1D solve as the sparse LDL^T does") {
  check_band("linear", 1);
  check_band("bspline2", 2);
  check_band("bspline3", 3);
}

TEST_CASE("consistent mass, band path: 2D, 3D and patterns wider than kMaxBand keep the sparse LDL^T") {
  Setup<2> s2("bspline2", 4, 4);
  MassMatrix<2> m2(true);
  m2.assemble(s2.table, s2.m, s2.active(), std::vector<char>(s2.nodes() * 2, 0), s2.nodes());
  CHECK(m2.band() == -1);
  Setup<3> s3("linear", 2, 2);
  MassMatrix<3> m3(true);
  m3.assemble(s3.table, s3.m, s3.active(), std::vector<char>(s3.nodes() * 3, 0), s3.nodes());
  CHECK(m3.band() == -1);
  // A row coupling nodes 0 and kMaxBand + 1: one entry outside the band.
  const int n = MassMatrix<1>::kMaxBand + 2;
  BasisTable<1> t;
  t.offset = {0};
  for (int I = 0; I + 1 < n; ++I) {
    t.node.insert(t.node.end(), {I, I + 1});
    t.N.insert(t.N.end(), {0.6, 0.4});
    t.offset.push_back(static_cast<int>(t.node.size()));
  }
  t.node.insert(t.node.end(), {0, n - 1});
  t.N.insert(t.N.end(), {0.5, 0.5});
  t.offset.push_back(static_cast<int>(t.node.size()));
  t.dN.assign(t.node.size(), Vec<1>::Zero());
  const std::vector<double> m(static_cast<std::size_t>(t.rows()), 1.0);
  MassMatrix<1> wide(true), narrow(true);
  wide.assemble(t, m, std::vector<char>(n, 1), std::vector<char>(n, 0), n);
  CHECK(wide.band() == -1);
  t.node[t.node.size() - 1] = MassMatrix<1>::kMaxBand; // now within the band
  narrow.assemble(t, m, std::vector<char>(n, 1), std::vector<char>(n, 0), n);
  CHECK(narrow.band() == MassMatrix<1>::kMaxBand);
  AlignedVector<Vec<1>> y(n, Vec<1>::Zero());
  narrow.solve(rhs<1>(n), y);
  CHECK(narrow.residual(rhs<1>(n), y) < kBandAgreement);
}

TEST_CASE("consistent mass, band path: a reused pattern gives the bits of a fresh assembly") {
  Setup<1> s("bspline2", 8, 5);
  const int n = s.nodes();
  const std::vector<char> active = s.active();
  std::vector<char> constrained(n, 0);
  constrained[2] = 1;
  MassMatrix<1> kept(true);
  kept.assemble(s.table, s.m, active, constrained, n);
  for (double& N : s.table.N) N *= 1.0 + 0.01 * std::sin(13.0 * N);
  kept.assemble(s.table, s.m, active, constrained, n);
  constrained[2] = 0, constrained[5] = 1; // other fixed rows: the band's places are recorded again
  kept.assemble(s.table, s.m, active, constrained, n);
  REQUIRE(kept.pattern_reuses() == 2);
  MassMatrix<1> fresh(true);
  fresh.assemble(s.table, s.m, active, constrained, n);
  CHECK(kept.band() == 2);
  CHECK(same_bits(kept, fresh, n));
}

TEST_CASE("consistent mass, band path: an active node without mass is reported as InstabilityError") {
  Setup<1> s("bspline2", 6, 3);
  const int n = s.nodes();
  MassMatrix<1> M(true);
  CHECK_THROWS_AS(M.assemble(s.table, s.m, std::vector<char>(n, 1), std::vector<char>(n, 0), n), InstabilityError);
  AlignedVector<Vec<1>> r(n, Vec<1>::Ones()), y(n, Vec<1>::Zero());
  CHECK_THROWS_AS(M.solve(r, y), std::invalid_argument);
  // With the empty nodes inactive the same table factorises.
  M.assemble(s.table, s.m, s.active(), std::vector<char>(n, 0), n);
  CHECK(M.band() == 2);
  M.solve(r, y);
  CHECK(M.residual(r, y) < kBandAgreement);
}
