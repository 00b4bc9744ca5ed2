/// \file neighbour_lists.cpp
/// Verlet (skin) lists over a node set (see neighbour_lists.hpp).
#include "otmpm/nodes/neighbour_lists.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace otmpm {

namespace {
/// Relative slack on the validity test, far above the round-off of the
/// distances involved (a few ulps of the coordinates).
constexpr double kSkinSlack = 1e-9;
/// Capacity per point after a list did not fit: the largest list seen times
/// this, plus kCapacityExtra.
constexpr double kCapacityGrowth = 1.25;
constexpr int kCapacityExtra = 4;
} // namespace

template <int D> NeighbourLists<D>& NeighbourLists<D>::operator=(const NeighbourLists& o) {
  if (this == &o) return *this;
  radius_ = o.radius_;
  skin_ = o.skin_;
  points_ = o.points_;
  capacity_ = o.capacity_;
  ids_ = o.ids_;
  count_ = o.count_;
  x_built_ = o.x_built_;
  nodes_built_ = o.nodes_built_;
  translation_ = o.translation_;
  drift_ = o.drift_;
  largest_.store(o.largest_.load());
  rebuilt_.store(o.rebuilt_.load());
  return *this;
}

template <int D> void NeighbourLists<D>::drop_all() {
  std::fill(count_.begin(), count_.end(), -1);
  translation_.setZero();
  drift_ = 0.0;
}

template <int D> void NeighbourLists<D>::prepare(const NodeSet<D>& nodes, int points, double radius) {
  require<std::invalid_argument>(points >= 0, "NeighbourLists::prepare: points must be >= 0, got ", points);
  require<std::invalid_argument>(finite_positive(radius),
                                 "NeighbourLists::prepare: radius must be finite and > 0, got ", radius);
  nodes.prepare_search();
  rebuilt_.store(0, std::memory_order_relaxed);
  const auto& x = nodes.positions();
  if (radius != radius_ || points != points_ || x.size() != nodes_built_.size()) {
    radius_ = radius;
    skin_ = default_skin * nodes.spacing();
    points_ = points;
    count_.assign(static_cast<std::size_t>(points), -1);
    x_built_.resize(static_cast<std::size_t>(points));
    ids_.assign(static_cast<std::size_t>(points) * static_cast<std::size_t>(capacity_), 0);
    nodes_built_ = x;
    drop_all();
  } else if (!x.empty()) {
    // T = centre of the box of node displacements; drift = max |dx_I - T|.
    Vec<D> lo = x[0] - nodes_built_[0], hi = lo;
    for (std::size_t I = 1; I < x.size(); ++I) {
      const Vec<D> d = x[I] - nodes_built_[I];
      lo = lo.cwiseMin(d);
      hi = hi.cwiseMax(d);
    }
    translation_ = 0.5 * (lo + hi);
    double drift2 = 0.0;
    for (std::size_t I = 0; I < x.size(); ++I)
      drift2 = std::max(drift2, (x[I] - nodes_built_[I] - translation_).squaredNorm());
    drift_ = std::sqrt(drift2);
    if (!(drift_ <= 0.5 * skin_)) { // also for a non-finite drift
      nodes_built_ = x;
      drop_all();
    }
  }
  if (const int largest = largest_.exchange(0); largest > capacity_) {
    capacity_ = static_cast<int>(kCapacityGrowth * largest) + kCapacityExtra;
    ids_.assign(static_cast<std::size_t>(points) * static_cast<std::size_t>(capacity_), 0);
    std::fill(count_.begin(), count_.end(), -1);
  }
}

template <int D>
std::span<const int> NeighbourLists<D>::candidates(const NodeSet<D>& nodes, int p, const Vec<D>& x,
                                                   std::vector<int>& scratch) {
  require<std::invalid_argument>(p >= 0 && p < points_, "NeighbourLists::candidates: point ", p, " of ",
                                 points_);
  const std::size_t slot = static_cast<std::size_t>(p) * static_cast<std::size_t>(capacity_);
  const Vec<D> moved = x - translation_;
  const int count = count_[static_cast<std::size_t>(p)];
  // Valid list: |x - T - x_built| + drift <= skin (see the file comment).
  if (count >= 0 &&
      (moved - x_built_[static_cast<std::size_t>(p)]).norm() + drift_ <= (1.0 - kSkinSlack) * skin_)
    return {ids_.data() + slot, static_cast<std::size_t>(count)};
  // Built with radius + skin + drift: nodes left out stay beyond `radius`
  // while the point and the nodes move by at most skin - drift from here.
  scratch.clear();
  nodes.within(x, radius_ + skin_ + drift_, scratch);
  rebuilt_.fetch_add(1, std::memory_order_relaxed);
  const int size = static_cast<int>(scratch.size());
  if (size > capacity_ || !x.allFinite()) {
    count_[static_cast<std::size_t>(p)] = -1;
    int seen = largest_.load(std::memory_order_relaxed);
    while (size > seen && !largest_.compare_exchange_weak(seen, size, std::memory_order_relaxed)) {
    }
    return {scratch.data(), scratch.size()};
  }
  std::copy(scratch.begin(), scratch.end(), ids_.begin() + static_cast<std::ptrdiff_t>(slot));
  count_[static_cast<std::size_t>(p)] = size;
  x_built_[static_cast<std::size_t>(p)] = moved;
  return {ids_.data() + slot, static_cast<std::size_t>(size)};
}

template class NeighbourLists<1>;
template class NeighbourLists<2>;
template class NeighbourLists<3>;

} // namespace otmpm
