/// \file run.cpp
/// A run of a scene to its end (run.hpp): run_scene() and restart_run() as a
/// loop over Simulation::step() (simulation.cpp), the run's summary line
/// and the check of its output names.
#include "otmpm/run/run.hpp"

#include "otmpm/interrupt.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/run/restart.hpp"
#include "otmpm/run/run_common.hpp"
#include "otmpm/run/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <new>
#include <optional>

namespace otmpm {

namespace {

/// Floor of EnergySummary::reference(), so a body at rest with no load has ratio 0, not 0/0.
constexpr double energy_reference_floor = 1e-300;

} // namespace

void EnergySummary::sample(double energy, double work, double balance_error) {
  if (!std::isfinite(energy) || !std::isfinite(work) || !std::isfinite(balance_error)) return;
  max_energy = std::max(max_energy, energy);
  max_work = std::max(max_work, std::abs(work));
  max_balance_error = std::max(max_balance_error, std::abs(balance_error));
}

double EnergySummary::reference() const { return std::max(initial + max_work, energy_reference_floor); }
double EnergySummary::max_energy_ratio() const { return max_energy / reference(); }
double EnergySummary::energy_drift() const { return max_balance_error / reference(); }

namespace {
/// Steps a simulation to t_end; an instability ends it with its status, a
/// request through options.interrupt (checked before each step) with status
/// "interrupted" and a last checkpoint.
RunSummary run_to_end(Simulation& sim, const RunOptions& options) {
  try {
    while (!sim.finished()) {
      if (interrupt_requested(options)) {
        sim.interrupt();
        break;
      }
      sim.step();
    }
  } catch (const InstabilityError&) { // the status is in the summary
  } catch (const OutputError&) {
  } catch (const DeferredOutOfMemory&) { // every rank of a distributed run, with the same status
  } catch (const std::bad_alloc&) {
    if (!sim.finished()) throw; // a distributed run: no status could be agreed on
  }
  return sim.finish();
}

/// The summary of a run that did not start at step `step`, time `t` (0 for
/// a new run, the checkpoint's for a restart), with `status` and `exit_code`.
RunSummary not_started(const Scene& scene, long step, double t, const std::string& status, int exit_code) {
  RunSummary s;
  s.mode = scene.simulation.mode;
  s.integrator = scene.simulation.integrator;
  s.basis = scene.basis.kind;
  s.steps = step;
  s.time = t;
  s.status = status;
  s.exit_code = exit_code;
  s.interrupted = exit_code == kInterruptedExit;
  return s;
}

/// Sets up a simulation (make(sim)) that starts at step `step`, time `t`
/// and runs it to the end - unless options.interrupt asked to stop before
/// the set-up (status "interrupted", no result file) or the result file
/// could not even be created (no room for its first bytes: "output error:
/// ...", kOutputErrorExit). scene_of() gives the scene for the summary of
/// a run that did not start.
template <class SceneOf, class Make>
RunSummary set_up_and_run(long step, double t, const RunOptions& options, SceneOf&& scene_of, Make&& make) {
  if (interrupt_requested(options)) return not_started(scene_of(), step, t, "interrupted", kInterruptedExit);
  std::optional<Simulation> sim;
  try {
    make(sim);
  } catch (const OutputError& err) {
    return not_started(scene_of(), step, t, "output error: " + diagnosis(err.what(), step, t), kOutputErrorExit);
  } catch (const InterruptedError&) { // inside the set-up's loops (DimRunner::build): nothing was written
    return not_started(scene_of(), step, t, "interrupted", kInterruptedExit);
  }
  return run_to_end(*sim, options);
}
} // namespace

RunSummary run_scene(const Scene& scene, const RunOptions& options) {
  return set_up_and_run(
      0, 0.0, options, [&] { return scene; }, [&](std::optional<Simulation>& sim) { sim.emplace(scene, options); });
}

RunSummary restart_run(const Checkpoint& checkpoint, const RunOptions& options) {
  const StateGroup& g = checkpoint.group("engine");
  return set_up_and_run(
      static_cast<long>(g.integer("step")), g.real("t"), options, [&] { return checkpoint_scene(checkpoint); },
      [&](std::optional<Simulation>& sim) { sim.emplace(checkpoint, options); });
}

std::string summary_line(const RunSummary& s) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s %s %s: %ld steps, t = %.6g s, %.3f s wall, %.3g particle-steps/s",
                s.mode.c_str(), s.integrator.c_str(), s.basis.c_str(), s.steps, s.time, s.wall_seconds,
                s.particle_steps_per_second());
  const bool memory = s.status.rfind(kOutOfMemoryStatus, 0) == 0;
  const char* head = s.interrupted                     ? "INTERRUPTED: "
                     : memory                          ? "OUT OF MEMORY: "
                     : s.exit_code == kOutputErrorExit ? "OUTPUT FAILED: "
                     : s.exit_code != 0                ? "UNSTABLE: "
                                                       : "ok: ";
  std::string line = head + std::string(buf);
  for (const auto& [name, value] : s.errors) {
    std::snprintf(buf, sizeof buf, ", %s = %.4g", name.c_str(), value);
    line += buf;
  }
  std::snprintf(buf, sizeof buf, ", max_energy_ratio = %.4g, energy_drift = %.3g", s.energy.max_energy_ratio(),
                s.energy.energy_drift());
  line += buf;
  if (s.impact != 0.0) {
    std::snprintf(buf, sizeof buf, ", impact = %.3g J", s.impact);
    line += buf;
  }
  for (const auto& [name, value] : s.diagnostics)
    if (value != 0.0) {
      std::snprintf(buf, sizeof buf, ", %s = %.0f", name.c_str(), value);
      line += buf;
    }
  return line;
}

void check_output_names(const Scene& scene, const std::string& out_file) {
  if (out_file.empty() && scene.output.file.empty()) return;
  RunOptions opt;
  opt.out_file = out_file;
  checked_output_files(output_request(scene, "", opt, nullptr));
}

} // namespace otmpm
