#pragma once
/// \file rows.hpp
/// The two forms of the step's basis rows the engine's passes read: the
/// basis table (BasisTable) and the compact rows of `linear` on an untouched
/// lattice (LatticeRows, rebuilt entry by entry with the table's bits). A
/// pass visits row p's entries (node I, N_Ip, grad N_Ip) through
/// visit_row(), the same calls in the same order for either form.
/// Internal to the engine.
#include "otmpm/basis/basis.hpp"

#include <utility>

namespace otmpm {

/// The basis table's rows, W entries each when W > 0 (linear_row_width),
/// else of any length; pointers by value, so that a pass's stores cannot
/// alias them.
template <int D, int W> struct TableView {
  const int* offset;
  const int* node;
  const double* N;
  const Vec<D>* dN;
  explicit TableView(const BasisTable<D>& t)
      : offset(t.offset.data()), node(t.node.data()), N(t.N.data()), dN(t.dN.data()) {}
  /// f(I, N_Ip, grad N_Ip) for the entries of row p in table order.
  template <class F> [[gnu::always_inline]] void visit_row(int p, F&& f) const {
    const auto [e0, e1] = row_entries<W>(offset, p);
    for (int e = e0; e < e1; ++e) f(node[e], N[e], dN[e]);
  }
};

/// The compact lattice rows (LatticeRows) as a pass reads them: each row's
/// 2^D entries rebuilt (LatticeRows::visit) before they are visited. The
/// arrays' pointers and the lattice's constants are the view's own copies,
/// so that a pass's stores cannot alias them.
template <int D> struct LatticeView {
  static constexpr int S = LatticeRows<D>::kCorners;
  const int* base;
  const Vec<D>* t;
  std::array<int, S> corner_offset;
  std::array<std::array<double, 2>, D> d;
  explicit LatticeView(const LatticeRows<D>& r)
      : base(r.base.data()), t(r.t.data()), corner_offset(r.corner_offset), d(r.d) {}
  /// f(I, N_Ip, grad N_Ip) for the entries of row p in the table's order.
  template <class F> [[gnu::always_inline]] void visit_row(int p, F&& f) const {
    LatticeRows<D>::visit(base[p], t[p], corner_offset, d, f);
  }
};

/// Runs f(view) with the view of `rows` for a pass: the table's of W =
/// 2^D entries per row when `width` (its linear_row_width) says so, else of
/// any length; the lattice rows' own.
template <int D, class F> decltype(auto) with_row_view(const BasisTable<D>& rows, int width, F&& f) {
  if (width == (1 << D)) return f(TableView<D, (1 << D)>(rows));
  return f(TableView<D, 0>(rows));
}
template <int D, class F> decltype(auto) with_row_view(const LatticeRows<D>& rows, int, F&& f) {
  return f(LatticeView<D>(rows));
}

/// The step's basis rows: the basis table, or - `linear` on an untouched
/// lattice, when no part of the step needs the table (Engine::evaluate_basis)
/// - the compact lattice rows, the table then built from them (the same
/// entries and bits) only when something asks for it (full()).
template <int D> struct StepRows {
  BasisTable<D> table;
  LatticeRows<D> lattice;
  bool compact = false; ///< the step's rows are `lattice`
  bool built = false;   ///< (compact) `table` holds them too
  int width = 0;        ///< linear_row_width(table) (compact: 2^D)

  /// The full table of the step's rows. Built on the first call of a
  /// step that kept the lattice rows, which must not run beside a pass (it
  /// writes the table); after that, and for the table's own steps, it only
  /// reads, so the threads of a pass may call it.
  const BasisTable<D>& full() {
    if (compact && !built) {
      expand_lattice_rows(lattice, table);
      built = true;
    }
    return table;
  }
  /// Runs f(view) with the view of the step's rows for a pass (with_row_view).
  template <class F> decltype(auto) view(F&& f) const {
    if (compact) return with_row_view(lattice, width, f);
    return with_row_view(table, width, f);
  }
};

} // namespace otmpm
