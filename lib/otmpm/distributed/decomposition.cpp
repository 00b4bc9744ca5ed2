/// \file decomposition.cpp
/// Recursive coordinate bisection of the cell lattice (decomposition.hpp).
#include "otmpm/distributed/decomposition.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>

namespace otmpm::distributed {

namespace {

/// The cut of a box along one axis: position (cells below) and how far its
/// weight below is from the target (infinite: no cut is allowed).
struct Cut {
  int at = 0;
  double miss = std::numeric_limits<double>::infinity();
  int particle_extent = 0; ///< slices between the first and last with particles
};

/// The best cut of `box` along axis k from the per-slice particle counts,
/// giving `below` of `ranks` ranks to the lower part.
template <int D> Cut best_cut(const IndexBox<D>& box, int k, const std::int64_t* counts, int below, int ranks) {
  Cut cut;
  const int E = box.extent(k);
  const long long slab = box.count() / E;
  int first = E, last = -1;
  double total = 0.0;
  for (int i = 0; i < E; ++i) {
    total += static_cast<double>(counts[i]) + kEmptyCellWeight * static_cast<double>(slab);
    if (counts[i] > 0) first = std::min(first, i), last = i;
  }
  cut.particle_extent = last >= first ? last - first + 1 : 0;
  const long long above = ranks - below;
  const int c_min = static_cast<int>((below + slab - 1) / slab);
  const int c_max = E - static_cast<int>((above + slab - 1) / slab);
  const double target = total * below / ranks;
  double prefix = 0.0;
  for (int c = 1; c < E; ++c) {
    prefix += static_cast<double>(counts[c - 1]) + kEmptyCellWeight * static_cast<double>(slab);
    if (c < c_min || c > c_max) continue;
    const double miss = std::abs(prefix - target);
    if (miss < cut.miss) cut = {c, miss, cut.particle_extent};
  }
  return cut;
}

/// The entries of a rank's per-slice counts of a box in rcb: along each
/// axis as differences (extent + 1 entries each).
template <int D> std::size_t slice_entries(const IndexBox<D>& box) {
  std::size_t n = 0;
  for (int k = 0; k < D; ++k) n += static_cast<std::size_t>(box.extent(k)) + 1;
  return n;
}

/// The entries of axis k's part of slice_entries' layout.
template <int D> int axis_entries(const IndexBox<D>& box, int k) { return box.extent(k) + 1; }

/// Per-slice counts of a box from slice_entries' layout (each axis'
/// differences summed): each axis' slices in turn.
template <int D> const std::vector<std::int64_t>& slice_counts(std::vector<std::int64_t>& v, const IndexBox<D>& box) {
  std::size_t from = 0, to = 0;
  for (int k = 0; k < D; ++k) {
    std::int64_t sum = 0;
    for (int i = 0; i < box.extent(k); ++i) v[to++] = sum += v[from++];
    ++from; // the difference past the last slice
  }
  v.resize(to);
  return v;
}

/// Appends counts in slice_entries' layout of `box` as each axis' blocks
/// of non-zero entries (zero gaps of fewer than 3 entries kept inside a
/// block): the number of blocks, then each block's (first, n, n entries).
template <int D> void put_blocks(Bytes& out, const IndexBox<D>& box, const std::vector<std::int64_t>& v) {
  std::vector<std::pair<std::size_t, std::size_t>> blocks; // [first, last) of each block
  std::size_t at = 0;
  for (int k = 0; k < D; ++k) {
    const std::size_t E = static_cast<std::size_t>(axis_entries(box, k));
    blocks.clear();
    for (std::size_t i = 0; i < E; ++i) {
      if (v[at + i] == 0) continue;
      if (!blocks.empty() && i < blocks.back().second + 3) blocks.back().second = i + 1;
      else blocks.emplace_back(i, i + 1);
    }
    put(out, static_cast<std::int64_t>(blocks.size()));
    for (const auto& [first, last] : blocks) {
      put(out, static_cast<std::int64_t>(first));
      put(out, static_cast<std::int64_t>(last - first));
      put_bytes(out, v.data() + at + first, (last - first) * sizeof(std::int64_t));
    }
    at += E;
  }
}

/// Adds the blocks put_blocks wrote (next in `rd`) to `v`; a block outside
/// the box is a std::runtime_error (a corrupt message).
template <int D>
void add_blocks(Reader& rd, const IndexBox<D>& box, std::vector<std::int64_t>& v, std::vector<std::int64_t>& part) {
  std::size_t at = 0;
  for (int k = 0; k < D; ++k) {
    const std::int64_t E = axis_entries(box, k), blocks = rd.get<std::int64_t>();
    for (std::int64_t b = 0; b < blocks; ++b) {
      const std::int64_t first = rd.get<std::int64_t>(), n = rd.get<std::int64_t>();
      require(first >= 0 && n >= 0 && first + n <= E, "Decomposition::rcb: a block of counts outside its box");
      part.resize(static_cast<std::size_t>(n));
      rd.get_bytes(part.data(), part.size() * sizeof(std::int64_t));
      for (std::size_t i = 0; i < part.size(); ++i) v[at + static_cast<std::size_t>(first) + i] += part[i];
    }
    at += static_cast<std::size_t>(E);
  }
}

/// The axis (-1: none allowed) and cut of a box of `ranks` ranks from its
/// per-slice counts: the cut of best_cut along the axis where the
/// particles extend furthest (ties: the longer box side, then the lower axis).
template <int D>
std::pair<int, int> choose_cut(const IndexBox<D>& box, const std::vector<std::int64_t>& counts, int ranks) {
  const int below = ranks / 2;
  int axis = -1;
  Cut chosen;
  std::size_t at = 0;
  for (int k = 0; k < D; ++k) {
    const Cut c = best_cut<D>(box, k, counts.data() + at, below, ranks);
    at += static_cast<std::size_t>(box.extent(k));
    if (!std::isfinite(c.miss)) continue;
    const bool longer = axis < 0 || c.particle_extent > chosen.particle_extent ||
                        (c.particle_extent == chosen.particle_extent && c.particle_extent == 0 &&
                         box.extent(k) > box.extent(axis));
    if (longer) axis = k, chosen = c;
  }
  return {axis, chosen.at};
}

} // namespace

template <int D> Decomposition<D>::Decomposition(const Index<D>& cells) : cells_(cells) {
  IndexBox<D> all;
  all.hi = cells;
  tree_.push_back({-1, 0, -1, -1, 0, 1, all});
  boxes_.push_back(all);
}

template <int D>
Decomposition<D> Decomposition<D>::rcb(const Index<D>& cells, int ranks, std::span<const Index<D>> home,
                                       const Comm& comm) {
  return rcb(cells, ranks, home, {}, comm);
}

template <int D>
Decomposition<D> Decomposition<D>::rcb(const Index<D>& cells, int ranks, std::span<const Index<D>> home,
                                       std::span<const std::int64_t> weight, const Comm& comm) {
  return rcb(cells, ranks, home, weight, {}, comm);
}

template <int D>
Decomposition<D> Decomposition<D>::rcb(const Index<D>& cells, int ranks, std::span<const Index<D>> home,
                                       std::span<const std::int64_t> weight, std::span<const int> length,
                                       const Comm& comm, std::vector<std::int64_t>* owned) {
  require<std::invalid_argument>(weight.empty() || weight.size() == home.size(), "Decomposition::rcb: ",
                                 weight.size(), " weights for ", home.size(), " cells");
  require<std::invalid_argument>(length.empty() || length.size() == home.size(), "Decomposition::rcb: ",
                                 length.size(), " lengths for ", home.size(), " cells");
  Decomposition d(cells);
  const long long total_cells = d.tree_[0].box.count();
  require(ranks >= 1 && total_cells >= ranks, "the node lattice has ", total_cells,
          " cells, fewer than the ", ranks, " ranks: run with fewer ranks or a finer grid");
  d.tree_[0].count = ranks;
  d.tree_.reserve(2 * static_cast<std::size_t>(ranks) - 1);
  d.boxes_.assign(static_cast<std::size_t>(ranks), IndexBox<D>{});
  std::vector<int> pending;
  std::vector<HomeBox> boxes = home_boxes(cells, home, weight, length), spare; // in the boxes still to be cut
  std::vector<std::int64_t> mine(static_cast<std::size_t>(ranks), 0); // this rank's particles per owner
  if (ranks > 1) {
    pending.push_back(0);
  } else {
    d.boxes_[0] = d.tree_[0].box;
    for (const HomeBox& b : boxes) mine[0] += b.weight * b.cells.count();
  }
  while (!pending.empty()) {
    // The per-slice counts of pending box j are summed, and its cut chosen,
    // on rank j % P; the ranks then share the cuts.
    const Messages received = comm.sparse_alltoall(d.slice_messages(pending, boxes, comm.size()));
    std::vector<std::int64_t> chosen = d.choose_cuts(pending, received, comm.rank(), comm.size());
    comm.sum(chosen);
    pending = d.split(pending, chosen, ranks);
    d.descend(boxes, spare, mine);
  }
  if (owned) *owned = std::move(mine);
  return d;
}

template <int D>
std::vector<typename Decomposition<D>::HomeBox> Decomposition<D>::home_boxes(const Index<D>& cells,
                                                                            std::span<const Index<D>> home,
                                                                            std::span<const std::int64_t> weight,
                                                                            std::span<const int> length) {
  std::vector<HomeBox> boxes;
  const auto merges = [](const HomeBox& a, const HomeBox& b, int k) { // b continues a along axis k
    if (a.weight != b.weight || a.cells.hi[k] != b.cells.lo[k]) return false;
    for (int i = 0; i < D; ++i)
      if (i != k && (a.cells.lo[i] != b.cells.lo[i] || a.cells.hi[i] != b.cells.hi[i])) return false;
    return true;
  };
  for (std::size_t i = 0; i < home.size(); ++i) { // the runs' parts inside the lattice
    HomeBox b{{home[i], home[i]}, weight.empty() ? 1 : weight[i], 0};
    b.cells.lo[0] = std::max(home[i][0], 0);
    b.cells.hi[0] = std::min(home[i][0] + (length.empty() ? 1 : length[i]), cells[0]);
    for (int k = 1; k < D; ++k) b.cells.hi[k] = home[i][k] + 1;
    bool inside = !b.cells.empty();
    for (int k = 1; k < D; ++k) inside = inside && home[i][k] >= 0 && home[i][k] < cells[k];
    if (!inside) continue;
    if (D > 1 && !boxes.empty() && merges(boxes.back(), b, 1)) boxes.back().cells.hi[1] = b.cells.hi[1];
    else boxes.push_back(b);
  }
  for (int k = 2; k < D; ++k) { // boxes merged along the further axes
    std::vector<HomeBox> merged;
    for (const HomeBox& b : boxes) {
      if (!merged.empty() && merges(merged.back(), b, k)) merged.back().cells.hi[k] = b.cells.hi[k];
      else merged.push_back(b);
    }
    boxes.swap(merged);
  }
  return boxes;
}

template <int D>
Messages Decomposition<D>::slice_messages(const std::vector<int>& pending, const std::vector<HomeBox>& boxes,
                                          int P) const {
  std::vector<int> slot(tree_.size(), -1);
  for (std::size_t j = 0; j < pending.size(); ++j) slot[static_cast<std::size_t>(pending[j])] = static_cast<int>(j);
  std::vector<std::vector<std::int64_t>> mine(pending.size()); // slice_entries' layout
  for (const HomeBox& b : boxes) {
    const IndexBox<D>& box = tree_[static_cast<std::size_t>(b.node)].box;
    std::vector<std::int64_t>& v = mine[static_cast<std::size_t>(slot[static_cast<std::size_t>(b.node)])];
    if (v.empty()) v.assign(slice_entries<D>(box), 0);
    std::size_t at = 0;
    for (int k = 0; k < D; ++k) { // the particles of each slice the box crosses, as differences
      const std::int64_t across = b.weight * (b.cells.count() / b.cells.extent(k));
      v[at + static_cast<std::size_t>(b.cells.lo[k] - box.lo[k])] += across;
      v[at + static_cast<std::size_t>(b.cells.hi[k] - box.lo[k])] -= across;
      at += static_cast<std::size_t>(box.extent(k)) + 1;
    }
  }
  std::map<int, Bytes> to; // one message per destination rank: its boxes in turn
  for (std::size_t j = 0; j < pending.size(); ++j) {
    if (mine[j].empty()) continue;
    Bytes& out = to[static_cast<int>(j % static_cast<std::size_t>(P))];
    put(out, static_cast<std::int64_t>(j));
    put_blocks<D>(out, tree_[static_cast<std::size_t>(pending[j])].box, mine[j]);
    std::vector<std::int64_t>().swap(mine[j]);
  }
  return {std::make_move_iterator(to.begin()), std::make_move_iterator(to.end())};
}

template <int D>
std::vector<std::int64_t> Decomposition<D>::choose_cuts(const std::vector<int>& pending, const Messages& received,
                                                        int rank, int P) const {
  std::map<int, std::vector<std::int64_t>> sums; // the boxes this rank cuts
  std::vector<std::int64_t> part;
  for (const auto& [from, in] : received)
    for (Reader rd(in); !rd.done();) {
      const std::int64_t j = rd.get<std::int64_t>();
      require(j >= 0 && j < static_cast<std::int64_t>(pending.size()) && j % P == rank,
              "Decomposition::rcb: counts of a box this rank does not cut");
      const IndexBox<D>& box = tree_[static_cast<std::size_t>(pending[static_cast<std::size_t>(j)])].box;
      std::vector<std::int64_t>& v = sums[static_cast<int>(j)];
      v.resize(slice_entries<D>(box), 0);
      add_blocks<D>(rd, box, v, part);
    }
  std::vector<std::int64_t> chosen(2 * pending.size(), 0); // per box: axis + 1 (0: none possible), cut; summed
  for (std::size_t j = static_cast<std::size_t>(rank); j < pending.size(); j += static_cast<std::size_t>(P)) {
    const Node& node = tree_[static_cast<std::size_t>(pending[j])];
    std::vector<std::int64_t>& v = sums[static_cast<int>(j)];
    v.resize(slice_entries<D>(node.box), 0);
    const auto [axis, at] = choose_cut<D>(node.box, slice_counts<D>(v, node.box), node.count);
    chosen[2 * j] = axis + 1, chosen[2 * j + 1] = at;
  }
  return chosen;
}

template <int D>
std::vector<int> Decomposition<D>::split(const std::vector<int>& pending, const std::vector<std::int64_t>& chosen,
                                         int ranks) {
  std::vector<int> next;
  for (std::size_t j = 0; j < pending.size(); ++j) {
    const int n = pending[j];
    const Node node = tree_[static_cast<std::size_t>(n)];
    const int below = node.count / 2, axis = static_cast<int>(chosen[2 * j]) - 1;
    require(axis >= 0, "the node lattice cannot be split over ", ranks, " ranks (a box of ", node.box.count(),
            " cells for ", node.count, " ranks): run with fewer ranks or a finer grid");
    Node lo{-1, 0, -1, -1, node.first, below, node.box}, hi{-1, 0, -1, -1, node.first + below, node.count - below,
                                                            node.box};
    lo.box.hi[axis] = node.box.lo[axis] + static_cast<int>(chosen[2 * j + 1]);
    hi.box.lo[axis] = lo.box.hi[axis];
    const int first_child = static_cast<int>(tree_.size());
    Node& parent = tree_[static_cast<std::size_t>(n)];
    parent.axis = axis;
    parent.cut = lo.box.hi[axis];
    parent.below = first_child;
    parent.above = first_child + 1;
    for (const Node& c : {lo, hi}) {
      if (c.count > 1) next.push_back(static_cast<int>(tree_.size()));
      else boxes_[static_cast<std::size_t>(c.first)] = c.box;
      tree_.push_back(c);
    }
  }
  return next;
}

template <int D>
void Decomposition<D>::descend(std::vector<HomeBox>& boxes, std::vector<HomeBox>& next,
                               std::vector<std::int64_t>& owned) const {
  next.clear();
  const auto keep = [&](HomeBox b, int child) {
    if (b.cells.empty()) return;
    const Node& c = tree_[static_cast<std::size_t>(child)];
    b.node = child;
    if (c.count > 1) next.push_back(b);
    else owned[static_cast<std::size_t>(c.first)] += b.weight * b.cells.count();
  };
  for (const HomeBox& b : boxes) {
    const Node& node = tree_[static_cast<std::size_t>(b.node)];
    HomeBox lo = b, hi = b;
    lo.cells.hi[node.axis] = std::min(b.cells.hi[node.axis], node.cut);
    hi.cells.lo[node.axis] = std::max(b.cells.lo[node.axis], node.cut);
    keep(lo, node.below);
    keep(hi, node.above);
  }
  boxes.swap(next);
}

template <int D> int Decomposition<D>::owner(const Index<D>& c) const {
  int n = 0;
  while (tree_[static_cast<std::size_t>(n)].axis >= 0) {
    const Node& node = tree_[static_cast<std::size_t>(n)];
    n = c[node.axis] < node.cut ? node.below : node.above;
  }
  return tree_[static_cast<std::size_t>(n)].first;
}

template <int D> std::vector<std::int64_t> Decomposition<D>::tree_rows() const {
  std::vector<std::int64_t> rows;
  for (const Node& n : tree_) {
    rows.insert(rows.end(), {n.axis, n.cut, n.below, n.above, n.first, n.count});
    rows.insert(rows.end(), n.box.lo.begin(), n.box.lo.end());
    rows.insert(rows.end(), n.box.hi.begin(), n.box.hi.end());
  }
  return rows;
}

template <int D>
std::optional<Decomposition<D>> Decomposition<D>::from_tree(const Index<D>& cells, int ranks,
                                                            const std::vector<std::int64_t>& rows) {
  const std::size_t cols = kTreeColumns, nodes = rows.size() / cols;
  if (nodes == 0 || rows.size() % cols != 0 || ranks < 1) return std::nullopt;
  Decomposition d(cells);
  d.tree_.clear();
  d.boxes_.assign(static_cast<std::size_t>(ranks), IndexBox<D>{});
  std::vector<int> leaves(static_cast<std::size_t>(ranks), 0);
  for (std::size_t i = 0; i < nodes; ++i) {
    const std::int64_t* r = rows.data() + i * cols;
    Node n;
    n.axis = static_cast<int>(r[0]), n.cut = static_cast<int>(r[1]), n.below = static_cast<int>(r[2]);
    n.above = static_cast<int>(r[3]), n.first = static_cast<int>(r[4]), n.count = static_cast<int>(r[5]);
    for (int k = 0; k < D; ++k) n.box.lo[k] = static_cast<int>(r[6 + k]), n.box.hi[k] = static_cast<int>(r[6 + D + k]);
    const auto child = [&](int c) { return c > static_cast<int>(i) && c < static_cast<int>(nodes); };
    if (n.axis >= D || n.first < 0 || n.count < 1 || n.first + n.count > ranks || n.box.empty()) return std::nullopt;
    if (n.axis >= 0 && !(child(n.below) && child(n.above))) return std::nullopt;
    if (n.axis < 0) {
      if (n.count != 1) return std::nullopt;
      d.boxes_[static_cast<std::size_t>(n.first)] = n.box;
      ++leaves[static_cast<std::size_t>(n.first)];
    }
    d.tree_.push_back(n);
  }
  IndexBox<D> all;
  all.hi = cells;
  if (!(d.tree_[0].box == all) || d.tree_[0].count != ranks) return std::nullopt;
  for (int l : leaves)
    if (l != 1) return std::nullopt;
  return d;
}

template <int D> double Decomposition<D>::imbalance(long long particles, const Comm& comm) const {
  const double mine = static_cast<double>(particles) + kEmptyCellWeight * static_cast<double>(box(comm.rank()).count());
  const double total = comm.sum(mine), largest = comm.max(mine);
  return total > 0.0 ? largest * ranks() / total : 1.0;
}

template class Decomposition<1>;
template class Decomposition<2>;
template class Decomposition<3>;

} // namespace otmpm::distributed
