#pragma once
/// \file scatter.hpp
/// The particle-to-node sum of the engine, with the same bits for any
/// thread count (docs/architecture.md, "Threads and identical results").
/// Particles are cut into fixed blocks of scatter_block; each block sums, in
/// particle order, into a buffer of its own, and each node then adds the
/// block sums in block order. Threads own blocks in the first half and node
/// ranges in the second, so nothing is shared and nothing depends on the
/// thread count. The buffer covers the block's whole node-index range while
/// those buffers stay small (dense), else only the nodes the block touches
/// (sparse: large 3D grids, whose slab blocks span two node layers each, or
/// particles in no spatial order). When even that would need more memory
/// than the transposed rows, a gather over the transposed rows does it.
/// Internal to the engine.
#include "otmpm/basis/basis.hpp"
#include "otmpm/engine/rows.hpp"
#include "otmpm/parallel.hpp"

#include <algorithm>
#include <optional>
#include <type_traits>
#include <utility>
#include <vector>

namespace otmpm {

/// Per-node partial sums of the particle-to-node map (mass, momentum, force).
template <int D> struct NodeSums {
  double m = 0.0;
  Vec<D> q = Vec<D>::Zero();
  Vec<D> f = Vec<D>::Zero();
};

/// The engine's sum of one basis entry (particle p, node I) into node I's
/// partial sums (docs/theory.md eqs. 5.1, 5.2): m_I += N_Ip m_p, q_I += N_Ip
/// (m w)_p, f_I -= (V sigma)_p grad N_Ip, then f_I += N_Ip fext_p; `Split`:
/// f_I += N_Ip (m a)_p instead. `W` is the particle's payload (m, mw, fext,
/// Vs). pair() adds two entries of one row, two corners of a compact lattice
/// row in the lanes of a CornerPair, each lane the arithmetic of operator()
/// in its order (V sigma grad N summed as Eigen sums it, product_row), so
/// the same bits (tests/test_scatter.cpp).
template <int D, bool Mass, bool Momentum, bool Forces, bool Split> struct NodeSumsAdd {
  /// rows_sums may hand it corner pairs (where the rows offer them): with the
  /// forces, whose products outweigh the lanes' moves (measured: the mass
  /// and momenta alone, one product per value, take more instructions so)
  static constexpr bool pairs = Forces;
  template <class W>
  [[gnu::always_inline]] void operator()(NodeSums<D>& acc, double N, const Vec<D>& dN, const W& w) const {
    if (Mass) acc.m += N * w.m;
    if (Momentum) acc.q += N * w.mw;
    if (Split) acc.f += N * w.fext;
    if (Forces) {
      acc.f -= w.Vs * dN;
      acc.f += N * w.fext;
    }
  }
  /// operator() for the entries (a, N[0], dN[.][0]) and (b, N[1], dN[.][1]).
  template <class W>
  [[gnu::always_inline]] void pair(NodeSums<D>& a, NodeSums<D>& b, CornerPair N, const CornerPair* dN,
                                   const W& w) const {
    if (Mass) store(a.m, b.m, CornerPair{a.m, b.m} + N * w.m);
    for (int i = 0; i < D; ++i) {
      if (Momentum) store(a.q[i], b.q[i], CornerPair{a.q[i], b.q[i]} + N * w.mw[i]);
      if (!Forces && !Split) continue;
      CornerPair f{a.f[i], b.f[i]};
      if (Split) f += N * w.fext[i];
      if (Forces) f = (f - product_row(w.Vs, i, dN)) + N * w.fext[i];
      store(a.f[i], b.f[i], f);
    }
  }

private:
  [[gnu::always_inline]] static void store(double& a, double& b, CornerPair v) { a = v[0], b = v[1]; }
  /// Row i of Vs grad N in the order Eigen 3.4 sums `Vs * dN` (measured, and
  /// held by tests/test_scatter.cpp): the rows it takes in SSE2 packets left
  /// to right, ((p0 + p1) + p2); the third row of a 3 x 3, a scalar
  /// reduction split in halves, p0 + (p1 + p2).
  [[gnu::always_inline]] static CornerPair product_row(const Mat<D>& Vs, int i, const CornerPair* dN) {
    if (D == 3 && i == 2) return Vs(i, 0) * dN[0] + (Vs(i, 1) * dN[1] + Vs(i, 2) * dN[2]);
    CornerPair t = Vs(i, 0) * dN[0];
    for (int k = 1; k < D; ++k) t += Vs(i, k) * dN[k];
    return t;
  }
};

/// Particles per scatter block, and a total of block node ranges (in units
/// of the node count) up to which the dense blocked scatter is used.
constexpr int scatter_block = static_cast<int>(home_granule);
constexpr int max_block_overlap = 2;
/// The dense blocked scatter is also used while the ranges add up to at
/// most the table's entries over this: its buffers then take at most 14
/// bytes per entry in 3D (the table itself 36), and it was measured faster
/// than the sparse path (docs/performance-log-2026.md).
constexpr int dense_entries_per_slot = 4;
/// The largest total of block node ranges, in table entries, for which the
/// sparse blocked scatter is used: its per-block slot maps (one int per node
/// of a block's range) then take at most the memory of the transposed table
/// (two ints per entry), and planning costs about a pass over the table.
/// Above it (particles in no spatial order on a large grid) the column gather.
constexpr int max_sparse_ranges = 2;

/// Fewer blocks than this per thread leave a pass that updates each block's
/// particles before it sums them (BlockedScatter::run's `update`) waiting for
/// the thread whose blocks cost most - a block of plastic particles among
/// elastic ones: such a pass then runs its updates first, in chunks the
/// threads share (few_scatter_blocks).
constexpr int min_blocks_per_thread = 4;

/// True when n particles make fewer than min_blocks_per_thread scatter
/// blocks per thread of team_size(n), with more than one thread.
inline bool few_scatter_blocks(long long n) {
  const int team = team_size(n);
  return team > 1 && (n + scatter_block - 1) / scatter_block < static_cast<long long>(min_blocks_per_thread) * team;
}

/// How ParticleToNodes sums for the current basis table.
enum class ScatterPath {
  dense,   ///< each block sums into a buffer over its whole node-index range
  sparse,  ///< each block sums into a buffer over the nodes it touches only
  columns, ///< a gather over the transposed rows
};

/// The particle-to-node sum with the same bits for any thread count. In
/// both blocked paths each block of scatter_block particles sums, in
/// particle order, into its own buffer, and each node then adds the block
/// sums in block order (dense and sparse give the same bits: a node a block
/// does not touch receives +0 in the dense path, which changes no sum).
/// `Sums` is the per-node partial sum (default-constructed = zero).
template <int D, class Sums> class BlockedScatter {
public:
  /// Forgets the plan and the transposed rows: the basis rows changed;
  /// `row_width` is the new table's linear_row_width (0: rows of any length).
  void invalidate(int row_width) {
    valid_ = false;
    columns_valid_ = false;
    width_ = row_width;
  }
  /// True when the last plan used a blocked scatter (false: column gather).
  bool blocked() const { return path_ != ScatterPath::columns; }
  /// The path of the last plan.
  ScatterPath path() const { return path_; }
  /// Makes every later plan take `path` (tests and measurements that compare
  /// the paths on one table); std::nullopt: the plan chooses.
  void force(std::optional<ScatterPath> path) {
    forced_ = path;
    valid_ = false;
  }

  /// The particle-to-node sum over `rows` (a BasisTable or the compact
  /// LatticeRows; rows: particles, `nodes` nodes): update(p0, p1) runs a
  /// per-particle update (or nothing) on particles [p0, p1), each particle
  /// once and before its prep; clear(I0, I1) zeroes the nodal fields of
  /// nodes [I0, I1); then for every entry (particle p, node I, N_Ip, grad
  /// N_Ip) add(acc_I, N_Ip, grad N_Ip, prep(p)), and merge(I, acc_I) adds
  /// acc_I into the nodal fields. `visit`: the nodes, ascending, that
  /// phase 2 clears and merges into (every node of a table row among them;
  /// the others' fields are left as they are), or null: every node.
  template <class Rows, class Update, class Prep, class Add, class Merge, class Clear>
  void run(const Rows& table, int nodes, Update&& update, Prep&& prep, Add&& add, Merge&& merge,
           Clear&& clear, const std::vector<int>* visit = nullptr) {
    plan(table, nodes);
    if (path_ == ScatterPath::columns)
      return gather_columns(table, nodes, update, prep, add, merge, clear, visit);
    const int n = table.rows(), count = static_cast<int>(lo_.size());
    const bool dense = path_ == ScatterPath::dense;
    buffer_.resize(static_cast<std::size_t>(offset_.back()));
    const bool clean = std::exchange(zeroed_, false); // the buffers need no clearing
    // 1. every block sums its particles, in particle order, into its own buffer
    parallel_chunks(
        count, team_size(n),
        [&](long long b0, long long b1) {
          for (int b = static_cast<int>(b0); b < b1; ++b)
            dense ? dense_block_sums(table, b, clean, update, prep, add) : sparse_block_sums(table, b, update, prep, add);
        },
        1);
    if (visit) return merge_visited(*visit, team_size(n), merge, clear);
    // 2. every node adds the block sums in block order (threads own node ranges)
    parallel_chunks(nodes, team_size(n), [&](long long I0, long long I1) {
      clear(static_cast<int>(I0), static_cast<int>(I1));
      for (int b = 0; b < count; ++b) {
        const int first = std::max<int>(static_cast<int>(I0), lo_[b]);
        const int last = std::min<int>(static_cast<int>(I1) - 1, hi_[b]);
        dense ? merge_dense(b, first, last, merge) : merge_sparse(b, first, last, merge);
      }
    });
  }

  /// Plans the sums over `rows` (the plan run() then takes) and returns
  /// its path (tests: the lattice rows and their table plan alike).
  template <class Rows> ScatterPath plan_for(const Rows& rows, int nodes) {
    plan(rows, nodes);
    return path_;
  }

private:
  /// Chooses the path for the current basis table: dense when the block
  /// ranges add up to at most max_block_overlap times the node count or to
  /// at most the entries over dense_entries_per_slot, else sparse when they
  /// add up to at most max_sparse_ranges times the entries, else the column
  /// gather (measured: both blocked paths are faster than the column gather,
  /// also for shuffled particles, docs/performance-log-2026.md).
  template <class Rows> void plan(const Rows& table, int nodes) {
    if (valid_) return;
    valid_ = true;
    const long long ranges = node_ranges(table, nodes);
    const auto entries = entry_count(table);
    path_ = ScatterPath::columns;
    if (ranges <= static_cast<long long>(max_block_overlap) * std::max(nodes, 1) ||
        ranges * dense_entries_per_slot <= entries)
      path_ = ScatterPath::dense;
    else if (ranges <= max_sparse_ranges * entries)
      path_ = ScatterPath::sparse;
    if (forced_) path_ = *forced_;
    if (path_ == ScatterPath::dense) offset_ = range_start_;
    if (path_ == ScatterPath::sparse) sparse_slots(table);
  }

  /// The node range [lo_, hi_] of every block and their prefix sums
  /// (range_start_); returns the total of the ranges.
  template <class Rows> long long node_ranges(const Rows& table, int nodes) {
    const int n = table.rows();
    const int count = (n + scatter_block - 1) / scatter_block;
    lo_.assign(static_cast<std::size_t>(count), nodes);
    hi_.assign(static_cast<std::size_t>(count), -1);
    parallel_chunks(
        count, team_size(n),
        [&](long long b0, long long b1) {
          for (int b = static_cast<int>(b0); b < b1; ++b) block_range(table, b, nodes, lo_[b], hi_[b]);
        },
        1);
    range_start_.assign(static_cast<std::size_t>(count) + 1, 0);
    for (int b = 0; b < count; ++b) range_start_[b + 1] = range_start_[b] + std::max(0, hi_[b] - lo_[b] + 1);
    return range_start_.back();
  }

  /// The sparse plan: for every block, over its node range, the slot of each
  /// node it touches (in node order) or -1 (slot_), and the start of its
  /// slots in the buffer (offset_).
  template <class Rows> void sparse_slots(const Rows& table) {
    const int count = static_cast<int>(lo_.size());
    slot_.resize(static_cast<std::size_t>(range_start_.back()));
    std::vector<long long> used(static_cast<std::size_t>(count));
    parallel_chunks(
        count, team_size(table.rows()),
        [&](long long b0, long long b1) {
          for (int b = static_cast<int>(b0); b < b1; ++b) used[b] = number_slots(table, b);
        },
        1);
    offset_.assign(static_cast<std::size_t>(count) + 1, 0);
    for (int b = 0; b < count; ++b) offset_[b + 1] = offset_[b] + used[b];
  }

  /// Marks the nodes block b touches in its part of slot_, then numbers
  /// them in node order; returns how many there are.
  template <class Rows> int number_slots(const Rows& table, int b) {
    int* slot = slot_.data() + range_start_[b];
    std::fill(slot, slot + (range_start_[b + 1] - range_start_[b]), -1);
    const int lo = lo_[b];
    block_nodes_visit(table, b, [slot, lo](int I) { slot[I - lo] = 0; });
    int used = 0;
    for (long long i = 0; i < range_start_[b + 1] - range_start_[b]; ++i)
      if (slot[i] == 0) slot[i] = used++;
    return used;
  }

  /// One past block b's last row.
  template <class Rows> static int block_end(const Rows& rows, int b) {
    return std::min(rows.rows(), (b + 1) * scatter_block);
  }
  static int entry_begin(const BasisTable<D>& table, int b) { return table.begin(b * scatter_block); }
  static int entry_end(const BasisTable<D>& table, int b) { return table.end(block_end(table, b) - 1); }
  static long long entry_count(const BasisTable<D>& table) { return static_cast<long long>(table.entries()); }
  static long long entry_count(const LatticeRows<D>& rows) {
    return static_cast<long long>(rows.rows()) * LatticeRows<D>::kCorners;
  }
  static long long entry_count(const ProductRows<D>& rows) { return rows.offset.back(); }

  /// The smallest and largest node id of block b's rows (lo = nodes, hi =
  /// -1: none; row_node_range).
  template <class Rows> static void block_range(const Rows& rows, int b, int nodes, int& lo_b, int& hi_b) {
    row_node_range(rows, b * scatter_block, block_end(rows, b), lo_b, hi_b);
    lo_b = std::min(lo_b, nodes); // an empty block: lo = nodes, hi = -1
  }

  /// f(I) for the node of every entry of block b's rows.
  template <class F> static void block_nodes_visit(const BasisTable<D>& table, int b, F&& f) {
    for (int e = entry_begin(table, b); e < entry_end(table, b); ++e) f(table.node[e]);
  }
  template <class F> static void block_nodes_visit(const LatticeRows<D>& rows, int b, F&& f) {
    for (int p = b * scatter_block; p < block_end(rows, b); ++p)
      for (int a = 0; a < LatticeRows<D>::kCorners; ++a) f(rows.lowest(p) + rows.corner_offset[a]);
  }
  template <class F> static void block_nodes_visit(const ProductRows<D>& rows, int b, F&& f) {
    for (int p = b * scatter_block; p < block_end(rows, b); ++p) rows.visit_nodes(p, f);
  }

  /// Phase 1 for block b, dense: update() on the block's particles, then
  /// their sums into the block's buffer (the block's table rows, read by
  /// both, partly still in cache; measured: updating smaller batches between
  /// their sums is slower, the two access streams interfere). `clean`: the
  /// buffer is all zero already (merge_visited left it so).
  template <class Rows, class Update, class Prep, class Add>
  void dense_block_sums(const Rows& table, int b, bool clean, Update& update, Prep& prep, Add& add) {
    const bool entries = hi_[b] >= lo_[b];
    Sums* buf = entries ? buffer_.data() + offset_[b] - lo_[b] : nullptr;
    if (entries && !clean) std::fill(buf + lo_[b], buf + hi_[b] + 1, Sums{});
    block_sums(table, b, [buf](int I) -> Sums& { return buf[I]; }, update, prep, add);
  }

  /// Phase 1 for block b, sparse: as dense_block_sums into the block's slots.
  template <class Rows, class Update, class Prep, class Add>
  void sparse_block_sums(const Rows& table, int b, Update& update, Prep& prep, Add& add) {
    Sums* buf = buffer_.data() + offset_[b];
    std::fill(buf, buffer_.data() + offset_[b + 1], Sums{});
    const int* slot = hi_[b] >= lo_[b] ? slot_.data() + range_start_[b] - lo_[b] : nullptr;
    block_sums(table, b, [buf, slot](int I) -> Sums& { return buf[slot[I]]; }, update, prep, add);
  }

  /// update() on block b's particles, then add() of each of their entries
  /// into at(node), in particle order.
  template <class Rows, class At, class Update, class Prep, class Add>
  void block_sums(const Rows& table, int b, At at, Update& update, Prep& prep, Add& add) {
    const int begin = b * scatter_block, end = block_end(table, b);
    update(begin, end);
    with_row_view(table, width_, [&](const auto& view) { rows_sums(view, begin, end, at, prep, add); });
  }

  /// add() of each entry of particles [begin, end) into at(node), in
  /// particle order (`view`: a TableView or LatticeView of the rows).
  template <class View, class At, class Prep, class Add>
  static void rows_sums(const View view, int begin, int end, At at, const Prep& prep_in, const Add& add_in) {
    // Local copies of the two functions (their captured pointers): the
    // sums' vector stores may alias any memory, so members reached through
    // the references would be loaded again for every entry.
    const Prep prep = prep_in;
    const Add add = add_in;
    for (int p = begin; p < end; ++p) {
      const auto w = prep(p);
      if constexpr (requires { requires View::pairs && Add::pairs; })
        view.visit_row_pairs(
            p, [&](int I, int J, CornerPair N, const CornerPair* dN)
                   __attribute__((always_inline)) { add.pair(at(I), at(J), N, dN, w); });
      else
        view.visit_row(
            p, [&](int I, double N, const Vec<D>& dN)
                   __attribute__((always_inline)) { add(at(I), N, dN, w); });
    }
  }

  /// Phase 2 on the nodes of `visit` only (ascending): each node cleared,
  /// then the block sums added in block order, as run() does for every node
  /// (threads own ranges of the list). The dense buffers are zeroed as they
  /// are read (every node a block touches is visited): the next run's
  /// blocks then need not clear their whole node ranges.
  template <class Merge, class Clear>
  void merge_visited(const std::vector<int>& visit, int team, Merge& merge, Clear& clear) {
    const bool dense = path_ == ScatterPath::dense;
    const int* list = visit.data();
    parallel_chunks(static_cast<long long>(visit.size()), team, [&](long long i0, long long i1) {
      for (long long i = i0; i < i1; ++i) clear(list[i], list[i] + 1);
      for (int b = 0; b < static_cast<int>(lo_.size()); ++b) {
        const int* first = std::lower_bound(list + i0, list + i1, lo_[b]);
        const int* last = std::upper_bound(first, list + i1, hi_[b]);
        if (dense) {
          Sums* buf = buffer_.data() + offset_[b] - lo_[b];
          for (const int* I = first; I < last; ++I) {
            merge(*I, buf[*I]);
            buf[*I] = Sums{};
          }
        } else if (first < last) { // the nodes it touches are listed: its slots over their span
          merge_sparse(b, *first, *(last - 1), merge);
        }
      }
    });
    zeroed_ = dense;
  }

  /// Phase 2, dense: block b's sums into nodes [first, last].
  template <class Merge> void merge_dense(int b, int first, int last, Merge& merge) const {
    if (first > last) return;
    const Sums* buf = buffer_.data() + offset_[b] - lo_[b];
    for (int I = first; I <= last; ++I) merge(I, buf[I]);
  }

  /// Phase 2, sparse: block b's sums into the nodes of [first, last] it touches.
  template <class Merge> void merge_sparse(int b, int first, int last, Merge& merge) const {
    if (first > last) return;
    const Sums* buf = buffer_.data() + offset_[b];
    const int* slot = slot_.data() + range_start_[b] - lo_[b];
    for (int I = first; I <= last; ++I)
      if (slot[I] >= 0) merge(I, buf[slot[I]]);
  }

  /// The same sums as run() by a gather over the transposed rows, after
  /// updating all particles (it calls prep once per entry; the lattice
  /// rows' entries are rebuilt one by one, with their bits).
  template <class Rows, class Update, class Prep, class Add, class Merge, class Clear>
  void gather_columns(const Rows& table, int nodes, Update& update, Prep& prep, Add& add, Merge& merge,
                      Clear& clear, const std::vector<int>* visit) {
    parallel_chunks(table.rows(), [&](long long p0, long long p1) { update(static_cast<int>(p0), static_cast<int>(p1)); });
    if (!columns_valid_) transpose_basis_table(table, nodes, columns_);
    columns_valid_ = true;
    const std::vector<int>& off = columns_.offset;
    const long long count = visit ? static_cast<long long>(visit->size()) : nodes;
    parallel_chunks(count, team_size(entry_count(table)), [&](long long i0, long long i1) {
      if (!visit) clear(static_cast<int>(i0), static_cast<int>(i1)); // the chunk's nodes at once
      for (auto i = i0; i < i1; ++i) {
        const int I = visit ? (*visit)[i] : static_cast<int>(i);
        if (visit) clear(I, I + 1);
        Sums acc{};
        for (int k = off[I]; k < off[I + 1]; ++k) {
          const int e = columns_.entry[k];
          if constexpr (std::is_same_v<Rows, BasisTable<D>>) {
            add(acc, table.N[e], table.dN[e], prep(columns_.particle[k]));
          } else if constexpr (std::is_same_v<Rows, ProductRows<D>>) {
            int J;
            double N;
            Vec<D> dN;
            table.entry(columns_.particle[k], e, J, N, dN);
            add(acc, N, dN, prep(columns_.particle[k]));
          } else {
            double N;
            Vec<D> dN;
            table.entry(e, N, dN);
            add(acc, N, dN, prep(columns_.particle[k]));
          }
        }
        merge(I, acc);
      }
    });
  }

  std::vector<int> lo_, hi_;         ///< node range of each block
  std::vector<long long> range_start_; ///< start of each block's range in slot_ (prefix of the ranges)
  std::vector<long long> offset_;    ///< start of each block's buffer
  std::vector<int> slot_;            ///< sparse: each block's slot per node of its range, or -1
  AlignedVector<Sums> buffer_;
  bool valid_ = false;
  bool zeroed_ = false; ///< buffer_ is all zero (merge_visited left it so)
  int width_ = 0; ///< linear_row_width of the table (0: rows of any length)
  std::optional<ScatterPath> forced_;
  ScatterPath path_ = ScatterPath::columns;
  NodeColumns columns_; ///< the transposed rows, for gather_columns
  bool columns_valid_ = false;
};

/// The engine's particle-to-node sum (mass, momentum, force).
template <int D> class ParticleToNodes final : public BlockedScatter<D, NodeSums<D>> {};

} // namespace otmpm
