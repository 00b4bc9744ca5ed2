/// \file mass_matrix.cpp
/// Assembly, constraint rows and LDL^T solve of the consistent mass matrix.
#include "otmpm/engine/mass_matrix.hpp"

#include <Eigen/SparseCholesky>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace otmpm {

template <int D> struct MassMatrix<D>::Factor {
  /// Eigen's LDL^T, with its numeric factorisation of a matrix that is
  /// already permuted (the step Eigen's factorize() takes after permuting).
  struct Ldlt : Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> {
    void factorize_permuted(const Eigen::SparseMatrix<double>& ap) { this->template factorize_preordered<true>(ap); }
  };
  Ldlt ldlt;
  Eigen::SparseMatrix<double> A;
  bool analysed = false; ///< ldlt holds the ordering and analysis of A's pattern
  /// The gather (valid for M_'s pattern `version`, these fixed flags and
  /// these zero entries of M_): ap is the upper triangle of P A P^T that
  /// factorize() forms, source[i] the place in M_'s values of ap's value i
  /// (-1: an identity diagonal, 1.0), zeros the places of M_ that A left out
  /// as exact zeros.
  Eigen::SparseMatrix<double> ap;
  std::vector<int> source, zeros;
  std::vector<char> fixed;
  long long version = -1;
  /// The band path (MassMatrix::band() = b >= 0): row i of the unit lower
  /// factor L at band[i (b + 1) + t], t = 0..b-1 for the columns i - b + t
  /// (zero before column 0; place b unused), and 1 / D in inv_d (D while
  /// band_factorise runs).
  /// band_source[s]: the place in M_'s values of the matrix entry at band
  /// place s, or kIdentity (a fixed row's diagonal, 1.0) or kZero (valid for
  /// `version` and `fixed`, as the gather of the sparse path).
  std::vector<double> band, inv_d;
  std::vector<int> band_source;
  static constexpr int kIdentity = -1, kZero = -2;
};

namespace {

/// True when the compressed matrices a and b have the same nonzero pattern.
bool same_pattern(const Eigen::SparseMatrix<double>& a, const Eigen::SparseMatrix<double>& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols() || a.nonZeros() != b.nonZeros()) return false;
  const auto n = static_cast<std::size_t>(a.outerSize()) + 1, nnz = static_cast<std::size_t>(a.nonZeros());
  return std::equal(a.outerIndexPtr(), a.outerIndexPtr() + n, b.outerIndexPtr()) &&
         std::equal(a.innerIndexPtr(), a.innerIndexPtr() + nnz, b.innerIndexPtr());
}

/// True when every id lies in [0, nodes): the top bit of I | (nodes - 1 - I),
/// in unsigned arithmetic, is set exactly when I < 0 or I >= nodes (also for
/// nodes = 0). Adds, ors and one test: the loop vectorises.
bool nodes_in_range(const std::vector<int>& node, int nodes) {
  const unsigned last = static_cast<unsigned>(nodes) - 1u;
  unsigned out = 0;
  for (const int I : node) out |= static_cast<unsigned>(I) | (last - static_cast<unsigned>(I));
  return (out >> 31) == 0;
}

/// True when every value is finite and >= +0: the sign and exponent bits of
/// such a double, plus one, stay below 0x800 (+Inf and NaN reach 0x800, a
/// negative number 0x801 or more). Shifts, adds and ors: the loop vectorises.
/// -0.0 is refused here (its sign bit is set).
bool finite_non_negative(const double* v, std::size_t n) {
  std::uint64_t out = 0;
  for (std::size_t i = 0; i < n; ++i) out |= (std::bit_cast<std::uint64_t>(v[i]) >> 52) + 1u;
  return (out & 0x1800u) == 0;
}

/// True when every mass is finite and >= +0 (a mass of -0.0 is refused here,
/// which only sends the caller to its exact test, which accepts it).
bool masses_valid(const std::vector<double>& m_p) { return finite_non_negative(m_p.data(), m_p.size()); }

/// The argument checks of MassMatrix::assemble: consistent sizes, node ids in
/// range (Eigen only asserts them, and not at all under NDEBUG), finite
/// non-negative masses. O(entries), once per assembly; ids_checked: the
/// table's offsets and node ids are those of the last assembly, checked then
/// for the same node count (the pass over the ids is left out).
template <int D>
void check_assembly(const BasisTable<D>& table, const std::vector<double>& m_p, const std::vector<char>& active,
                    const std::vector<char>& constrained, int nodes, bool ids_checked) {
  const std::string f = "MassMatrix::assemble: ";
  require<std::invalid_argument>(nodes >= 0, f, "nodes must be >= 0, got ", nodes);
  require<std::invalid_argument>(!table.offset.empty() && table.offset.front() == 0 &&
                                     static_cast<std::size_t>(table.offset.back()) == table.node.size() &&
                                     table.N.size() == table.node.size(),
                                 f, "the basis table is malformed (offset, node and N do not agree)");
  require<std::invalid_argument>(m_p.size() == static_cast<std::size_t>(table.rows()), f, "m_p has ", m_p.size(),
                                 " masses for ", table.rows(), " table rows");
  require<std::invalid_argument>(active.size() == static_cast<std::size_t>(nodes), f, "active has ", active.size(),
                                 " flags for ", nodes, " nodes");
  require<std::invalid_argument>(constrained.size() == static_cast<std::size_t>(nodes) * D, f, "constrained has ",
                                 constrained.size(), " flags for ", nodes, " nodes x ", D, " components");
  // The loops run every step: one branch-free pass each (vectorised), the
  // offending entry looked for only when a pass fails.
  if (!ids_checked && !nodes_in_range(table.node, nodes)) [[unlikely]]
    for (std::size_t a = 0; a < table.node.size(); ++a)
      require<std::invalid_argument>(table.node[a] >= 0 && table.node[a] < nodes, f, "table entry ", a, " names node ",
                                     table.node[a], ", outside [0, ", nodes, ")");
  if (!masses_valid(m_p)) [[unlikely]]
    for (std::size_t p = 0; p < m_p.size(); ++p)
      require<InputError>(std::isfinite(m_p[p]) && m_p[p] >= 0.0, f, "mass m_p[", p, "] = ", m_p[p],
                          " is not finite and >= 0");
}

/// One table row's products m_p N_a N_b added to their places (slot: the
/// row's n^2 places in order); S > 0: n = S known at compile time. Returns
/// the next row's slots.
template <int S>
[[gnu::always_inline]] inline const int* sum_row(double* __restrict value, const double* __restrict Np, double m,
                                                 const int* __restrict slot, int n) {
  if constexpr (S > 0) n = S;
  for (int a = 0; a < n; ++a) {
    const double m_a = m * Np[a];
    for (int b = 0; b < n; ++b) value[slot[b]] += m_a * Np[b];
    slot += n;
  }
  return slot;
}

/// The rows of a run (consecutive rows with the same node list, hence the
/// same S^2 places in `slot`) summed place by place in a register: each
/// place still adds the run's products in row order, m_p N_a first formed
/// for each a - the same additions as sum_row's, one load and one store per
/// place and run instead of per product. Up to S = 4 all S^2 sums stay in
/// registers over one pass of the rows; wider rows take one pass per a.
template <int S>
inline void sum_run(double* __restrict value, const double* __restrict N, const double* __restrict m, int rows,
                    const int* __restrict slot) {
  constexpr int A = S <= 4 ? S : 1; // rows of the S x S block summed per pass
  for (int a0 = 0; a0 < S; a0 += A) {
    double acc[A * S];
    for (int i = 0; i < A * S; ++i) acc[i] = value[slot[a0 * S + i]];
    for (int p = 0; p < rows; ++p) {
      const double* const Np = N + static_cast<std::ptrdiff_t>(p) * S;
      for (int a = 0; a < A; ++a) {
        const double m_a = m[p] * Np[a0 + a];
        for (int b = 0; b < S; ++b) acc[a * S + b] += m_a * Np[b];
      }
    }
    for (int i = 0; i < A * S; ++i) value[slot[a0 * S + i]] = acc[i];
  }
}

/// The first row of every run of rows with the same node list in a table
/// whose rows all hold S entries, and `rows` at the end; none (empty) when
/// a row names a node twice (sum_run would then load one place into two
/// accumulators).
std::vector<int> row_runs(const std::vector<int>& node, int S, int rows) {
  std::vector<int> first;
  for (int p = 0; p < rows; ++p) {
    const auto row = node.begin() + static_cast<std::ptrdiff_t>(p) * S;
    for (int a = 1; a < S; ++a)
      if (std::find(row, row + a, row[a]) != row + a) return {};
    if (p == 0 || !std::equal(row, row + S, row - S)) first.push_back(p);
  }
  first.push_back(rows);
  return first;
}

/// max |I - J| over the stored entries of the compressed matrix A.
int half_bandwidth(const Eigen::SparseMatrix<double>& A) {
  const int* inner = A.innerIndexPtr();
  const int* outer = A.outerIndexPtr();
  int b = 0;
  for (int J = 0; J < A.outerSize(); ++J)
    for (int e = outer[J]; e < outer[J + 1]; ++e) b = std::max(b, std::abs(inner[e] - J));
  return b;
}

/// L D L^T of a symmetric band matrix of half bandwidth b (B > 0: b = B
/// known at compile time), row by row in Crout order: on entry band[i (b+1)
/// + t] holds A_ij for the columns j = i - b + t (t = 0..b; +0 before column
/// 0), on return L_ij (t < b), and d[i] = D_i. With w_j = L_ij D_j:
/// w_j = A_ij - sum_{k<j} w_k L_jk, L_ij = w_j / D_j, D_i = A_ii - sum_j w_j L_ij.
/// Returns the first row whose pivot D_i is zero or not finite, or n.
template <int B> int band_factorise(double* __restrict band, double* __restrict d, int n, int b) {
  if constexpr (B > 0) b = B;
  const int width = b + 1;
  for (int i = 0; i < n; ++i) {
    double* const Li = band + static_cast<std::ptrdiff_t>(i) * width;
    double w[MassMatrix<1>::kMaxBand];
    double Di = Li[b];
    const int t0 = std::max(0, b - i); // the first column of row i in the band
    for (int t = t0; t < b; ++t) {
      const int j = i - b + t;
      const double* const Lj = band + static_cast<std::ptrdiff_t>(j) * width + (b - t); // Lj[u] = L_jk, k = i - b + u
      double s = Li[t];
      if constexpr (B != 1) // with b = 1 there is no earlier column (and GCC 12 under ASan sees a w[-1] here)
        for (int u = t0; u < t; ++u) s -= w[u] * Lj[u];
      w[t] = s;
      Li[t] = s / d[j];
      Di -= s * Li[t];
    }
    if (!(std::isfinite(Di) && Di != 0.0)) return i;
    d[i] = Di;
  }
  return n;
}

/// x = (L D L^T)^{-1} x with band_factorise's factor and inv_d = 1 / D:
/// L y = x forward, then L^T x = y / D backward, x_i = y_i / D_i - sum_k
/// L_ki x_k over the b rows k below i. Each sweep keeps the b values it
/// reads last in registers (`last`), so that a row waits for the one before
/// it through a multiplication and a subtraction, not through memory. The
/// band holds +0 before column 0, so the forward sweep needs no test at the
/// first rows; the backward one tests k < n only in its first b rows.
template <int B> void band_solve(const double* __restrict band, const double* __restrict inv_d, int n, int b,
                                 double* __restrict x) {
  if constexpr (B > 0) b = B;
  const int width = b + 1;
  double last[MassMatrix<1>::kMaxBand + 1] = {}; // last[t]: the value of row i - b + t (forward), i + b - t (backward)
  auto push = [&](double v) {
    for (int t = 0; t + 1 < b; ++t) last[t] = last[t + 1];
    if (b > 0) last[b - 1] = v;
  };
  for (int i = 0; i < n; ++i) {
    const double* const Li = band + static_cast<std::ptrdiff_t>(i) * width;
    double s = x[i];
    for (int t = 0; t < b; ++t) s -= Li[t] * last[t];
    push(s);
    x[i] = s * inv_d[i];
  }
  for (int t = 0; t < b; ++t) last[t] = 0.0;
  auto backward_row = [&](int i, int t0) { // the rows k = i + b - t, t >= t0
    double s = x[i];
    for (int t = t0; t < b; ++t) s -= band[static_cast<std::ptrdiff_t>(i + b - t) * width + t] * last[t]; // L_ki
    push(s);
    x[i] = s;
  };
  int i = n - 1;
  for (; i >= 0 && i > n - 1 - b; --i) backward_row(i, b - (n - 1 - i));
  for (; i >= 0; --i) backward_row(i, 0);
}

/// True when rows p and q hold the same node list (a loop: the lists are a
/// few ids, shorter than a call to memcmp).
template <int D> bool same_list(const BasisTable<D>& table, int p, int q) {
  const int n = table.size(p);
  if (table.size(q) != n) return false;
  const int* a = table.node.data() + table.begin(p);
  const int* b = table.node.data() + table.begin(q);
  bool same = true;
  for (int i = 0; i < n; ++i) same = same && a[i] == b[i];
  return same;
}

/// f(std::integral_constant<int, B>) with B = b for the half bandwidths of
/// the fixed stencils (linear 1, B-splines 2 and 3), else B = 0 (b at run
/// time: a diagonal M, b = 0).
template <class F> decltype(auto) with_band(int b, F&& f) {
  switch (b) {
  case 1: return f(std::integral_constant<int, 1>{});
  case 2: return f(std::integral_constant<int, 2>{});
  case 3: return f(std::integral_constant<int, 3>{});
  default: return f(std::integral_constant<int, 0>{});
  }
}

} // namespace

template <int D> MassMatrix<D>::MassMatrix(bool band) : band_allowed_(band) {}
template <int D> MassMatrix<D>::~MassMatrix() = default;

template <int D>
void MassMatrix<D>::assemble(const BasisTable<D>& table, const std::vector<double>& m_p,
                             const std::vector<char>& active, const std::vector<char>& constrained,
                             int nodes) {
  // offset_ and node_ only ever hold a table that passed check_assembly
  const bool same = M_.rows() == nodes && table.offset == offset_ && table.node == node_;
  check_assembly<D>(table, m_p, active, constrained, nodes, same);
  assemble_values(table, m_p, nodes, same);
  free_columns_add_nothing_ = finite_non_negative(M_.valuePtr(), static_cast<std::size_t>(M_.nonZeros()));
  std::vector<std::unique_ptr<Factor>> old = std::move(factor_);
  factor_.clear();
  fixed_.clear();
  try {
    for (int k = 0; k < D; ++k) {
      std::vector<char> fixed(nodes, 0);
      for (int I = 0; I < nodes; ++I) fixed[I] = !active[I] || constrained[I * D + k];
      if (k > 0 && fixed == fixed_.back()) { // same constraints: share the factor
        fixed_.push_back(fixed);
        factor_.push_back(nullptr);
        continue;
      }
      factorise(k, fixed, old);
      fixed_.push_back(std::move(fixed));
    }
  } catch (...) { // no factor of some component: solve() refuses until the next assembly
    factor_.clear();
    fixed_.clear();
    throw;
  }
}

/// M_ from the table: by Eigen's triplet assembly when the node lists
/// changed (then the place of every product in M_ is recorded), otherwise
/// (same: the last assembly's node lists) by summing the products into those
/// places in the same order - setFromTriplets sums the duplicates of an
/// entry in triplet order, starting from the first.
template <int D>
void MassMatrix<D>::assemble_values(const BasisTable<D>& table, const std::vector<double>& m_p, int nodes,
                                    bool same) {
  if (same) {
    ++pattern_reuses_;
    sum_into_slots(table, m_p);
    return;
  }
  // Forget the last table first: should this assembly throw half-way (an
  // allocation), M_ may already have the new size, and the next call must
  // not take the old node lists for this M_'s pattern.
  offset_.clear();
  node_.clear();
  if (M_.rows() == nodes && slots_on_pattern(table)) {
    ++pattern_kept_;
    keep_node_lists(table);
    sum_into_slots(table, m_p);
    return;
  }
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(table.entries() * 4);
  for (int p = 0; p < table.rows(); ++p)
    for (int a = table.begin(p); a < table.end(p); ++a)
      for (int b = table.begin(p); b < table.end(p); ++b)
        triplets.emplace_back(table.node[a], table.node[b], m_p[p] * table.N[a] * table.N[b]);
  ++version_;
  M_.resize(nodes, nodes);
  M_.setFromTriplets(triplets.begin(), triplets.end());
  M_.makeCompressed();
  // The place of each product in M_ (binary search in its column).
  slot_.resize(triplets.size());
  const int* outer = M_.outerIndexPtr();
  const int* inner = M_.innerIndexPtr();
  for (std::size_t t = 0; t < triplets.size(); ++t) {
    const int col = triplets[t].col(), row = triplets[t].row();
    slot_[t] = static_cast<int>(std::lower_bound(inner + outer[col], inner + outer[col + 1], row) - inner);
  }
  band_ = D == 1 && band_allowed_ ? half_bandwidth(M_) : -1;
  if (band_ > kMaxBand) band_ = -1;
  keep_node_lists(table);
}

template <int D> void MassMatrix<D>::keep_node_lists(const BasisTable<D>& table) {
  row_size_ = uniform_row_width(table.offset);
  runs_ = row_size_ > 0 ? row_runs(table.node, row_size_, table.rows()) : std::vector<int>{};
  offset_ = table.offset;
  node_ = table.node;
}

/// The place in M_ of every product of the table, in the triplet order
/// (slot_), found in M_'s columns - when every product falls on an entry of
/// M_ and every entry receives one, M_'s pattern is the one the triplet
/// assembly would build from this table and summing into the places gives
/// its values bit for bit (sum_into_slots). A row with the node list of the
/// row before takes its places. False (slot_ then meaningless) otherwise.
/// In `mpm` mode the node lists change every step, as particles cross
/// cells, while the pattern changes only when a pair of nodes gains or
/// loses its last shared particle.
template <int D> bool MassMatrix<D>::slots_on_pattern(const BasisTable<D>& table) {
  const int* outer = M_.outerIndexPtr();
  const int* inner = M_.innerIndexPtr();
  const auto entries = static_cast<std::size_t>(M_.nonZeros());
  hit_.assign(entries, 0);
  std::size_t covered = 0, products = 0;
  for (int p = 0; p < table.rows(); ++p) products += static_cast<std::size_t>(table.size(p)) * table.size(p);
  slot_.resize(products);
  std::size_t t = 0;
  for (int p = 0; p < table.rows(); ++p) {
    const int b0 = table.begin(p), n = table.size(p);
    const std::size_t n2 = static_cast<std::size_t>(n) * n;
    if (p > 0 && same_list(table, p - 1, p)) {
      std::copy_n(slot_.begin() + static_cast<std::ptrdiff_t>(t - n2), n2, slot_.begin() + static_cast<std::ptrdiff_t>(t));
      t += n2;
      continue;
    }
    for (int a = b0; a < b0 + n; ++a)
      for (int b = b0; b < b0 + n; ++b) {
        const int I = table.node[a], J = table.node[b];
        const int* first = inner + outer[J];
        const int* last = inner + outer[J + 1];
        const int* it = std::lower_bound(first, last, I);
        if (it == last || *it != I) return false;
        const auto e = static_cast<std::size_t>(it - inner);
        covered += hit_[e] ? 0 : 1;
        hit_[e] = 1;
        slot_[t++] = static_cast<int>(e);
      }
  }
  return covered == entries;
}

/// The products m_p N_a N_b of every table row summed into their places in
/// M_ (slot_), in table order - the sums setFromTriplets formed, which stores
/// the first product of a place and adds the others: every place starts at
/// -0.0, and -0.0 + v is v bit for bit (also for v = +0.0). m_p N_a is formed
/// once per a: the same bits as m_p * N_a * N_b. Rows of one size S known
/// at compile time (the fixed stencils: 2^D, 3^D, 4^D) get unrolled loops.
template <int D> void MassMatrix<D>::sum_into_slots(const BasisTable<D>& table, const std::vector<double>& m_p) {
  std::fill_n(M_.valuePtr(), M_.nonZeros(), -0.0);
  switch (row_size_) {
  case 2: return sum_rows<2>(table, m_p);
  case 3: return sum_rows<3>(table, m_p);
  case 4: return sum_rows<4>(table, m_p);
  case 8: return sum_rows<8>(table, m_p);
  case 9: return sum_rows<9>(table, m_p);
  case 16: return sum_rows<16>(table, m_p);
  case 27: return sum_rows<27>(table, m_p);
  case 64: return sum_rows<64>(table, m_p);
  default: return sum_rows<0>(table, m_p);
  }
}

/// sum_into_slots' loop: rows of S entries each (S > 0), or of any size
/// (S = 0: the sizes of max-ent and LME stencils up to 16 entries get the
/// unrolled row, others the general one).
template <int D>
template <int S>
void MassMatrix<D>::sum_rows(const BasisTable<D>& table, const std::vector<double>& m_p) {
  double* const value = M_.valuePtr();
  const double* const N = table.N.data();
  const int* const offset = table.offset.data();
  const int* slot = slot_.data();
  const int rows = table.rows();
  if constexpr (S > 0) { // runs of rows with the same node list (row_runs), else row by row
    if (runs_.empty()) {
      for (int p = 0; p < rows; ++p) slot = sum_row<S>(value, N + static_cast<std::ptrdiff_t>(p) * S, m_p[p], slot, S);
      return;
    }
    for (std::size_t r = 0; r + 1 < runs_.size(); ++r) {
      const int p0 = runs_[r], p1 = runs_[r + 1];
      sum_run<S>(value, N + static_cast<std::ptrdiff_t>(p0) * S, m_p.data() + p0, p1 - p0,
                 slot_.data() + static_cast<std::ptrdiff_t>(p0) * S * S);
    }
    return;
  }
  for (int p = 0; p < rows; ++p) {
    const int b0 = offset[p], n = offset[p + 1] - b0;
    const double* const Np = N + b0;
    switch (n) {
#define OTMPM_ROW(k)                                                                                                     \
  case k: slot = sum_row<k>(value, Np, m_p[p], slot, k); break;
      OTMPM_ROW(3) OTMPM_ROW(4) OTMPM_ROW(5) OTMPM_ROW(6) OTMPM_ROW(7) OTMPM_ROW(8) OTMPM_ROW(9) OTMPM_ROW(10)
      OTMPM_ROW(11) OTMPM_ROW(12) OTMPM_ROW(13) OTMPM_ROW(14) OTMPM_ROW(15) OTMPM_ROW(16)
#undef OTMPM_ROW
    default: slot = sum_row<0>(value, Np, m_p[p], slot, n);
    }
  }
}

namespace {

/// M with the rows and columns of `fixed` replaced by identity rows (their
/// diagonal set to `one`, the rest removed) and its exact zeros removed: the
/// matrix a component's solve factorises (one = 1.0), or with one = -1.0 and
/// M's values replaced by their places + 1, the map of its values (gather).
Eigen::SparseMatrix<double> with_identity_rows(Eigen::SparseMatrix<double> A, const std::vector<char>& fixed,
                                               double one) {
  for (int col = 0; col < A.outerSize(); ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, col); it; ++it)
      if (fixed[it.row()] || fixed[it.col()]) it.valueRef() = it.row() == it.col() ? one : 0.0;
  for (int I = 0; I < A.rows(); ++I)
    if (fixed[I]) A.coeffRef(I, I) = one;
  A.prune(0.0);
  A.makeCompressed();
  return A;
}

} // namespace

/// The factor of component k: M_ with identity rows at `fixed`, factorised.
/// While M_'s pattern, the fixed flags and the zero entries of M_ are the
/// last step's, the permuted matrix is gathered from M_'s values and only
/// the numeric factorisation runs; else the matrix is formed and the last
/// step's symbolic analysis (in `old`) kept when its pattern is the same.
/// The same bits either way: the same values in the same places go through
/// Eigen's factorisation.
template <int D>
void MassMatrix<D>::factorise(int k, const std::vector<char>& fixed, std::vector<std::unique_ptr<Factor>>& old) {
  const std::size_t kk = static_cast<std::size_t>(k);
  std::unique_ptr<Factor> f = kk < old.size() && old[kk] ? std::move(old[kk]) : std::make_unique<Factor>();
  if (band_ >= 0) {
    factorise_band(*f, fixed);
    factor_.push_back(std::move(f));
    return;
  }
  if (f->version == version_ && f->fixed == fixed && gather(*f)) {
    ++analysis_reuses_;
    f->ldlt.factorize_permuted(f->ap);
  } else {
    Eigen::SparseMatrix<double> A = with_identity_rows(M_, fixed, 1.0);
    const bool same = f->analysed && same_pattern(f->A, A);
    f->A = std::move(A);
    if (same) {
      ++analysis_reuses_;
      f->ldlt.factorize(f->A); // the ordering and analysis depend on the pattern only
    } else {
      f->ldlt.compute(f->A);
      f->analysed = true;
    }
    f->version = -1;
    if (f->ldlt.info() == Eigen::Success) map_gather(*f, fixed);
  }
  if (f->ldlt.info() != Eigen::Success) { // Eigen stops at the first zero pivot: the row eliminated there
    const Eigen::VectorXd pivots = f->ldlt.vectorD();
    const Eigen::Index e = std::find(pivots.begin(), pivots.end(), 0.0) - pivots.begin();
    singular(e < pivots.size() ? f->ldlt.permutationPinv().indices()[e] : -1);
  }
  factor_.push_back(std::move(f));
}

template <int D> void MassMatrix<D>::singular(int node) {
  const std::string where = node >= 0 ? " at node " + std::to_string(node) : "";
  throw SingularMassError("consistent mass matrix: factorisation failed (singular matrix)" + where, node);
}

/// The band path of factorise(): M_ with identity rows at `fixed` copied into
/// f's band (lower triangle, row by row; the places of the copy recorded
/// once per pattern and fixed flags), then L D L^T. Throws
/// SingularMassError, as the sparse path does (Eigen's LDL^T tests D_i == 0),
/// for a pivot D_i that is exactly zero (an active node whose row is empty:
/// no mass) or not finite. A matrix that is singular only numerically (rank
/// deficient, e.g. one particle alone in a cell of nodes all active) leaves
/// a pivot of round-off size on both paths and is not caught here; the
/// run's energy monitor reports what its solve does.
template <int D> void MassMatrix<D>::factorise_band(Factor& f, const std::vector<char>& fixed) const {
  const int n = static_cast<int>(M_.rows()), b = band_, width = b + 1;
  const std::size_t places = static_cast<std::size_t>(n) * width;
  if (f.version != version_ || f.fixed != fixed || f.band_source.size() != places) {
    f.band_source.assign(places, Factor::kZero);
    const int* inner = M_.innerIndexPtr();
    const int* outer = M_.outerIndexPtr();
    for (int J = 0; J < n; ++J)
      for (int e = outer[J]; e < outer[J + 1]; ++e) {
        const int I = inner[e];
        if (I >= J && !fixed[I] && !fixed[J]) f.band_source[static_cast<std::size_t>(I) * width + (J - I + b)] = e;
      }
    for (int I = 0; I < n; ++I)
      if (fixed[I]) f.band_source[static_cast<std::size_t>(I) * width + b] = Factor::kIdentity;
    f.fixed = fixed;
    f.version = version_;
  }
  f.band.resize(places);
  f.inv_d.resize(static_cast<std::size_t>(n));
  const double* v = M_.valuePtr();
  for (std::size_t s = 0; s < places; ++s) {
    const int e = f.band_source[s];
    f.band[s] = e >= 0 ? v[e] : e == Factor::kIdentity ? 1.0 : 0.0;
  }
  const int stop =
      with_band(b, [&](auto B) { return band_factorise<B()>(f.band.data(), f.inv_d.data(), n, b); });
  if (stop < n) singular(stop);
  for (double& D_i : f.inv_d) D_i = 1.0 / D_i; // the solve multiplies
}

/// Records where each value of the permuted matrix that f's factorisation
/// reads comes from in M_: the same construction (identity rows, pruning,
/// Eigen's permutation) applied to the places of M_'s values instead of the
/// values, so that the map follows Eigen's own order.
template <int D> void MassMatrix<D>::map_gather(Factor& f, const std::vector<char>& fixed) {
  Eigen::SparseMatrix<double> places = M_;
  const double* v = M_.valuePtr();
  for (Eigen::Index i = 0; i < M_.nonZeros(); ++i) places.valuePtr()[i] = v[i] == 0.0 ? 0.0 : static_cast<double>(i + 1);
  places = with_identity_rows(std::move(places), fixed, -1.0);
  if (!same_pattern(places, f.A)) return; // cannot happen; the full path then stays in use
  const int n = static_cast<int>(M_.rows());
  f.ap.resize(n, n);
  f.ap.template selfadjointView<Eigen::Upper>() =
      places.template selfadjointView<Eigen::Lower>().twistedBy(f.ldlt.permutationP());
  f.ap.makeCompressed();
  f.source.resize(static_cast<std::size_t>(f.ap.nonZeros()));
  for (std::size_t i = 0; i < f.source.size(); ++i) {
    const double place = f.ap.valuePtr()[i];
    f.source[i] = place > 0.0 ? static_cast<int>(place) - 1 : -1;
  }
  f.zeros.clear();
  for (int col = 0; col < M_.outerSize(); ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(M_, col); it; ++it)
      if (!fixed[it.row()] && !fixed[col] && it.value() == 0.0) f.zeros.push_back(static_cast<int>(&it.valueRef() - M_.valuePtr()));
  f.fixed = fixed;
  f.version = version_;
}

/// f's permuted matrix from M_'s values by the map of map_gather; false
/// (f.ap then unusable) when an entry of M_ became zero or a zero entry
/// nonzero, so that the matrix to factorise has another pattern.
template <int D> bool MassMatrix<D>::gather(Factor& f) const {
  const double* v = M_.valuePtr();
  double* out = f.ap.valuePtr();
  const int* source = f.source.data();
  const std::size_t n = f.source.size();
  bool zero = false;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = source[i] >= 0 ? v[source[i]] : 1.0;
    zero |= x == 0.0;
    out[i] = x;
  }
  for (const int z : f.zeros) zero |= v[z] != 0.0;
  return !zero;
}

template <int D>
double MassMatrix<D>::residual(const AlignedVector<Vec<D>>& r, const AlignedVector<Vec<D>>& y) const {
  require<std::invalid_argument>(!factor_.empty(), "MassMatrix::residual: call assemble() first");
  const int n = static_cast<int>(M_.rows());
  require<std::invalid_argument>(r.size() == static_cast<std::size_t>(n) && y.size() == r.size(),
                                 "MassMatrix::residual: r has ", r.size(), " and y ", y.size(), " entries for ", n,
                                 " nodes");
  double worst = 0.0;
  for (int k = 0; k < D; ++k) {
    Eigen::VectorXd yk(n), rk(n);
    for (int I = 0; I < n; ++I) yk[I] = y[I][k], rk[I] = r[I][k];
    const Eigen::VectorXd res = M_ * yk - rk;
    double num = 0.0, den = 0.0;
    for (int I = 0; I < n; ++I) {
      if (!fixed_[k][I]) num = std::max(num, std::abs(res[I]));
      den = std::max(den, std::abs(rk[I]));
    }
    if (den > 0.0) worst = std::max(worst, num / den);
  }
  return worst;
}

/// b = r_k - M y0 (y0: the prescribed values of the fixed rows, +0 at the
/// others) as Eigen evaluates it: b = r_k, then column by column b_I +=
/// M_IJ (-y0_J). A free column adds M_IJ (-(+0)) = -0 when every value of
/// M_ is finite and >= +0 (a negative value or -0 would add +0, which turns
/// a -0 into +0; an infinite or NaN value would add NaN), and adding -0
/// changes nothing: then the free columns are skipped.
template <int D>
void MassMatrix<D>::move_prescribed(int k, const std::vector<char>& fixed, const AlignedVector<Vec<D>>& y,
                                    Eigen::VectorXd& b) const {
  const int n = static_cast<int>(M_.rows());
  const double* v = M_.valuePtr();
  const int* inner = M_.innerIndexPtr();
  const int* outer = M_.outerIndexPtr();
  for (int J = 0; J < n; ++J) {
    if (!fixed[J] && free_columns_add_nothing_) continue;
    const double r_J = fixed[J] ? -y[J][k] : -0.0;
    for (int e = outer[J]; e < outer[J + 1]; ++e) b[inner[e]] += v[e] * r_J;
  }
}

template <int D>
void MassMatrix<D>::solve(const AlignedVector<Vec<D>>& r, AlignedVector<Vec<D>>& y) const {
  require<std::invalid_argument>(!factor_.empty(), "MassMatrix::solve: call assemble() first");
  const int n = static_cast<int>(M_.rows());
  require<std::invalid_argument>(r.size() == static_cast<std::size_t>(n) && y.size() == r.size(),
                                 "MassMatrix::solve: r has ", r.size(), " and y ", y.size(), " entries for ", n,
                                 " nodes");
  const Factor* f = nullptr;
  Eigen::VectorXd b(n), sol;
  for (int k = 0; k < D; ++k) {
    if (factor_[k]) f = factor_[k].get();
    const std::vector<char>& fixed = fixed_[k];
    for (int I = 0; I < n; ++I) b[I] = r[I][k];
    move_prescribed(k, fixed, y, b);
    for (int I = 0; I < n; ++I)
      if (fixed[I]) b[I] = y[I][k];
    if (band_ >= 0)
      with_band(band_, [&](auto B) { band_solve<B()>(f->band.data(), f->inv_d.data(), n, band_, b.data()); });
    else
      sol = f->ldlt.solve(b);
    const Eigen::VectorXd& x = band_ >= 0 ? b : sol;
    for (int I = 0; I < n; ++I) y[I][k] = x[I];
  }
}

template <int D>
void MassMatrix<D>::constrained_rows_product(const AlignedVector<Vec<D>>& y, AlignedVector<Vec<D>>& rho) const {
  require<std::invalid_argument>(!fixed_.empty(), "MassMatrix::constrained_rows_product: call assemble() first");
  const int n = static_cast<int>(M_.rows());
  rho.assign(static_cast<std::size_t>(n), Vec<D>::Zero());
  const double* v = M_.valuePtr();
  const int* inner = M_.innerIndexPtr();
  const int* outer = M_.outerIndexPtr();
  for (int k = 0; k < D; ++k) {
    const std::vector<char>& fixed = fixed_[static_cast<std::size_t>(k)];
    for (int I = 0; I < n; ++I) { // column I of the symmetric M is its row I
      if (!fixed[I]) continue;
      double s = 0.0;
      for (int e = outer[I]; e < outer[I + 1]; ++e)
        if (!fixed[inner[e]]) s += v[e] * y[inner[e]][k];
      rho[I][k] = s;
    }
  }
}

template class MassMatrix<1>;
template class MassMatrix<2>;
template class MassMatrix<3>;

} // namespace otmpm
