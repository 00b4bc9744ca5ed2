/// \file decomposition.cpp
/// Recursive coordinate bisection of the cell lattice (decomposition.hpp).
#include "otmpm/distributed/decomposition.hpp"

#include <algorithm>
#include <cmath>
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

/// The entries of a rank's per-slice counts of a box in rcb: along axis 0
/// as differences (extent + 1), then the slices of each further axis.
template <int D> std::size_t slice_entries(const IndexBox<D>& box) {
  std::size_t n = 1;
  for (int k = 0; k < D; ++k) n += static_cast<std::size_t>(box.extent(k));
  return n;
}

/// Per-slice counts of a box from slice_entries' layout (the differences
/// along axis 0 summed; `E0` slices along axis 0): each axis' slices in turn.
inline const std::vector<std::int64_t>& slice_counts(std::vector<std::int64_t>& v, int E0) {
  std::int64_t sum = 0;
  for (int i = 0; i < E0; ++i) v[static_cast<std::size_t>(i)] = sum += v[static_cast<std::size_t>(i)];
  v.erase(v.begin() + E0);
  return v;
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
                                       const Comm& comm) {
  require<std::invalid_argument>(weight.empty() || weight.size() == home.size(), "Decomposition::rcb: ",
                                 weight.size(), " weights for ", home.size(), " cells");
  require<std::invalid_argument>(length.empty() || length.size() == home.size(), "Decomposition::rcb: ",
                                 length.size(), " lengths for ", home.size(), " cells");
  Decomposition d(cells);
  const long long total_cells = d.tree_[0].box.count();
  require(ranks >= 1 && total_cells >= ranks, "the node lattice has ", total_cells,
          " cells, fewer than the ", ranks, " ranks: run with fewer ranks or a finer grid");
  d.tree_[0].count = ranks;
  d.boxes_.assign(static_cast<std::size_t>(ranks), IndexBox<D>{});
  std::vector<int> pending;
  if (ranks > 1) pending.push_back(0);
  else d.boxes_[0] = d.tree_[0].box;
  while (!pending.empty()) {
    // The per-slice particle counts of pending box j are summed, and its cut
    // chosen, on rank j % P; the ranks then share the cuts.
    std::vector<int> slot(d.tree_.size(), -1);
    for (std::size_t j = 0; j < pending.size(); ++j) slot[static_cast<std::size_t>(pending[j])] = static_cast<int>(j);
    std::map<int, std::vector<std::int64_t>> mine; // per pending box this rank's particles reach: slice_counts' layout
    for (std::size_t i = 0; i < home.size(); ++i) {
      const Index<D>& c = home[i];
      const std::int64_t w = weight.empty() ? 1 : weight[i];
      d.pieces(c, c[0], c[0] + (length.empty() ? 1 : length[i]), [&](int n, int lo, int hi) {
        const int j = slot[static_cast<std::size_t>(n)];
        const IndexBox<D>& box = d.tree_[static_cast<std::size_t>(n)].box;
        lo = std::max(lo, box.lo[0]), hi = std::min(hi, box.hi[0]);
        if (j < 0 || lo >= hi) return;
        for (int k = 1; k < D; ++k)
          if (c[k] < box.lo[k] || c[k] >= box.hi[k]) return;
        std::vector<std::int64_t>& v = mine[j];
        if (v.empty()) v.assign(slice_entries<D>(box), 0);
        v[static_cast<std::size_t>(lo - box.lo[0])] += w; // along axis 0 as differences
        v[static_cast<std::size_t>(hi - box.lo[0])] -= w;
        std::size_t at = static_cast<std::size_t>(box.extent(0)) + 1;
        for (int k = 1; k < D; ++k) {
          v[at + static_cast<std::size_t>(c[k] - box.lo[k])] += w * (hi - lo);
          at += static_cast<std::size_t>(box.extent(k));
        }
      });
    }
    std::vector<Bytes> send(static_cast<std::size_t>(comm.size()));
    for (const auto& [j, v] : mine) {
      Bytes& out = send[static_cast<std::size_t>(j % comm.size())];
      put(out, static_cast<std::int64_t>(j));
      put_bytes(out, v.data(), v.size() * sizeof(std::int64_t));
    }
    std::map<int, std::vector<std::int64_t>> sums; // the boxes this rank cuts
    std::vector<std::int64_t> part;
    for (const Bytes& in : comm.alltoall(std::move(send)))
      for (Reader rd(in); !rd.done();) {
        const int j = static_cast<int>(rd.get<std::int64_t>());
        std::vector<std::int64_t>& v = sums[j];
        v.resize(slice_entries<D>(d.tree_[static_cast<std::size_t>(pending[static_cast<std::size_t>(j)])].box), 0);
        part.resize(v.size());
        rd.get_bytes(part.data(), part.size() * sizeof(std::int64_t));
        for (std::size_t i = 0; i < v.size(); ++i) v[i] += part[i];
      }
    std::vector<std::int64_t> chosen(2 * pending.size(), 0); // per box: axis + 1 (0: none possible), cut; summed
    for (std::size_t j = static_cast<std::size_t>(comm.rank()); j < pending.size(); j += static_cast<std::size_t>(comm.size())) {
      const Node& node = d.tree_[static_cast<std::size_t>(pending[j])];
      std::vector<std::int64_t>& v = sums[static_cast<int>(j)];
      v.resize(slice_entries<D>(node.box), 0);
      const auto [axis, at] = choose_cut<D>(node.box, slice_counts(v, node.box.extent(0)), node.count);
      chosen[2 * j] = axis + 1, chosen[2 * j + 1] = at;
    }
    comm.sum(chosen);
    std::vector<int> next;
    for (std::size_t j = 0; j < pending.size(); ++j) {
      const int n = pending[j];
      const Node node = d.tree_[static_cast<std::size_t>(n)];
      const int below = node.count / 2, axis = static_cast<int>(chosen[2 * j]) - 1;
      require(axis >= 0, "the node lattice cannot be split over ", ranks, " ranks (a box of ", node.box.count(),
              " cells for ", node.count, " ranks): run with fewer ranks or a finer grid");
      Node lo{-1, 0, -1, -1, node.first, below, node.box}, hi{-1, 0, -1, -1, node.first + below, node.count - below,
                                                              node.box};
      lo.box.hi[axis] = node.box.lo[axis] + static_cast<int>(chosen[2 * j + 1]);
      hi.box.lo[axis] = lo.box.hi[axis];
      Node& parent = d.tree_[static_cast<std::size_t>(n)];
      parent.axis = axis;
      parent.cut = lo.box.hi[axis];
      parent.below = static_cast<int>(d.tree_.size());
      parent.above = parent.below + 1;
      d.tree_.push_back(lo);
      d.tree_.push_back(hi);
      for (int child : {d.tree_.size() - 2, d.tree_.size() - 1}) {
        const Node& c = d.tree_[static_cast<std::size_t>(child)];
        if (c.count > 1) next.push_back(child);
        else d.boxes_[static_cast<std::size_t>(c.first)] = c.box;
      }
    }
    pending = std::move(next);
  }
  return d;
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
