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
#include "otmpm/particles/particles_box.hpp"
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

/// The largest extent of the bodies' particles along an axis: L of eq. 15.17.
template <int D> double extent(const Particles<D>& P) {
  const auto [lo, hi] = particles_box(P);
  return P.size() > 0 ? (hi - lo).maxCoeff() : 0.0;
}

/// "particle P (body 'NAME') at (x, y): |v| = V m/s", the fastest of the
/// phase's particles (serial: P is the particle's number in the run too).
template <int D> std::string fastest_particle(const Scene& scene, const Particles<D>& P) {
  if (P.size() == 0) return "";
  int fastest = 0;
  for (int p = 1; p < P.size(); ++p)
    if (P.v[p].squaredNorm() > P.v[fastest].squaredNorm()) fastest = p;
  const auto body = static_cast<std::size_t>(P.body[static_cast<std::size_t>(fastest)]);
  char speed[48];
  std::snprintf(speed, sizeof speed, ": |v| = %.3g m/s", P.v[fastest].norm());
  return "particle " + std::to_string(fastest) + " (body '" + scene.bodies.at(body).name + "') at " +
         format_point<D>(P.x[fastest]) + speed;
}

/// The rule of eq. 15.17: the phase has converged when both residuals have
/// been below the tolerance at every step over the last W.
struct SustainedBelow {
  double since = -1.0; ///< the phase time at the start of the first step of the current run below the tolerance
  /// r.held and r.converged after a step that started at `start` and ended at r.time.
  void check(EquilibriumReport& r, double start, double tolerance) {
    const bool below = std::max(r.force_residual, r.velocity_residual) < tolerance;
    since = !below ? -1.0 : since < 0.0 ? start : since;
    r.held = below ? r.time - since : 0.0;
    r.converged = below && r.held >= r.window * (1.0 - time_slack);
  }
};

/// Why a phase did not converge, from its last residuals, and what to try.
std::string not_converged_hint(const EquilibriumReport& r, double tolerance) {
  char buf[160];
  if (std::max(r.force_residual, r.velocity_residual) < tolerance) {
    std::snprintf(buf, sizeof buf, "both below the tolerance for the last %.3g s of the %.3g s they must hold",
                  r.held, r.window);
    return std::string(buf) + ": give a longer time";
  }
  if (r.force_residual < tolerance)
    return "R_v above the tolerance with no unbalanced force to damp: the bodies creep (consolidation, a "
           "rate-dependent material) or slide as a mechanism (a slope steeper than its strength holds): give a "
           "longer time, or check that the bodies have an equilibrium under their weight";
  return "R_f above the tolerance: give a longer time; an unbalanced force that does not decrease is a part "
         "that nothing holds (a boundary missing) or that slides (a slope steeper than its strength holds)";
}

} // namespace

std::string EquilibriumReport::describe(double tolerance) const {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s %ld steps (%.6g s): R_f = %.3g, R_v = %.3g (tolerance %.3g",
                converged ? "converged after" : "not converged in", steps, time, force_residual,
                velocity_residual, tolerance);
  std::string s = buf;
  std::snprintf(buf, sizeof buf, ", held for %.3g s)", window);
  if (converged) return s + buf;
  return s + "); " + not_converged_hint(*this, tolerance) + (fastest.empty() ? "" : "; the fastest: " + fastest);
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

template <int D>
EquilibriumReport settle(const Scene& scene, Engine<D>& e,
                         const std::function<void(const EquilibriumReport&)>& each_step) {
  const InitialEquilibrium& q = *scene.simulation.initial_equilibrium;
  const Scene phase_scene = equilibrium_scene(scene);
  Engine<D> phase(assemble_parts<D>(phase_scene));
  const Particles<D>& P = phase.particles();
  double weight = 0.0;
  for (int p = 0; p < P.size(); ++p) weight += P.m[p];
  const double g = first_components(scene.body_force->value, D).norm(); // |b| of the run's components
  weight *= g;
  const double speed = std::sqrt(g * phase.settings().h);
  const double L = extent(P);
  EquilibriumReport report;
  AlignedVector<Vec<D>> v0;
  std::vector<double> w0;
  SustainedBelow rule;
  try {
    while (phase.time() < q.time * (1.0 - time_slack)) {
      interrupt_point("bringing the bodies into their initial equilibrium");
      const double start = phase.time();
      std::tie(report.force_residual, report.velocity_residual) =
          damped_step(phase, q.damping, weight, speed, v0, w0);
      report.steps = phase.steps();
      report.time = phase.time();
      report.window = 2.0 * L / phase.wave_speed(); // eq. 15.17
      rule.check(report, start, q.tolerance);
      if (each_step) each_step(report);
      if (report.converged) break;
    }
  } catch (const InstabilityError& err) { // the phase's step and time, before the run's t = 0
    throw InstabilityError(
        std::string("in the initial equilibrium phase (simulation.initial_equilibrium): ") + err.what());
  }
  if (!report.converged) report.fastest = fastest_particle(scene, phase.particles());
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

template EquilibriumReport settle<1>(const Scene&, Engine<1>&,
                                        const std::function<void(const EquilibriumReport&)>&);
template EquilibriumReport settle<2>(const Scene&, Engine<2>&,
                                        const std::function<void(const EquilibriumReport&)>&);
template EquilibriumReport settle<3>(const Scene&, Engine<3>&,
                                        const std::function<void(const EquilibriumReport&)>&);

} // namespace otmpm
