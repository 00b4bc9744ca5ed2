/// \file constraints.cpp
/// Dirichlet constraints (constraints.hpp).
#include "otmpm/engine/constraints.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace otmpm {

template <int D>
Constraints<D>::Constraints(Dirichlet<D> dirichlet, std::vector<Wall<D>> walls, int nodes)
    : d_(std::move(dirichlet)), walls_(std::move(walls)), impulse_(walls_.size(), Vec<D>::Zero()) {
  for (Wall<D>& w : walls_) {
    require<std::invalid_argument>(w.point.allFinite() && w.velocity.allFinite() && std::isfinite(w.friction) &&
                                       w.friction >= 0.0,
                                   "Constraints: wall '", w.name, "': point, velocity and friction >= 0 must be finite");
    require<std::invalid_argument>(is_direction<D>(w.normal), "Constraints: wall '", w.name,
                                   "': the normal must be finite and non-zero");
    w.normal = w.normal.stableNormalized();
  }
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

template <int D> void Constraints<D>::zero_fixed(AlignedVector<Vec<D>>& r) const {
  for (std::size_t i = 0; i < d_.node.size(); ++i)
    for (int k = 0; k < D; ++k)
      if (d_.fix[i][k]) r[d_.node[i]][k] = 0.0;
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

template <int D>
void Constraints<D>::apply_walls(AlignedVector<Vec<D>>& v, const NodeView<D>& nodes, double t, double dt,
                                 const WallEffect<D>& effect, double& work) {
  held_.resize(walls_.size());
  for (std::size_t w = 0; w < walls_.size(); ++w) {
    const Wall<D>& wall = walls_[w];
    const Vec<D> p = wall.point + t * wall.velocity;
    std::vector<char>& held = held_[w];
    held.resize(v.size(), 0);
    Vec<D> impulse = Vec<D>::Zero();
    for (std::size_t I = 0; I < v.size(); ++I) {
      if (!nodes.active[I]) continue;
      const double d = (nodes.x[I] - p).dot(wall.normal), floor = -std::max(d, 0.0) / dt;
      const Vec<D> u = v[I] - wall.velocity;
      const double un = u.dot(wall.normal);
      double dn;
      if (held[I]) {
        // Held: its normal velocity stays at the floor - by losing its normal
        // rate (hold_rate) or by being set there - until the wall would have
        // to pull it (decided where the change is the body's impulse; a
        // stress-only pass holds both ways).
        dn = effect.impulse && effect.hold_rate ? -effect.c * (*effect.rate)[I].dot(wall.normal) : floor - un;
        if (effect.impulse && dn < 0.0) {
          held[I] = 0;
          continue;
        }
      } else {
        if (un >= floor) continue;
        dn = floor - un; // a new contact: just the change that stops the approach
        held[I] = 1;
      }
      const Vec<D> dv = wall_change<D>(u, wall.normal, dn, wall.friction);
      v[I] += dv;
      if (effect.rate) (*effect.rate)[I] += dv / effect.c;
      if (counts(static_cast<int>(I)))
        impulse += nodes.m[I] * dv; // the particles' momentum changes by m dv dt / c through the rate
    }
    if (!effect.impulse) continue;
    if (effect.rate) impulse *= dt / effect.c;
    (counted_.empty() ? impulse_ : rank_impulse_)[w] += impulse;
    work += impulse.dot(wall.velocity);
  }
}

template <int D>
void Constraints<D>::apply_walls_to_increment(AlignedVector<Vec<D>>& dx, const NodeView<D>& nodes, double t,
                                              double dt) const {
  for (const Wall<D>& wall : walls_) {
    const Vec<D> p = wall.point + t * wall.velocity;
    for (std::size_t I = 0; I < dx.size(); ++I) {
      if (!nodes.active[I]) continue;
      const double d = (nodes.x[I] - p).dot(wall.normal);
      const Vec<D> u = dx[I] - dt * wall.velocity;
      const double floor = -std::max(d, 0.0), un = u.dot(wall.normal);
      if (un < floor) dx[I] += wall_change<D>(u, wall.normal, floor - un, wall.friction);
    }
  }
}

template class Constraints<1>;
template class Constraints<2>;
template class Constraints<3>;

} // namespace otmpm
