/// \file integrators.cpp
/// One step of each time integrator, written to read like the listings of
/// spec algorithms.md sect. 3. The stages (project_mass, compute_forces, ...)
/// live in the engine and are shared; advect_nodes() is a no-op in `mpm`
/// mode, which is the only difference between the two node modes.
#include "otmpm/engine/engine.hpp"
#include "otmpm/engine/parallel.hpp"

namespace otmpm {

namespace {
/// a += s * b over nodal or particle arrays (threaded, per item).
template <int D> void axpy(AlignedVector<Vec<D>>& a, double s, const AlignedVector<Vec<D>>& b) {
  parallel_for(static_cast<long long>(a.size()), [&](long long i) { a[i] += s * b[i]; });
}
/// y = s * x over nodal or particle arrays (threaded, per item).
template <int D> void scale(AlignedVector<Vec<D>>& y, double s, const AlignedVector<Vec<D>>& x) {
  y.resize(x.size());
  parallel_for(static_cast<long long>(x.size()), [&](long long i) { y[i] = s * x[i]; });
}
/// The nodal increment of OTM and the unified approach (wobbes eq. 51):
/// v_I = M^{-1} (q + (dt + dt_prev)/2 f) with Dirichlet values, dx_I = dt v_I.
/// dx holds the right-hand side q + (dt + dt_prev)/2 f until the solve.
template <int D> void transport_increment(Engine<D>& e, NodalFields<D>& n, double dt, double dt_prev) {
  n.dx.resize(n.q.size());
  parallel_for(static_cast<long long>(n.q.size()),
               [&](long long I) { n.dx[I] = n.q[I] + (0.5 * (dt + dt_prev)) * n.f[I]; });
  e.solve_mass(n.dx, n.v);
  e.apply_dirichlet_velocity(n.v);
  scale(n.dx, dt, n.v);
}
} // namespace

/// fe / musl: forward Euler, update stress last (wobbes Algorithm 1, lumped).
template <int D> void step_fe(Engine<D>& e, bool musl) {
  auto& P = e.P_;
  auto& n = e.nodal_;
  const double dt = e.dt_;
  e.evaluate_basis();
  // 1. m_I, q_I = sum N_Ip m_p v_p and f_I in one pass; Dirichlet on f_I.
  e.to_nodes({.mass = true, .w = &P.v, .forces = true, .t = e.t_});
  e.apply_dirichlet_force(n.f);
  // 2. a_I = f_I / m_I; v_I = q_I / m_I + dt a_I.
  e.solve_mass(n.f, n.a);
  e.solve_mass(n.q, n.v);
  axpy(n.v, dt, n.a);
  e.apply_dirichlet_velocity(n.v);
  // 3. v_p += dt sum N_Ip a_I; x_p += dt sum N_Ip v_I; x_I += dt v_I in ul.
  // 4. (usl) L_p = sum v_I (x) grad N_Ip; strain, density and stress update,
  //    in the same pass over the particles.
  e.to_particles({.rate = &n.a, .c_rate = dt, .move = &n.v, .c_move = dt, .grad = musl ? nullptr : &n.v, .c_grad = dt});
  scale(n.dx, dt, n.v);
  e.advect_nodes(n.dx);
  // musl: v_I recomputed from the updated particle momenta, then step 4.
  if (musl) {
    e.project_momentum(P.v, 0.0, nullptr);
    e.solve_mass(n.q, n.v);
    e.apply_dirichlet_velocity(n.v);
    e.update_stress(n.v, dt);
  }
}

/// npc: explicit Newmark predictor-corrector (molinos Algorithm 1).
template <int D> void step_npc(Engine<D>& e) {
  auto& P = e.P_;
  auto& n = e.nodal_;
  const double dt = e.dt_;
  const double gamma = e.scene_.simulation.gamma;
  e.evaluate_basis();
  // 1. m_I = sum N_Ip m_p, and (same pass)
  // 2. predictor: v_I^pred = sum N_Ip m_p (v_p + (1-gamma) dt a_p) / m_I.
  e.to_nodes({.mass = true, .w = &P.v, .c = (1.0 - gamma) * dt, .a = &P.a});
  e.solve_mass(n.q, n.v);
  // 3. Dirichlet on the predictor.
  e.apply_dirichlet_velocity(n.v);
  // 4. L_p from the predictor; strain, density and stress update, and (same
  //    pass over the basis table, each particle updated before it scatters)
  // 5. f_I with the updated stresses and b(t + dt); fixed components zeroed.
  e.to_nodes({.forces = true, .t = e.t_ + dt, .stress_from = &n.v, .dt = dt});
  e.apply_dirichlet_force(n.f);
  // 6. corrector: v_I = v_I^pred + gamma dt f_I / m_I.
  e.solve_mass(n.f, n.a);
  axpy(n.v, gamma * dt, n.a);
  // 7. a_p = sum N_Ip f_I/m_I; v_p += dt a_p; x_p += sum N_Ip (dt v_I + dt^2/2 f_I/m_I).
  n.dx.resize(n.v.size());
  parallel_for(static_cast<long long>(n.v.size()),
               [&](long long I) { n.dx[I] = dt * n.v[I] + (0.5 * dt * dt) * n.a[I]; });
  e.to_particles({.rate = &n.a, .c_rate = dt, .rate_out = &P.a, .move = &n.dx, .c_move = 1.0});
  e.advect_nodes(n.dx);
}

/// otm: optimal transportation meshfree update (wobbes Algorithm 2), ul only.
template <int D> void step_otm(Engine<D>& e) {
  auto& P = e.P_;
  auto& n = e.nodal_;
  const double dt = e.dt_, dt_prev = e.dt_prev_;
  e.evaluate_basis();
  // v_p := (x_p^s - x_p^{s-1}) / dt_s (initially x^{-1} = x^0 - dt v^0).
  if (e.step_ > 0) parallel_for(P.size(), [&](long long p) { P.v[p] = (P.x[p] - P.x_prev[p]) / dt_prev; });
  // 1. q_I = sum N_Ip m_p v_p; dx_I = dt M^{-1} (q + (dt + dt_prev)/2 f).
  e.to_nodes({.mass = true, .w = &P.v, .forces = true, .t = e.t_});
  e.apply_dirichlet_force(n.f);
  transport_increment(e, n, dt, dt_prev);
  // 2. x_I += dx_I; x_p = sum N_Ip x_I (old N): x_p += sum N_Ip dx_I, and
  //    v_p = sum N_Ip dx_I / dt, in one threaded pass.
  {
    ScopedPhase timer(e.timers_, Phase::to_particles);
    P.x_prev.resize(P.x.size());
    parallel_for(P.size(), [&](long long p) {
      const Vec<D> dx = e.interpolate(static_cast<int>(p), n.dx);
      P.x_prev[p] = P.x[p];
      P.x[p] += dx;
      P.v[p] = dx / dt;
    });
  }
  e.advect_nodes(n.dx);
  // 3. G_p = I + sum dx_I (x) grad N_Ip; F_p = G_p F_p; V_p = det(G_p) V_p; stress.
  e.update_stress_from_increment(n.dx);
}

/// unified: B-spline basis on advected knots, consistent mass (wobbes Algorithm 3).
template <int D> void step_unified(Engine<D>& e) {
  auto& P = e.P_;
  auto& n = e.nodal_;
  const double dt = e.dt_, dt_prev = e.dt_prev_;
  e.evaluate_basis();
  e.to_nodes({.mass = true, .w = &P.v, .forces = true, .t = e.t_});
  e.apply_dirichlet_force(n.f);
  // 1. a = M^{-1} f; dx = dt M^{-1} (q + (dt + dt_prev)/2 f); x_I += dx_I.
  e.solve_mass(n.f, n.a);
  transport_increment(e, n, dt, dt_prev);
  // 2. x_p += sum N_Ip dx_I; v_p += dt sum N_Ip a_I; and (same pass)
  // 3. F_p = (I + sum dx_I (x) grad N_Ip) F_p; V_p = det(F_p) V0_p; stress.
  e.to_particles({.rate = &n.a, .c_rate = dt, .move = &n.dx, .c_move = 1.0, .grad = &n.dx, .c_grad = 1.0});
  e.advect_nodes(n.dx);
}

#define OTMPM_INSTANTIATE(D)                                                             \
  template void step_fe<D>(Engine<D>&, bool);                                           \
  template void step_npc<D>(Engine<D>&);                                                \
  template void step_otm<D>(Engine<D>&);                                                \
  template void step_unified<D>(Engine<D>&);
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm
