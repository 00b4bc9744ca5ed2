/// \file npc.cpp
/// npc: the explicit Newmark predictor-corrector of molinos et al.
/// (Algorithm 1; docs/theory.md sect. 8.3). gamma is the Newmark parameter.
#include "otmpm/integrators/nodal_ops.hpp"

namespace otmpm {

template <int D> void step_npc(Engine<D>& e, const StepContext<D>& s) {
  auto& P = s.particles;
  auto& n = s.nodes;
  const double dt = s.dt;
  const double gamma = s.parameters.get("gamma");
  e.evaluate_basis();
  // 1. m_I, q_I = sum N_Ip m_p v_p and (kept in f) sum N_Ip m_p a_p, one pass;
  // 2. predictor: v_I^pred = M^{-1} (q_I + (1 - gamma) dt sum N_Ip m_p a_p) (molinos eq. 30).
  e.to_nodes({.mass = true, .w = &P.v, .a = &P.a, .split = true});
  n.dx.resize(n.q.size());
  for_nodes(n, [&](int I) { n.dx[I] = n.q[I] + ((1.0 - gamma) * dt) * n.f[I]; });
  e.solve_mass(n.dx, n.v);
  // 3. Constraints on the predictor (it drives only the stress update).
  e.constrain_velocity(n.v, {.impulse = false});
  // 4. L_p from the predictor; strain, density and stress update, and (same
  //    pass over the basis table, each particle updated before it scatters)
  // 5. f_I with the updated stresses and b(t + dt); fixed components zeroed.
  e.update_stress_and_to_nodes({&n.v, dt}, {.forces = true, .t = s.t + dt});
  e.apply_dirichlet_force(n.f, dt);
  // 6. corrector: v_I = v_I^pred + gamma dt f_I / m_I; a wall holds a node
  //    by zeroing its normal acceleration, as a Dirichlet set zeroes f_I.
  e.solve_mass_add(n.f, n.a, 0.0, n.v, gamma * dt);
  e.constrain_velocity(n.v,
                       {.rate = &n.a, .c = gamma * dt, .hold_rate = true, .booking = Booking::held, .reach = 1.0 / gamma});
  // 7. x_p += sum N_Ip (dt v_I + dt^2/2 a_I); a_p = sum N_Ip a_I; v_p += dt
  //    a_p + sum N_Ip k_I, where the kick k_I of a held component makes the
  //    particles take up the change from the velocity they brought to the
  //    held one, v_I - q_I / m_I (q becomes the kick); then the PIC
  //    relaxation toward sum N_Ip v_I, if any.
  n.dx.resize(n.v.size());
  for_nodes(n, [&](int I) { n.dx[I] = dt * n.v[I] + (0.5 * dt * dt) * n.a[I]; });
  e.constrain_increment(n.dx);
  e.book_held(n.a);
  e.to_particles({.rate = &n.a,
                  .c_rate = dt,
                  .rate_out = &P.a,
                  .kick = &n.q,
                  .move = &n.dx,
                  .c_move = 1.0,
                  .pic = &n.v,
                  .pic_share = pic_share(s),
                  .last = true});
  e.advect_nodes(n.dx);
}

template void step_npc<1>(Engine<1>&, const StepContext<1>&);
template void step_npc<2>(Engine<2>&, const StepContext<2>&);
template void step_npc<3>(Engine<3>&, const StepContext<3>&);

} // namespace otmpm
