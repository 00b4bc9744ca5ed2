#pragma once
/// \file mass_matrix.hpp
/// The consistent mass matrix M_IJ = sum_p N_Ip m_p N_Jp (docs/theory.md
/// sect. 8), assembled from the basis table into a sparse matrix and solved
/// with a sparse Cholesky (LDL^T) factorisation, once per step. Rows of
/// inactive nodes and of Dirichlet components are replaced by identity rows, so
/// the solve returns the prescribed value there. Work that depends only on
/// the sparsity is kept between steps: while the table's node lists are
/// unchanged the products are summed straight into the last step's matrix
/// (in the order the triplet assembly sums them: the same bits); when they
/// changed but their products still fill exactly the last pattern (`mpm`
/// mode, particles crossing cells) the places are looked up in it and the
/// same holds; and while
/// a component's pattern is unchanged its factorisation skips the ordering
/// and symbolic analysis and the permuted matrix it factorises is gathered
/// straight from M's values (again the same bits).
///
/// In 1D the nodes are numbered along the axis, so M is a band matrix: half
/// bandwidth 1 for linear elements, p for B-splines of degree p. With the band
/// path on (the engine's choice for the bases of fixed stencils: linear
/// elements and B-splines) and M's half bandwidth in node order at most
/// kMaxBand, M is factorised as a band, M = L D L^T in node order without
/// pivoting or fill (O(n b^2) per step, no ordering or symbolic analysis),
/// and solved by the band's two sweeps. These mass matrices are well
/// conditioned (64 cells, 4 particles per cell: condition number 4.2 linear,
/// 11.5 bspline2, 32 bspline3), so the band path, another order of the same
/// kind of operations, moves a solve by ~1e-15 relative to the sparse one.
/// Max-ent and LME keep the sparse LDL^T (their matrices are as well
/// conditioned, 18 and 4.2, tested): the band would save them about 1% of a step,
/// whose basis evaluation dominates, and an `otm` run's velocities, formed
/// as (x - x_prev) / dt, would move with the last bits of x (measured 4e-11
/// on the max-ent fixed bar, 5e-10 on the LME Dyka bar). A given
/// pattern always takes the same path.
#include "otmpm/basis/basis.hpp"
#include "otmpm/core.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <string>

namespace otmpm {

/// The consistent mass matrix could not be factorised: the pivot of `node`'s
/// row (the first zero one in the order of elimination) is zero or not
/// finite - an active node without mass, or a node whose shape function is,
/// at the particles, a combination of the others' (a cell its particles fill
/// only partly: a lone particle or a sliver of them beside a new cell).
class SingularMassError : public InstabilityError {
public:
  SingularMassError(const std::string& what, int node) : InstabilityError(what), node(node) {}
  int node; ///< the node id (-1: not known)
};

template <int D> class MassMatrix {
public:
  /// band: take the band path where M's pattern allows (see above).
  explicit MassMatrix(bool band = false);
  ~MassMatrix();
  /// Assembles M from the table and the particle masses and factorises it.
  /// constrained[I*D + k] marks a fixed component (identity row for that
  /// component's solve); inactive[I] marks a node with no mass. Throws
  /// std::invalid_argument unless m_p has one mass per table row, active
  /// `nodes` and constrained nodes * D flags, and every table node id lies in
  /// [0, nodes); InputError for a mass that is negative or not finite;
  /// SingularMassError, naming the node, when the factorisation fails.
  void assemble(const BasisTable<D>& table, const std::vector<double>& m_p,
                const std::vector<char>& active, const std::vector<char>& constrained, int nodes);
  /// y = M^{-1} r per component; constrained components and inactive nodes
  /// take the value already in y (for velocity-like fields: the prescribed
  /// value; zero otherwise) - the caller sets them. Throws
  /// std::invalid_argument before assemble() or unless r and y have one entry
  /// per node.
  void solve(const AlignedVector<Vec<D>>& r, AlignedVector<Vec<D>>& y) const;
  /// rho_Ik = sum_{J free} M_IJ y_Jk on the rows solve() leaves to the
  /// caller (constrained components and inactive nodes; free: the others),
  /// zero elsewhere: the inertial reaction of those rows.
  void constrained_rows_product(const AlignedVector<Vec<D>>& y, AlignedVector<Vec<D>>& rho) const;
  /// The relative residual max_k |M y_k - r_k| / |r_k| of the free rows (not
  /// constrained, active) of a solve's y (for tests; solve() does not form it).
  double residual(const AlignedVector<Vec<D>>& r, const AlignedVector<Vec<D>>& y) const;
  /// The assembled matrix (before constraints), for tests.
  const Eigen::SparseMatrix<double>& matrix() const { return M_; }

  /// Assemblies of the last calls that reused the table's pattern, and
  /// factorisations that reused the symbolic analysis (for tests).
  int pattern_reuses() const { return pattern_reuses_; }
  /// Assemblies whose node lists changed but whose products fell on the
  /// last pattern, every entry of it (slots_on_pattern; for tests).
  int pattern_kept() const { return pattern_kept_; }
  int analysis_reuses() const { return analysis_reuses_; }
  /// The half bandwidth of the band factorisation in use, or -1 when the
  /// sparse LDL^T is (band path off, 2D, 3D, or a pattern wider than kMaxBand).
  int band() const { return band_; }
  /// The widest half bandwidth the band path takes (bspline3's).
  static constexpr int kMaxBand = 3;

private:
  struct Factor;
  void assemble_values(const BasisTable<D>& table, const std::vector<double>& m_p, int nodes, bool same);
  void sum_into_slots(const BasisTable<D>& table, const std::vector<double>& m_p);
  bool slots_on_pattern(const BasisTable<D>& table);
  void keep_node_lists(const BasisTable<D>& table);
  template <int S> void sum_rows(const BasisTable<D>& table, const std::vector<double>& m_p);
  void factorise(int k, const std::vector<char>& fixed, std::vector<std::unique_ptr<Factor>>& old);
  void factorise_band(Factor& f, const std::vector<char>& fixed) const;
  [[noreturn]] static void singular(int node);
  void map_gather(Factor& f, const std::vector<char>& fixed);
  bool gather(Factor& f) const;
  void move_prescribed(int k, const std::vector<char>& fixed, const AlignedVector<Vec<D>>& y,
                       Eigen::VectorXd& b) const;
  Eigen::SparseMatrix<double> M_;
  std::vector<std::unique_ptr<Factor>> factor_; // one per component
  std::vector<std::vector<char>> fixed_;        // per component: identity rows
  // The table's node lists of the last assembly and, per product of that
  // order, its place in M_'s values; row_size_: the size of every row of
  // that table when they are all equal, else 0.
  std::vector<int> offset_, node_, slot_;
  std::vector<int> runs_; // rows of one size: the first row of each run with one node list, then the row count
  int row_size_ = 0;
  bool band_allowed_ = false;
  int band_ = -1;               // half bandwidth of the band path (band()), -1: the sparse LDL^T
  long long version_ = 0;       // M_'s pattern: counts the triplet assemblies
  bool free_columns_add_nothing_ = false; // every value of M_ finite and >= +0 (move_prescribed)
  int pattern_reuses_ = 0, analysis_reuses_ = 0, pattern_kept_ = 0;
  std::vector<char> hit_; // slots_on_pattern: the entries of M_ that received a product
};

extern template class MassMatrix<1>;
extern template class MassMatrix<2>;
extern template class MassMatrix<3>;

} // namespace otmpm
