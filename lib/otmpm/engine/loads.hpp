#pragma once
/// \file loads.hpp
/// The external loads on the particles (docs/theory.md sect. 7): a body
/// force per unit mass b(X, t) = b g(t) + b_field(X, t) (gravity, or the body
/// force of a manufactured solution) and tractions on sets of particles.
/// The engine adds them to the nodal forces, f_I += sum_p N_Ip f_ext,p(t),
/// and their work to the energy balance: the body force's by its power
/// sum_p m_p b . v_p, a traction's by the motion of the particles it loads
/// (the power that reaches the nodes, f_p . sum_I N_Ip v_I, is f_p times
/// the rate of x_p; the particle's own v_p is not that rate in MPM). A benchmark that needs a load of
/// its own (the traction history of wobbes et al. eq. 103, a manufactured
/// body force) supplies it as a function here: the engine knows no benchmark.
#include "otmpm/particles/particles.hpp"
#include "otmpm/time_function.hpp"

#include <functional>
#include <optional>
#include <vector>

namespace otmpm {

/// A body force per unit mass on every particle: b(X, t) = value g(t) +
/// field(X, t) (field: e.g. a manufactured solution's body force; optional).
template <int D> struct BodyForce {
  Vec<D> value = Vec<D>::Zero();
  TimeFunction time;
  std::function<Vec<D>(const Vec<D>& X, double t)> field;
};

/// A traction on a surface: force per unit reference area value g(t)
/// (component `axis` replaced by history(t) when a history is given),
/// applied to the particles that carry the surface, particle[i] over its
/// share area[i] of the loaded area (the areas add up to the loaded area, so
/// the total force does not depend on how many particles carry it).
template <int D> struct Traction {
  std::vector<int> particle;
  std::vector<double> area;
  Vec<D> value = Vec<D>::Zero();
  TimeFunction time;
  std::function<double(double)> history;
  int axis = 0;
};

/// All external loads of a run.
template <int D> class Loads {
public:
  std::optional<BodyForce<D>> body_force;
  std::vector<Traction<D>> tractions;

  /// True when there is any load.
  bool any() const { return body_force.has_value() || !tractions.empty(); }
  /// True when the only load is a body force b g(t) without a field: the
  /// particle force is then m_p b(t), computed inline by the transfer.
  bool uniform() const { return body_force && !body_force->field && tractions.empty(); }
  /// The uniform part b g(t) of the body force (zero without one).
  Vec<D> body_force_at(double t) const;
  /// The external force on every particle at time t into fext (sized to the
  /// particles, zero where there is none). Unused when uniform().
  void particle_forces(double t, const Particles<D>& P, AlignedVector<Vec<D>>& fext) const;
  /// Power of the body force sum_p m_p b(X_p, t) . v_p; `momentum` = sum_p
  /// m_p v_p (read only without a field: then the power is b(t) . momentum).
  double power(double t, const Particles<D>& P, const Vec<D>& momentum) const;
  /// The positions of the particles the tractions load, in their order
  /// (the start of a step for traction_work).
  void traction_positions(const Particles<D>& P, AlignedVector<Vec<D>>& x0) const;
  /// The work of the tractions over a step from t0 to t1 in which the loaded
  /// particles moved from x0 (traction_positions) to x_p: the trapezoidal
  /// rule on the force, sum (f_p(t0) + f_p(t1)) / 2 . (x_p - x0) - exact for
  /// a constant or linearly varying load on the step's motion.
  double traction_work(double t0, double t1, const Particles<D>& P, const AlignedVector<Vec<D>>& x0) const;
  /// What traction_work cannot see: the work of the tractions at t over
  /// motions below the rounding of the loaded positions, sum |f_p|_1 eps
  /// |x_p|_inf (eps the machine epsilon). A load that starts from nearly
  /// 0 (a ramp) moves its particles by less than that in the first steps:
  /// their kinetic energy, up to about this, appears with no work booked.
  double unresolved_work(double t, const Particles<D>& P) const;
  /// std::invalid_argument naming the load unless every particle index is in
  /// [0, n) with a finite area >= 0, the values are finite and the axis is in [0, D).
  void check(int n) const;

private:
  template <class Visit> void for_each_force(double t, const Particles<D>& P, Visit&& visit) const;
  /// The traction of load `load` at t (force per unit reference area).
  Vec<D> traction_at(const Traction<D>& load, double t) const;
};

extern template class Loads<1>;
extern template class Loads<2>;
extern template class Loads<3>;

} // namespace otmpm
