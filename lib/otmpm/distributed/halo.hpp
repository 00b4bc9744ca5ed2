#pragma once
/// \file halo.hpp
/// The nodal exchange of a distributed run: each rank sums its particles
/// into the points of its window; the partial sums on ghost points go to
/// their owners, which add them (in increasing rank order, so the bits do
/// not depend on message timing) and send the totals back to every rank
/// that holds the point as a ghost. Afterwards every rank has the complete
/// sums on all its local points, and the node-wise stages of a step
/// (mass solve, Dirichlet, increments) give the same values on a ghost as
/// on its owner.
#include "otmpm/distributed/lattice.hpp"
#include "otmpm/engine/distribution.hpp"

#include <span>
#include <vector>

namespace otmpm::distributed {

template <int D> class NodeExchange {
public:
  NodeExchange() = default;
  /// The exchange lists of `rank`: for every other rank q, this rank's
  /// ghost points owned by q and its own points in q's window, both in
  /// lattice order (so both sides list the same points in the same order
  /// without asking each other).
  NodeExchange(const PointLattice<D>& lattice, const Decomposition<D>& decomposition, int rank);

  const Window<D>& window() const { return window_; }
  /// Per local point: 1 when this rank owns it.
  const std::vector<char>& owned() const { return owned_; }
  /// Sums the partial nodal sums over the ranks and copies the totals to
  /// the ghosts (collective over the ranks of `comm`); returns the bytes
  /// this rank sent.
  long long sum(const Comm& comm, std::span<const NodalArray> fields);
  /// Bytes this rank sent in exchanges since construction.
  long long bytes_sent() const { return bytes_sent_; }
  /// Ranks this rank exchanges nodal values with, ascending.
  const std::vector<int>& neighbours() const { return ranks_; }
  /// Per neighbour: the local ids of its points in this window (ghosts),
  /// and of this rank's points in its window, in lattice order.
  const std::vector<std::vector<int>>& ghosts() const { return ghosts_; }
  const std::vector<std::vector<int>>& shared() const { return shared_; }
  /// Local ids of this rank's ghost points (owned by another rank).
  int ghost_count() const;

private:
  Window<D> window_;
  std::vector<int> ranks_;                ///< neighbours, ascending
  std::vector<std::vector<int>> ghosts_;  ///< per neighbour: local ids of its points in this window
  std::vector<std::vector<int>> shared_;  ///< per neighbour: local ids of own points in its window
  std::vector<char> owned_;
  long long bytes_sent_ = 0;
};

extern template class NodeExchange<1>;
extern template class NodeExchange<2>;
extern template class NodeExchange<3>;

} // namespace otmpm::distributed
