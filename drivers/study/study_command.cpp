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
// with it (PR_SET_PDEATHSIG). A run whose result file is still locked by
// another process (a child of a killed study that is still stopping) waits
// for it instead of failing; the study holds otmpm's lock on its CSV, so a
// second study on the same CSV is refused. Every run executes the study's
// own binary, so rebuilding otmpm under a running study changes nothing; a
// run that cannot be started is not recorded, and the study exits 1.
#include "../cli.hpp"
#include "../interrupt.hpp"
#include "../system.hpp"
#include "process_pool.hpp"
#include "study_csv.hpp"
#include "study_file.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/openmp_wait.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/scene/scene.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <thread>

namespace fs = std::filesystem;

namespace otmpm::cli {

namespace {

using study::Study;
using study::StudyRun;

struct StudyArgs {
  std::string file;
  int threads = 1; ///< OpenMP threads of each child run
  std::string scripts, python;
  std::vector<std::string> variants, meshes; ///< --variant / --mesh: run only these (empty: all)
  bool check = false;                        ///< --check: check every chosen run's scene, run none
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

/// The program every run of a study executes: the study's own executable
/// (/proc/self/exe), so that an otmpm rebuilt or reinstalled while the
/// study runs - its file now another binary, or gone - neither stops nor
/// changes the runs still to come; the file's path where /proc is missing.
std::string run_program() { return fs::exists("/proc/self/exe") ? "/proc/self/exe" : self_path().string(); }

/// Draws the plots with the scripts found beside the executable (or --scripts):
/// with [[measure]], the errors against the reference run (convergence.py:
/// STEM_errors.csv and one pair of plots per measure).
void draw_plots(const Study& s, const StudyArgs& a) {
  const std::string name = s.stability.enabled   ? "plot_stability.py"
                           : !s.measures.empty() ? "convergence.py"
                                                 : "plot_study.py";
  const fs::path script = scripts_dir(a.scripts) / name;
  std::vector<std::string> args{script.string(), s.csv.string()};
  if (!s.measures.empty()) {
    args = {script.string(), s.file.string(), "--plots"};
  } else if (s.stability.enabled) {
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
    std::fprintf(stderr, "otmpm: the %s script %s failed (exit status %d)\n",
                 s.measures.empty() ? "plot" : "error and plot", script.c_str(), rc);
}

/// True when a child did not finish its run: killed by a signal, or an
/// `otmpm run` that stopped on SIGINT/SIGTERM (exit 130/143).
bool cut_short(const study::ChildExit& c) { return c.signalled || c.status == 130 || c.status == 143; }

/// How long a run waits for another process (the child of a killed study,
/// still stopping) to release otmpm's lock on its result file.
constexpr std::chrono::seconds kLockWait{300};
/// How often the study looks at its children, its interrupt flag and a lock it waits for.
constexpr std::chrono::milliseconds kPoll{200};

/// The runs of one `otmpm study` that are not in the CSV: started `jobs` at a
/// time, each recorded in the CSV when its child ends - except a child that
/// was cut short (killed by a signal or interrupted), which is left for the
/// next `otmpm study`. On SIGINT/SIGTERM it starts no more runs, sends
/// SIGTERM to the children and waits for them.
class StudyRunner {
public:
  StudyRunner(const Study& s, const StudyArgs& a, std::vector<const StudyRun*> todo)
      : s_(s), a_(a), todo_(std::move(todo)) {
    pool_.share_cpus(openmp_place_cpus(), s_.jobs); // bound threads: each run its own CPUs
  }
  /// Runs until every run ended or the study was interrupted; returns 0 or
  /// the interrupted exit status (130/143).
  int run();

private:
  fs::path result_path(const StudyRun& r) const { return s_.results / (r.file_stem + ".h5"); }
  fs::path log_path(const StudyRun& r) const { return s_.results / (r.file_stem + ".log"); }
  void start_runs();
  bool may_start(const StudyRun& r);
  void finish(const study::ChildExit& c);
  int report() const;

  const Study& s_;
  const StudyArgs& a_;
  std::vector<const StudyRun*> todo_;
  study::ProcessPool pool_;
  std::map<pid_t, const StudyRun*> running_;
  std::size_t next_ = 0, recorded_ = 0, not_recorded_ = 0, skipped_ = 0, not_started_ = 0;
  bool stopping_ = false;
  std::optional<std::chrono::steady_clock::time_point> lock_wait_since_;
};

int StudyRunner::run() {
  for (;;) {
    if (interrupt_flag().load() && !stopping_) {
      stopping_ = true;
      pool_.terminate_all();
    }
    if (!stopping_) start_runs();
    const bool more = !stopping_ && next_ < todo_.size();
    if (pool_.running() == 0 && !more) break;
    if (pool_.running() == 0) std::this_thread::sleep_for(kPoll); // waiting for a lock
    else if (const study::ChildExit c = pool_.wait_any(kPoll); c.pid >= 0) finish(c);
  }
  return report();
}

void StudyRunner::start_runs() {
  while (next_ < todo_.size() && static_cast<int>(pool_.running()) < s_.jobs) {
    const StudyRun& r = *todo_[next_];
    if (!may_start(r)) return;
    running_[pool_.start(run_program(), run_argv(s_, r, a_, result_path(r)), log_path(r), {})] = &r;
    ++next_;
  }
}

/// False while another process holds otmpm's lock on the run's result file
/// (flock: a killed child holds none, so only a live one delays the run);
/// after kLockWait the run is skipped, not recorded.
bool StudyRunner::may_start(const StudyRun& r) {
  const std::string out = result_path(r).string(), holder = lock_holder_of(out);
  if (holder.empty()) {
    lock_wait_since_.reset();
    return true;
  }
  const auto now = std::chrono::steady_clock::now();
  if (!lock_wait_since_) {
    lock_wait_since_ = now;
    std::printf("[~] %s %s: %s is being written by %s: waiting for it to end (at most %lld s)\n",
                r.variant.c_str(), r.mesh.c_str(), out.c_str(), holder.c_str(),
                static_cast<long long>(kLockWait.count()));
  } else if (now - *lock_wait_since_ > kLockWait) {
    std::printf("[-] %s %s: %s is still being written by %s: not started, not recorded\n", r.variant.c_str(),
                r.mesh.c_str(), out.c_str(), holder.c_str());
    ++skipped_;
    ++next_;
    lock_wait_since_.reset();
  }
  std::fflush(stdout);
  return false;
}

void StudyRunner::finish(const study::ChildExit& c) {
  const StudyRun* r = running_.at(c.pid);
  running_.erase(c.pid);
  if (cut_short(c)) {
    ++not_recorded_;
    std::printf("[-] %s %s: stopped (exit %d), not recorded: the next `otmpm study` runs it again\n",
                r->variant.c_str(), r->mesh.c_str(), c.status);
  } else if (c.status == study::kNotStarted) {
    ++not_started_;
    std::printf("[-] %s %s: could not be started (%s says why), not recorded\n", r->variant.c_str(),
                r->mesh.c_str(), log_path(*r).c_str());
  } else {
    study::append_row(s_, study::result_row(s_, *r, c.status, result_path(*r), log_path(*r)));
    std::printf("[%zu/%zu] %s %s: exit %d\n", ++recorded_, todo_.size(), r->variant.c_str(), r->mesh.c_str(),
                c.status);
  }
  std::fflush(stdout);
}

int StudyRunner::report() const {
  if (stopping_) {
    std::printf("study interrupted by %s: %zu runs recorded, %zu stopped and %zu not started (not recorded); run "
                "`otmpm study %s` again to continue\n",
                interrupt_signal_name(), recorded_, not_recorded_, todo_.size() - next_ + skipped_,
                a_.file.c_str());
    return interrupted_exit_status();
  }
  if (not_recorded_ + skipped_ + not_started_ > 0)
    std::printf(
        "%zu runs were stopped by a signal or not started and are not in the CSV: run the study again to "
        "retry them\n",
        not_recorded_ + skipped_ + not_started_);
  return not_started_ > 0 ? 1 : 0;
}

/// Creates the results folder (InputError naming the study file's `results` key when it cannot).
void create_results_folder(const Study& s) {
  std::error_code ec;
  fs::create_directories(s.results, ec);
  if (ec)
    throw InputError(s.results_where.describe() + ": cannot create the folder " + s.results.string() + ": " +
                     ec.message());
}

/// otmpm's lock on the study's CSV: one study per CSV at a time (flock:
/// released when the study ends or dies).
OutputLock lock_csv(const Study& s) {
  try {
    return OutputLock({s.csv.string()});
  } catch (const InputError& e) {
    throw InputError("study " + s.file.string() + ": another otmpm study is running on its CSV: " + e.what());
  }
}

/// Refuses (InputError) a --variant or --mesh name that is none of the
/// study's, naming the option, the name and the study's names of that kind.
void check_names(const Study& s, const std::vector<std::string>& wanted, const std::string& kind,
                 std::string StudyRun::*field) {
  std::vector<std::string> names;
  for (const StudyRun& r : s.runs)
    if (std::find(names.begin(), names.end(), r.*field) == names.end()) names.push_back(r.*field);
  for (const std::string& w : wanted) {
    if (std::find(names.begin(), names.end(), w) != names.end()) continue;
    std::string list;
    for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
    throw InputError("study " + s.file.string() + ": --" + kind + " '" + w + "' is none of its " + kind +
                     (kind == "mesh" ? "es: " : "s: ") + list);
  }
}

/// Whether `r` is one of the runs --variant and --mesh select (all when neither is given).
bool selected(const StudyArgs& a, const StudyRun& r) {
  const auto in = [](const std::vector<std::string>& v, const std::string& x) {
    return v.empty() || std::find(v.begin(), v.end(), x) != v.end();
  };
  return in(a.variants, r.variant) && in(a.meshes, r.mesh);
}

/// Prints what the study will do: its runs, the `chosen` ones (by --variant
/// and --mesh), how many of those the CSV already holds and the `todo` left.
void announce(const Study& s, std::size_t chosen, std::size_t todo) {
  const bool all = chosen == s.runs.size();
  const std::string runs = all ? "all " + std::to_string(chosen) + " runs"
                               : "the " + std::to_string(chosen) + " runs chosen by --variant/--mesh";
  const std::string of = all ? "" : ", " + std::to_string(chosen) + " chosen by --variant/--mesh";
  if (todo == 0)
    std::printf("study %s: nothing to run: %s are already in %s (delete it, or set another `csv`, to run them "
                "again); drawing the plots from it\n",
                s.file.c_str(), runs.c_str(), s.csv.c_str());
  else
    std::printf("study %s: %zu runs%s, %zu %salready in %s, %zu to do, %d at a time\n", s.file.c_str(),
                s.runs.size(), of.c_str(), chosen - todo, all ? "" : "of them ", s.csv.c_str(), todo, s.jobs);
}

/// `otmpm study --check`: reads the scene of every chosen run with its
/// overrides and checks it as `otmpm run --check` does (check_scene: the
/// reader's rules, the memory and step estimates, the set-up), one line per
/// run; runs nothing and writes nothing (no CSV, no results folder). Exit 0
/// when every run would start, 2 when one or more are refused.
int check_study(const Study& s, const StudyArgs& a) {
  std::size_t chosen = 0, refused = 0;
  for (const StudyRun& r : s.runs) {
    if (!selected(a, r)) continue;
    ++chosen;
    try {
      const Scene scene = load_scene(s.scene.string(), r.sets);
      const SceneCheck c = check_scene(scene);
      std::printf("  ok       %s %s: %ld particles, %ld nodes, about %.0f steps\n", r.variant.c_str(),
                  r.mesh.c_str(), c.particles, c.nodes, c.estimated_steps);
    } catch (const InputError& e) {
      ++refused;
      std::printf("  refused  %s %s: %s\n", r.variant.c_str(), r.mesh.c_str(), e.what());
    }
    std::fflush(stdout);
  }
  std::printf("study %s: %zu of %zu runs checked would start, %zu refused (nothing run or written)\n",
              s.file.c_str(), chosen - refused, chosen, refused);
  return refused > 0 ? 2 : 0;
}

int study_command(const StudyArgs& a) {
  const Study s = study::read_study(a.file);
  check_names(s, a.variants, "variant", &StudyRun::variant);
  check_names(s, a.meshes, "mesh", &StudyRun::mesh);
  if (a.check) return check_study(s, a);
  create_results_folder(s);
  const OutputLock csv_lock = lock_csv(s);
  const study::DoneRuns done = study::prepare_csv(s);
  std::vector<const StudyRun*> todo;
  std::size_t chosen = 0;
  for (const StudyRun& r : s.runs) {
    if (!selected(a, r)) continue;
    ++chosen;
    if (!done.count({r.variant, r.mesh})) todo.push_back(&r);
  }
  announce(s, chosen, todo.size());
  std::fflush(stdout);
  InterruptHandlers handlers;
  if (const int status = StudyRunner(s, a, std::move(todo)).run(); status != 0) return status;
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
  sub->add_option(
         "--variant", a->variants,
         "Run only this variant (repeat for more; default: every variant); the CSV keeps the other rows")
      ->type_name("NAME")
      ->expected(1)
      ->take_all();
  sub->add_option("--mesh", a->meshes, "Run only this mesh (repeat for more; default: every mesh)")
      ->type_name("NAME")
      ->expected(1)
      ->take_all();
  sub->add_flag("--check", a->check,
                "Check the scene of every chosen run as `otmpm run --check` does, one line per run; run "
                "nothing, write nothing (exit 2 when a run would be refused)");
  sub->footer(
      "Rows already in the CSV are skipped, so an interrupted study resumes, and --variant / --mesh run it "
      "in parts. SIGINT/SIGTERM stop the children cleanly; unfinished runs are not recorded (exit 130/143).");
  return [a] { return study_command(*a); };
}

} // namespace otmpm::cli
