/// \file constraints.cpp
/// Dirichlet constraints (constraints.hpp).
#include "otmpm/engine/constraints.hpp"
#include "otmpm/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

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
  vbar_.assign(constrained_.size(), 0.0);
  for (std::size_t i = 0; i < d_.node.size(); ++i) {
    const int I = d_.node[i];
    require<std::invalid_argument>(I >= 0 && I < nodes, "Constraints: node ", I, " out of range [0, ", nodes, ")");
    for (int k = 0; k < D; ++k) {
      require<std::invalid_argument>(std::isfinite(d_.value[i][k]), "Constraints: node ", I, " component ", k,
                                     ": prescribed velocity ", d_.value[i][k], " is not finite");
      if (d_.fix[i][k]) constrained_[static_cast<std::size_t>(I) * D + k] = 1, vbar_[static_cast<std::size_t>(I) * D + k] = d_.value[i][k];
    }
  }
  nodes_ = d_.node;
  std::sort(nodes_.begin(), nodes_.end());
  nodes_.erase(std::unique(nodes_.begin(), nodes_.end()), nodes_.end());
}

template <int D>
void Constraints<D>::book_fixed(std::size_t I, int k, double J, const Ledger<D>& ledger) const {
  const std::size_t c = I * D + static_cast<std::size_t>(k);
  if (!counts(static_cast<int>(I))) return;
  (*ledger.impulse)[k] += J;
  *ledger.work += J * vbar_[c];
}

template <int D>
void Constraints<D>::apply_velocity(AlignedVector<Vec<D>>& v, const NodeView<D>& nodes, const WallEffect<D>& effect,
                                    const Ledger<D>& ledger, bool first) {
  // Particles that read a rate take up the change of a held component's
  // value: in the first step a component held at a velocity jumps from what
  // they bring to it, nothing later (the value is constant); a support at
  // rest holds what reaches it. Particles that read v itself take every change.
  const bool jumps = effect.impulse && (first || !effect.rate);
  for (std::size_t i = 0; i < d_.node.size(); ++i) {
    const int I = d_.node[i];
    for (int k = 0; k < D; ++k) {
      if (!d_.fix[i][k]) continue;
      const double vbar = d_.value[i][k], before = v[I][k];
      const auto node = static_cast<std::size_t>(I);
      const double jump = effect.impulse ? vbar - effect.start(v, node)[k] : 0.0;
      v[I][k] = vbar;
      if (!jumps || (effect.rate && vbar == 0.0) || !nodes.active[I]) continue;
      Vec<D> dv = Vec<D>::Zero();
      dv[k] = vbar - before; // zero the second time a node listed by two sets is met
      if (effect.kick) (*effect.kick)[node] += dv;
      else effect.hand_on(node, dv);
      const double J = nodes.m[I] * dv[k];
      if (effect.booking == Booking::held) continue; // book_held
      // The jump from the start velocity to vbar (zero once the particles
      // carry vbar) takes its kinetic energy: a perfectly plastic impact.
      // Not where the particles read v itself (otm): their velocity is the
      // nodes' field, of which the node's start velocity is no part.
      if (counts(I) && dv[k] != 0.0 && effect.rate) *ledger.work -= 0.5 * nodes.m[I] * jump * jump;
      if (effect.booking == Booking::now || effect.kick) book_fixed(node, k, J, ledger);
      if (effect.booking != Booking::carried || effect.kick) continue;
      size_carried(v.size());
      carried_step_[0][node][k] += J; // booked by book_carried
    }
  }
}

template <int D> void Constraints<D>::apply_increment(AlignedVector<Vec<D>>& dx, double dt) const {
  for (std::size_t i = 0; i < d_.node.size(); ++i)
    for (int k = 0; k < D; ++k)
      if (d_.fix[i][k]) dx[d_.node[i]][k] = dt * d_.value[i][k];
}

template <int D>
void Constraints<D>::apply_force(AlignedVector<Vec<D>>& f, AlignedVector<Vec<D>>& reaction, double c,
                                 const Ledger<D>& ledger) const {
  // Only Dirichlet nodes carry a reaction (it stays zero elsewhere).
  for (int I : nodes_) reaction[I].setZero();
  for (std::size_t i = 0; i < d_.node.size(); ++i) {
    const int I = d_.node[i];
    for (int k = 0; k < D; ++k)
      if (d_.fix[i][k]) {
        // -= keeps the reaction of a node listed by two sets (its f is zero the second time)
        reaction[I][k] -= f[I][k];
        f[I][k] = 0.0;
      }
  }
  if (c != 0.0) book_reaction(reaction, c, ledger);
}

template <int D>
void Constraints<D>::book_reaction(const AlignedVector<Vec<D>>& rho, double c, const Ledger<D>& ledger) const {
  for (int I : nodes_)
    for (int k = 0; k < D; ++k)
      if (constrained_[static_cast<std::size_t>(I) * D + k]) book_fixed(static_cast<std::size_t>(I), k, c * rho[I][k], ledger);
}

template <int D>
double Constraints<D>::held_body_power(const Vec<D>& b, const AlignedVector<Vec<D>>& q, const std::vector<double>& m) const {
  double power = 0.0;
  if (b == Vec<D>::Zero()) return power;
  for (const int I : nodes_)
    for (int k = 0; k < D; ++k) {
      const std::size_t c = static_cast<std::size_t>(I) * D + static_cast<std::size_t>(k);
      if (constrained_[c] && counts(I)) power += b[k] * (q[I][k] - m[I] * vbar_[c]);
    }
  return power;
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
                                 const WallEffect<D>& effect, const Ledger<D>& ledger,
                                 std::vector<std::pair<int, Vec<D>>>* touched) {
  held_.resize(walls_.size());
  for (std::size_t w = 0; w < walls_.size(); ++w) {
    const Wall<D>& wall = walls_[w];
    const Vec<D> p = wall.point + t * wall.velocity;
    std::vector<char>& held = held_[w];
    held.resize(v.size(), 0);
    Vec<D> impulse = Vec<D>::Zero();
    const double reach = nodes.reach + std::max(wall.velocity.dot(wall.normal), 0.0) * dt;
    // Most nodes are out of reach with no contact to keep: the threads find
    // the others, in node order; the changes and their sums follow in order.
    std::vector<int> near;
    parallel_filter(
        nodes.active_nodes,
        [&](int node) {
          const auto I = static_cast<std::size_t>(node);
          return held[I] || !((nodes.x[I] - p).dot(wall.normal) > reach); // a NaN distance stays, as in the loop
        },
        near);
    for (const int node : near) {
      const auto I = static_cast<std::size_t>(node);
      const double d = (nodes.x[I] - p).dot(wall.normal);
      const double floor = -std::max(d, 0.0) / dt;
      const Vec<D> u = v[I] - wall.velocity;
      const double un = u.dot(wall.normal);
      const Vec<D> s = effect.start(v, I) - wall.velocity;
      // Particles that read v itself (otm) see a held node's normal velocity
      // stay at its floor from step to step: only a new contact stops them.
      const bool stops = effect.rate || !held[I];
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
        if (un >= floor || d > reach) continue;
        dn = floor - un; // a new contact: just the change that stops the approach
        held[I] = 1;
      }
      const Vec<D> dv = wall_change<D>(u, wall.normal, dn, wall.friction);
      if (touched) touched->emplace_back(node, v[I]);
      v[I] += dv;
      if (!effect.impulse) continue;
      effect.hand_on(I, dv);
      if (effect.booking == Booking::carried) {
        size_carried(v.size());
        carried_step_[1 + w][I] += nodes.m[I] * dv;
      }
      if (effect.booking == Booking::held || !counts(static_cast<int>(I))) continue; // held: book_held
      if (effect.booking == Booking::now)
        *ledger.friction += friction_loss<D>(nodes.m[I], s, u, dv, wall.normal);
      if (stops) *ledger.impact += impact_loss<D>(nodes.m[I], s, Vec<D>(u + dv), wall.normal);
      if (effect.booking == Booking::now) impulse += nodes.m[I] * dv; // the particles' momentum changes by m dv
    }
    if (!effect.impulse || effect.booking != Booking::now) continue;
    (counted_.empty() ? impulse_ : rank_impulse_)[w] += impulse;
    *ledger.work += impulse.dot(wall.velocity);
  }
}

template <int D> bool Constraints<D>::holds(std::size_t I, bool first) const {
  for (const std::vector<char>& held : held_)
    if (!held.empty() && held[I]) return true;
  if (first)
    for (int k = 0; k < D; ++k) {
      const std::size_t c = I * D + static_cast<std::size_t>(k);
      if (constrained_[c] && vbar_[c] != 0.0) return true;
    }
  return false;
}

template <int D>
void Constraints<D>::book_held(const Held<D>& step, AlignedVector<Vec<D>>& q, const NodeView<D>& nodes,
                               const Ledger<D>& ledger) {
  AlignedVector<Vec<D>>& wall_impulse = counted_.empty() ? impulse_ : rank_impulse_;
  held_.resize(walls_.size());
  // the inactive nodes get no kick (the nodes not visited hold zero)
  if (nodes.visited) {
    const std::vector<int>& visited = *nodes.visited;
    parallel_for(static_cast<long long>(visited.size()), [&](long long i) {
      const auto I = static_cast<std::size_t>(visited[static_cast<std::size_t>(i)]);
      if (!nodes.active[I]) q[I] = Vec<D>::Zero();
    });
  } else {
    parallel_for(static_cast<long long>(q.size()), [&](long long I) {
      if (!nodes.active[static_cast<std::size_t>(I)]) q[static_cast<std::size_t>(I)] = Vec<D>::Zero();
    });
  }
  // Most nodes get no kick: the threads zero theirs and find the held ones,
  // whose kicks and sums follow in node order.
  std::vector<int> kicked;
  parallel_filter(
      nodes.active_nodes,
      [&](int node) {
        const auto I = static_cast<std::size_t>(node);
        if (holds(I, step.first)) return true;
        q[I] = Vec<D>::Zero();
        return false;
      },
      kicked);
  for (const int node : kicked) {
    const auto I = static_cast<std::size_t>(node);
    const double m = nodes.m[I];
    const Vec<D> brought = q[I] / m;
    Vec<D> end = brought + step.dt * Vec<D>(step.f[I] / m); // the particles' velocity at the node after the step
    bool held = false;
    for (std::size_t w = 0; w < walls_.size(); ++w) {
      if (held_[w].empty() || !held_[w][I]) continue;
      held = true;
      const Wall<D>& wall = walls_[w];
      const double d = (nodes.x[I] - (wall.point + step.t * wall.velocity)).dot(wall.normal);
      const Vec<D> u = end - wall.velocity;
      const double dn = -std::max(d, 0.0) / step.dt - u.dot(wall.normal);
      if (dn <= 0.0) continue; // it leaves the wall at least as fast as the node: no pull
      const Vec<D> dv = wall_change<D>(u, wall.normal, dn, wall.friction);
      end += dv;
      if (!counts(static_cast<int>(I))) continue;
      *ledger.friction += friction_loss<D>(m, Vec<D>(brought - wall.velocity), u, dv, wall.normal);
      *ledger.impact += impact_loss<D>(m, Vec<D>(brought - wall.velocity), Vec<D>(u + dv), wall.normal);
      wall_impulse[w] += m * dv;
      *ledger.work += (m * dv).dot(wall.velocity);
    }
    for (int k = 0; k < D && step.first; ++k) {
      const std::size_t c = I * D + static_cast<std::size_t>(k);
      if (!constrained_[c] || vbar_[c] == 0.0) continue;
      held = true;
      // f is zero here (apply_force booked it); the jump from what the
      // particles brought is the set's.
      end[k] = vbar_[c];
      const double jump = vbar_[c] - brought[k];
      book_fixed(I, k, m * jump, ledger);
      if (counts(static_cast<int>(I))) *ledger.work -= 0.5 * m * jump * jump;
    }
    q[I] = held ? Vec<D>(end - brought - step.dt * step.rate[I]) : Vec<D>::Zero(); // the kick
  }
}

template <int D> void Constraints<D>::size_carried(std::size_t nodes) {
  if (carried_step_.size() == walls_.size() + 1 && zeroed_.size() == nodes) return;
  carried_.resize(walls_.size() + 1);
  carried_step_.resize(walls_.size() + 1);
  for (std::size_t s = 0; s < carried_.size(); ++s) {
    if (carried_[s].size() != nodes) carried_[s].assign(nodes, Vec<D>::Zero());
    carried_step_[s].assign(nodes, Vec<D>::Zero());
  }
  zeroed_.assign(nodes, Vec<D>::Zero());
}

template <int D> void Constraints<D>::zero_carried(AlignedVector<Vec<D>>& a, const std::vector<double>& m) {
  size_carried(a.size());
  for (std::size_t i = 0; i < d_.node.size(); ++i) {
    const int I = d_.node[i];
    for (int k = 0; k < D; ++k)
      if (d_.fix[i][k]) {
        zeroed_[I][k] += m[I] * a[I][k];
        a[I][k] = 0.0;
      }
  }
}

template <int D> void Constraints<D>::book_carried(const Carried<D>& step, const Ledger<D>& ledger) {
  const AlignedVector<Vec<D>>& reaction = step.reaction;
  size_carried(reaction.size());
  AlignedVector<Vec<D>>& wall_impulse = counted_.empty() ? impulse_ : rank_impulse_;
  // One node of source s (0: the Dirichlet sets, 1 + w: wall w): its part
  // of the new total, the momentum the particles take up now (returned).
  auto carry = [&](std::size_t s, std::size_t I, const Vec<D>& removed, const Vec<D>& z) {
    const Vec<D> J = step.take_up(carried_[s][I], removed, z, carried_step_[s][I]);
    carried_step_[s][I] = Vec<D>::Zero();
    return J;
  };
  for (int I : nodes_) {
    const auto node = static_cast<std::size_t>(I);
    const Vec<D> J = carry(0, node, reaction[node], zeroed_[node]);
    zeroed_[node] = Vec<D>::Zero();
    for (int k = 0; k < D; ++k)
      if (constrained_[node * D + static_cast<std::size_t>(k)]) book_fixed(node, k, J[k], ledger);
  }
  for (std::size_t w = 0; w < walls_.size(); ++w)
    for (std::size_t I = 0; I < reaction.size(); ++I) {
      const Vec<D> J = carry(1 + w, I, Vec<D>::Zero(), Vec<D>::Zero());
      if (!counts(static_cast<int>(I)) || J == Vec<D>::Zero()) continue;
      wall_impulse[w] += J;
      *ledger.work += J.dot(walls_[w].velocity);
      *ledger.friction +=
          friction_loss<D>(J, Vec<D>(step.mean2(I) - 2.0 * walls_[w].velocity), walls_[w].normal);
    }
}

template <int D>
void Constraints<D>::apply_walls_to_increment(AlignedVector<Vec<D>>& dx, const NodeView<D>& nodes, double t,
                                              double dt) const {
  for (const Wall<D>& wall : walls_) {
    const Vec<D> p = wall.point + t * wall.velocity;
    parallel_for(static_cast<long long>(nodes.active_nodes.size()), [&](long long i) {
      const int I = nodes.active_nodes[static_cast<std::size_t>(i)];
      const double d = (nodes.x[I] - p).dot(wall.normal);
      const Vec<D> u = dx[I] - dt * wall.velocity;
      const double floor = -std::max(d, 0.0), un = u.dot(wall.normal);
      if (un < floor) dx[I] += wall_change<D>(u, wall.normal, floor - un, wall.friction);
    });
  }
}

template class Constraints<1>;
template class Constraints<2>;
template class Constraints<3>;

} // namespace otmpm
