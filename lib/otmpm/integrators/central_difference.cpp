/// \file central_difference.cpp
/// central_difference: the central difference method in velocity-Verlet
/// form (kick, drift, kick; docs/theory.md sect. 8.6), second-order and
/// free of numerical dissipation. The particles carry v_p at whole steps;
/// the second kick uses the forces of the updated stresses on the basis of
/// the step (as npc's corrector does).
#include "otmpm/integrators/nodal_ops.hpp"

namespace otmpm {

template <int D> void step_central_difference(Engine<D>& e, const StepContext<D>& s) {
  auto& P = s.particles;
  auto& n = s.nodes;
  const double dt = s.dt, half = 0.5 * dt;
  e.evaluate_basis();
  // 1. m_I, q_I = sum N_Ip m_p v_p^n and f_I^n (sigma^n, loads at t_n); Dirichlet on f_I.
  e.to_nodes({.mass = true, .w = &P.v, .forces = true, .t = s.t});
  // Each kick hands dt/2 of the force to the particles (step 5): the
  // reactions of each kick are booked with dt/2.
  e.apply_dirichlet_force(n.f, half);
  // 2. kick: a^n = f / m; v^{n+1/2} = q / m + dt/2 a^n; constraints. a^n kept in q.
  e.solve_mass_add(n.f, n.a, half, n.v, half, &n.q);
  e.constrain_velocity(n.v, {.rate = &n.a, .c = half});
  scale(n, n.q, 1.0, n.a);
  // 3. drift: dx_I = dt v^{n+1/2}; sigma^{n+1} from sum dx_I (x) grad N_Ip and (same
  //    pass) f^{n+1} with the updated stresses and the loads at t_{n+1}.
  scale(n, n.dx, dt, n.v);
  e.update_stress_and_to_nodes({&n.dx, 1.0}, {.forces = true, .t = s.t + dt});
  e.apply_dirichlet_force(n.f, half);
  // 4. kick: a^{n+1} = f / m; v^{n+1} = v^{n+1/2} + dt/2 a^{n+1}; constraints.
  e.solve_mass_add(n.f, n.a, half, n.v, half);
  e.constrain_velocity(n.v, {.rate = &n.a, .c = half, .hold_rate = true});
  // 5. v_p += dt/2 sum N_Ip (a^n + a^{n+1}), then the PIC relaxation toward
  //    sum N_Ip v^{n+1}, if any; x_p += sum N_Ip dx_I; x_I += dx_I in ul.
  axpy(n, n.a, 1.0, n.q);
  e.to_particles({.rate = &n.a,
                  .c_rate = half,
                  .move = &n.dx,
                  .c_move = 1.0,
                  .pic = &n.v,
                  .pic_share = pic_share(s),
                  .last = true});
  e.advect_nodes(n.dx);
}

template void step_central_difference<1>(Engine<1>&, const StepContext<1>&);
template void step_central_difference<2>(Engine<2>&, const StepContext<2>&);
template void step_central_difference<3>(Engine<3>&, const StepContext<3>&);

} // namespace otmpm
