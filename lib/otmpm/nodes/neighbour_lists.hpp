#pragma once
/// \file neighbour_lists.hpp
/// Verlet (skin) lists for the neighbour search of a set of points that move
/// a little every step (the particles, for the max-ent families): for each
/// point p the ids of the nodes within radius + skin of the position x_p had
/// when its list was built. Nodes that were farther than radius + skin are
/// still farther than radius while
///
///     |x_p - x_p^built - T| + max_I |x_I - x_I^built - T| <= skin
///
/// for any common translation T (triangle inequality; T is the centre of the
/// box of the node displacements, so that a rigid translation of the whole
/// set, as in `ul` mode, costs nothing). A query then scans the list instead
/// of searching the node set; a point that moved too far gets its list rebuilt
/// by NodeSet::within. Lists hold ascending ids, and candidates() is followed
/// by the exact distance test, so the result is exactly what NodeSet::within
/// returns, in the same order: the lists change the cost, never the answer.
#include "otmpm/nodes/node_set.hpp"

#include <atomic>
#include <span>
#include <vector>

namespace otmpm {

template <int D> class NeighbourLists {
public:
  /// Skin as a fraction of the node spacing h.
  static constexpr double default_skin = 0.25;

  NeighbourLists() = default;
  NeighbourLists(const NeighbourLists& o) { *this = o; }
  NeighbourLists& operator=(const NeighbourLists& o);

  /// Call before a round of candidates() queries (not concurrently with
  /// them): sizes the lists for `points` points and search radius `radius`
  /// (a new radius, point count or node count drops every list), measures how
  /// far the nodes moved since the lists were built (all lists are dropped
  /// once that drift exceeds half the skin) and grows the capacity per point
  /// when a list did not fit during the last round. Also builds the node
  /// set's search index (NodeSet::prepare_search). std::invalid_argument for
  /// points < 0 or a radius that is not finite and > 0.
  void prepare(const NodeSet<D>& nodes, int points, double radius);

  /// A superset of the nodes within `radius` of x (the radius of prepare()),
  /// in ascending id: the list of point p when it is still valid for x, else
  /// the nodes within radius + skin of x, stored as p's new list when they
  /// fit (else left in `scratch` only). Thread-safe for distinct p. The span
  /// stays valid until the next call for p or prepare().
  std::span<const int> candidates(const NodeSet<D>& nodes, int p, const Vec<D>& x, std::vector<int>& scratch);

  /// Entries reserved per point (0 before the first list was built).
  int capacity() const { return capacity_; }
  /// Lists (re)built since the last prepare().
  long long rebuilt() const { return rebuilt_.load(std::memory_order_relaxed); }

private:
  void drop_all();

  double radius_ = 0.0, skin_ = 0.0;
  int points_ = 0, capacity_ = 0;
  std::vector<int> ids_;   ///< capacity_ entries per point
  std::vector<int> count_; ///< entries of each list; -1: no list
  AlignedVector<Vec<D>> x_built_;
  AlignedVector<Vec<D>> nodes_built_;
  Vec<D> translation_ = Vec<D>::Zero(); ///< T of the node displacements
  double drift_ = 0.0;                  ///< max_I |x_I - x_I^built - T|
  std::atomic<int> largest_{0};         ///< largest list seen that did not fit
  std::atomic<long long> rebuilt_{0};
};

extern template class NeighbourLists<1>;
extern template class NeighbourLists<2>;
extern template class NeighbourLists<3>;

} // namespace otmpm
