// Timing an engine's steps and whole runs for the benchmark tables
// (bench_table): wall time per step, the phase timers, thread counts.
#pragma once

#include "bench_util.hpp"
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/run/run.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

namespace otmpm::bench {

/// Seconds per step and phase times of one timed stretch of steps, or of a
/// whole run (per_step = wall time / steps).
struct Timing {
  double per_step = 0.0;
  double wall = 0.0; ///< seconds of the whole timed stretch
  /// CPU seconds of the calling thread over the stretch: on one thread, the
  /// time without the moments the thread was descheduled (a busy host)
  double cpu = 0.0;
  long particles = 0;
  long steps = 0;
  double nodes_per_particle = 0.0; ///< mean basis-table row length (0: not known, whole runs)
  PhaseTimers phases;
};

/// The OpenMP thread count of the following parallel loops (0: leave it,
/// e.g. as OMP_NUM_THREADS set it).
inline void set_threads(int threads) {
#ifdef OTMPM_HAVE_OPENMP
  if (threads > 0) omp_set_num_threads(threads);
#else
  (void)threads;
#endif
}

/// Times `steps` steps of the engine (0: up to t_end) on `threads` threads
/// (set_threads), its phase timers reset first.
template <int D> Timing time_steps(Engine<D>& e, long steps, int threads, double t_end) {
  set_threads(threads);
  e.timers() = PhaseTimers{};
  const double c0 = thread_ns();
  const auto t0 = std::chrono::steady_clock::now();
  long done = 0;
  for (; steps > 0 ? done < steps : e.time() < t_end; ++done) e.step();
  Timing t;
  t.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  t.cpu = 1e-9 * (thread_ns() - c0);
  t.per_step = t.wall / double(done);
  t.particles = e.particles().size();
  t.steps = done;
  // counted from the step's rows: building the table here would add its
  // bytes to the memory row's peak, which the runs never allocate
  t.nodes_per_particle = double(e.basis_entries()) / double(std::max(1, e.particles().size()));
  t.phases = e.timers();
  return t;
}

/// Builds the engine, takes one untimed step (first basis evaluation, cold
/// LME start, buffers grow), then times `steps` steps (0: up to t_end).
template <int D> Timing time_run(const Scene& scene, long steps, int threads) {
  set_threads(threads);
  Engine<D> e = assemble<D>(scene);
  e.step();
  return time_steps(e, steps, threads, scene.simulation.t_end);
}

/// A whole run as `otmpm run` makes it (run_scene: engine built, stepped to
/// t_end, energies and reference errors checked; wall = RunSummary's
/// wall_seconds), without writing a result file. Exits 1 when the run does
/// not finish ok.
inline Timing time_whole_run(const Scene& scene, int threads) {
  set_threads(threads);
  RunOptions options;
  options.write_results = false;
  const double c0 = thread_ns();
  const RunSummary s = run_scene(scene, options);
  const double cpu = 1e-9 * (thread_ns() - c0);
  if (s.exit_code != 0) {
    std::fprintf(stderr, "bench: %s %s %s run failed: %s\n", s.mode.c_str(), s.basis.c_str(), s.integrator.c_str(),
                 s.status.c_str());
    std::exit(1);
  }
  Timing t;
  t.wall = s.wall_seconds;
  t.cpu = cpu;
  t.per_step = s.wall_seconds / double(s.steps);
  t.particles = s.particles;
  t.steps = s.steps;
  t.phases = s.timers;
  return t;
}

/// "basis 40%, to_nodes 25%, ..." - each phase's share of the timed phases.
inline std::string phase_shares(const PhaseTimers& p) {
  double total = 0;
  for (double s : p.seconds) total += s;
  std::string out;
  char buf[64];
  for (std::size_t i = 0; i < phase_names.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%s %.0f%%%s", std::string(phase_names[i]).c_str(),
                  total > 0 ? 100 * p.seconds[i] / total : 0.0, i + 1 < phase_names.size() ? ", " : "");
    out += buf;
  }
  return out;
}

} // namespace otmpm::bench
