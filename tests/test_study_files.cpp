// `otmpm study` and the files it owns (docs/stability.md, "What otmpm
// guarantees about your files"): a killed study leaves no child running,
// and its resume keeps the finished runs, redoes the stopped ones and waits
// for result files another process still writes; colliding names, a results
// path that is a file, a bad common or mesh `set` entry and a directory as
// study or scene file are refused before any run; a cut-off CSV row is
// redone. `study --check` checks every run's scene without running it, and
// every run of every example study file passes it.
#include "study_support.hpp"

#include <doctest/doctest.h>

#include <fcntl.h>
#include <sched.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace fs = std::filesystem;
using namespace otmpm::test;

namespace {

/// Refusal of a study file: exit 2, every fragment in the output, nothing written.
void expect_refused(const std::string& name, const std::string& body, const std::vector<std::string>& fragments) {
  const fs::path dir = study_dir(name, body);
  std::string out;
  INFO(body);
  CHECK(run_study(dir, out) == 2);
  INFO(out);
  for (const std::string& f : fragments) CHECK(out.find(f) != std::string::npos);
  CHECK(!fs::exists(dir / "study.csv"));
  CHECK(!fs::exists(dir / "study_results"));
  fs::remove_all(dir);
}

/// Starts `otmpm study study.toml` in dir (stdout and stderr to study.out)
/// with the executable `binary`; returns its pid.
pid_t start_study(const fs::path& dir, const std::string& binary = OTMPM_BINARY) {
  std::fflush(nullptr); // or the child flushes the test's buffered output a second time
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    if (::chdir(dir.c_str()) != 0) ::_exit(127);
    std::FILE* f = std::freopen("study.out", "w", stdout);
    if (f) ::dup2(::fileno(stdout), STDERR_FILENO);
    ::execl(binary.c_str(), binary.c_str(), "study", "study.toml", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  return pid;
}

/// The pids whose parent is `parent` (from /proc/PID/stat: "pid (comm) state ppid ...").
std::vector<pid_t> children_of(pid_t parent) {
  std::vector<pid_t> out;
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream in(e.path() / "stat");
    std::string stat;
    std::getline(in, stat);
    const auto close = stat.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream rest(stat.substr(close + 2));
    char state = 0;
    pid_t ppid = 0;
    rest >> state >> ppid;
    if (ppid == parent && state != 'Z') out.push_back(static_cast<pid_t>(std::stoi(name)));
  }
  return out;
}

/// True while `pid` runs (exists and is not a zombie); does not reap it.
bool running(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string stat;
  if (!std::getline(in, stat)) return false;
  const auto close = stat.rfind(')');
  return close != std::string::npos && close + 2 < stat.size() && stat[close + 2] != 'Z';
}

/// Polls `done` every 100 ms for up to `limit`; true once it holds.
bool wait_until(const std::function<bool()>& done, std::chrono::seconds limit = std::chrono::seconds(300)) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return done();
}

/// Waits until `study` has `n` children and every file of `files` exists;
/// returns the children (a test failure after 5 minutes).
std::vector<pid_t> wait_for_children(pid_t study, std::size_t n, const std::vector<fs::path>& files) {
  std::vector<pid_t> kids;
  const bool started = wait_until([&] {
    kids = children_of(study);
    bool all = kids.size() == n;
    for (const fs::path& f : files) all = all && fs::exists(f);
    return all;
  });
  REQUIRE_MESSAGE(started, "the study did not start its runs");
  std::this_thread::sleep_for(std::chrono::milliseconds(200)); // past the set-up, inside the run loop
  return kids;
}

int wait_exit(pid_t pid) {
  int wstatus = 0;
  REQUIRE(::waitpid(pid, &wstatus, 0) == pid);
  return WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : 128 + WTERMSIG(wstatus);
}

/// Waits (up to a minute) until none of `pids` runs.
bool all_stopped(const std::vector<pid_t>& pids) {
  return wait_until(
      [&] {
        for (pid_t p : pids)
          if (running(p)) return false;
        return true;
      },
      std::chrono::seconds(60));
}

std::string status_attribute(const fs::path& h5) {
  std::string out;
  run_command("/usr/bin/python3 -c 'import sys, h5py; a = h5py.File(sys.argv[1], \"r\").attrs[\"status\"]; "
              "print(a.decode() if isinstance(a, bytes) else a)' " + quote(h5.string()),
              out);
  return out.substr(0, out.find('\n'));
}

/// Variants a and b of the Dyka bar ending at t_end_a and t_end_b (1.0 s:
/// millions of steps, a run that is still going when the test stops it).
std::string two_variants(const std::string& t_end_a, const std::string& t_end_b, int jobs) {
  return "jobs = " + std::to_string(jobs) + "\nset = [\"output.every=1e-5\"]\n" +
         "[[variant]]\nname = \"a\"\nset = [\"simulation.t_end=" + t_end_a + "\"]\n" +
         "[[variant]]\nname = \"b\"\nset = [\"simulation.t_end=" + t_end_b + "\"]\n" + kMeshN13;
}

/// Rewrites dir/study.toml with two_variants(...).
void rewrite_study(const fs::path& dir, const std::string& t_end_a, const std::string& t_end_b, int jobs) {
  std::ofstream(dir / "study.toml", std::ios::trunc) << study_head() << two_variants(t_end_a, t_end_b, jobs);
}

/// The lines of a text file.
std::vector<std::string> lines_of(const fs::path& file) {
  std::vector<std::string> lines;
  std::ifstream in(file);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

} // namespace

// ---------------------------------------------------------------- killed studies and children

TEST_CASE("study: SIGINT, SIGTERM or SIGKILL of the study stops its children, the resume keeps the finished "
          "run and redoes the stopped one") {
  const fs::path dir = study_dir("d9", "");
  const fs::path a_h5 = dir / "study_results" / "a_n13.h5";
  for (int sig : {SIGINT, SIGTERM, SIGKILL}) {
    INFO("signal " << sig);
    fs::remove_all(dir / "study_results");
    fs::remove(dir / "study.csv");
    rewrite_study(dir, "1.0", "2e-5", 2);
    const pid_t study = start_study(dir);
    // b finishes and is recorded; a goes on.
    REQUIRE(wait_until([&] { return lines_of(dir / "study.csv").size() == 2 || !running(study); }));
    const std::vector<pid_t> kids = wait_for_children(study, 1, {a_h5});
    const std::vector<std::string> before = lines_of(dir / "study.csv");
    ::kill(study, sig);
    CHECK(wait_exit(study) == 128 + sig);
    CHECK(all_stopped(kids)); // no child left running (SIGKILL: through PR_SET_PDEATHSIG)
    CHECK(status_attribute(a_h5) == "interrupted");
    CHECK(lines_of(dir / "study.csv") == before); // b only: a is not recorded
    if (sig != SIGKILL)
      CHECK(contains(read_text(dir / "study.out"), std::string("study interrupted by ") +
                                                       (sig == SIGINT ? "SIGINT" : "SIGTERM")));
    // The resume (a short now): b is kept as it was, a is done again and succeeds.
    rewrite_study(dir, "2e-5", "2e-5", 2);
    std::string out;
    REQUIRE(run_study(dir, out) == 0);
    INFO(out);
    CHECK(contains(out, "1 already in study.csv, 1 to do"));
    const std::vector<std::string> after = lines_of(dir / "study.csv");
    REQUIRE(after.size() == 3);
    CHECK(after[1] == before[1]);
    const auto rows = read_csv(dir / "study.csv");
    CHECK(rows[2][0] == "a");
    CHECK(rows[2][column(rows[0], "status")] == "ok");
  }
  fs::remove_all(dir);
}

TEST_CASE("study: a child killed by a signal is not recorded, and its left-over lock does not stop the retry") {
  const fs::path dir = study_dir("d9_child", two_variants("1.0", "2e-5", 1));
  const pid_t study = start_study(dir);
  const std::vector<pid_t> kids = wait_for_children(study, 1, {dir / "study_results" / "a_n13.h5"});
  REQUIRE(kids.size() == 1);
  ::kill(kids.front(), SIGKILL);
  CHECK(wait_exit(study) == 0); // the study goes on with b
  const std::string printed = read_text(dir / "study.out");
  INFO(printed);
  CHECK(contains(printed, "a n13: stopped (exit 137), not recorded"));
  auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 2);
  CHECK(rows[1][0] == "b");
  // The killed child's lock file is still there, unlocked (flock ends with its holder).
  CHECK(fs::exists(dir / "study_results" / ".a_n13.h5.otmpm-lock"));
  rewrite_study(dir, "2e-5", "2e-5", 1);
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  INFO(out);
  CHECK(contains(out, "1 to do"));
  CHECK(!contains(out, "waiting"));
  rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 3);
  CHECK(rows[2][0] == "a");
  CHECK(rows[2][column(rows[0], "status")] == "ok");
  CHECK(!fs::exists(dir / "study_results" / ".a_n13.h5.otmpm-lock"));
  fs::remove_all(dir);
}

TEST_CASE("study: otmpm rebuilt under a running study: the runs still to come run the study's own binary") {
  const fs::path dir = study_dir("d9_rebuilt", two_variants("1.0", "2e-5", 1));
  const fs::path bin = dir / "bin" / "otmpm";
  fs::create_directories(bin.parent_path());
  fs::copy_file(OTMPM_BINARY, bin);
  const pid_t study = start_study(dir, bin.string());
  const std::vector<pid_t> kids = wait_for_children(study, 1, {dir / "study_results" / "a_n13.h5"});
  REQUIRE(kids.size() == 1);
  // The file is replaced, as a rebuild or reinstall does: another binary at its path.
  fs::remove(bin);
  std::ofstream(bin) << "#!/bin/sh\necho 'not the study'\nexit 3\n";
  fs::permissions(bin, fs::perms::owner_all);
  ::kill(kids.front(), SIGTERM); // a stops (not recorded); b starts after the replacement
  CHECK(wait_exit(study) == 0);
  const std::string printed = read_text(dir / "study.out");
  INFO(printed);
  CHECK(contains(printed, "a n13: stopped (exit 143), not recorded"));
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 2);
  CHECK(rows[1][0] == "b");
  CHECK(rows[1][column(rows[0], "status")] == "ok");
  fs::remove_all(dir);
}

TEST_CASE("study: a run that cannot be started is not recorded, says why in its log, and the study exits 1") {
  // An argument over Linux's 128 KiB per argument: execve refuses it (E2BIG).
  const std::string huge = "[[variant]]\nname = \"huge\"\nset = [\"simulation.t_end=2e-5\", \"output.file=" +
                           std::string(200000, 'x') + ".h5\"]\n";
  const fs::path dir = study_dir("d9_unstartable", two_variants("2e-5", "2e-5", 1) + huge);
  std::string out;
  CHECK(run_study(dir, out) == 1);
  INFO(out.substr(0, 2000));
  CHECK(contains(out, "huge n13: could not be started (study_results/huge_n13.log says why), not recorded"));
  CHECK(contains(out, "1 runs were stopped by a signal or not started and are not in the CSV"));
  CHECK(contains(read_text(dir / "study_results" / "huge_n13.log"), ": Argument list too long"));
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 3); // a and b, not huge
  CHECK(rows[1][column(rows[0], "status")] == "ok");
  CHECK(rows[2][column(rows[0], "status")] == "ok");
  fs::remove_all(dir);
}

TEST_CASE("study: with bound threads (OMP_PROC_BIND) the runs side by side get CPUs of their own") {
  // libgomp binds each process's first thread to the first CPU it may use:
  // two runs that may both use every CPU would both run on the first one
  cpu_set_t mask;
  REQUIRE(sched_getaffinity(0, sizeof mask, &mask) == 0);
  const fs::path dir = study_dir("d9_bound", two_variants("2e-5", "2e-5", 2));
  std::string out;
  REQUIRE(run_command("cd " + quote(dir.string()) +
                          " && env OMP_PROC_BIND=true OMP_DISPLAY_ENV=true '" OTMPM_BINARY
                          "' study study.toml",
                      out) == 0);
  const auto places = [&](const std::string& run) { // the last process of the run's log to print them
    const std::string text = read_text(dir / "study_results" / (run + ".log")), key = "OMP_PLACES = '";
    const auto at = text.rfind(key);
    REQUIRE(at != std::string::npos);
    return text.substr(at + key.size(), text.find('\'', at + key.size()) - at - key.size());
  };
  const std::string a = places("a_n13"), b = places("b_n13");
  CHECK(a != "");
  if (CPU_COUNT(&mask) >= 2)
    CHECK(a != b); // one CPU each on two, half of them each on more
  else
    MESSAGE("one CPU: both runs have it");
  fs::remove_all(dir);
}

TEST_CASE("study: a run whose result file another process still writes waits for it and is never recorded "
          "as an input error") {
  const fs::path dir = study_dir("d9_lock", std::string("jobs = 1\nset = [\"simulation.t_end=2e-5\"]\n") + kMeshN13);
  fs::create_directories(dir / "study_results");
  // Another process (here: this test) holds otmpm's lock on base_n13.h5, as
  // the child of a killed study does until it has stopped.
  const std::string lock = (dir / "study_results" / ".base_n13.h5.otmpm-lock").string();
  const int fd = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  REQUIRE(fd >= 0);
  REQUIRE(::flock(fd, LOCK_EX) == 0);
  const std::string holder = std::to_string(::getpid()) + " testhost\n";
  REQUIRE(::write(fd, holder.data(), holder.size()) == static_cast<ssize_t>(holder.size()));
  const pid_t study = start_study(dir);
  const bool waits = wait_until([&] { return contains(read_text(dir / "study.out"), "[~]") || !running(study); });
  ::close(fd); // the holder ends
  CHECK(waits);
  CHECK(wait_exit(study) == 0);
  const std::string printed = read_text(dir / "study.out");
  INFO(printed);
  CHECK(contains(printed, "is being written by process " + std::to_string(::getpid()) + " on host testhost"));
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 2);
  CHECK(rows[1][column(rows[0], "status")] == "ok");
  CHECK(rows[1][column(rows[0], "exit_code")] == "0");
  fs::remove_all(dir);
}

TEST_CASE("study: a second study on the same CSV is refused with exit 2 and changes nothing") {
  const fs::path dir = study_dir("d9_twice", two_variants("1.0", "1.0", 1));
  const pid_t study = start_study(dir);
  wait_for_children(study, 1, {dir / "study_results" / "a_n13.h5"});
  const std::string csv = read_text(dir / "study.csv");
  std::string out;
  CHECK(run_study(dir, out) == 2);
  INFO(out);
  CHECK(contains(out, "another otmpm study is running on its CSV"));
  CHECK(contains(out, "is being written by process " + std::to_string(study)));
  CHECK(read_text(dir / "study.csv") == csv);
  CHECK(!fs::exists(dir / "study_results" / "b_n13.log")); // no run of b started
  ::kill(study, SIGTERM);
  CHECK(wait_exit(study) == 143);
  CHECK(!fs::exists(dir / ".study.csv.otmpm-lock")); // the study's lock is removed when it ends
  fs::remove_all(dir);
}

// ---------------------------------------------------------------- refused up front

TEST_CASE("study: duplicate variant or mesh names, or names mapping to one file, are refused naming both") {
  expect_refused("d10_same_file",
                 "jobs = 1\n[[variant]]\nname = \"fe a\"\nset = [\"simulation.integrator=fe\"]\n"
                 "[[variant]]\nname = \"fe/a\"\nset = [\"simulation.integrator=npc\"]\n" +
                     std::string(kMeshN13),
                 {"study.toml:7: key 'variant.fe/a'", "variant \"fe/a\" and variant \"fe a\" (study.toml:4",
                  "same result file", "fe_a_n13.h5"});
  expect_refused("d10_case",
                 "jobs = 2\n[[variant]]\nname = \"A\"\nset = [\"simulation.integrator=fe\"]\n"
                 "[[variant]]\nname = \"a\"\nset = [\"simulation.integrator=npc\"]\n" +
                     std::string(kMeshN13),
                 {"study.toml:7: key 'variant.a'", "variant \"a\" and variant \"A\" (study.toml:4", "case does not count"});
  expect_refused("d10_mesh_case", std::string(kMeshN13) + "[[mesh]]\nname = \"N13\"\nh = 0.01\n",
                 {"key 'mesh.N13'", "mesh \"N13\" and mesh \"n13\" (study.toml:3"});
  expect_refused("d10_duplicate",
                 "[[variant]]\nname = \"x\"\nset = [\"simulation.integrator=fe\"]\n"
                 "[[variant]]\nname = \"x\"\nset = [\"simulation.integrator=npc\"]\n" +
                     std::string(kMeshN13),
                 {"study.toml:6:", "variant name \"x\" is used twice", "study.toml:3"});
  expect_refused("d10_sweep", std::string("[sweep]\n\"simulation.cfl\" = [0.5, 0.5]\n") + kMeshN13,
                 {"sweep.simulation.cfl", "\"0.5\" is used twice"});
  expect_refused("d10_mesh", std::string(kMeshN13) + kMeshN13, {"mesh name \"n13\" is used twice"});
  expect_refused("d10_long", "[[variant]]\nname = \"" + std::string(250, 'x') + "\"\n" + kMeshN13,
                 {"study.toml:3:", "gives a result file name of 257 bytes; at most 203"});
}

TEST_CASE("study: a results path that is an existing file, or lies under one, is refused with exit 2") {
  for (const std::string results : {"taken.txt", "taken.txt/sub"}) {
    const fs::path dir = study_dir("d14", "results = \"" + results + "\"\n" + kMeshN13);
    std::ofstream(dir / "taken.txt") << "not a folder\n";
    std::string out;
    INFO(results);
    CHECK(run_study(dir, out) == 2);
    INFO(out);
    CHECK(contains(out, "study.toml:3: key 'results'"));
    CHECK(contains(out, results == "taken.txt" ? "exists and is not a directory" : "taken.txt is a file"));
    CHECK(read_text(dir / "taken.txt") == "not a folder\n");
    CHECK(!fs::exists(dir / "study.csv"));
    fs::remove_all(dir);
  }
}

TEST_CASE("study: every common set entry is applied to the scene before any run, a bad one is exit 2 at it") {
  // The form of an entry.
  expect_refused("d15", std::string("set = [\"simulation.t_end\"]\n") + kMeshN13,
                 {"study.toml:3: key 'set'", "'simulation.t_end' is not KEY=VALUE"});
  expect_refused("d15_type", std::string("set = [1]\n") + kMeshN13, {"key 'set'", "expected a string"});
  expect_refused("d15_key", std::string("set = [\"a..b=1\"]\n") + kMeshN13, {"'a..b=1' is not KEY=VALUE"});
  expect_refused("d15_mesh", "[[mesh]]\nname = \"m\"\nh = 0.01\nset = [\"=3\"]\n", {"key 'mesh.m.set'"});
  // Its key and value, as the scene reader sees them.
  expect_refused("d15_unknown", std::string("set = [\"output.every=1e-5\", \"simulation.nonsense=1\"]\n") + kMeshN13,
                 {"study.toml:3: key 'set'", "\"simulation.nonsense=1\"", "--set simulation.nonsense: unknown key"});
  expect_refused("d15_value", std::string("set = [\"simulation.t_end=-1\"]\n") + kMeshN13,
                 {"study.toml:3: key 'set'", "\"simulation.t_end=-1\"", "must be > 0"});
  expect_refused("d15_string", std::string("set = [\"simulation.t_end=soon\"]\n") + kMeshN13,
                 {"study.toml:3: key 'set'", "\"simulation.t_end=soon\"", "expected a number"});
  expect_refused("d15_element", std::string("set = [\"material.nope.young=1\"]\n") + kMeshN13,
                 {"study.toml:3: key 'set'", "no element 'nope'"});
  expect_refused("d15_mesh_value", "[[mesh]]\nname = \"m\"\nh = 0.01\nset = [\"grid.cells=[0]\"]\n",
                 {"study.toml:6: key 'mesh.m.set'", "\"grid.cells=[0]\"", "must be >= 1"});
  // A variant's value is still the variant's result: a stability study records it as refused.
  const fs::path dir = study_dir("d15_variant", std::string("set = [\"simulation.t_end=2e-5\", \"basis.kind=linear\", "
                                                            "\"simulation.integrator=fe\"]\n[stability]\nband = 0.05\n"
                                                            "[sweep]\n\"simulation.cfl\" = [-1.0, 0.5]\n") +
                                                    kMeshN13);
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  INFO(out);
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 3);
  for (std::size_t r = 1; r < rows.size(); ++r) {
    const std::string cfl = rows[r][column(rows[0], "simulation.cfl")];
    CHECK(rows[r][column(rows[0], "stability")] == (cfl == "-1" ? "refused" : "stable"));
  }
  fs::remove_all(dir);
}

TEST_CASE("study: a directory given as the study file or as its scene gets a clear message") {
  const fs::path dir = study_dir("d20", kMeshN13);
  std::string out;
  CHECK(run_command("'" OTMPM_BINARY "' study " + quote(dir.string()), out) == 2);
  CHECK(contains(out, "is a directory, not a study file"));
  std::ofstream(dir / "study.toml", std::ios::trunc) << "scene = \"" << dir.string() << "\"\n" << kMeshN13;
  CHECK(run_study(dir, out) == 2);
  INFO(out);
  CHECK(contains(out, "study.toml:1: key 'scene'"));
  CHECK(contains(out, "is a directory, not a scene file"));
  fs::remove_all(dir);
}

// ---------------------------------------------------------------- a cut-off row

TEST_CASE("study: a cut-off last CSV row is dropped and redone, and the next row starts on its own line") {
  const fs::path dir = make_study_dir("d16");
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  const std::string full = read_text(dir / "study.csv");
  // A study killed while writing its last row: half of that row, no newline.
  const std::size_t last = full.rfind('\n', full.size() - 2) + 1;
  const std::string cut_run = full.substr(last, full.find(',', full.find(',', last) + 1) - last);
  std::ofstream(dir / "study.csv", std::ios::trunc) << full.substr(0, last + (full.size() - last) / 2);
  REQUIRE(run_study(dir, out) == 0);
  INFO(out);
  CHECK(contains(out, "the last row was cut off"));
  CHECK(contains(out, "3 already in study.csv, 1 to do"));
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 5);
  std::set<std::string> runs;
  for (const auto& row : rows) {
    CHECK(row.size() == rows[0].size());
    runs.insert(row[0] + "," + row[1]);
  }
  CHECK(runs.size() == 5); // header + four distinct runs
  CHECK(rows[4][0] + "," + rows[4][1] == cut_run); // the cut-off run, done again
  CHECK(rows[4][column(rows[0], "status")] == "ok");
  fs::remove_all(dir);
}

TEST_CASE(
    "study --check: every chosen run's scene is checked, a refused run is named with the reader's message, "
    "nothing is run or written") {
  const std::string bad =
      "[[variant]]\nname = \"bad\"\nset = [\"simulation.t_end=2e-5\", \"material.steel.young=-1\"]\n";
  const fs::path dir = study_dir("d12_check", two_variants("2e-5", "2e-5", 1) + bad);
  std::string out;
  CHECK(run_study(dir, out, " --check") == 2);
  INFO(out);
  CHECK(out.find("ok       a n13: ") != std::string::npos);
  CHECK(out.find("ok       b n13: ") != std::string::npos);
  CHECK(out.find("refused  bad n13: ") != std::string::npos);
  CHECK(out.find("material.steel.young: must be > 0") != std::string::npos);
  CHECK(out.find("2 of 3 runs checked would start, 1 refused") != std::string::npos);
  CHECK(run_study(dir, out, " --check --variant a") == 0);
  CHECK(out.find("1 of 1 runs checked would start, 0 refused") != std::string::npos);
  CHECK(out.find("bad") == std::string::npos);
  CHECK(!fs::exists(dir / "study.csv"));
  CHECK(!fs::exists(dir / "study_results"));
  fs::remove_all(dir);
}

TEST_CASE("study --check: every run of every example study file would start") {
  // A change of the scene reader or of an example scene that leaves a
  // study's variant behind (a renamed key, a refused combination) shows here,
  // not hours into the study.
  int files = 0;
  for (const auto& e : fs::directory_iterator(fs::path(OTMPM_SOURCE_DIR) / "examples/studies")) {
    if (e.path().extension() != ".toml") continue;
    ++files;
    std::string out;
    INFO(e.path().string());
    const int status =
        run_command("cd " + quote(e.path().parent_path().string()) + " && '" OTMPM_BINARY "' study --check " +
                        quote(e.path().filename().string()),
                    out);
    INFO(out);
    CHECK(status == 0);
    CHECK(out.find(" 0 refused (nothing run or written)") != std::string::npos);
  }
  CHECK(files >= 10);
}
