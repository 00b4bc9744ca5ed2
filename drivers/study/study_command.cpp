// `otmpm study STUDY.toml`: sweeps a base scene over mesh sizes and variants
// (study_file.hpp), runs every (variant, mesh) pair as a child `otmpm run`
// process, `jobs` at a time (process_pool.hpp), and appends one CSV row per
// finished run (study_csv.hpp). Resumable: rows already in the CSV are
// skipped. At the end it draws the work-precision and convergence plots
// (plot_study.py) or, with [stability], the stability map (plot_stability.py).
//
// SIGINT/SIGTERM: the study stops starting runs, sends SIGTERM to the running
// children (each stops cleanly with status "interrupted"), waits for them and
// exits 130/143; runs that did not finish are not recorded, so the next
// `otmpm study` runs them again. A child killed by a signal is not recorded
// either (retried next time); a study killed by SIGKILL takes its children
// with it (PR_SET_PDEATHSIG).
#include "../cli.hpp"
#include "../interrupt.hpp"
#include "../system.hpp"
#include "process_pool.hpp"
#include "study_csv.hpp"
#include "study_file.hpp"

#include "otmpm/core.hpp"

#include <cstdio>
#include <map>
#include <memory>

namespace fs = std::filesystem;

namespace otmpm::cli {

namespace {

using study::Study;
using study::StudyRun;

struct StudyArgs {
  std::string file;
  int threads = 1; ///< OpenMP threads of each child run
  std::string scripts, python;
};

/// The `otmpm run` command line of one study run.
std::vector<std::string> run_argv(const Study& s, const StudyRun& r, const StudyArgs& a, const fs::path& out) {
  std::vector<std::string> argv{self_path().string(), "run", s.scene.string(), "--quiet", "--force",
                                "--threads",          std::to_string(a.threads), "--out", out.string()};
  for (const std::string& set : r.sets) {
    argv.push_back("--set");
    argv.push_back(set);
  }
  return argv;
}

/// Draws the plots with the scripts found beside the executable (or --scripts).
void draw_plots(const Study& s, const StudyArgs& a) {
  const std::string name = s.stability.enabled ? "plot_stability.py" : "plot_study.py";
  const fs::path script = scripts_dir(a.scripts) / name;
  std::vector<std::string> args{script.string(), s.csv.string()};
  if (s.stability.enabled) {
    char band[32];
    std::snprintf(band, sizeof band, "%.8g", s.stability.band);
    args.insert(args.end(), {"--band", band, "--key", s.stability.key});
  } else {
    args.insert(args.end(), {"--error", s.error});
  }
  const std::string python = find_python(a.python);
  if (!fs::exists(script) || python.empty()) {
    std::printf("plots: %s; draw them with: python3", python.empty() ? "no python3 found"
                                                                     : (script.string() + " not found").c_str());
    for (const std::string& arg : args) std::printf(" '%s'", arg.c_str());
    std::printf("\n");
    return;
  }
  args.insert(args.begin(), python);
  std::fflush(stdout);
  if (const int rc = run_and_wait(args); rc != 0)
    std::fprintf(stderr, "otmpm: the plot script %s failed (exit status %d)\n", script.c_str(), rc);
}

/// True when a child did not finish its run: killed by a signal, or an
/// `otmpm run` that stopped on SIGINT/SIGTERM (exit 130/143).
bool cut_short(const study::ChildExit& c) { return c.signalled || c.status == 130 || c.status == 143; }

int study_command(const StudyArgs& a) {
  const Study s = study::read_study(a.file);
  fs::create_directories(s.results);
  const study::DoneRuns done = study::prepare_csv(s);
  std::vector<const StudyRun*> todo;
  for (const StudyRun& r : s.runs)
    if (!done.count({r.variant, r.mesh})) todo.push_back(&r);
  std::printf("study %s: %zu runs, %zu already in %s, %zu to do, %d at a time\n", s.file.c_str(), s.runs.size(),
              s.runs.size() - todo.size(), s.csv.c_str(), todo.size(), s.jobs);
  std::fflush(stdout);
  InterruptHandlers handlers;
  study::ProcessPool pool;
  std::map<pid_t, const StudyRun*> running;
  std::size_t next = 0, recorded = 0, not_recorded = 0;
  bool stopping = false;
  auto paths = [&](const StudyRun& r) {
    return std::make_pair(s.results / (r.file_stem + ".h5"), s.results / (r.file_stem + ".log"));
  };
  for (;;) {
    if (interrupt_flag().load() && !stopping) {
      stopping = true;
      pool.terminate_all();
    }
    while (!stopping && next < todo.size() && static_cast<int>(pool.running()) < s.jobs) {
      const auto [out, log] = paths(*todo[next]);
      running[pool.start(run_argv(s, *todo[next], a, out), log, {})] = todo[next];
      ++next;
    }
    if (pool.running() == 0) break;
    const study::ChildExit c = pool.wait_any();
    if (c.pid < 0) continue; // a signal interrupted the wait
    const StudyRun* r = running.at(c.pid);
    running.erase(c.pid);
    if (cut_short(c)) {
      ++not_recorded;
      std::printf("[-] %s %s: stopped (exit %d), not recorded: the next `otmpm study` runs it again\n",
                  r->variant.c_str(), r->mesh.c_str(), c.status);
    } else {
      const auto [out, log] = paths(*r);
      study::append_row(s, study::result_row(s, *r, c.status, out, log));
      std::printf("[%zu/%zu] %s %s: exit %d\n", ++recorded, todo.size(), r->variant.c_str(), r->mesh.c_str(),
                  c.status);
    }
    std::fflush(stdout);
  }
  if (stopping) {
    std::printf("study interrupted by %s: %zu runs recorded, %zu stopped and %zu not started (not recorded); run "
                "`otmpm study %s` again to continue\n",
                interrupt_signal_name(), recorded, not_recorded, todo.size() - next, a.file.c_str());
    return interrupted_exit_status();
  }
  if (not_recorded > 0)
    std::printf("%zu runs were stopped by a signal and are not in the CSV: run the study again to retry them\n",
                not_recorded);
  draw_plots(s, a);
  return 0;
}

} // namespace

Command add_study_command(CLI::App& app) {
  auto a = std::make_shared<StudyArgs>();
  CLI::App* sub = app.add_subcommand(
      "study", "Run a scene over mesh sizes and variants (child runs), one CSV row per run, then plot");
  sub->add_option("study", a->file, "Study file (TOML; the keys are listed in the user guide)")
      ->required()
      ->type_name("STUDY.toml");
  add_threads_option(*sub, a->threads, "OpenMP threads of each child run (runs go side by side: `jobs` in the file)")
      ->capture_default_str();
  sub->add_option("--scripts", a->scripts,
                  "Folder with plot_study.py and plot_stability.py (default: share/otmpm beside the executable's "
                  "bin folder)")
      ->type_name("DIR");
  sub->add_option("--python", a->python,
                  "Python with matplotlib for the plots (default: /usr/bin/python3, else python3 on PATH)")
      ->type_name("PATH");
  sub->footer("Rows already in the CSV are skipped, so an interrupted study resumes. SIGINT/SIGTERM stop the "
              "children cleanly; unfinished runs are not recorded (exit 130/143).");
  return [a] { return study_command(*a); };
}

} // namespace otmpm::cli
