#pragma once
/// \file wall_transfer.hpp
/// The share of the walls' velocity changes in the kinetic energy the
/// particles' update loses against the nodes' (internal to engine/).
#include "otmpm/basis/basis.hpp"
#include "otmpm/core.hpp"
#include "otmpm/engine/constraints.hpp"
#include "otmpm/particles/particles.hpp"

#include <algorithm>
#include <utility>
#include <vector>

namespace otmpm {

/// The nodes a wall held and changed the velocity of in a pass whose change
/// the particles take up in the step, and the impact energy booked for them
/// (docs/theory.md eq. 6.6): with the lumped mass the particles' kinetic
/// energy changes by the nodes' plus T(Delta) = 1/2 sum_p m_p |sum_I N_Ip
/// Delta_I|^2 - 1/2 sum_I m_I |Delta_I|^2 <= 0, Delta_I the velocity change
/// they take up from node I; W_i gets T(Delta - g) - T(Delta), g_I the
/// normal part of Delta_I at the held nodes.
template <int D> struct WallTransfer {
  AlignedVector<Vec<D>> axis;   ///< per node: the holding wall's normal, zero elsewhere
  std::vector<int> noted;       ///< the nodes whose axis is not zero, in the order noted
  std::vector<char> is_noted;   ///< per node: in `noted` (booked skips the particles of none)
  std::vector<std::pair<int, Vec<D>>> touched; ///< a pass's wall changes: (node, velocity before)

  /// Notes node I (of `nodes`) with the normal of the first wall that holds it.
  void note(std::size_t I, const Constraints<D>& c, std::size_t nodes) {
    const auto& held = c.held();
    for (std::size_t w = 0; w < held.size(); ++w)
      if (I < held[w].size() && held[w][I]) {
        axis.resize(nodes, Vec<D>::Zero());
        is_noted.resize(nodes, 0);
        if (!is_noted[I]) noted.push_back(static_cast<int>(I));
        is_noted[I] = 1;
        axis[I] = c.walls()[w].normal;
        return;
      }
  }

  /// A node is noted.
  bool any() const { return !noted.empty(); }

  /// Forgets the noted nodes (a step that booked none of them, or after booking).
  void clear() {
    for (const int I : noted) {
      axis[static_cast<std::size_t>(I)] = Vec<D>::Zero();
      is_noted[static_cast<std::size_t>(I)] = 0;
    }
    noted.clear();
  }

  /// T(Delta - g) - T(Delta), change(I) = Delta_I: with d_p = sum_I N_Ip
  /// Delta_I and h_p = sum_I N_Ip g_I, |d|^2 - |d - h|^2 = h . (2 d - h).
  /// The nodes are summed where c.counts(I) (a distributed run's owned nodes).
  /// nodes_of(p0, p1, lo, hi): a node-id range [lo, hi] that holds every
  /// node of the rows of particles [p0, p1) (StepRows::node_range); a
  /// summing block whose range holds no noted node is skipped.
  /// `rows`: the step's rows as a pass reads them (rows.hpp, visit_row).
  template <class Change, class Rows, class NodesOf>
  double booked(Change&& change, const Rows& rows, const Particles<D>& P, const std::vector<double>& m,
                const Constraints<D>& c,
                NodesOf&& nodes_of) const; // engine.cpp (it sums over the particles in parallel blocks)
};

} // namespace otmpm
