/// \file explicit_alpha.cpp
/// explicit_alpha: the explicit generalised-alpha method of Hulbert & Chung
/// (1996; docs/theory.md sect. 8.7) with the spectral radius rho_inf (their
/// rho_b) at the bifurcation limit:
///   alpha_m = (2 rho - 1) / (1 + rho),  beta = (5 - 3 rho) / ((1 + rho)^2 (2 - rho)),
///   gamma = 3/2 - alpha_m,
///   (1 - alpha_m) a_{n+1} + alpha_m a_n = M^{-1} f(sigma_n, t_n),
///   x_{n+1} = x_n + dt v_n + dt^2 ((1/2 - beta) a_n + beta a_{n+1}),
///   v_{n+1} = v_n + dt ((1 - gamma) a_n + gamma a_{n+1}),
/// second-order accurate, stable to omega dt <= Omega_s(rho) (2 for rho = 1,
/// where it is dissipation free; 1.87 for rho = 1/2). On the particles:
/// a_p carries a_n from step to step (a_n = M^{-1} f_0 in the first step),
/// v_p += dt ((1 - gamma) a_p + gamma sum N a_{n+1}), a_p = sum N a_{n+1},
/// x_p += sum N dx, and the stress follows the increment (as otm's).
#include "otmpm/integrators/nodal_ops.hpp"

namespace otmpm {

template <int D> void step_explicit_alpha(Engine<D>& e, const StepContext<D>& s) {
  auto& P = s.particles;
  auto& n = s.nodes;
  const double dt = s.dt, rho = s.parameters.get("rho_inf");
  const double am = (2.0 * rho - 1.0) / (1.0 + rho);
  const double beta = (5.0 - 3.0 * rho) / ((1.0 + rho) * (1.0 + rho) * (2.0 - rho));
  const double gamma = 1.5 - am;
  e.evaluate_basis();
  // 1. m_I, q_I = sum N_Ip m_p v_p, f_I^n; Dirichlet on f_I. a = f / m, v = q / m.
  e.to_nodes({.mass = true, .w = &P.v, .forces = true, .t = s.t});
  e.apply_dirichlet_force(n.f, 0.0); // booked as the rate hands it on (step 3)
  e.solve_mass(n.f, n.a);
  e.solve_mass(n.q, n.v);
  // 2. a_n at the nodes (held in dx): sum N_Ip m_p a_p / m_I; f / m in the first step.
  if (s.step == 0) {
    scale(n, n.dx, 1.0, n.a);
  } else {
    e.to_nodes({.w = &P.a});
    e.solve_mass(n.q, n.dx);
  }
  e.constrain_rate(n.dx);
  // The particles start from it too, a_p = sum N a_0: step 5 takes (1 -
  // gamma) dt a_p up, and with a_p = 0 the first step gave them gamma dt a_0
  // instead of dt a_0 (1.5 times at rho_inf = 1/2), an offset FLIP kept.
  if (s.step == 0) e.to_particles({.rate = &n.dx, .c_rate = 0.0, .rate_out = &P.a});
  // 3. a_{n+1} = (f / m - alpha_m a_n) / (1 - alpha_m); v_{n+1}; constraints
  //    (their change enters a_{n+1}, which the particles keep as a_p: the
  //    momentum it gives them over this and the next steps is booked as they
  //    take it up).
  for_nodes(n, [&](int I) {
    n.a[I] = (n.a[I] - am * n.dx[I]) / (1.0 - am);
    n.v[I] += dt * ((1.0 - gamma) * n.dx[I] + gamma * n.a[I]);
  });
  // In the first step the held components jump to their values: a kick (in
  // q), which a_p does not keep.
  const bool first = s.step == 0;
  if (first) scale(n, n.q, 0.0, n.v);
  e.constrain_velocity(n.v, {.rate = &n.a, .c = gamma * dt, .booking = Booking::carried, .kick = first ? &n.q : nullptr});
  e.book_carried(am, gamma, first, n.dx);
  // 4. dx = dt v_{n+1} + dt^2 ((gamma - 1/2 - beta) a_n + (beta - gamma) a_{n+1})
  //    (= dt v_n + dt^2 ((1/2 - beta) a_n + beta a_{n+1})).
  for_nodes(n, [&](int I) {
    n.dx[I] = dt * n.v[I] + (dt * dt) * ((gamma - 0.5 - beta) * n.dx[I] + (beta - gamma) * n.a[I]);
  });
  e.constrain_increment(n.dx);
  // 5. v_p += dt ((1 - gamma) a_p + gamma sum N a_{n+1}), then the PIC
  //    relaxation toward sum N v_{n+1}, if any; a_p = sum N a_{n+1}; x_p += sum N dx.
  parallel_for(P.size(), [&](long long p) { P.v[p] += (dt * (1.0 - gamma)) * P.a[p]; });
  e.to_particles({.rate = &n.a, .c_rate = gamma * dt, .rate_out = &P.a, .kick = first ? &n.q : nullptr, .move = &n.dx,
                  .c_move = 1.0, .pic = &n.v, .pic_share = pic_share(s)});
  // 6. the stress from the increment, F_p = (I + sum dx_I (x) grad N_Ip) F_p; x_I += dx_I in ul.
  e.update_stress({&n.dx, 1.0});
  e.advect_nodes(n.dx);
}

template void step_explicit_alpha<1>(Engine<1>&, const StepContext<1>&);
template void step_explicit_alpha<2>(Engine<2>&, const StepContext<2>&);
template void step_explicit_alpha<3>(Engine<3>&, const StepContext<3>&);

} // namespace otmpm
