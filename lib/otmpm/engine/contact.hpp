#pragma once
/// \file contact.hpp
/// Body-body contact on the fixed grid (docs/theory.md sect. 6.2), after
/// Bardenhagen, Brackbill & Sulsky (2000): every body carries its own copy
/// of the nodal fields, and where two bodies have mass at one node and
/// approach each other along the contact normal, their nodal velocities are
/// corrected so that they no longer approach, with Coulomb friction on the
/// tangential slip.
///
/// The copies are laid out as "field nodes": field b of node I is the index
/// I + b N (N nodes). The engine remaps its basis table so that particle p
/// of body b addresses the nodes of field b; every stage of a step (mass,
/// momentum and forces to the nodes, the mass solve, the walls and Dirichlet
/// sets, the node-to-particle map) then runs on the B N field nodes
/// unchanged, and a node where one body only has mass behaves as on the
/// shared grid. The contact correction is the one coupling between the
/// copies of a node.
#include "otmpm/basis/basis.hpp"
#include "otmpm/engine/constraints.hpp"

#include <vector>

namespace otmpm {

/// The scene's [contact]: Coulomb friction coefficient between bodies.
struct ContactLaw {
  double friction = 0.0;
};

/// The field nodes a contact correction acts on: lumped masses, active
/// flags and the Dirichlet flags (constrained[J * D + k]: component k of
/// field node J is held), all over the B N field nodes.
struct ContactNodes {
  const std::vector<double>& m;
  const std::vector<char>& active;
  const std::vector<char>& constrained;
};

/// Contact between the bodies of a run on N grid nodes. For a pair of
/// bodies (a, b) present at node I (both field nodes active), with lumped
/// masses m_a, m_b and mass gradients g_a = sum_{p in a} m_p grad N_Ip:
///  - the contact normal from a to b, n = g_a/|g_a| if |g_a| >= |g_b|,
///    else -g_b/|g_b| (g = sum_p m_p grad N_I(x_p) points out of a body at
///    its surface; the body with the larger gradient has the better
///    resolved surface at the node; one normal for the pair, so the
///    correction conserves momentum);
///  - the separation velocity s = (v_b - v_a) . n; they approach when s < 0;
///  - the correction raises s by ds: the relative velocity u = v_a - v_b
///    changes by du = -ds n - min(1, mu ds / |u_t|) u_t (Coulomb friction on
///    the tangential part u_t, only when ds > 0), shared as
///    dv_a = m_b / (m_a + m_b) du, dv_b = -m_a / (m_a + m_b) du - so the
///    pair's momentum and centre-of-mass velocity are unchanged (Bardenhagen
///    et al. eqs. 16-21 with the centre-of-mass velocity of the pair).
/// The decision follows the walls (constraints.hpp, WallEffect): a pair
/// that approaches is set to s = 0 and held; a held pair stays at s = 0 -
/// both ways in the velocity fields that only drive the stress update - and
/// is released in a pass whose change is the bodies' (effect.impulse) when
/// holding it would take a pull (ds < 0). With effect.hold_rate a held pair
/// is held by removing its relative normal rate instead. Components held by
/// a Dirichlet set are not changed. Three or more bodies at a node: the
/// pairs in order (a < b), each with the velocities the previous left.
template <int D> class BodyContact {
public:
  /// std::invalid_argument unless nodes >= 1, bodies >= 2 and the friction is finite and >= 0.
  BodyContact(int nodes, int bodies, ContactLaw law);

  int nodes() const { return nodes_; }
  int fields() const { return fields_; }
  const ContactLaw& law() const { return law_; }
  /// Points the basis table at the field nodes: node I of particle p -> I + body[p] N.
  void remap(BasisTable<D>& table, const std::vector<int>& body) const;
  /// g_J = sum_p m_p grad N_Jp per field node (filled by the engine with
  /// each step's masses).
  AlignedVector<Vec<D>>& mass_gradient() { return grad_m_; }
  /// The correction of a nodal velocity-like field v over the field nodes;
  /// `effect` says how it reaches the particles (as for the walls). In a
  /// pass whose change is the bodies' (effect.impulse), the energy Coulomb
  /// friction takes from the pairs' relative motion (friction_loss with the
  /// reduced mass m_a m_b / (m_a + m_b)) is added to `friction`, the energy
  /// the stopped approach takes (impact_loss, same mass) to `impact`; with
  /// Booking::carried the friction is left to book_carried.
  void apply(AlignedVector<Vec<D>>& v, const ContactNodes& nodes, const WallEffect<D>& effect, double& friction,
             double& impact);
  /// After a Booking::carried pass (explicit_alpha; Constraints::book_carried
  /// for the walls): per pair and node, the momentum J that body a's
  /// particles take up in this step from the changes the rate carries (b's:
  /// -J), and the friction as the work of J's tangential part against the
  /// pair's mean relative slip over the step (friction_loss; at a node
  /// where both field nodes are active), added to `friction`.
  void book_carried(const Carried<D>& step, const std::vector<char>& active, double& friction);
  /// The carried parts X of book_carried (body a's side), per node and pair
  /// (I * pairs() + k); empty until first carried.
  AlignedVector<Vec<D>>& carried() { return carried_; }
  const AlignedVector<Vec<D>>& carried() const { return carried_; }
  /// For the held pairs, an approaching relative normal increment of the
  /// field-node increments dx is removed (same sharing, no friction).
  void apply_to_increment(AlignedVector<Vec<D>>& dx, const ContactNodes& nodes) const;
  /// held()[I * pairs() + k]: pair k at node I is held (carried from step
  /// to step; pairs (a, b), a < b, in lexicographic order).
  std::vector<char>& held() { return held_; }
  const std::vector<char>& held() const { return held_; }
  int pairs() const { return fields_ * (fields_ - 1) / 2; }

private:
  /// The unit normal from body a to body b at node I, or zero when the two
  /// mass gradients give none.
  Vec<D> normal(int I, int a, int b) const;
  /// Adds du to u = v_a - v_b at the field nodes Ja, Jb, shared by mass,
  /// on the components no Dirichlet set holds (handed on to the particles
  /// as `effect` says); returns the du it added.
  Vec<D> share(int Ja, int Jb, Vec<D> du, AlignedVector<Vec<D>>& v, const ContactNodes& nodes,
               const WallEffect<D>& effect) const;


  int nodes_ = 0, fields_ = 0;
  ContactLaw law_;
  AlignedVector<Vec<D>> grad_m_;
  std::vector<char> held_;
  std::vector<double> loss_;   ///< per grid node: the friction loss of the last pass
  std::vector<double> impact_; ///< per grid node: the impact loss of the last pass
  /// book_carried: the parts X and the pass's changes m_a dv_a, per node and pair.
  AlignedVector<Vec<D>> carried_, carried_step_;
};

extern template class BodyContact<1>;
extern template class BodyContact<2>;
extern template class BodyContact<3>;

} // namespace otmpm
