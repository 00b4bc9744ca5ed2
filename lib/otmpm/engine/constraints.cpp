/// \file constraints.cpp
/// Dirichlet constraints (constraints.hpp).
#include "otmpm/engine/constraints.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace otmpm {

template <int D> Constraints<D>::Constraints(Dirichlet<D> dirichlet, int nodes) : d_(std::move(dirichlet)) {
  require<std::invalid_argument>(d_.fix.size() == d_.node.size() && d_.value.size() == d_.node.size(),
                                 "Constraints: ", d_.node.size(), " nodes but ", d_.fix.size(), " fix flags and ",
                                 d_.value.size(), " values");
  constrained_.assign(static_cast<std::size_t>(nodes) * D, 0);
  for (std::size_t i = 0; i < d_.node.size(); ++i) {
    const int I = d_.node[i];
    require<std::invalid_argument>(I >= 0 && I < nodes, "Constraints: node ", I, " out of range [0, ", nodes, ")");
    for (int k = 0; k < D; ++k) {
      require<std::invalid_argument>(std::isfinite(d_.value[i][k]), "Constraints: node ", I, " component ", k,
                                     ": prescribed velocity ", d_.value[i][k], " is not finite");
      if (d_.fix[i][k]) constrained_[static_cast<std::size_t>(I) * D + k] = 1;
    }
  }
  nodes_ = d_.node;
  std::sort(nodes_.begin(), nodes_.end());
  nodes_.erase(std::unique(nodes_.begin(), nodes_.end()), nodes_.end());
}

template <int D> void Constraints<D>::apply_velocity(AlignedVector<Vec<D>>& v) const {
  for (std::size_t i = 0; i < d_.node.size(); ++i)
    for (int k = 0; k < D; ++k)
      if (d_.fix[i][k]) v[d_.node[i]][k] = d_.value[i][k];
}

template <int D>
void Constraints<D>::apply_force(AlignedVector<Vec<D>>& f, AlignedVector<Vec<D>>& reaction, double dt,
                                 Vec<D>& impulse, double& work) const {
  // Only Dirichlet nodes carry a reaction (it stays zero elsewhere).
  for (int I : nodes_) reaction[I].setZero();
  for (std::size_t i = 0; i < d_.node.size(); ++i) {
    const int I = d_.node[i];
    for (int k = 0; k < D; ++k)
      if (d_.fix[i][k]) {
        // -= keeps the reaction of a node listed by two sets (its f is zero
        // the second time); the work uses the prescribed velocity, which is
        // what every integrator sets on this component during the step.
        reaction[I][k] -= f[I][k];
        if (counts(I)) work -= dt * f[I][k] * d_.value[i][k];
        f[I][k] = 0.0;
      }
  }
  // In node order, as a sum over all nodes would add them (the others add zero).
  for (int I : nodes_)
    if (counts(I)) impulse += dt * reaction[I];
}

template <int D> double Constraints<D>::prescribed_kinetic_energy(const std::vector<double>& m) const {
  double e = 0.0;
  for (std::size_t i = 0; i < d_.node.size(); ++i)
    for (int k = 0; k < D; ++k)
      if (d_.fix[i][k] && counts(d_.node[i])) e += 0.5 * m[d_.node[i]] * d_.value[i][k] * d_.value[i][k];
  return e;
}

template class Constraints<1>;
template class Constraints<2>;
template class Constraints<3>;

} // namespace otmpm
