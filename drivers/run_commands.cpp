// `otmpm run` and `otmpm pair`.
#include "commands.hpp"

#include "otmpm/distributed/comm.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/scene/scene.hpp"

#include <algorithm>
#include <chrono>
#include <functional>
#include <memory>
#include <cstdio>
#include <unistd.h>

namespace otmpm::cli {

#ifndef OTMPM_CLI_VERSION
#define OTMPM_CLI_VERSION "0.1.0"
#endif
const char* version() { return "otmpm " OTMPM_CLI_VERSION; }

namespace {

struct SceneArgs {
  std::string scene;
  std::vector<std::string> sets;
  std::string out;
  std::string restart; ///< checkpoint file to continue (run only)
  bool quiet = false;
};

/// Reads the arguments of `run` (allow_out: --out and --restart) or `pair`.
SceneArgs parse_scene_args(const std::vector<std::string>& args, bool allow_out) {
  SceneArgs a;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& s = args[i];
    auto value = [&](const char* opt) {
      if (i + 1 >= args.size()) throw InputError(std::string("option ") + opt + " needs a value");
      return args[++i];
    };
    if (s == "--set") a.sets.push_back(value("--set"));
    else if (s.rfind("--set=", 0) == 0) a.sets.push_back(s.substr(6));
    else if (s == "--out" && allow_out) a.out = value("--out");
    else if (s == "--restart" && allow_out) a.restart = value("--restart");
    else if (s == "--quiet" || s == "-q") a.quiet = true;
    else if (!s.empty() && s[0] == '-') throw InputError("unknown option '" + s + "'");
    else if (a.scene.empty()) a.scene = s;
    else throw InputError("unexpected argument '" + s + "' (one scene file per run)");
  }
  if (!a.restart.empty() && !a.scene.empty())
    throw InputError("give either a scene file or --restart CHECKPOINT, not both");
  if (!a.restart.empty() && !a.sets.empty())
    throw InputError("--set cannot be combined with --restart: a restart continues the scene stored in the checkpoint");
  if (a.scene.empty() && a.restart.empty()) throw InputError("no scene file given");
  return a;
}

/// True on the rank that prints (rank 0; the only rank of a serial run).
bool prints() { return distributed::Comm::world().root(); }

/// A progress bar on stderr when it is a terminal, redrawn at most 10 times a second.
std::function<void(double, double, long)> progress_bar(bool quiet) {
  if (quiet || !isatty(STDERR_FILENO) || !prints()) return {};
  auto last = std::make_shared<std::chrono::steady_clock::time_point>();
  return [last](double t, double t_end, long steps) {
    const auto now = std::chrono::steady_clock::now();
    if (now - *last < std::chrono::milliseconds(100) && t < t_end) return;
    *last = now;
    constexpr int width = 40;
    const double frac = t_end > 0 ? std::min(1.0, t / t_end) : 1.0;
    const int filled = static_cast<int>(frac * width);
    std::fprintf(stderr, "\r[%s%s] %5.1f%%  step %ld  t = %.4g s", std::string(filled, '#').c_str(),
                 std::string(width - filled, ' ').c_str(), 100.0 * frac, steps, t);
    if (t >= t_end) std::fputc('\n', stderr);
    std::fflush(stderr);
  };
}

void print_phases(const RunSummary& s) {
  std::printf("phases:");
  for (std::size_t i = 0; i < phase_names.size(); ++i)
    std::printf(" %s %.3f s%s", std::string(phase_names[i]).c_str(), s.timers.seconds[i],
                i + 1 < phase_names.size() ? "," : "\n");
}

} // namespace

int run_command(const std::vector<std::string>& args) {
  const SceneArgs a = parse_scene_args(args, true);
  RunOptions opt;
  opt.out_file = a.out;
  opt.progress = progress_bar(a.quiet);
  const RunSummary s = a.restart.empty() ? run_scene(load_scene(a.scene, a.sets), opt)
                                         : restart_run(read_checkpoint(a.restart), opt);
  if (!prints()) return s.exit_code;
  if (s.exit_code != 0) std::fprintf(stderr, "otmpm: %s\n", s.status.c_str());
  if (!a.quiet) print_phases(s);
  std::printf("%s\n", summary_line(s).c_str());
  if (!s.out_file.empty() && !a.quiet) std::printf("results: %s\n", s.out_file.c_str());
  return s.exit_code;
}

int pair_command(const std::vector<std::string>& args) {
  const SceneArgs a = parse_scene_args(args, false);
  std::vector<RunSummary> runs;
  for (const char* mode : {"mpm", "ul"}) {
    std::vector<std::string> sets = a.sets;
    sets.push_back(std::string("simulation.mode=") + mode);
    const Scene scene = load_scene(a.scene, sets);
    RunOptions opt;
    std::string out = scene.output.file;
    const auto dot = out.rfind(".h5");
    opt.out_file = (dot == std::string::npos ? out : out.substr(0, dot)) + "_" + mode + ".h5";
    opt.progress = progress_bar(a.quiet);
    runs.push_back(run_scene(scene, opt));
  }
  if (!prints()) return std::max(runs[0].exit_code, runs[1].exit_code);
  std::vector<std::string> names;
  for (const auto& r : runs)
    for (const auto& [n, v] : r.errors)
      if (std::find(names.begin(), names.end(), n) == names.end()) names.push_back(n);
  std::printf("%-26s %16s %16s\n", "", "mpm", "ul");
  auto row_s = [&](const char* label, auto get) {
    std::printf("%-26s %16s %16s\n", label, get(runs[0]).c_str(), get(runs[1]).c_str());
  };
  auto fmt = [](const char* f, double v) {
    char b[64];
    std::snprintf(b, sizeof b, f, v);
    return std::string(b);
  };
  row_s("status", [](const RunSummary& r) { return r.exit_code == 0 ? std::string("ok") : std::string("unstable"); });
  row_s("basis / integrator", [](const RunSummary& r) { return r.basis + "/" + r.integrator; });
  for (const std::string& n : names)
    row_s(n.c_str(), [&](const RunSummary& r) {
      auto it = r.errors.find(n);
      return it == r.errors.end() ? std::string("-") : fmt("%.4e", it->second);
    });
  row_s("wall time [s]", [&](const RunSummary& r) { return fmt("%.3f", r.wall_seconds); });
  row_s("steps", [&](const RunSummary& r) { return fmt("%.0f", static_cast<double>(r.steps)); });
  row_s("particles", [&](const RunSummary& r) { return fmt("%.0f", static_cast<double>(r.particles)); });
  row_s("nodes", [&](const RunSummary& r) { return fmt("%.0f", static_cast<double>(r.nodes)); });
  row_s("particle-steps per second", [&](const RunSummary& r) { return fmt("%.3e", r.particle_steps_per_second()); });
  for (const auto& r : runs)
    if (r.exit_code != 0) std::fprintf(stderr, "otmpm: %s run: %s\n", r.mode.c_str(), r.status.c_str());
  return std::max(runs[0].exit_code, runs[1].exit_code);
}

} // namespace otmpm::cli
