#pragma once
/// \file constraints.hpp
/// Constraints on node velocities (docs/theory.md sect. 6):
///  - Dirichlet sets: listed node components are held at a prescribed
///    velocity; their force components are removed from the nodal forces and
///    kept as reactions, whose impulse and work enter the energy balance;
///  - rigid walls: a node may not approach a wall faster than it can reach
///    the wall's plane within the step (a node on or behind the plane not at
///    all); the normal velocity removed is the wall's impulse, and Coulomb
///    friction reduces the tangential velocity relative to the wall by
///    friction x the normal velocity removed (not below zero). A node the
///    wall holds stays held - both ways in the velocity fields that only
///    drive the stress update - until the wall would have to pull it, so
///    contact ends when the body's own force takes it off the wall.
#include "otmpm/core.hpp"

#include <algorithm>
#include <array>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace otmpm {

/// A Dirichlet set: node ids and, per entry, which components are fixed and
/// their prescribed velocity (a node may appear in several entries).
template <int D> struct Dirichlet {
  std::vector<int> node;
  std::vector<std::array<bool, 3>> fix;
  std::vector<std::array<double, 3>> value;
};

/// A rigid wall: the plane through `point` (at t = 0) with unit `normal`
/// pointing to the side the material is on, moving at `velocity`, with
/// Coulomb `friction` (0: frictionless).
template <int D> struct Wall {
  std::string name;
  Vec<D> point = Vec<D>::Zero();
  Vec<D> normal = Vec<D>::Zero();
  Vec<D> velocity = Vec<D>::Zero();
  double friction = 0.0;
};

/// When a pass books the momentum its constraints give the particles:
/// `now`, as m_I dv_I (the particles take the change up as it is: fe, musl,
/// central_difference, otm, unified); `held`, after the step from the
/// components the pass holds (Constraints::book_held: npc, whose particles
/// take up a held component's change from the velocity they brought, not
/// its rate); `carried`, as the rate hands it on from step to step
/// (Constraints::book_carried: explicit_alpha, whose particles keep the
/// rate as their acceleration).
enum class Booking { now, held, carried };

/// How the change dv_I that a constraint makes to a nodal velocity-like
/// field v = v0 + c rate reaches the particles: in a pass whose change is
/// the body's (`impulse`), through `rate` when given (rate_I += dv_I / c;
/// the particles read the rate times c), else directly (they read v itself:
/// otm); `booking` says when its momentum is booked. A pass that is not the
/// body's (`impulse` false: a predictor or a re-projection that only drives
/// the stress update) changes v alone. `hold_rate`: a node held earlier in
/// the step is held by zeroing the normal part of its rate (relative to the
/// wall) instead of setting its velocity - as a Dirichlet set zeroes its
/// force components (npc's corrector, central_difference's second kick).
template <int D> struct WallEffect {
  AlignedVector<Vec<D>>* rate = nullptr;
  double c = 0.0;
  bool impulse = true;
  bool hold_rate = false;
  Booking booking = Booking::now;
  /// A held component's jump goes here instead of to the rate (kick_I +=
  /// dv_I): a velocity change the particles take up as it is and do not keep
  /// as an acceleration (explicit_alpha, whose kept rate would hand part of
  /// it back later); booked at once.
  AlignedVector<Vec<D>>* kick = nullptr;
  /// The particles take up reach x dv through the rate (npc's corrector,
  /// whose particles read its rate times dt: 1 / gamma).
  double reach = 1.0;
  /// Hands dv of node I on to the rate.
  void hand_on(std::size_t I, const Vec<D>& dv) const {
    if (rate) (*rate)[I] += dv / c;
  }
  /// The velocity node I had at the start of the time the pass covers,
  /// v_I - c rate_I (v_I itself without a rate): the changes of the pass
  /// leave it as it is.
  Vec<D> start(const AlignedVector<Vec<D>>& v, std::size_t I) const {
    return rate ? Vec<D>(v[I] - c * (*rate)[I]) : v[I];
  }
};

/// Where the constraints book what a pass did: the run's totals (or, in a
/// distributed run, this rank's share of the step, summed over the ranks
/// after it). `impulse` and `work`: the impulse and the work of the
/// Dirichlet reactions, at the prescribed velocity (the walls' work J . w is
/// added to `work` too); `friction`: the energy Coulomb friction took
/// (friction_loss); `impact`: the energy the stopped normal approach took
/// (impact_loss).
template <int D> struct Ledger {
  Vec<D>* impulse = nullptr;
  double* work = nullptr;
  double* friction = nullptr;
  double* impact = nullptr;
  double* relaxation = nullptr; ///< W_v of the PIC relaxation (ToParticles::pic)
};

/// The energy that the tangential part of an impulse J (relative to the
/// unit normal n) takes over a pass in which the relative velocity it acts
/// on went from s to e: its work against the mean tangential velocity,
/// -J_t . (s_t + e_t) / 2 (mean2 = s + e). For Coulomb friction, the energy
/// it dissipates: friction times the mean slip.
template <int D> double friction_loss(const Vec<D>& J, const Vec<D>& mean2, const Vec<D>& n) {
  return -0.5 * (J - J.dot(n) * n).dot(mean2 - mean2.dot(n) * n);
}

/// The energy an impact takes from a mass m whose velocity relative to a
/// wall or another body (unit normal n) went from s at the start of a pass
/// to e at its end, the constraint's change included: the kinetic energy of
/// its normal part, m/2 ((s . n)^2 - (e . n)^2) (docs/theory.md eq. 6.5). The
/// forces of the pass are part of it: the held node's velocity, not the
/// particles' motion, drives the stress update, so the work of its normal
/// force is not in the stored energy.
template <int D> double impact_loss(double m, const Vec<D>& s, const Vec<D>& e, const Vec<D>& n) {
  const double sn = s.dot(n), en = e.dot(n);
  return 0.5 * m * (sn * sn - en * en);
}

/// friction_loss of the change du that a constraint makes to the relative
/// velocity u of a mass m, where s was the relative velocity at the start of
/// the pass (WallEffect::start) and u follows from it by the forces of the
/// pass: J = m du, e = u + du (for s = u, the tangential kinetic energy
/// m/2 (|u_t|^2 - |u_t + du_t|^2)).
template <int D> double friction_loss(double m, const Vec<D>& s, const Vec<D>& u, const Vec<D>& du, const Vec<D>& n) {
  return friction_loss<D>(Vec<D>(m * du), s + u + du, n);
}

/// The change of u (velocity or increment relative to a wall or another
/// body, with unit normal n pointing to u's side) that adds `dn` to its
/// normal part, with Coulomb friction mu reducing the tangential part by
/// mu dn when the contact pushes (dn > 0), not below zero.
template <int D> Vec<D> wall_change(const Vec<D>& u, const Vec<D>& n, double dn, double mu) {
  Vec<D> change = dn * n;
  const Vec<D> ut = u - u.dot(n) * n;
  const double t = ut.norm();
  if (mu > 0.0 && dn > 0.0 && t > 0.0) change -= std::min(1.0, mu * dn / t) * ut;
  return change;
}

/// What Constraints::book_carried reads of explicit_alpha's step: its
/// parameters, whether it is the run's first, the reactions R removed from
/// the force, and the nodal velocity v_{n+1} with the accelerations a_n and
/// a_{n+1} it came from (v_n = v_{n+1} - dt ((1 - gamma) a_n + gamma
/// a_{n+1}), the constraints' changes included in a_{n+1}).
template <int D> struct Carried {
  double alpha_m, gamma, dt;
  bool first;
  const AlignedVector<Vec<D>>& reaction;
  const AlignedVector<Vec<D>>& v;
  const AlignedVector<Vec<D>>& a_n;
  const AlignedVector<Vec<D>>& a_next;
  /// The mean of node I's velocity over the step, times 2: v_n + v_{n+1}.
  Vec<D> mean2(std::size_t I) const { return 2.0 * v[I] - dt * ((1.0 - gamma) * a_n[I] + gamma * a_next[I]); }
  /// Eq. 8.7.3 for one node and source: from its carried part X (which
  /// becomes Y), the reaction s removed from the force, the momentum z
  /// zeroed and the pass's change W = m dv, the momentum the particles take
  /// up in the step, J = dt ((1 - gamma) X + gamma Y).
  Vec<D> take_up(Vec<D>& X, const Vec<D>& s, const Vec<D>& z, const Vec<D>& W) const {
    const Vec<D> Y = (s - alpha_m * ((first ? s : X) - z)) / (1.0 - alpha_m) + W / (gamma * dt);
    const Vec<D> J = ((1.0 - gamma) * dt) * X + (gamma * dt) * Y;
    X = Y;
    return J;
  }
};

/// What Constraints::book_held reads of npc's step: the time t and step dt
/// (and whether it is the run's first), the nodal forces f (the fixed
/// components zeroed) and the rate the particles take up times dt.
template <int D> struct Held {
  double t, dt;
  bool first; ///< the run's first step
  const AlignedVector<Vec<D>>& f;
  const AlignedVector<Vec<D>>& rate;
};

/// The nodes a velocity constraint acts on: positions, lumped masses, active
/// flags and the active nodes, ascending (the walls' passes visit only
/// these: the others carry no mass and keep their velocity), and `reach`,
/// how far from a node its shape function reaches (wall_reach): a wall
/// takes a new contact only at a node whose support it can meet in the step.
/// `visited`: the nodes the step visits (NodalFields::visited; the others'
/// fields are zero), or null: every node.
template <int D> struct NodeView {
  const AlignedVector<Vec<D>>& x;
  const std::vector<double>& m;
  const std::vector<char>& active;
  const std::vector<int>& active_nodes;
  double reach = std::numeric_limits<double>::infinity();
  const std::vector<int>* visited = nullptr;
};

/// The constraints of a run with the bookkeeping derived from them.
template <int D> class Constraints {
public:
  Constraints() = default;
  /// std::invalid_argument unless every node id lies in [0, nodes) and the
  /// prescribed values are finite.
  Constraints(Dirichlet<D> dirichlet, std::vector<Wall<D>> walls, int nodes);

  const Dirichlet<D>& dirichlet() const { return d_; }
  /// constrained()[I * D + k]: component k of node I is fixed.
  const std::vector<char>& constrained() const { return constrained_; }
  /// Sets the fixed components of a nodal velocity-like field to their
  /// value. In a pass whose change is the body's (effect.impulse) the change
  /// dv = vbar - v_Ik of an active node reaches the particles as `effect`
  /// says: where they read a rate, only in the `first` step of the run and
  /// for a component held at a velocity (vbar != 0: the jump from the
  /// velocity they bring to the held one; the value is constant, so its
  /// rate is zero later; a support at rest holds what reaches it); where
  /// they read v itself (otm), every step. Its impulse J = m_I dv is booked
  /// (book_fixed) as effect.booking says, and the kinetic energy m_I (vbar -
  /// s)^2 / 2 that the jump from the component's start velocity s
  /// (WallEffect::start) takes comes off the work (a perfectly plastic
  /// impact on the set). With the component's force removed (s = v_Ik) the
  /// work is that at the mean velocity, J (s + vbar) / 2.
  void apply_velocity(AlignedVector<Vec<D>>& v, const NodeView<D>& nodes, const WallEffect<D>& effect,
                      const Ledger<D>& ledger, bool first);
  /// Sets the fixed components of a nodal increment to dt vbar.
  void apply_increment(AlignedVector<Vec<D>>& dx, double dt) const;
  /// Moves the fixed components of f into `reaction` (zeroing them in f)
  /// and books their impulse c R (book_reaction), where c is the factor
  /// with which the particles' velocities take up f / m (dt; dt/2 for each
  /// kick of central_difference; (dt + dt_prev)/2 for otm).
  void apply_force(AlignedVector<Vec<D>>& f, AlignedVector<Vec<D>>& reaction, double c, const Ledger<D>& ledger) const;
  /// Books (book_fixed) the impulse c rho of a reaction rho on the fixed
  /// components (the removed forces, a consistent-mass solve's inertial reaction).
  void book_reaction(const AlignedVector<Vec<D>>& rho, double c, const Ledger<D>& ledger) const;
  /// After a pass with Booking::held (npc's corrector; `step` gives its
  /// nodal fields), whose particles take up dt rate: at the nodes it holds,
  /// the particles are to end the step as the constraints have them end it,
  /// starting from the velocity they would have without them, u = q_I / m_I
  /// + dt f_I / m_I (npc's particle update, from the velocity they brought):
  /// each wall that holds node I applies its rule (6.2-6.3) to u - so
  /// Coulomb's bound holds between the tangential and the normal momentum
  /// the particles get - and, in the first step, a Dirichlet set's
  /// components held at a velocity end at vbar (apply_velocity). q
  /// becomes the kick that adds the difference to dt rate there (zero
  /// elsewhere); the walls' m dv are their impulses (work m dv . w, friction
  /// by friction_loss from the velocity brought), a set's m_I (vbar - q_Ik /
  /// m_I) its reaction (book_fixed; its jump's kinetic energy off the work);
  /// the impact a wall's normal change takes is impact_loss from the velocity
  /// brought to the end velocity.
  void book_held(const Held<D>& step, AlignedVector<Vec<D>>& q, const NodeView<D>& nodes, const Ledger<D>& ledger);
  /// Before a pass with Booking::carried (explicit_alpha): zeroes the fixed
  /// components of the acceleration a_n the step starts from, noting the
  /// momentum m_I a_nIk removed.
  void zero_carried(AlignedVector<Vec<D>>& a, const std::vector<double>& m);
  /// After it: books the momentum the constraints give the particles in
  /// this step through explicit_alpha's rate, which the particles keep as
  /// their acceleration a_p and take up again in the next steps (theory.md
  /// sect. 8.7). Per component, with the constraint's part X of sum_p m_p
  /// a_p carried from step to step, its part of the new total
  ///   Y = (s - alpha_m (X - z)) / (1 - alpha_m) + W / (gamma dt)
  /// (s: the reaction R = -f removed from the force, z: the momentum
  /// zero_carried removed - both on fixed components -, W: a wall's m dv in
  /// the pass; X = s in the first step, where a_n = f / m), of which the
  /// particles take up J = dt ((1 - gamma) X +
  /// gamma Y) now; X becomes Y. J is booked as a Dirichlet reaction
  /// (book_fixed) or as the wall's impulse (work J . w), and a wall's
  /// friction as the work of J's tangential part against the node's mean
  /// slip over the step (friction_loss): the rate hands part of a change back
  /// in the next steps, which the wall takes again with its friction, so the
  /// changes themselves would count that friction more than once (1 + 1/3 +
  /// 1/9 + ... = 1.5 times at rho_inf = 1/2).
  void book_carried(const Carried<D>& step, const Ledger<D>& ledger);
  /// explicit_alpha's carried parts X (book_carried), per node: the
  /// Dirichlet sets' (entry 0) and each wall's (entry 1 + w); empty until
  /// first carried.
  std::vector<AlignedVector<Vec<D>>>& carried() { return carried_; }
  const std::vector<AlignedVector<Vec<D>>>& carried() const { return carried_; }
  /// sum over the fixed components k of counted nodes I of b_k (q_Ik - m_I
  /// vbar_Ik): the body force's power on the momentum the particles bring
  /// to the fixed components beyond what they keep (docs/theory.md eq. 11.1c).
  double held_body_power(const Vec<D>& b, const AlignedVector<Vec<D>>& q, const std::vector<double>& m) const;
  /// sum over fixed components of 1/2 m_I v_prescribed^2 (zero for fixed supports).
  double prescribed_kinetic_energy(const std::vector<double>& m) const;
  /// Only the nodes with counted[I] != 0 add to the impulse, the work and
  /// the prescribed kinetic energy (a rank of a distributed run counts the
  /// nodes it owns; its ghost nodes are constrained all the same). Default:
  /// every node counts. With count_only, a wall's impulse goes to
  /// rank_wall_impulse() (the caller sums it over the ranks into
  /// wall_impulse()).
  void count_only(std::vector<char> counted) {
    counted_ = std::move(counted);
    rank_impulse_.assign(walls_.size(), Vec<D>::Zero());
  }

  /// Node I adds to the books (count_only).
  bool counts(int I) const { return counted_.empty() || counted_[static_cast<std::size_t>(I)]; }
  const std::vector<Wall<D>>& walls() const { return walls_; }
  /// The nodes of the Dirichlet sets, each once, ascending.
  const std::vector<int>& fixed_nodes() const { return nodes_; }
  /// Applies the walls at time t to the nodal velocities v of a step dt:
  /// with d_I the distance of node I from the wall plane (positive on the
  /// material side) and u = v_I - v_wall, the normal part u.n is raised to
  /// -max(d_I, 0) / dt when below it, and friction reduces the tangential
  /// part. A new contact needs d_I <= nodes.reach + max(v_wall . n, 0) dt:
  /// no particle of a node farther away can meet the wall in the step (its
  /// support ends short of the plane), and the approach that such a node
  /// shows is the velocity dt f_I / m_I of a node with little mass, which a
  /// wall would turn into friction and impact that no particle has. In a
  /// pass whose change is the body's (effect.impulse) the change
  /// reaches the particles as `effect` says; its impulse (m_I dv_I summed
  /// per wall) is added to wall_impulse() and its work (impulse . v_wall) to
  /// `ledger` as effect.booking says, the energy the impact took
  /// (impact_loss) at once, and friction's (friction_loss) at once unless
  /// the booking is Booking::carried (book_carried books it then).
  /// `touched`, if given, receives
  /// (I, v_I before the change) for every change a wall makes, in the
  /// order made (a node two walls change appears twice).
  void apply_walls(AlignedVector<Vec<D>>& v, const NodeView<D>& nodes, double t, double dt,
                   const WallEffect<D>& effect, const Ledger<D>& ledger,
                   std::vector<std::pair<int, Vec<D>>>* touched = nullptr);
  /// The same rule for node increments dx of the step (positions after it:
  /// x_I + dx_I): the normal increment relative to the wall is raised to
  /// -max(d_I, 0); no impulse is counted.
  void apply_walls_to_increment(AlignedVector<Vec<D>>& dx, const NodeView<D>& nodes, double t, double dt) const;
  /// Per wall and node: the node is held by the wall (state carried from
  /// step to step).
  std::vector<std::vector<char>>& held() { return held_; }
  const std::vector<std::vector<char>>& held() const { return held_; }
  /// The impulse each wall gave the body since t = 0 (sum of m_I dv_I).
  const AlignedVector<Vec<D>>& wall_impulse() const { return impulse_; }
  AlignedVector<Vec<D>>& wall_impulse() { return impulse_; }
  /// After count_only: the impulse of the counted nodes not yet summed over the ranks.
  AlignedVector<Vec<D>>& rank_wall_impulse() { return rank_impulse_; }

private:
  /// Node I is held by a wall, or (first step) has a component set to a
  /// non-zero velocity: book_held gives it a kick (the others none).
  bool holds(std::size_t I, bool first) const;
  Dirichlet<D> d_;
  std::vector<Wall<D>> walls_;
  AlignedVector<Vec<D>> impulse_; ///< per wall
  AlignedVector<Vec<D>> rank_impulse_; ///< per wall, after count_only
  std::vector<std::vector<char>> held_; ///< per wall and node: held by the wall
  std::vector<int> nodes_;       ///< the distinct nodes of d_.node, ascending
  std::vector<char> constrained_;
  std::vector<double> vbar_;     ///< per node and component: the prescribed velocity (the last set's)
  /// Booking::carried: the parts X (per node, entry 0 Dirichlet, 1 + w the
  /// walls), and the step's W (same layout) and zeroed momentum z.
  std::vector<AlignedVector<Vec<D>>> carried_, carried_step_;
  AlignedVector<Vec<D>> zeroed_;
  /// Books the impulse J a Dirichlet set gave component k of node I: its
  /// reaction impulse and work J vbar (counted nodes only).
  void book_fixed(std::size_t I, int k, double J, const Ledger<D>& ledger) const;
  /// The step's buffers of Booking::carried, sized for `nodes` nodes.
  void size_carried(std::size_t nodes);
  std::vector<char> counted_; ///< empty: every node counts
};

extern template class Constraints<1>;
extern template class Constraints<2>;
extern template class Constraints<3>;

} // namespace otmpm
