#pragma once
/// \file decomposition.hpp
/// Which rank owns which cells of the node lattice: recursive coordinate
/// bisection (RCB) of the lattice's cells by lattice index, weighted by the
/// particles in each cell (docs/architecture.md, "Distributed runs"). Every
/// rank owns one box of cells, the particles whose home cell lies in it and
/// the lattice points (nodes or B-spline control points) assigned to its
/// cells. The boxes tile the lattice; all ranks hold the same tree, so
/// each can tell the owner of any cell without asking.
#include "otmpm/core.hpp"
#include "otmpm/distributed/comm.hpp"

#include <optional>
#include <span>
#include <vector>

namespace otmpm::distributed {

/// A box of lattice indices [lo, hi) per axis.
template <int D> struct IndexBox {
  Index<D> lo{}, hi{};

  bool contains(const Index<D>& i) const {
    for (int k = 0; k < D; ++k)
      if (i[k] < lo[k] || i[k] >= hi[k]) return false;
    return true;
  }
  bool empty() const {
    for (int k = 0; k < D; ++k)
      if (hi[k] <= lo[k]) return true;
    return false;
  }
  long long count() const {
    long long n = 1;
    for (int k = 0; k < D; ++k) n *= std::max(0, hi[k] - lo[k]);
    return n;
  }
  int extent(int k) const { return hi[k] - lo[k]; }
  /// The common part of two boxes (empty when they do not meet).
  IndexBox intersect(const IndexBox& o) const {
    IndexBox r;
    for (int k = 0; k < D; ++k) {
      r.lo[k] = std::max(lo[k], o.lo[k]);
      r.hi[k] = std::min(hi[k], o.hi[k]);
    }
    return r;
  }
  /// Calls f(index) for every index of the box, axis 0 fastest (the
  /// lexicographic order of the lattice ids).
  template <class F> void for_each(F&& f) const {
    if (empty()) return;
    Index<D> i = lo;
    for (;;) {
      f(static_cast<const Index<D>&>(i));
      int k = 0;
      for (; k < D; ++k) {
        if (++i[k] < hi[k]) break;
        i[k] = lo[k];
      }
      if (k == D) return;
    }
  }
  bool operator==(const IndexBox&) const = default;
};

/// Weight of an empty cell relative to one particle in the bisection, for
/// the nodal work of cells without particles.
inline constexpr double kEmptyCellWeight = 0.125;

/// The RCB decomposition of a lattice of `cells` cells over `ranks` ranks.
template <int D> class Decomposition {
public:
  static constexpr int dimension = D;
  Decomposition() = default;
  /// One rank owning everything.
  explicit Decomposition(const Index<D>& cells);
  /// Bisects the lattice recursively: each box's ranks are split in halves
  /// (lower half floor(n/2)), the box along the axis where the particles
  /// extend furthest (in cells; ties: the lower axis), at the cut whose
  /// weight below is nearest to the lower half's share (weight of a cell:
  /// its particles + kEmptyCellWeight), keeping at least one cell per rank
  /// on each side. `home` holds the home cells of this rank's particles;
  /// the counts are summed over `comm` (collective, exact), so every rank
  /// builds the same tree. InputError when the lattice has fewer cells than
  /// ranks.
  static Decomposition rcb(const Index<D>& cells, int ranks, std::span<const Index<D>> home, const Comm& comm);
  /// The same with `weight[i]` particles in cell home[i] (a rank's
  /// particle count per cell, e.g. counted while seeding without storing
  /// the particles): the same tree as rcb over the cells repeated.
  static Decomposition rcb(const Index<D>& cells, int ranks, std::span<const Index<D>> home,
                           std::span<const std::int64_t> weight, const Comm& comm);
  /// The same with runs of cells along axis 0: `length[i]` cells from
  /// home[i] (home[i] + t e_0, 0 <= t < length[i]) of `weight[i]` particles
  /// each: the same tree as rcb over the cells of the runs. `owned`, when
  /// given, receives per rank the particles of this rank's runs in that
  /// rank's box (summed over the ranks: each rank's particles).
  static Decomposition rcb(const Index<D>& cells, int ranks, std::span<const Index<D>> home,
                           std::span<const std::int64_t> weight, std::span<const int> length, const Comm& comm,
                           std::vector<std::int64_t>* owned = nullptr);

  int ranks() const { return static_cast<int>(boxes_.size()); }
  const Index<D>& cells() const { return cells_; }
  /// The cells of rank r.
  const IndexBox<D>& box(int r) const { return boxes_[static_cast<std::size_t>(r)]; }
  /// The rank owning cell c (c inside the lattice).
  int owner(const Index<D>& c) const;
  /// Calls f(rank, cells) for the pieces of the run of `length` cells from
  /// c along axis 0 (inside the lattice) that each rank owns, along axis 0.
  template <class F> void owners(const Index<D>& c, int length, F&& f) const {
    pieces(c, c[0], c[0] + length, [&](int node, int lo, int hi) { f(tree_[static_cast<std::size_t>(node)].first, hi - lo); });
  }
  /// The tree as rows of kTreeColumns integers (axis, cut, below, above,
  /// first rank, ranks, the box's lo and hi), and back: a checkpoint keeps
  /// the decomposition of its run, so that a restart on as many ranks
  /// continues it bit for bit. from_tree: std::nullopt when the rows are
  /// not a tree of `ranks` ranks over `cells` cells.
  static constexpr int kTreeColumns = 6 + 2 * D;
  std::vector<std::int64_t> tree_rows() const;
  static std::optional<Decomposition> from_tree(const Index<D>& cells, int ranks,
                                                const std::vector<std::int64_t>& rows);
  /// max over ranks of (weight of the rank / mean weight) when this rank
  /// holds `particles` particles, all with home cells in its box
  /// (collective): 1 is perfect balance. The weight is that of rcb().
  double imbalance(long long particles, const Comm& comm) const;

private:
  /// Calls f(leaf, lo, hi) for the pieces [lo, hi) along axis 0 of the
  /// cells c + (i - c[0]) e_0, i in [lo, hi), that the tree's leaves hold.
  template <class F> void pieces(const Index<D>& c, int lo, int hi, F&& f, int n = 0) const {
    const Node& node = tree_[static_cast<std::size_t>(n)];
    if (node.axis < 0) return f(n, lo, hi);
    if (node.axis != 0) return pieces(c, lo, hi, f, c[node.axis] < node.cut ? node.below : node.above);
    if (lo < node.cut) pieces(c, lo, std::min(hi, node.cut), f, node.below);
    if (hi > node.cut) pieces(c, std::max(lo, node.cut), hi, f, node.above);
  }
  struct Node {
    int axis = -1;           ///< -1: a leaf (rank = first)
    int cut = 0;             ///< cells with index < cut on `axis` go below
    int below = -1, above = -1;
    int first = 0, count = 1; ///< ranks [first, first + count)
    IndexBox<D> box;
  };
  /// A box of cells of this rank's home runs in rcb (runs merged where
  /// they line up), `weight` particles in each cell, inside the box of
  /// tree node `node`, a box of more than one rank.
  struct HomeBox {
    IndexBox<D> cells;
    std::int64_t weight;
    int node;
  };
  /// The runs of rcb as boxes inside the lattice: consecutive runs of one
  /// weight and extent along axis 0 merged along axis 1, then such boxes
  /// along axis 2.
  static std::vector<HomeBox> home_boxes(const Index<D>& cells, std::span<const Index<D>> home,
                                         std::span<const std::int64_t> weight, std::span<const int> length);
  /// rcb's messages of one level: this rank's per-slice counts of each
  /// pending box its boxes reach, to the rank that cuts it (pending box j
  /// on rank j % P), as blocks of non-zero entries.
  Messages slice_messages(const std::vector<int>& pending, const std::vector<HomeBox>& boxes, int P) const;
  /// The cuts this rank chooses (rcb): per pending box, axis + 1 (0: none
  /// possible) and the cut, from the counts received; zero for the boxes of
  /// other ranks.
  std::vector<std::int64_t> choose_cuts(const std::vector<int>& pending, const Messages& received, int rank,
                                        int P) const;
  /// Splits the pending boxes at the chosen cuts; returns the children of
  /// more than one rank (the next level's pending boxes).
  std::vector<int> split(const std::vector<int>& pending, const std::vector<std::int64_t>& chosen, int ranks);
  /// Moves the boxes into the children of their nodes, just cut (written
  /// to `spare`, then swapped in); the particles of those in one-rank
  /// children are added to `owned` (per rank) and the boxes dropped.
  void descend(std::vector<HomeBox>& boxes, std::vector<HomeBox>& spare, std::vector<std::int64_t>& owned) const;
  Index<D> cells_{};
  std::vector<Node> tree_;
  std::vector<IndexBox<D>> boxes_;
};

extern template class Decomposition<1>;
extern template class Decomposition<2>;
extern template class Decomposition<3>;

} // namespace otmpm::distributed
