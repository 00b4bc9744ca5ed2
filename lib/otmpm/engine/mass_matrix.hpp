#pragma once
/// \file mass_matrix.hpp
/// The consistent mass matrix M_IJ = sum_p N_Ip m_p N_Jp (docs/theory.md
/// sect. 8), assembled from the basis table into a sparse matrix and solved
/// with a sparse Cholesky (LDL^T) factorisation, once per step. Rows of
/// inactive nodes and of Dirichlet components are replaced by identity rows, so
/// the solve returns the prescribed value there.
#include "otmpm/basis/basis.hpp"

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
  /// value; zero otherwise) - the caller sets them. Returns the relative
  /// residual max_k |M y_k - r_k| / |r_k| of the solve. Throws
  /// std::invalid_argument before assemble() or unless r and y have one entry
  /// per node.
  double solve(const AlignedVector<Vec<D>>& r, AlignedVector<Vec<D>>& y) const;
  /// The assembled matrix (before constraints), for tests.
  const Eigen::SparseMatrix<double>& matrix() const { return M_; }

private:
  struct Factor;
  Eigen::SparseMatrix<double> M_;
  std::vector<std::unique_ptr<Factor>> factor_; // one per component
  std::vector<std::vector<char>> fixed_;        // per component: identity rows
};

extern template class MassMatrix<1>;
extern template class MassMatrix<2>;
extern template class MassMatrix<3>;

} // namespace otmpm
