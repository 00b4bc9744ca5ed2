/// \file initial_equilibrium.cpp
/// The gravity-loading phase (initial_equilibrium.hpp, docs/theory.md
/// sect. 15, "Initial equilibrium"): an engine of the phase's scene stepped
/// with local damping, then its state moved into the run's engine through
/// the checkpoint groups (Engine::save_state / restore_state), which carry
/// everything a step hands to the next.
#include "otmpm/run/initial_equilibrium.hpp"

#include "otmpm/assembly/assembler.hpp"
#include "otmpm/interrupt.hpp"
#include "otmpm/materials/pore_fluid.hpp"
#include "otmpm/run/run_common.hpp"
#include "otmpm/state.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace otmpm {

namespace {

/// Cundall's local damping of one velocity component over a step (eq. 15.15):
/// the change dv the unbalanced force gave it, less alpha |dv| in the
/// direction of the velocity v0 at the step's start.
double damped(double v0, double dv, double alpha) {
  const double sign = v0 > 0.0 ? 1.0 : v0 < 0.0 ? -1.0 : 0.0;
  return v0 + dv - alpha * std::abs(dv) * sign;
}

/// One step of the phase: the engine's step, then the damping of every
/// particle's solid (and liquid) velocity; returns the residuals of eq. 15.16
/// with `weight` = sum_p m_p |b| and `speed` = sqrt(|b| h).
template <int D>
std::pair<double, double> damped_step(Engine<D>& e, double alpha, double weight, double speed,
                                      AlignedVector<Vec<D>>& v0, std::vector<double>& w0) {
  Particles<D>& P = e.particles();
  StateField* w = P.find_state(kLiquidVelocityField);
  v0.assign(P.v.begin(), P.v.end());
  if (w) w0 = w->values;
  e.step();
  const double dt = e.last_dt();
  double unbalanced = 0.0, kinetic = 0.0, mass = 0.0;
  for (int p = 0; p < P.size(); ++p) { // in particle order: the same sums for any thread count
    const Vec<D> dv = P.v[p] - v0[p];
    unbalanced += P.m[p] * dv.norm() / dt;
    for (int k = 0; k < D; ++k) P.v[p][k] = damped(v0[p][k], dv[k], alpha);
    kinetic += P.m[p] * P.v[p].squaredNorm();
    mass += P.m[p];
  }
  if (w)
    for (std::size_t i = 0; i < w->values.size(); ++i)
      w->values[i] = damped(w0[i], w->values[i] - w0[i], alpha);
  return {unbalanced / weight, std::sqrt(kinetic / mass) / speed};
}

/// The phase's particles at rest where the run starts: X_p = x_p (zero
/// displacement), x_prev_p = x_p, a_p = 0, the plastic work zeroed (the
/// energy series start at zero); the velocities are the run's own (set by
/// settle from the run's engine).
template <int D> void start_here(Particles<D>& P) {
  P.X.assign(P.x.begin(), P.x.end());
  if (!P.x_prev.empty()) P.x_prev.assign(P.x.begin(), P.x.end());
  for (auto& a : P.a) a = Vec<D>::Zero();
  if (StateField* f = P.find_state("plastic_work")) std::fill(f->values.begin(), f->values.end(), 0.0);
}

/// The energies of eq. 11.1 that describe a state rather than a history,
/// from the engine `from` into the checkpoint group `g`; E(0) their total.
template <int D> void put_energies(StateGroup& g, const Engine<D>& from) {
  const EnergyBalance& E = from.energy();
  g.reals["energy_kinetic"] = E.kinetic;
  g.reals["energy_strain"] = E.strain;
  g.reals["energy_dissipated"] = E.dissipated;
  g.reals["energy_initial"] = E.total();
  g.reals["wave_speed"] = from.wave_speed();
}

} // namespace

std::string EquilibriumReport::describe(double tolerance) const {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s %ld steps (%.6g s): R_f = %.3g, R_v = %.3g (tolerance %.3g)",
                converged ? "converged after" : "not converged in", steps, time, force_residual,
                velocity_residual, tolerance);
  return buf;
}

Scene equilibrium_scene(const Scene& scene) {
  Scene s = scene;
  s.simulation.t_end = scene.simulation.initial_equilibrium->time;
  s.simulation.initial_equilibrium.reset();
  for (BodySection& b : s.bodies) b.velocity = Vec3{0, 0, 0}, b.velocity_profile.reset();
  s.initial_velocities.clear();
  for (BoundarySection& b : s.boundaries) {
    b.value = Vec3{0, 0, 0};
    if (b.time.kind != "constant") b.water_rise.reset(), b.time = {};
  }
  for (WallSection& w : s.walls) w.velocity = Vec3{0, 0, 0};
  for (PlateSection& p : s.plates)
    if (p.time.kind != "constant") p.force = 0.0, p.time = {};
  std::erase_if(s.tractions,
                [](const TractionSection& t) { return t.time.kind != "constant" || !t.function.empty(); });
  return s;
}

template <int D> EquilibriumReport settle(const Scene& scene, Engine<D>& e) {
  const InitialEquilibrium& q = *scene.simulation.initial_equilibrium;
  const Scene phase_scene = equilibrium_scene(scene);
  Engine<D> phase(assemble_parts<D>(phase_scene));
  const Particles<D>& P = phase.particles();
  double weight = 0.0;
  for (int p = 0; p < P.size(); ++p) weight += P.m[p];
  const double g = first_components(scene.body_force->value, D).norm(); // |b| of the run's components
  weight *= g;
  const double speed = std::sqrt(g * phase.settings().h);
  EquilibriumReport report;
  AlignedVector<Vec<D>> v0;
  std::vector<double> w0;
  try {
    while (phase.time() < q.time * (1.0 - time_slack)) {
      interrupt_point("bringing the bodies into their initial equilibrium");
      std::tie(report.force_residual, report.velocity_residual) =
          damped_step(phase, q.damping, weight, speed, v0, w0);
      report.steps = phase.steps();
      report.time = phase.time();
      report.converged = std::max(report.force_residual, report.velocity_residual) < q.tolerance;
      if (report.converged) break;
    }
  } catch (const InstabilityError& err) { // the phase's step and time, before the run's t = 0
    throw InstabilityError(
        std::string("in the initial equilibrium phase (simulation.initial_equilibrium): ") + err.what());
  }
  Checkpoint run; // the run's engine as built: its clock, impulses and works at zero, its initial velocities
  e.save_state(run);
  Particles<D>& settled = phase.particles();
  settled.v.assign(e.particles().v.begin(), e.particles().v.end());
  if (StateField* w = settled.find_state(kLiquidVelocityField))
    w->values = e.particles().find_state(kLiquidVelocityField)->values;
  start_here(settled);
  Checkpoint moved;
  phase.save_state(moved);
  run.groups["particles"] = moved.groups.at("particles");
  run.groups["basis"] = moved.groups.at("basis");
  e.restore_state(run);
  e.update_energy(); // the moved state's energies and wave speed
  put_energies(run.group("engine"), e);
  run.group("engine").reals["external_power"] = e.external_power(0.0);
  e.restore_state(run);
  return report;
}

template EquilibriumReport settle<1>(const Scene&, Engine<1>&);
template EquilibriumReport settle<2>(const Scene&, Engine<2>&);
template EquilibriumReport settle<3>(const Scene&, Engine<3>&);

} // namespace otmpm
