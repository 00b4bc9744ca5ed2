/// \file contact.cpp
/// Body-body contact on the field nodes (contact.hpp).
#include "otmpm/engine/contact.hpp"

#include "otmpm/parallel.hpp"

#include <cmath>
#include <stdexcept>

namespace otmpm {

template <int D>
BodyContact<D>::BodyContact(int nodes, int bodies, ContactLaw law) : nodes_(nodes), fields_(bodies), law_(law) {
  using E = std::invalid_argument;
  require<E>(nodes >= 1 && bodies >= 2, "BodyContact: ", nodes, " nodes and ", bodies,
             " bodies (contact needs nodes and two bodies)");
  require<E>(std::isfinite(law.friction) && law.friction >= 0.0, "BodyContact: friction ", law.friction,
             " must be finite and >= 0");
  grad_m_.assign(static_cast<std::size_t>(nodes) * fields_, Vec<D>::Zero());
  held_.assign(static_cast<std::size_t>(nodes) * pairs(), 0);
}

template <int D> void BodyContact<D>::remap(BasisTable<D>& table, const std::vector<int>& body) const {
  parallel_for(table.rows(), [&](long long p) {
    const int shift = body[static_cast<std::size_t>(p)] * nodes_;
    for (int e = table.begin(static_cast<int>(p)); e < table.end(static_cast<int>(p)); ++e) table.node[e] += shift;
  });
}

template <int D> Vec<D> BodyContact<D>::normal(int I, int a, int b) const {
  const Vec<D>& ga = grad_m_[static_cast<std::size_t>(I + a * nodes_)];
  const Vec<D>& gb = grad_m_[static_cast<std::size_t>(I + b * nodes_)];
  // g = sum_p m_p grad N_I(x_p) points out of a body at its surface; the
  // normal from a to b is g_a/|g_a| or -g_b/|g_b|: the larger gradient's,
  // i.e. that of the body whose surface is better resolved at this node (an
  // average tilts the normal at a corner of one body sliding along a flat
  // face of the other, and the corner then "collides" with the face).
  const double na = ga.norm(), nb = gb.norm();
  if (na >= nb) return na > 0.0 ? Vec<D>(ga / na) : Vec<D>::Zero();
  return Vec<D>(-gb / nb);
}

template <int D>
Vec<D> BodyContact<D>::share(int Ja, int Jb, Vec<D> du, AlignedVector<Vec<D>>& v, const ContactNodes& nodes,
                             const WallEffect<D>& effect) const {
  for (int k = 0; k < D; ++k)
    if (nodes.constrained[static_cast<std::size_t>(Ja) * D + k] || nodes.constrained[static_cast<std::size_t>(Jb) * D + k])
      du[k] = 0.0;
  const double ma = nodes.m[static_cast<std::size_t>(Ja)], mb = nodes.m[static_cast<std::size_t>(Jb)];
  const Vec<D> dva = (mb / (ma + mb)) * du, dvb = (-ma / (ma + mb)) * du;
  v[Ja] += dva;
  v[Jb] += dvb;
  if (effect.impulse) {
    effect.hand_on(static_cast<std::size_t>(Ja), dva);
    effect.hand_on(static_cast<std::size_t>(Jb), dvb);
  }
  return du;
}

template <int D>
void BodyContact<D>::apply(AlignedVector<Vec<D>>& v, const ContactNodes& nodes, const WallEffect<D>& effect,
                           double& friction, double& impact) {
  const int P = pairs();
  loss_.assign(static_cast<std::size_t>(nodes_), 0.0);
  impact_.assign(static_cast<std::size_t>(nodes_), 0.0);
  const std::size_t slots = static_cast<std::size_t>(nodes_) * static_cast<std::size_t>(P);
  if (effect.booking == Booking::carried && carried_step_.size() != slots)
    carried_step_.assign(slots, Vec<D>::Zero());
  parallel_for(nodes_, [&](long long node) {
    const int I = static_cast<int>(node);
    for (int a = 0, k = 0; a < fields_; ++a)
      for (int b = a + 1; b < fields_; ++b, ++k) {
        char& held = held_[static_cast<std::size_t>(I) * P + k];
        const int Ja = I + a * nodes_, Jb = I + b * nodes_;
        const Vec<D> n = nodes.active[Ja] && nodes.active[Jb] ? normal(I, a, b) : Vec<D>::Zero();
        if (n.isZero()) {
          held = 0;
          continue;
        }
        const Vec<D> u = v[Ja] - v[Jb];
        const Vec<D> start = effect.start(v, static_cast<std::size_t>(Ja)) - effect.start(v, static_cast<std::size_t>(Jb));
        const double s = -u.dot(n); // separation velocity
        double ds;
        if (held) {
          // Held: s stays at 0 - by losing the relative normal rate
          // (hold_rate) or by being set there - until holding would pull.
          ds = effect.impulse && effect.hold_rate ? -effect.c * ((*effect.rate)[Jb] - (*effect.rate)[Ja]).dot(n) : -s;
          if (effect.impulse && ds < 0.0) {
            held = 0;
            continue;
          }
        } else {
          if (s >= 0.0) continue;
          ds = -s; // a new contact: just the change that stops the approach
          held = 1;
        }
        // From a's side, b is a wall with normal -n moving at v_b.
        const Vec<D> du = share(Ja, Jb, wall_change<D>(u, Vec<D>(-n), ds, law_.friction), v, nodes, effect);
        if (!effect.impulse) continue;
        // The pair's kinetic energy relative to its centre of mass is
        // mu* |u|^2 / 2 with the reduced mass mu* = m_a m_b / (m_a + m_b);
        // the particles take up reach x the change.
        const double ma = nodes.m[static_cast<std::size_t>(Ja)], mb = nodes.m[static_cast<std::size_t>(Jb)];
        const double reduced = effect.reach * ma * mb / (ma + mb);
        if (effect.booking == Booking::carried)
          carried_step_[static_cast<std::size_t>(I) * P + k] += reduced * du;
        else
          loss_[static_cast<std::size_t>(I)] += friction_loss<D>(reduced, start, u, du, n);
        impact_[static_cast<std::size_t>(I)] += impact_loss<D>(reduced, start, Vec<D>(u + du), n);
      }
  });
  if (!effect.impulse) return;
  // Summed in fixed blocks of nodes: the same bits for any thread count.
  struct Sum {
    double friction = 0.0, impact = 0.0;
    Sum& operator+=(const Sum& o) {
      friction += o.friction;
      impact += o.impact;
      return *this;
    }
  };
  const Sum sum = blocked_reduce<Sum>(nodes_, [&](long long I, Sum& acc) {
    acc.friction += loss_[static_cast<std::size_t>(I)];
    acc.impact += impact_[static_cast<std::size_t>(I)];
  });
  friction += sum.friction;
  impact += sum.impact;
}

template <int D>
void BodyContact<D>::book_carried(const Carried<D>& step, const std::vector<char>& active, double& friction) {
  const int P = pairs();
  const std::size_t slots = static_cast<std::size_t>(nodes_) * static_cast<std::size_t>(P);
  if (carried_.size() != slots) carried_.assign(slots, Vec<D>::Zero());
  if (carried_step_.size() != slots) carried_step_.assign(slots, Vec<D>::Zero());
  loss_.assign(static_cast<std::size_t>(nodes_), 0.0);
  parallel_for(nodes_, [&](long long node) {
    const int I = static_cast<int>(node);
    for (int a = 0, k = 0; a < fields_; ++a)
      for (int b = a + 1; b < fields_; ++b, ++k) {
        const std::size_t slot = static_cast<std::size_t>(I) * P + k;
        const Vec<D> J = step.take_up(carried_[slot], Vec<D>::Zero(), Vec<D>::Zero(), carried_step_[slot]);
        carried_step_[slot] = Vec<D>::Zero();
        const auto Ja = static_cast<std::size_t>(I + a * nodes_),
                   Jb = static_cast<std::size_t>(I + b * nodes_);
        const Vec<D> n = active[Ja] && active[Jb] ? normal(I, a, b) : Vec<D>::Zero();
        if (J == Vec<D>::Zero() || n.isZero()) continue; // no slip to take it: a body has left the node
        loss_[static_cast<std::size_t>(I)] += friction_loss<D>(J, Vec<D>(step.mean2(Ja) - step.mean2(Jb)), n);
      }
  });
  friction += blocked_reduce<double>(
      nodes_, [&](long long I, double& acc) { acc += loss_[static_cast<std::size_t>(I)]; });
}

template <int D> void BodyContact<D>::apply_to_increment(AlignedVector<Vec<D>>& dx, const ContactNodes& nodes) const {
  const int P = pairs();
  parallel_for(nodes_, [&](long long node) {
    const int I = static_cast<int>(node);
    for (int a = 0, k = 0; a < fields_; ++a)
      for (int b = a + 1; b < fields_; ++b, ++k) {
        if (!held_[static_cast<std::size_t>(I) * P + k]) continue;
        const int Ja = I + a * nodes_, Jb = I + b * nodes_;
        const Vec<D> n = normal(I, a, b);
        const double s = (dx[Jb] - dx[Ja]).dot(n);
        if (s < 0.0) share(Ja, Jb, Vec<D>(s * n), dx, nodes, {});
      }
  });
}

template class BodyContact<1>;
template class BodyContact<2>;
template class BodyContact<3>;

} // namespace otmpm
