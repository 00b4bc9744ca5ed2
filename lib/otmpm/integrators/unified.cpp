/// \file unified.cpp
/// unified: B-spline basis on advected knots with the consistent mass
/// (wobbes et al. Algorithm 3; docs/theory.md sect. 8.5), advected nodes only.
#include "otmpm/integrators/nodal_ops.hpp"

namespace otmpm {

template <int D> void step_unified(Engine<D>& e, const StepContext<D>& s) {
  auto& P = s.particles;
  auto& n = s.nodes;
  const double dt = s.dt, dt_prev = s.dt_prev;
  e.evaluate_basis();
  e.to_nodes({.mass = true, .w = &P.v, .forces = true, .t = s.t});
  e.apply_dirichlet_force(n.f, dt);
  // 1. a = M^{-1} f; dx = dt M^{-1} (q + (dt + dt_prev)/2 f); x_I += dx_I.
  //    The constraints' change of v also enters a, which updates the particle velocities.
  e.solve_mass(n.f, n.a, dt);
  transport_increment(e, n, dt, dt_prev, {.rate = &n.a, .c = dt}, 0.0);
  // 2. x_p += sum N_Ip dx_I; v_p += dt sum N_Ip a_I; and (same pass)
  // 3. F_p = (I + sum dx_I (x) grad N_Ip) F_p; V_p = det(F_p) V0_p; stress.
  e.to_particles_and_update_stress({.rate = &n.a, .c_rate = dt, .move = &n.dx, .c_move = 1.0}, {&n.dx, 1.0});
  e.advect_nodes(n.dx);
}

template void step_unified<1>(Engine<1>&, const StepContext<1>&);
template void step_unified<2>(Engine<2>&, const StepContext<2>&);
template void step_unified<3>(Engine<3>&, const StepContext<3>&);

} // namespace otmpm
