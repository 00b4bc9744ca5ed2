/// \file fe.cpp
/// fe and musl: forward Euler with the stress updated last (USL; wobbes et
/// al. Algorithm 1, lumped mass), and its modified variant (MUSL) that
/// recomputes the nodal velocities from the updated particle momenta before
/// the stress update (docs/theory.md sect. 8.1-8.2).
#include "otmpm/integrators/nodal_ops.hpp"

namespace otmpm {

namespace {

template <int D> void step_usl(Engine<D>& e, const StepContext<D>& s, bool musl) {
  auto& P = s.particles;
  auto& n = s.nodes;
  const double dt = s.dt;
  e.evaluate_basis();
  // 1. m_I, q_I = sum N_Ip m_p v_p and f_I in one pass; Dirichlet on f_I.
  //    Saturated bodies: the liquid's sums in the same pass, then the
  //    coupled solve (f_I becomes m_s a_s).
  TwoPhase<D>* liquid = e.settings().two_phase.get();
  e.to_nodes({.mass = true, .w = &P.v, .forces = true, .t = s.t, .liquid = liquid});
  if (liquid) liquid->to_nodes(e, s.t, dt);
  e.apply_dirichlet_force(n.f, dt);
  // 2. a_I = f_I / m_I; v_I = q_I / m_I + dt a_I; constraints (their change
  //    of v_I - a held value, a wall - also enters a_I, which updates the
  //    particle velocities).
  e.solve_mass_add(n.f, n.a, dt, n.v, dt, &n.q);
  e.constrain_velocity(n.v, {.rate = &n.a, .c = dt});
  if (liquid) liquid->nodal_velocity(e, dt);
  // 3. v_p += dt sum N_Ip a_I; x_p += dt sum N_Ip v_I; x_I += dt v_I in ul;
  //    usl: then the PIC relaxation toward sum N_Ip v_I, if any.
  //    usl, saturated bodies: w_p and the pore pressure increments in the same pass.
  TwoPhase<D>* rows = musl ? nullptr : liquid;
  if (rows) rows->begin_rows(e, dt);
  const double share = pic_share(s);
  const ToParticles<D> move{.rate = &n.a,
                            .c_rate = dt,
                            .move = &n.v,
                            .c_move = dt,
                            .liquid = rows,
                            .pic = musl ? nullptr : &n.v,
                            .pic_share = share,
                            .last = !musl};
  // 4. (usl) L_p = sum v_I (x) grad N_Ip; strain, density and stress
  //    update, in the same pass over the particles.
  // musl: v_I recomputed from the updated particle momenta (each block of
  // particles moved, then scattered, in one pass), then step 4.
  if (musl) e.to_particles_then_to_nodes(move, {.w = &P.v});
  else e.to_particles_and_update_stress(move, {&n.v, dt});
  scale(n, n.dx, dt, n.v); // also in mpm mode: the step's nodal increments (Engine::nodal)
  e.advect_nodes(n.dx);
  if (!musl) {
    if (liquid) liquid->to_particles(e, dt); // the cell average of the pore pressure increments
    return;
  }
  e.solve_mass(n.q, n.v);
  e.constrain_velocity(n.v, {.impulse = false});
  if (liquid) liquid->remap(e, dt); // w_p, its re-projection, the rigid plates
  e.update_stress({&n.v, dt});
  if (liquid) liquid->update_pressure(e, dt);
  // musl: the PIC relaxation toward the remapped sum N_Ip v_I, if any.
  if (share > 0.0) e.to_particles({.pic = &n.v, .pic_share = share});
}

} // namespace

template <int D> void step_fe(Engine<D>& e, const StepContext<D>& s) { step_usl(e, s, false); }
template <int D> void step_musl(Engine<D>& e, const StepContext<D>& s) { step_usl(e, s, true); }

#define OTMPM_INSTANTIATE(D)                                                   \
  template void step_fe<D>(Engine<D>&, const StepContext<D>&);                \
  template void step_musl<D>(Engine<D>&, const StepContext<D>&);
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm
