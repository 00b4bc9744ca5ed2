/// \file otm.cpp
/// otm: the optimal transportation meshfree update of wobbes et al.
/// (Algorithm 2; docs/theory.md sect. 8.4), with advected nodes only.
#include "otmpm/integrators/nodal_ops.hpp"

namespace otmpm {

template <int D> void step_otm(Engine<D>& e, const StepContext<D>& s) {
  auto& P = s.particles;
  auto& n = s.nodes;
  const double dt = s.dt, dt_prev = s.dt_prev;
  e.evaluate_basis();
  // v_p := (x_p^s - x_p^{s-1}) / dt_s (initially x^{-1} = x^0 - dt v^0).
  if (s.step > 0) parallel_for(P.size(), [&](long long p) { P.v[p] = (P.x[p] - P.x_prev[p]) / dt_prev; });
  // 1. q_I = sum N_Ip m_p v_p; dx_I = dt M^{-1} (q + (dt + dt_prev)/2 f).
  e.to_nodes({.mass = true, .w = &P.v, .forces = true, .t = s.t});
  // v_p = sum N_Ip v_I: the particles take up (dt + dt_prev)/2 of the force
  // and every change the constraints make to v_I.
  e.apply_dirichlet_force(n.f, 0.5 * (dt + dt_prev));
  transport_increment(e, n, dt, dt_prev, {}, 1.0); // v_p comes from dx
  // 2. x_I += dx_I; x_p = sum N_Ip x_I (old N): x_p += sum N_Ip dx_I, and
  //    v_p = sum N_Ip dx_I / dt, in one threaded pass.
  {
    ScopedPhase timer(e.timers(), Phase::to_particles);
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
  e.update_stress({&n.dx, 1.0});
}

template void step_otm<1>(Engine<1>&, const StepContext<1>&);
template void step_otm<2>(Engine<2>&, const StepContext<2>&);
template void step_otm<3>(Engine<3>&, const StepContext<3>&);

} // namespace otmpm
