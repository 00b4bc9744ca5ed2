#pragma once
/// \file scatter.hpp
/// The particle-to-node sum of the engine, with the same bits for any
/// thread count (docs/architecture.md, "Threads and identical results").
/// Particles are cut into fixed blocks of scatter_block; each block sums, in
/// particle order, into a buffer over its own node range, and each node then
/// adds the block sums in block order. Threads own blocks in the first half
/// and node ranges in the second, so nothing is shared and nothing depends
/// on the thread count. When the block ranges overlap too much (particles
/// not spatially ordered), a gather over the transposed table does it instead.
/// Internal to the engine.
#include "otmpm/basis/basis.hpp"
#include "otmpm/parallel.hpp"

#include <algorithm>
#include <vector>

namespace otmpm {

/// Per-node partial sums of the particle-to-node map (mass, momentum, force).
template <int D> struct NodeSums {
  double m = 0.0;
  Vec<D> q = Vec<D>::Zero();
  Vec<D> f = Vec<D>::Zero();
};

/// Particles per scatter block, and the largest total of block node ranges
/// (in units of the node count) for which the blocked scatter is used.
constexpr int scatter_block = 8192;
constexpr int max_block_overlap = 2;

template <int D> class ParticleToNodes {
public:
  /// Forgets the plan and the transposed table: the basis table changed.
  void invalidate() {
    valid_ = false;
    columns_valid_ = false;
  }
  /// True when the last plan used the blocked scatter (false: column gather).
  bool blocked() const { return compact_; }

  /// The particle-to-node sum over `table` (rows: particles, `nodes` nodes):
  /// update(p0, p1) runs a per-particle update (or nothing) on particles
  /// [p0, p1), each particle once and before its prep; clear(I0, I1) zeroes
  /// the nodal fields of nodes [I0, I1); then for every table entry e
  /// (particle p, node I) add(acc_I, e, prep(p)), and merge(I, acc_I) adds
  /// acc_I into the nodal fields.
  template <class Update, class Prep, class Add, class Merge, class Clear>
  void run(const BasisTable<D>& table, int nodes, Update&& update, Prep&& prep, Add&& add, Merge&& merge,
           Clear&& clear) {
    plan(table, nodes);
    if (!compact_) return gather_columns(table, nodes, update, prep, add, merge, clear);
    const int n = table.rows(), count = static_cast<int>(lo_.size());
    buffer_.resize(static_cast<std::size_t>(offset_.back()));
    // 1. every block sums its particles, in particle order, into its own range
    parallel_chunks(count, team_size(n), [&](long long b0, long long b1) {
      for (int b = static_cast<int>(b0); b < b1; ++b) block_sums(table, b, update, prep, add);
    });
    // 2. every node adds the block sums in block order (threads own node ranges)
    parallel_chunks(nodes, team_size(n), [&](long long I0, long long I1) {
      clear(static_cast<int>(I0), static_cast<int>(I1));
      for (int b = 0; b < count; ++b) {
        const NodeSums<D>* buf = buffer_.data() + offset_[b] - lo_[b];
        const int first = std::max<int>(static_cast<int>(I0), lo_[b]);
        const int last = std::min<int>(static_cast<int>(I1) - 1, hi_[b]);
        for (int I = first; I <= last; ++I) merge(I, buf[I]);
      }
    });
  }

private:
  /// Node ranges of the scatter blocks for the current basis table.
  void plan(const BasisTable<D>& table, int nodes) {
    if (valid_) return;
    valid_ = true;
    const int n = table.rows();
    const int count = (n + scatter_block - 1) / scatter_block;
    lo_.assign(static_cast<std::size_t>(count), nodes);
    hi_.assign(static_cast<std::size_t>(count), -1);
    parallel_chunks(count, team_size(n), [&](long long b0, long long b1) {
      for (long long b = b0; b < b1; ++b) {
        const int e0 = table.begin(static_cast<int>(b * scatter_block));
        const int e1 = table.end(static_cast<int>(std::min<long long>(n, (b + 1) * scatter_block)) - 1);
        int lo = nodes, hi = -1; // locals: the loop vectorises
        for (int e = e0; e < e1; ++e) {
          lo = std::min(lo, table.node[e]);
          hi = std::max(hi, table.node[e]);
        }
        lo_[b] = lo;
        hi_[b] = hi;
      }
    });
    offset_.assign(static_cast<std::size_t>(count) + 1, 0);
    for (int b = 0; b < count; ++b) offset_[b + 1] = offset_[b] + std::max(0, hi_[b] - lo_[b] + 1);
    // Spatially coherent particle order (as seeded): each node lies in the
    // range of one or two blocks. Otherwise the gather over node columns.
    compact_ = offset_.back() <= max_block_overlap * std::max(nodes, 1);
  }

  /// Phase 1 for block b: update() on the block's particles, then their
  /// sums into the block's buffer (the block's table rows, read by both,
  /// partly still in cache; measured: updating smaller batches between their
  /// sums is slower, the two access streams interfere).
  template <class Update, class Prep, class Add>
  void block_sums(const BasisTable<D>& table, int b, Update& update, Prep& prep, Add& add) {
    const bool entries = hi_[b] >= lo_[b];
    NodeSums<D>* buf = entries ? buffer_.data() + offset_[b] - lo_[b] : nullptr;
    if (entries) std::fill(buf + lo_[b], buf + hi_[b] + 1, NodeSums<D>{});
    const int begin = b * scatter_block, end = std::min(table.rows(), begin + scatter_block);
    update(begin, end);
    for (int p = begin; p < end; ++p) {
      const auto w = prep(p);
      for (int e = table.begin(p); e < table.end(p); ++e) add(buf[table.node[e]], e, w);
    }
  }

  /// The same sums as run() by a gather over the transposed table, after
  /// updating all particles (it calls prep once per entry).
  template <class Update, class Prep, class Add, class Merge, class Clear>
  void gather_columns(const BasisTable<D>& table, int nodes, Update& update, Prep& prep, Add& add, Merge& merge,
                      Clear& clear) {
    parallel_chunks(table.rows(), [&](long long p0, long long p1) { update(static_cast<int>(p0), static_cast<int>(p1)); });
    if (!columns_valid_) transpose_basis_table(table, nodes, columns_);
    columns_valid_ = true;
    const std::vector<int>& off = columns_.offset;
    parallel_chunks(nodes, team_size(static_cast<long long>(table.entries())), [&](long long I0, long long I1) {
      clear(static_cast<int>(I0), static_cast<int>(I1));
      for (int I = static_cast<int>(I0); I < I1; ++I) {
        NodeSums<D> acc{};
        for (int k = off[I]; k < off[I + 1]; ++k) add(acc, columns_.entry[k], prep(columns_.particle[k]));
        merge(I, acc);
      }
    });
  }

  std::vector<int> lo_, hi_, offset_; ///< node range of each block, its start in the buffer
  AlignedVector<NodeSums<D>> buffer_;
  bool valid_ = false, compact_ = false;
  NodeColumns columns_; ///< the transposed table, for gather_columns
  bool columns_valid_ = false;
};

} // namespace otmpm
