// `otmpm run` and `otmpm pair`.
#include "cli.hpp"
#include "interrupt.hpp"
#include "progress.hpp"
#include "system.hpp"

#include "otmpm/distributed/comm.hpp"
#include "otmpm/distributed/global_view.hpp"
#include "otmpm/run/restart.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/scene/resources.hpp"
#include "otmpm/scene/scene.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

namespace otmpm::cli {

#ifndef OTMPM_CLI_VERSION
#define OTMPM_CLI_VERSION "0.1.0"
#endif
const char* version() { return "otmpm " OTMPM_CLI_VERSION; }

namespace {

/// Seconds between two progress lines when stderr is not a terminal.
constexpr double kProgressInterval = 5.0;

/// The options of `run` and `pair`.
struct SceneArgs {
  std::string scene;
  std::vector<std::string> sets;
  std::string out;
  std::string restart; ///< checkpoint file to continue (run only)
  bool check = false;  ///< run only: validate and report, do not run
  int ranks = 0;       ///< run --check only: the rank count to plan for (0: the ranks it runs on)
  bool quiet = false;
  bool force = false;
  int threads = 0;
  double progress_interval = kProgressInterval;
};

/// The options `run` and `pair` share; returns the scene positional.
CLI::Option* add_scene_options(CLI::App& sub, SceneArgs& a) {
  CLI::Option* scene = sub.add_option("scene", a.scene, "Scene file (TOML)")->type_name("SCENE.toml");
  sub.add_option("--set", a.sets, "Override a scene value before it is checked (repeatable), e.g. --set grid.cells=[135]")
      ->type_name("KEY=VALUE")
      ->allow_extra_args(false);
  add_threads_option(sub, a.threads);
  sub.add_flag("--force", a.force, "Replace an existing result file");
  sub.add_flag("-q,--quiet", a.quiet, "No progress, no phase times, no 'results:' line (the summary line stays)");
  sub.add_option("--progress-interval", a.progress_interval,
                 "Seconds between progress lines when stderr is not a terminal")
      ->check(CLI::PositiveNumber)
      ->type_name("S")
      ->capture_default_str();
  return scene;
}

/// The phase times of a run; a phase that never ran (zero seconds: the
/// constitutive update of fe, unified and npc runs in a transfer pass and
/// counts there) is not printed.
void print_phases(const RunSummary& s) {
  std::printf("phases:");
  const char* sep = "";
  for (std::size_t i = 0; i < phase_names.size(); ++i) {
    if (s.timers.seconds[i] == 0.0) continue;
    std::printf("%s %s %.3f s", sep, std::string(phase_names[i]).c_str(), s.timers.seconds[i]);
    sep = ",";
  }
  std::printf("\n");
}

/// True on the rank that prints (rank 0; the only rank of a serial run).
bool prints() { return distributed::Comm::world().root(); }

/// The progress callback of a run: on the printing rank only.
std::function<void(double, double, long)> progress(const SceneArgs& a) {
  if (!prints()) return {};
  return make_progress(a.quiet, a.progress_interval);
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

/// The most ranks `run --check --ranks N` plans for (each played by a thread
/// of this process while it plans).
constexpr int kMaxPlannedRanks = 65536;

/// Ranks up to which `run --check` under mpirun prints a row per rank.
constexpr std::size_t kRankTableRows = 16;

/// A per-rank figure over the ranks: "min .. max (the most on rank R)", or
/// "V on every rank"; `text` formats one value.
template <class F, class T>
std::string range_of(const std::vector<RankCheck>& ranks, F get, T text) {
  std::size_t lo = 0, hi = 0;
  for (std::size_t r = 0; r < ranks.size(); ++r) {
    if (get(ranks[r]) < get(ranks[lo])) lo = r;
    if (get(ranks[r]) > get(ranks[hi])) hi = r;
  }
  const std::string least = text(get(ranks[lo])), most = text(get(ranks[hi]));
  if (least == most) return most + " on every rank";
  return least + " .. " + most + " (the most on rank " + std::to_string(hi) + ")";
}

std::string integer_text(double v) { return fmt("%.0f", v); }

/// The decomposition, memory per rank, halo and step time of `run --check` under mpirun.
void print_ranks(const SceneCheck& c, const Scene& scene) {
  const std::vector<RankCheck>& R = c.ranks;
  const auto particles = [](const RankCheck& r) { return static_cast<double>(r.particles); };
  const auto nodes = [](const RankCheck& r) { return static_cast<double>(r.nodes); };
  const auto memory = [](const RankCheck& r) { return r.memory_bytes; };
  std::printf("  particles  %ld: %s\n", c.particles, range_of(R, particles, integer_text).c_str());
  std::printf("  nodes      %ld: with its ghosts %s\n", c.nodes, range_of(R, nodes, integer_text).c_str());
  std::printf("  dt         %.6g s (first step, %s)\n", c.dt,
              scene.simulation.dt ? "fixed" : "cfl rule on the scene's fastest wave speed");
  std::printf("  steps      about %.0f (t_end = %.6g s)\n", c.estimated_steps, c.t_end);
  std::printf("  memory     about %s; %s all %zu ranks together (the run's estimates; limit %s per rank)\n",
              range_of(R, memory, format_bytes).c_str(), format_bytes(c.memory_bytes).c_str(), R.size(),
              format_bytes(c.memory_limit).c_str());
  std::printf("  halo       ghost nodes %s; neighbours %s; sent per nodal exchange %s\n",
              range_of(R, [](const RankCheck& r) { return static_cast<double>(r.ghosts); }, integer_text).c_str(),
              range_of(R, [](const RankCheck& r) { return static_cast<double>(r.neighbours); }, integer_text).c_str(),
              range_of(R, [](const RankCheck& r) { return r.halo_bytes; }, format_bytes).c_str());
  const StepTime& t = c.step_time;
  if (!t.calibrated) std::printf("  step time  not calibrated (%s)\n", t.why_not.c_str());
  else if (t.comm_rounds == 0) {
    std::printf("  step time  about %.3g s of compute on rank %d, communication not included (it is timed only "
                "between real ranks: run --check under mpirun); the run's steps at least %.3g s\n",
                t.compute, t.busiest, t.compute * c.estimated_steps);
    std::printf("             calibrated here: %d steps of a block of %ld particles of this scene's kind (%.3g us "
                "per particle, %.3g us per node)\n",
                t.calibration_steps, t.calibration_particles, 1e6 * t.per_particle, 1e6 * t.per_node);
  } else {
    std::printf("  step time  about %.3g s: compute %.3g s on rank %d, communication %.3g s (per step: nodal "
                "exchanges %.3g, reductions %.3g); the run's steps about %.3g s\n",
                t.seconds, t.compute, t.busiest, t.communication, t.exchanges, t.reductions,
                t.seconds * c.estimated_steps);
    std::printf("             calibrated on each rank: %d steps of a block of %ld particles of this scene's kind "
                "(%.3g us per particle, %.3g us per node on rank %d), and the step's exchanges with the neighbours "
                "and reductions, %d times\n",
                t.calibration_steps, t.calibration_particles, 1e6 * t.per_particle, 1e6 * t.per_node, t.busiest,
                t.comm_rounds);
  }
  if (R.size() > kRankTableRows) return;
  std::printf("  %6s %12s %12s %10s %10s %12s %12s\n", "rank", "particles", "nodes", "ghosts", "neighbours", "halo",
              "memory");
  for (std::size_t r = 0; r < R.size(); ++r)
    std::printf("  %6zu %12lld %12lld %10lld %10d %12s %12s\n", r, R[r].particles, R[r].nodes, R[r].ghosts,
                R[r].neighbours, format_bytes(R[r].halo_bytes).c_str(), format_bytes(R[r].memory_bytes).c_str());
}

/// `otmpm run --check`: what a run of the scene would be, without running it.
int check_command(const SceneArgs& a) {
  set_threads(a.threads);
  Scene scene;
  const distributed::Comm& world = distributed::Comm::world();
  const int ranks = world.size() > 1 ? world.size() : std::max(a.ranks, 1);
  distributed::agree_on(world, [&] { scene = load_scene(a.scene, a.sets, ranks); });
  const SceneCheck c = check_scene(scene, a.ranks);
  distributed::agree_on(world, [&] { check_output_names(scene, a.out); });
  if (!prints()) return 0;
  if (!c.ranks.empty()) {
    if (world.size() > 1)
      std::printf("%s: ok (the scene reads and divides over %zu ranks; nothing allocated)\n", a.scene.c_str(),
                  c.ranks.size());
    else
      std::printf("%s: ok (the scene reads and would divide over %zu ranks as shown: planned in this process, "
                  "nothing allocated)\n",
                  a.scene.c_str(), c.ranks.size());
    std::printf("  %dD, mode %s, integrator %s, basis %s\n", c.dimension, c.mode.c_str(), c.integrator.c_str(),
                c.basis.c_str());
    print_ranks(c, scene);
    std::printf("  threads    on rank 0: %s\n", threads_line().c_str());
    std::printf("  results    %s\n", (a.out.empty() ? c.out_file : a.out).c_str());
    return 0;
  }
  std::printf("%s: ok (the scene reads and the run can be set up)\n", a.scene.c_str());
  std::printf("  %dD, mode %s, integrator %s, basis %s\n", c.dimension, c.mode.c_str(), c.integrator.c_str(),
              c.basis.c_str());
  std::printf("  particles  %ld\n  nodes      %ld\n", c.particles, c.nodes);
  std::printf("  dt         %.6g s (first step%s)\n", c.dt, scene.simulation.dt ? ", fixed" : ", cfl rule");
  std::printf("  steps      about %.0f (t_end = %.6g s)\n", c.estimated_steps, c.t_end);
  if (c.phase_steps > 0)
    std::printf("  settling   up to about %.0f steps before t = 0 (simulation.initial_equilibrium, time = %.6g s; "
                "its engine is in the memory below)\n",
                c.phase_steps, scene.simulation.initial_equilibrium->time);
  std::printf("  memory     about %s (the run's estimate; limit %s)\n", format_bytes(c.memory_bytes).c_str(),
              format_bytes(c.memory_limit).c_str());
  std::printf("  threads    %s\n", threads_line().c_str());
  std::printf("  results    %s\n", (a.out.empty() ? c.out_file : a.out).c_str());
  for (const BodyVolume& v : c.volumes) {
    if (!std::isfinite(v.exact)) continue; // a file body: its particles' volumes are its volume
    const double error = (v.seeded - v.exact) / v.exact;
    std::printf("  volume     body '%s' (%s): particles %.6g, shape %.6g (error %+.3g %%)%s\n", v.name.c_str(),
                v.shape.c_str(), v.seeded, v.exact, 100.0 * error,
                std::abs(error) > 1e-12 ? "; volume = \"exact\" scales the particles to the shape" : "");
  }
  return 0;
}

/// Tells why the run stopped early and how to continue it.
void report_interrupt(const RunSummary& s, const Scene* scene) {
  std::fprintf(stderr, "otmpm: interrupted by %s at t = %.6g s (step %ld)", interrupt_signal_name(), s.time, s.steps);
  if (!s.out_file.empty()) std::fprintf(stderr, "; %s is valid, status \"interrupted\"", s.out_file.c_str());
  if (scene && scene->output.checkpoint_every > 0 && !s.out_file.empty())
    std::fprintf(stderr, "; continue with: otmpm run --restart %s",
                 checkpoint_path(*scene, s.out_file).c_str());
  std::fputc('\n', stderr);
}

int run_command(const SceneArgs& a) {
  if (a.check) return check_command(a);
  set_threads(a.threads);
  InterruptHandlers handlers;
  RunOptions opt;
  opt.out_file = a.out;
  opt.force = a.force;
  opt.background_output = core_free_for_writer();
  opt.interrupt = &interrupt_flag();
  opt.progress = progress(a);
  std::unique_ptr<Scene> scene;
  RunSummary s;
  // Each rank reads the scene or checkpoint itself; one that fails (a file
  // not yet visible on its node) fails all at once (agree_on).
  const distributed::Comm& world = distributed::Comm::world();
  if (a.restart.empty()) {
    distributed::agree_on(world, [&] { scene = std::make_unique<Scene>(load_scene(a.scene, a.sets, world.size())); });
    s = run_scene(*scene, opt);
  } else {
    // A distributed restart reads the checkpoint's head on every rank and
    // each rank's rows later (open_checkpoint, collective: it agrees on its
    // errors itself); one process reads it whole.
    std::unique_ptr<Checkpoint> ck;
    distributed::agree_on(world, [&] { require_file(a.restart, "checkpoint file"); });
    if (world.size() > 1) ck = std::make_unique<Checkpoint>(open_checkpoint(a.restart, distributed::parallel_io(world)));
    distributed::agree_on(world, [&] {
      if (!ck) ck = std::make_unique<Checkpoint>(read_checkpoint(a.restart));
      scene = std::make_unique<Scene>(checkpoint_scene(*ck));
    });
    s = restart_run(*ck, opt);
  }
  if (s.interrupted) share_interrupt_signal();
  if (!prints()) return s.interrupted ? interrupted_exit_status() : s.exit_code;
  end_progress_line();
  if (s.interrupted) report_interrupt(s, scene.get());
  else if (s.exit_code != 0) std::fprintf(stderr, "otmpm: %s\n", s.status.c_str());
  if (!a.quiet) print_phases(s);
  if (!s.initial_equilibrium.empty()) std::printf("initial equilibrium: %s\n", s.initial_equilibrium.c_str());
  std::printf("%s\n", summary_line(s).c_str());
  if (!s.out_file.empty() && !a.quiet) std::printf("results: %s\n", s.out_file.c_str());
  return s.interrupted ? interrupted_exit_status() : s.exit_code;
}

/// An error's row label with its unit: absolute RMS errors in the
/// quantity's SI unit (velocity and a probe's velocity history m/s,
/// displacement m, stress Pa).
std::string error_label(const std::string& name) {
  const char* unit = name.rfind("history_error_", 0) == 0 ? "m/s"
                     : name == "rms_velocity_error"       ? "m/s"
                     : name == "rms_displacement_error"   ? "m"
                     : name == "rms_stress_error"         ? "Pa"
                                                          : "";
  return *unit ? name + " [" + unit + "]" : name;
}

/// The side-by-side table of `pair` (one column per finished run).
void print_pair_table(const std::vector<RunSummary>& runs) {
  std::vector<std::string> names;
  for (const auto& r : runs)
    for (const auto& [n, v] : r.errors)
      if (std::find(names.begin(), names.end(), n) == names.end()) names.push_back(n);
  std::printf("%-32s", "");
  for (const auto& r : runs) std::printf(" %16s", r.mode.c_str());
  std::printf("\n");
  auto row = [&](const std::string& label, auto get) {
    std::printf("%-32s", label.c_str());
    for (const auto& r : runs) std::printf(" %16s", get(r).c_str());
    std::printf("\n");
  };
  row("status", [](const RunSummary& r) {
    return std::string(r.interrupted ? "interrupted" : r.exit_code != 0 ? "unstable" : "ok");
  });
  row("basis / integrator", [](const RunSummary& r) { return r.basis + "/" + r.integrator; });
  for (const std::string& n : names)
    row(error_label(n), [&](const RunSummary& r) {
      auto it = r.errors.find(n);
      return it == r.errors.end() ? std::string("-") : fmt("%.4e", it->second);
    });
  row("wall time [s]", [](const RunSummary& r) { return fmt("%.3f", r.wall_seconds); });
  row("steps", [](const RunSummary& r) { return fmt("%.0f", static_cast<double>(r.steps)); });
  row("particles", [](const RunSummary& r) { return fmt("%.0f", static_cast<double>(r.particles)); });
  row("nodes", [](const RunSummary& r) { return fmt("%.0f", static_cast<double>(r.nodes)); });
  row("particle-steps per second", [](const RunSummary& r) { return fmt("%.3e", r.particle_steps_per_second()); });
}

int pair_command(const SceneArgs& a) {
  set_threads(a.threads);
  InterruptHandlers handlers;
  std::vector<RunSummary> runs;
  for (const char* mode : {"mpm", "ul"}) {
    if (distributed::Comm::world().size() == 1 && interrupt_flag().load()) break; // ranks agree in the run
    std::vector<std::string> sets = a.sets;
    sets.push_back(std::string("simulation.mode=") + mode);
    Scene scene;
    const distributed::Comm& world = distributed::Comm::world();
    distributed::agree_on(world, [&] { scene = load_scene(a.scene, sets, world.size()); });
    RunOptions opt;
    const std::string& out = scene.output.file;
    const auto dot = out.rfind(".h5");
    opt.out_file = (dot == std::string::npos ? out : out.substr(0, dot)) + "_" + mode + ".h5";
    opt.force = a.force;
    opt.background_output = core_free_for_writer();
    opt.interrupt = &interrupt_flag();
    opt.progress = progress(a);
    runs.push_back(run_scene(scene, opt));
    if (runs.back().interrupted) share_interrupt_signal();
    end_progress_line();
    if (runs.back().interrupted && prints()) report_interrupt(runs.back(), &scene);
    if (runs.back().interrupted) break;
  }
  if (!runs.empty() && prints()) print_pair_table(runs);
  int status = 0;
  for (const auto& r : runs) {
    if (r.exit_code != 0 && !r.interrupted && prints())
      std::fprintf(stderr, "otmpm: %s run: %s\n", r.mode.c_str(), r.status.c_str());
    status = std::max(status, r.exit_code);
  }
  const bool stopped = interrupt_flag().load() || (!runs.empty() && runs.back().interrupted);
  return stopped ? interrupted_exit_status() : status;
}

} // namespace

Command add_run_command(CLI::App& app) {
  auto a = std::make_shared<SceneArgs>();
  CLI::App* sub = app.add_subcommand("run", "Run one scene to t_end and write the result file (HDF5 + XDMF)");
  CLI::Option* scene = add_scene_options(*sub, *a);
  CLI::Option* restart = sub->add_option("--restart", a->restart,
                                         "Continue the run saved in a checkpoint (output.checkpoint_every); "
                                         "takes no scene and no --set")
                             ->type_name("CHECKPOINT.h5");
  sub->add_option("--out", a->out, "Result file (default: output.file of the scene)")->type_name("FILE.h5");
  CLI::Option* check = sub->add_flag("--check", a->check,
                                     "Validate the scene and print particles, nodes, dt, estimated steps and "
                                     "memory; do not run (under mpirun: per rank, with the halo and a step time, "
                                     "nothing allocated)");
  sub->add_option("--ranks", a->ranks,
                  "With --check: the decomposition, memory and compute time per rank of a run on N ranks, planned "
                  "in this process without starting them (under mpirun the ranks it runs on are used)")
      ->check(CLI::Range(1, kMaxPlannedRanks))
      ->needs(check)
      ->type_name("N");
  restart->excludes(scene)->excludes("--set")->excludes(check);
  sub->footer("One of SCENE.toml and --restart is required. SIGINT/SIGTERM stop the run after the current step: "
              "the result file keeps status \"interrupted\" (and a last checkpoint is written if checkpointing is "
              "on); exit status 130/143.");
  return [a] {
    if (a->scene.empty() && a->restart.empty())
      throw InputError("give a scene file (otmpm run SCENE.toml) or --restart CHECKPOINT.h5");
    return run_command(*a);
  };
}

Command add_pair_command(CLI::App& app) {
  auto a = std::make_shared<SceneArgs>();
  CLI::App* sub = app.add_subcommand("pair", "Run a scene in mpm and in ul mode and print them side by side");
  add_scene_options(*sub, *a)->required();
  sub->footer("Result files: output.file with _mpm and _ul before .h5.");
  return [a] { return pair_command(*a); };
}

} // namespace otmpm::cli
