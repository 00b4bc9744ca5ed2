#pragma once
/// \file rows.hpp
/// The three forms of the step's basis rows the engine's passes read: the
/// basis table (BasisTable), the compact rows of `linear` on an untouched
/// lattice (LatticeRows) and the product rows of `lme_box` on its lattice
/// (ProductRows), the last two rebuilt entry by entry with the table's bits. A
/// pass visits row p's entries (node I, N_Ip, grad N_Ip) through
/// visit_row(), the same calls in the same order for either form.
/// Internal to the engine.
#include "otmpm/basis/basis.hpp"

#include <algorithm>
#include <limits>
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

/// Two values in the lanes of one SSE2 register (a GCC vector extension):
/// two corners of a compact lattice row at once (LatticeView::visit_row_pairs).
using CornerPair = double __attribute__((vector_size(16)));

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
  /// In 3D the passes that take the most instructions per entry (the forces'
  /// sums, the gathers) read the rows two entries at a time, in the lanes of
  /// a CornerPair (measured on the 3D Taylor bar: 2 164 -> 1 945 instructions
  /// per particle-step). In 2D a row's vectors already fill one register and
  /// the lanes' moves cost more than they save (measured: 578 -> 608).
  static constexpr bool pairs = D == 3;
  /// Row p's entries two at a time, f(I, J, N, dN) with the corners a (lane
  /// 0, node I) and a + 4 (lane 1, node J, the upper node along z) for a =
  /// 0 .. 3: the 2D hats of (x, y) (visit_hats) times the two z factors, so
  /// each lane's products those of visit_hats in 3D, in its order - the bits
  /// of visit_row's entries.
  template <class F> [[gnu::always_inline]] void visit_row_pairs(int p, F&& f) const {
    static_assert(D == 3);
    const Vec<D>& tp = t[p];
    const CornerPair wz{1.0 - tp[2], tp[2]}, dz{d[2][0], d[2][1]};
    const int b = base[p];
    visit_hats<2>( // reads the x and y of tp and d alone
        tp, d, [&](int a, double ww, const Vec<2>& g) __attribute__((always_inline)) {
          const CornerPair dN[3] = {g[0] * wz, g[1] * wz, ww * dz};
          f(b + corner_offset[a], b + corner_offset[a + S / 2], ww * wz, dN);
        });
  }
  /// Rows p and p + 1 together, f(I, J, N, dN) for every corner a in
  /// visit_row's order, lane 0 row p's entry (node I), lane 1 row p + 1's
  /// (node J): visit_hats of the two points in lanes, so the bits of
  /// visit_row's entries of either row.
  template <class F> [[gnu::always_inline]] void visit_two_rows(int p, F&& f) const {
    static_assert(D == 3);
    std::array<CornerPair, D> tt;
    for (int k = 0; k < D; ++k) tt[k] = CornerPair{t[p][k], t[p + 1][k]};
    const int b0 = base[p], b1 = base[p + 1];
    visit_hats<D>(
        tt, d, [&](int a, CornerPair N, const std::array<CornerPair, D>& dN) __attribute__((always_inline)) {
          f(b0 + corner_offset[a], b1 + corner_offset[a], N, dN.data());
        });
  }
};

/// The product rows (ProductRows) as a pass reads them: each row's entries
/// formed from its axes' factors (ProductRows::visit) as they are visited,
/// with the arrays' pointers and the lattice's strides in the view's own
/// copies, so that a pass's stores cannot alias them.
template <int D> struct ProductView {
  const int* base;
  const std::array<int, D>* m;
  const double* f;
  int lanes;
  std::array<int, D> stride;
  explicit ProductView(const ProductRows<D>& r)
      : base(r.base.data()), m(r.m.data()), f(r.f.data()), lanes(r.lanes), stride(r.stride) {}
  /// f(I, N_Ip, grad N_Ip) for the entries of row p in the table's order;
  /// the common box widths along axis 0 (gamma_lme = 3: 4 and 5 lines)
  /// with the loop over them unrolled.
  template <class F> [[gnu::always_inline]] void visit_row(int p, F&& g) const {
    const double* r = f + static_cast<std::ptrdiff_t>(p) * 2 * D * lanes;
    switch (m[p][0]) {
    case 4:
      return ProductRows<D>::template visit<4>(base[p], m[p], r, lanes, stride, g);
    case 5:
      return ProductRows<D>::template visit<5>(base[p], m[p], r, lanes, stride, g);
    default:
      return ProductRows<D>::visit(base[p], m[p], r, lanes, stride, g);
    }
  }
};

/// The node-to-particle sums of two rows at once (LatticeView::visit_two_rows;
/// lane l: row p + l): r = sum N rate_I, k = sum N kick_I, u = sum N move_I,
/// G = sum field_I (grad N)^T, each lane in its row's entry order with the
/// arithmetic of the engine's one-row sums (docs/theory.md eq. 5.3),
/// so the same bits. A flag off: that sum is neither formed nor read.
template <int D, bool Rate, bool Kick, bool Move, bool Field> struct TwoRowSums {
  CornerPair r[D] = {}, k[D] = {}, u[D] = {}, G[D][D] = {};
  const Vec<D>*rate, *kick, *move, *field;
  /// Adds the entries (I, N[0], dN[.][0]) of the first row and (J, N[1], dN[.][1]) of the second.
  [[gnu::always_inline]] void add(int I, int J, CornerPair N, const CornerPair* dN) {
    for (int i = 0; i < D; ++i) {
      if constexpr (Rate) r[i] += N * CornerPair{rate[I][i], rate[J][i]};
      if constexpr (Kick) k[i] += N * CornerPair{kick[I][i], kick[J][i]};
      if constexpr (Move) u[i] += N * CornerPair{move[I][i], move[J][i]};
      if constexpr (Field) {
        const CornerPair f{field[I][i], field[J][i]};
        for (int m = 0; m < D; ++m) G[i][m] += f * dN[m];
      }
    }
  }
  /// Lane l of a vector sum (r, k or u), and of G.
  static Vec<D> lane(const CornerPair* a, int l) {
    Vec<D> out;
    for (int i = 0; i < D; ++i) out[i] = a[i][l];
    return out;
  }
  Mat<D> gradient(int l) const {
    Mat<D> out;
    for (int i = 0; i < D; ++i)
      for (int m = 0; m < D; ++m) out(i, m) = G[i][m][l];
    return out;
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
template <int D, class F> decltype(auto) with_row_view(const ProductRows<D>& rows, int, F&& f) {
  return f(ProductView<D>(rows));
}

/// The smallest and largest node id of rows [p0, p1) of `rows` (lo > hi
/// when they hold no entry): a pass over the lattice or product rows'
/// lowest and highest nodes, in locals so that the loop vectorises.
template <class Rows> void row_node_range(const Rows& rows, int p0, int p1, int& lo_out, int& hi_out) {
  int lo = std::numeric_limits<int>::max(), hi = -1;
  for (int p = p0; p < p1; ++p) lo = std::min(lo, rows.lowest(p)), hi = std::max(hi, rows.highest(p));
  lo_out = lo, hi_out = hi;
}
/// row_node_range over a table's entries.
template <int D> void row_node_range(const BasisTable<D>& table, int p0, int p1, int& lo_out, int& hi_out) {
  int lo = std::numeric_limits<int>::max(), hi = -1;
  for (int e = table.begin(p0); e < table.begin(p1); ++e)
    lo = std::min(lo, table.node[e]), hi = std::max(hi, table.node[e]);
  lo_out = lo, hi_out = hi;
}

/// The step's basis rows: the basis table, or - when no part of the step
/// needs the table (Engine::evaluate_basis) - the compact lattice rows of
/// `linear` on an untouched lattice or the product rows of `lme_box` on its
/// lattice, the table then built from them (the same entries and bits)
/// only when something asks for it (full()).
template <int D> struct StepRows {
  BasisTable<D> table;
  LatticeRows<D> lattice;
  ProductRows<D> product;
  bool compact = false;  ///< the step's rows are `lattice`
  bool factored = false; ///< the step's rows are `product`
  bool built = false;    ///< (compact or factored) `table` holds them too
  int width = 0;         ///< linear_row_width(table) (compact: 2^D)

  /// The full table of the step's rows. Built on the first call of a
  /// step that kept the lattice rows, which must not run beside a pass (it
  /// writes the table); after that, and for the table's own steps, it only
  /// reads, so the threads of a pass may call it.
  const BasisTable<D>& full() {
    if ((compact || factored) && !built) {
      if (compact)
        expand_lattice_rows(lattice, table);
      else
        expand_product_rows(product, table);
      built = true;
    }
    return table;
  }
  /// The entries of the step's rows (their nodes summed over the
  /// particles), counted without building the table.
  std::size_t entries() const {
    if (compact) return static_cast<std::size_t>(lattice.rows()) * LatticeRows<D>::kCorners;
    if (factored) return static_cast<std::size_t>(product.offset.back());
    return table.entries();
  }
  /// The smallest and largest node id of the rows of particles [p0, p1)
  /// (row_node_range).
  void node_range(int p0, int p1, int& lo, int& hi) const {
    if (compact) return row_node_range(lattice, p0, p1, lo, hi);
    if (factored) return row_node_range(product, p0, p1, lo, hi);
    row_node_range(table, p0, p1, lo, hi);
  }
  /// Runs f(view) with the view of the step's rows for a pass (with_row_view).
  template <class F> decltype(auto) view(F&& f) const {
    if (compact) return with_row_view(lattice, width, f);
    if (factored) return with_row_view(product, width, f);
    return with_row_view(table, width, f);
  }
};

} // namespace otmpm
