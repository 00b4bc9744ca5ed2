#pragma once
/// \file nodal_ops.hpp
/// Small threaded operations on nodal (or particle) arrays shared by the
/// integrators, each item written only by its own thread (the same bits for
/// any thread count). Internal to integrators/.
#include "otmpm/engine/engine.hpp"
#include "otmpm/parallel.hpp"

namespace otmpm {

/// body(I) for every node the step visits (NodalFields::visited; the
/// others' fields are zero and stay so).
template <int D, class Body> void for_nodes(const NodalFields<D>& n, Body&& body) {
  const int* visited = n.visited.data();
  parallel_for(static_cast<long long>(n.visited.size()), [&](long long i) { body(visited[i]); });
}

/// The share min(1, dt / tau) of the grid's (PIC) velocity sum_I N_Ip v_I
/// in the particles' new velocity (ToParticles::pic), tau the integrator's
/// pic_relaxation_time; 0 without one (FLIP).
template <int D> double pic_share(const StepContext<D>& s) {
  const double tau = s.parameters.get("pic_relaxation_time");
  return tau > 0.0 ? std::min(1.0, s.dt / tau) : 0.0;
}

/// a += s * b on the nodes of n.
template <int D> void axpy(const NodalFields<D>& n, AlignedVector<Vec<D>>& a, double s, const AlignedVector<Vec<D>>& b) {
  for_nodes(n, [&](int I) { a[I] += s * b[I]; });
}

/// y = s * x on the nodes of n.
template <int D>
void scale(const NodalFields<D>& n, AlignedVector<Vec<D>>& y, double s, const AlignedVector<Vec<D>>& x) {
  y.resize(x.size());
  for_nodes(n, [&](int I) { y[I] = s * x[I]; });
}

/// The nodal increment of OTM and the unified approach (wobbes et al. eq. 51):
/// v_I = M^{-1} (q + (dt + dt_prev)/2 f) with the constraints (`effect`: how
/// a constraint's change reaches the particles), dx_I = dt v_I. n.dx holds
/// the right-hand side until the solve. `c`: the factor with which the
/// particles' velocities take up v_I (Engine::solve_mass; 0: they do not).
template <int D>
void transport_increment(Engine<D>& e, NodalFields<D>& n, double dt, double dt_prev, const WallEffect<D>& effect,
                         double c) {
  n.dx.resize(n.q.size());
  for_nodes(n, [&](int I) { n.dx[I] = n.q[I] + (0.5 * (dt + dt_prev)) * n.f[I]; });
  e.solve_mass(n.dx, n.v, c);
  e.constrain_velocity(n.v, effect);
  scale(n, n.dx, dt, n.v);
}

} // namespace otmpm
