#pragma once
/// \file constraints.hpp
/// Dirichlet constraints on node velocities (docs/theory.md sect.
/// 6): listed node components are held at a prescribed velocity;
/// their force components are removed from the nodal forces and kept as
/// reactions, whose impulse and work enter the energy balance.
#include "otmpm/core.hpp"

#include <array>
#include <vector>

namespace otmpm {

/// A Dirichlet set: node ids and, per entry, which components are fixed and
/// their prescribed velocity (a node may appear in several entries).
template <int D> struct Dirichlet {
  std::vector<int> node;
  std::vector<std::array<bool, 3>> fix;
  std::vector<std::array<double, 3>> value;
};

/// The constraints of a run with the bookkeeping derived from them.
template <int D> class Constraints {
public:
  Constraints() = default;
  /// std::invalid_argument unless every node id lies in [0, nodes) and the
  /// prescribed values are finite.
  Constraints(Dirichlet<D> dirichlet, int nodes);

  const Dirichlet<D>& dirichlet() const { return d_; }
  /// constrained()[I * D + k]: component k of node I is fixed.
  const std::vector<char>& constrained() const { return constrained_; }
  /// Sets the fixed components of a nodal velocity-like field to their value.
  void apply_velocity(AlignedVector<Vec<D>>& v) const;
  /// Moves the fixed components of f into `reaction` (zeroing them in f),
  /// adds their impulse dt R to `impulse` and their work dt R . v_prescribed
  /// to `work`.
  void apply_force(AlignedVector<Vec<D>>& f, AlignedVector<Vec<D>>& reaction, double dt, Vec<D>& impulse,
                   double& work) const;
  /// sum over fixed components of 1/2 m_I v_prescribed^2 (zero for fixed supports).
  double prescribed_kinetic_energy(const std::vector<double>& m) const;
  /// Only the nodes with counted[I] != 0 add to the impulse, the work and
  /// the prescribed kinetic energy (a rank of a distributed run counts the
  /// nodes it owns; its ghost nodes are constrained all the same). Default:
  /// every node counts.
  void count_only(std::vector<char> counted) { counted_ = std::move(counted); }

private:
  Dirichlet<D> d_;
  std::vector<int> nodes_;       ///< the distinct nodes of d_.node, ascending
  std::vector<char> constrained_;
  std::vector<char> counted_; ///< empty: every node counts
  bool counts(int I) const { return counted_.empty() || counted_[static_cast<std::size_t>(I)]; }
};

extern template class Constraints<1>;
extern template class Constraints<2>;
extern template class Constraints<3>;

} // namespace otmpm
