#pragma once
/// \file loads.hpp
/// The external loads on the particles (docs/theory.md sect. 7): a body
/// force per unit mass b(X, t) = b g(t) + b_field(X, t) (gravity, or the body
/// force of a manufactured solution) and tractions on sets of particles.
/// The engine adds them to the nodal forces, f_I += sum_p N_Ip f_ext,p(t),
/// and to the work of the energy balance. A benchmark that needs a load of
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
  /// Power of the loads sum_p f_ext,p(t) . v_p; `momentum` = sum_p m_p v_p
  /// (read only when uniform(): then the power is b(t) . momentum).
  double power(double t, const Particles<D>& P, const Vec<D>& momentum) const;
  /// std::invalid_argument naming the load unless every particle index is in
  /// [0, n) with a finite area >= 0, the values are finite and the axis is in [0, D).
  void check(int n) const;

private:
  template <class Visit> void for_each_force(double t, const Particles<D>& P, Visit&& visit) const;
};

extern template class Loads<1>;
extern template class Loads<2>;
extern template class Loads<3>;

} // namespace otmpm
