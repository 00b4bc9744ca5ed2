#pragma once
/// \file mass_matrix.hpp
/// The consistent mass matrix M_IJ = sum_p N_Ip m_p N_Jp (docs/theory.md
/// sect. 8), assembled from the basis table into a sparse matrix and solved
/// with a sparse Cholesky (LDL^T) factorisation, once per step. Rows of
/// inactive nodes and of Dirichlet components are replaced by identity rows, so
/// the solve returns the prescribed value there. Work that depends only on
/// the sparsity is kept between steps: while the table's node lists are
/// unchanged the products are summed straight into the last step's matrix
/// (in the order the triplet assembly sums them: the same bits), and while
/// a component's pattern is unchanged its factorisation skips the ordering
/// and symbolic analysis and the permuted matrix it factorises is gathered
/// straight from M's values (again the same bits).
#include "otmpm/basis/basis.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace otmpm {

template <int D> class MassMatrix {
public:
  MassMatrix();
  ~MassMatrix();
  /// Assembles M from the table and the particle masses and factorises it.
  /// constrained[I*D + k] marks a fixed component (identity row for that
  /// component's solve); inactive[I] marks a node with no mass. Throws
  /// std::invalid_argument unless m_p has one mass per table row, active
  /// `nodes` and constrained nodes * D flags, and every table node id lies in
  /// [0, nodes); InputError for a mass that is negative or not finite;
  /// InstabilityError when the factorisation fails.
  void assemble(const BasisTable<D>& table, const std::vector<double>& m_p,
                const std::vector<char>& active, const std::vector<char>& constrained, int nodes);
  /// y = M^{-1} r per component; constrained components and inactive nodes
  /// take the value already in y (for velocity-like fields: the prescribed
  /// value; zero otherwise) - the caller sets them. Throws
  /// std::invalid_argument before assemble() or unless r and y have one entry
  /// per node.
  void solve(const AlignedVector<Vec<D>>& r, AlignedVector<Vec<D>>& y) const;
  /// The relative residual max_k |M y_k - r_k| / |r_k| of the free rows (not
  /// constrained, active) of a solve's y (for tests; solve() does not form it).
  double residual(const AlignedVector<Vec<D>>& r, const AlignedVector<Vec<D>>& y) const;
  /// The assembled matrix (before constraints), for tests.
  const Eigen::SparseMatrix<double>& matrix() const { return M_; }

  /// Assemblies of the last calls that reused the table's pattern, and
  /// factorisations that reused the symbolic analysis (for tests).
  int pattern_reuses() const { return pattern_reuses_; }
  int analysis_reuses() const { return analysis_reuses_; }

private:
  struct Factor;
  void assemble_values(const BasisTable<D>& table, const std::vector<double>& m_p, int nodes);
  void sum_into_slots(const BasisTable<D>& table, const std::vector<double>& m_p);
  template <int S> void sum_rows(const BasisTable<D>& table, const std::vector<double>& m_p);
  void factorise(int k, const std::vector<char>& fixed, std::vector<std::unique_ptr<Factor>>& old);
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
  long long version_ = 0;       // M_'s pattern: counts the triplet assemblies
  bool free_columns_add_nothing_ = false; // every value of M_ finite and >= +0 (move_prescribed)
  int pattern_reuses_ = 0, analysis_reuses_ = 0;
};

extern template class MassMatrix<1>;
extern template class MassMatrix<2>;
extern template class MassMatrix<3>;

} // namespace otmpm
