// `otmpm study`: a 2 x 2 sweep (two integrators x two meshes of the Dyka bar)
// writes one CSV row per run with the expected parameters and errors, and a
// rerun resumes: rows already present are not run again. A [stability] study
// classifies a stable and a blown-up cfl and draws the stability map. The
// issue-20 defects: a killed study leaves no child running and its resume
// redoes the interrupted runs (D9); colliding names (D10), a results path
// that is a file (D14), a malformed common set (D15) and a directory as
// study or scene file (D20) are refused; a cut-off CSV row is redone (D16).
#include "cli_support.hpp"

#include <doctest/doctest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <csignal>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

namespace fs = std::filesystem;
using otmpm::test::read_text;

namespace {

/// The mesh h = L/13 of the Dyka bar as a [[mesh]] table.
const char* const kMeshN13 = "[[mesh]]\nname = \"n13\"\nh = 0.010253846\n"
                             "set = [\"grid.cells=[15]\", \"grid.lower=[-0.020507692]\"]\n";

/// A fresh directory with study.toml: the Dyka bar scene, study.csv, and `body`.
fs::path study_dir(const std::string& name, const std::string& body) {
  const fs::path dir = fs::temp_directory_path() / ("otmpm_study_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "study.toml") << "scene = \"" OTMPM_SOURCE_DIR "/examples/dyka.toml\"\n"
                                    << "csv = \"study.csv\"\n"
                                    << body;
  return dir;
}

/// Two integrators x two meshes (h = L/13, L/20), 2e-5 s each.
fs::path make_study_dir(const std::string& name) {
  return study_dir(name, std::string("jobs = 2\n"
                                     "set = [\"output.every=1e-5\", \"simulation.t_end=2e-5\"]\n"
                                     "[sweep]\n\"simulation.integrator\" = [\"fe\", \"npc\"]\n") +
                             kMeshN13 +
                             "[[mesh]]\nname = \"n20\"\nh = 0.006665\n"
                             "set = [\"grid.cells=[22]\", \"grid.lower=[-0.01333]\"]\n");
}

/// Runs a shell command; returns its exit status and fills `out` with its stdout and stderr.
int run_command(const std::string& cmd, std::string& out) {
  std::FILE* p = ::popen((cmd + " 2>&1").c_str(), "r");
  REQUIRE(p != nullptr);
  char buf[512];
  out.clear();
  while (std::fgets(buf, sizeof buf, p)) out += buf;
  const int status = ::pclose(p);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// Runs `otmpm study` in dir; returns the exit status and fills `out` with stdout.
int run_study(const fs::path& dir, std::string& out) {
  return run_command("cd '" + dir.string() + "' && '" OTMPM_BINARY "' study study.toml", out);
}

std::vector<std::vector<std::string>> read_csv(const fs::path& file) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) { // RFC 4180 cells: "a, ""b""" is one cell; trailing empty cells are kept
    std::vector<std::string> cols(1);
    bool quoted = false;
    for (std::size_t i = 0; i < line.size(); ++i) {
      const char c = line[i];
      if (c == '"' && quoted && i + 1 < line.size() && line[i + 1] == '"') cols.back() += line[++i];
      else if (c == '"') quoted = !quoted;
      else if (c == ',' && !quoted) cols.emplace_back();
      else cols.back() += c;
    }
    rows.push_back(cols);
  }
  return rows;
}

int column(const std::vector<std::string>& header, const std::string& name) {
  for (std::size_t i = 0; i < header.size(); ++i)
    if (header[i] == name) return static_cast<int>(i);
  FAIL("no column " << name);
  return -1;
}

} // namespace

TEST_CASE("study: a 2x2 sweep writes one CSV row per run with parameters, status and errors") {
  const fs::path dir = make_study_dir("rows");
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 5); // header + 2 integrators x 2 meshes
  const auto& h = rows[0];
  std::set<std::string> seen;
  for (std::size_t r = 1; r < rows.size(); ++r) {
    const auto& row = rows[r];
    REQUIRE(row.size() == h.size());
    seen.insert(row[column(h, "variant")] + "@" + row[column(h, "mesh")]);
    CHECK(row[column(h, "status")] == "ok");
    CHECK(row[column(h, "simulation.integrator")] == row[column(h, "variant")]);
    // The Dyka velocity error after 2e-5 s is of the order of the 5 m/s jump
    // smeared over a few cells: positive, finite and well below 5 m/s.
    const double e = std::stod(row[column(h, "rms_velocity_error")]);
    CHECK(e > 0.0);
    CHECK(e < 5.0);
    CHECK(std::stod(row[column(h, "wall_seconds")]) > 0.0);
    CHECK(std::stod(row[column(h, "steps")]) > 0.0);
  }
  CHECK(seen == std::set<std::string>{"fe@n13", "npc@n13", "fe@n20", "npc@n20"});
  CHECK(fs::exists(dir / "study_work_precision.png"));
  CHECK(fs::exists(dir / "study_convergence.svg"));
  fs::remove_all(dir);
}

TEST_CASE("study: a rerun skips the runs already in the CSV and completes a truncated one") {
  const fs::path dir = make_study_dir("resume");
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  REQUIRE(run_study(dir, out) == 0);
  CHECK(out.find("0 to do") != std::string::npos);
  CHECK(read_csv(dir / "study.csv").size() == 5);
  // Drop the last row, as if the study had been interrupted: only that run is redone.
  auto rows = read_csv(dir / "study.csv");
  std::ifstream in(dir / "study.csv");
  std::string text, line;
  for (std::size_t i = 0; i + 1 < rows.size() && std::getline(in, line); ++i) text += line + "\n";
  in.close();
  std::ofstream(dir / "study.csv") << text;
  REQUIRE(run_study(dir, out) == 0);
  CHECK(out.find("1 to do") != std::string::npos);
  CHECK(read_csv(dir / "study.csv").size() == 5);
  fs::remove_all(dir);
}

TEST_CASE("study: a CSV written before the energy columns is extended in place and resumed") {
  const fs::path dir = make_study_dir("upgrade");
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  // Rewrite the CSV as an older otmpm wrote it: without the two energy
  // columns, and without its last row.
  const auto rows = read_csv(dir / "study.csv");
  const int ratio = column(rows[0], "max_energy_ratio");
  REQUIRE(ratio + 2 == static_cast<int>(rows[0].size()));
  std::string text;
  for (std::size_t r = 0; r + 1 < rows.size(); ++r) {
    for (int c = 0; c < ratio; ++c) text += (c ? "," : "") + rows[r][static_cast<std::size_t>(c)];
    text += "\n";
  }
  std::ofstream(dir / "study.csv") << text;
  REQUIRE(run_study(dir, out) == 0);
  CHECK(out.find("added the columns") != std::string::npos);
  CHECK(out.find("1 to do") != std::string::npos);
  const auto now = read_csv(dir / "study.csv");
  REQUIRE(now.size() == 5);
  CHECK(now[0] == rows[0]);
  CHECK(now[1].size() == rows[0].size()); // padded with empty cells
  CHECK(now[1][static_cast<std::size_t>(ratio)].empty());
  CHECK(std::stod(now[4][static_cast<std::size_t>(ratio)]) > 0.0); // the rerun row is measured
  fs::remove_all(dir);
}

TEST_CASE("study: a [stability] sweep marks a blown-up cfl unstable, the stable one stable, and draws the map") {
  // The Dyka bar at h = L/13 with the linear basis and forward Euler: cfl 0.5
  // is below the limit measured for this combination at L/133 and L/401
  // (0.7, docs/stability.md); cfl 3 is far past it (measured: the runaway
  // monitor stops the run at step 2).
  const fs::path dir = study_dir("stability", std::string("jobs = 1\n"
                                                          "set = [\"output.fields=[]\", \"basis.kind=linear\", "
                                                          "\"simulation.integrator=fe\"]\n"
                                                          "[stability]\nband = 0.05\n"
                                                          "[sweep]\n\"simulation.cfl\" = [0.5, 3.0]\n") +
                                                  kMeshN13);
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 3);
  const auto& h = rows[0];
  CHECK(h.back() == "stability");
  for (std::size_t r = 1; r < rows.size(); ++r) {
    const auto& row = rows[r];
    const std::string cfl = row[column(h, "simulation.cfl")];
    INFO("cfl " << cfl << ": " << row[column(h, "status")]);
    const double ratio = std::stod(row[column(h, "max_energy_ratio")]);
    if (cfl == "0.5") {
      CHECK(row[column(h, "stable")] == "1");
      CHECK(row[column(h, "stability")] == "stable");
      CHECK(ratio <= 1.05);
      CHECK(ratio >= 1.0);
    } else {
      CHECK(cfl == "3");
      CHECK(row[column(h, "stable")] == "0");
      CHECK(row[column(h, "stability")] == "blown_up");
      CHECK(row[column(h, "exit_code")] == "1");
      CHECK(ratio > 10.0); // the runaway monitor stops at 10 x the reference
    }
  }
  // scripts/plot_stability.py ran: the map and the markdown table.
  CHECK(fs::exists(dir / "study_map.png"));
  CHECK(fs::exists(dir / "study_map.svg"));
  CHECK(out.find("| base | 0.5 | 3 (blown_up) |") != std::string::npos);
  // scripts/plot_energy_histories.py reads the /energy series of both result files.
  std::string printed;
  CHECK(run_command("/usr/bin/python3 '" OTMPM_SOURCE_DIR "/scripts/plot_energy_histories.py' 'cfl 0.5=" +
                        (dir / "study_results" / "0.5_n13.h5").string() + "' 'cfl 3=" +
                        (dir / "study_results" / "3_n13.h5").string() + "' --out '" + (dir / "energy.png").string() +
                        "'",
                    printed) == 0);
  INFO(printed);
  CHECK(fs::exists(dir / "energy.png"));
  CHECK(printed.find("cfl 0.5: ") != std::string::npos);
  CHECK(printed.find("status unstable") != std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE("study: a [stability] table without a positive band or with an unswept key is refused") {
  for (const auto& [table, what] : std::vector<std::pair<std::string, std::string>>{
           {"[stability]\nband = 0.0\n", "stability.band"},
           {"[stability]\n", "stability.band"},
           {"[stability]\nband = 0.05\nkey = \"simulation.gamma\"\n", "'simulation.gamma' is not swept"}}) {
    const fs::path dir = study_dir("bad_stability", table + "[sweep]\n\"simulation.cfl\" = [0.5]\n" + kMeshN13);
    std::string out;
    INFO(table);
    CHECK(run_study(dir, out) == 2);
    CHECK(out.find(what) != std::string::npos);
    CHECK(!fs::exists(dir / "study.csv")); // refused before any run
    fs::remove_all(dir);
  }
}

TEST_CASE("study: a malformed study file is refused with exit status 2 and the line") {
  const fs::path dir = make_study_dir("bad");
  std::stringstream text;
  text << "colour = \"red\"\n" << std::ifstream(dir / "study.toml").rdbuf();
  std::ofstream(dir / "study.toml") << text.str();
  std::string out;
  CHECK(run_study(dir, out) == 2);
  CHECK(out.find("study.toml:1:") != std::string::npos);
  CHECK(out.find("colour") != std::string::npos);
  fs::remove_all(dir);
}

// ---------------------------------------------------------------- issue 20: D9, D10, D14, D15, D16, D20

namespace {

/// Refusal of a study file: exit 2, every fragment in the output, no CSV written.
void expect_refused(const std::string& name, const std::string& body, const std::vector<std::string>& fragments) {
  const fs::path dir = study_dir(name, body);
  std::string out;
  INFO(body);
  CHECK(run_study(dir, out) == 2);
  INFO(out);
  for (const std::string& f : fragments) CHECK(out.find(f) != std::string::npos);
  CHECK(!fs::exists(dir / "study.csv"));
  fs::remove_all(dir);
}

/// Starts `otmpm study study.toml` in dir (stdout and stderr to study.out); returns its pid.
pid_t start_study(const fs::path& dir) {
  std::fflush(nullptr); // or the child flushes the test's buffered output a second time
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    if (::chdir(dir.c_str()) != 0) ::_exit(127);
    std::FILE* f = std::freopen("study.out", "w", stdout);
    if (f) ::dup2(::fileno(stdout), STDERR_FILENO);
    ::execl(OTMPM_BINARY, OTMPM_BINARY, "study", "study.toml", static_cast<char*>(nullptr));
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

/// True while `pid` runs (exists and is not a zombie).
bool running(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string stat;
  if (!std::getline(in, stat)) return false;
  const auto close = stat.rfind(')');
  return close != std::string::npos && close + 2 < stat.size() && stat[close + 2] != 'Z';
}

/// Waits until `study` has `n` children that have each created the result file named in `files`.
std::vector<pid_t> wait_for_children(pid_t study, std::size_t n, const std::vector<fs::path>& files) {
  for (int i = 0; i < 3000; ++i) { // 5 min
    const std::vector<pid_t> kids = children_of(study);
    bool all = kids.size() == n;
    for (const fs::path& f : files) all = all && fs::exists(f);
    if (all) {
      std::this_thread::sleep_for(std::chrono::milliseconds(200)); // past the set-up, inside the run loop
      return kids;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  FAIL("the study did not start its runs");
  return {};
}

int wait_exit(pid_t pid) {
  int wstatus = 0;
  REQUIRE(::waitpid(pid, &wstatus, 0) == pid);
  return WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : 128 + WTERMSIG(wstatus);
}

/// Waits (up to 20 s) until none of `pids` runs.
bool all_stopped(const std::vector<pid_t>& pids) {
  for (int i = 0; i < 200; ++i) {
    bool any = false;
    for (pid_t p : pids) any = any || running(p);
    if (!any) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

std::string status_attribute(const fs::path& h5) {
  std::string out;
  run_command("/usr/bin/python3 -c 'import sys, h5py; a = h5py.File(sys.argv[1], \"r\").attrs[\"status\"]; "
              "print(a.decode() if isinstance(a, bytes) else a)' '" + h5.string() + "'",
              out);
  return out.substr(0, out.find('\n'));
}

/// Two variants that run for a long time (t_end = 1 s of the Dyka bar: millions of steps) or `t_end`.
std::string two_variants(const std::string& t_end_a, const std::string& t_end_b, int jobs) {
  return "jobs = " + std::to_string(jobs) + "\nset = [\"output.every=1e-5\"]\n" +
         "[[variant]]\nname = \"a\"\nset = [\"simulation.t_end=" + t_end_a + "\"]\n" +
         "[[variant]]\nname = \"b\"\nset = [\"simulation.t_end=" + t_end_b + "\"]\n" + kMeshN13;
}

} // namespace

TEST_CASE("study (D9): SIGTERM or SIGKILL of the study stops its children, and the resume redoes those runs") {
  const fs::path dir = study_dir("d9", two_variants("1.0", "1.0", 2));
  const std::vector<fs::path> results{dir / "study_results" / "a_n13.h5", dir / "study_results" / "b_n13.h5"};
  for (int sig : {SIGTERM, SIGKILL}) {
    INFO("signal " << sig);
    const pid_t study = start_study(dir);
    const std::vector<pid_t> kids = wait_for_children(study, 2, results);
    ::kill(study, sig);
    const int status = wait_exit(study);
    CHECK(status == 128 + sig);
    CHECK(all_stopped(kids)); // no child left running (SIGKILL: through PR_SET_PDEATHSIG)
    for (const fs::path& r : results) CHECK(status_attribute(r) == "interrupted");
    // Nothing recorded: only the header.
    CHECK(read_csv(dir / "study.csv").size() == 1);
    if (sig == SIGTERM) CHECK(read_text(dir / "study.out").find("study interrupted by SIGTERM") != std::string::npos);
  }
  // Resume with short runs: both are done again, and both succeed (the
  // interrupted result files are replaced, nothing is an input error).
  std::ofstream(dir / "study.toml") << "scene = \"" OTMPM_SOURCE_DIR "/examples/dyka.toml\"\ncsv = \"study.csv\"\n"
                                    << two_variants("2e-5", "2e-5", 2);
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  INFO(out);
  CHECK(out.find("2 to do") != std::string::npos);
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 3);
  for (std::size_t r = 1; r < rows.size(); ++r) CHECK(rows[r][column(rows[0], "status")] == "ok");
  fs::remove_all(dir);
}

TEST_CASE("study (D9): a child killed by a signal is not recorded, and the next study retries it") {
  const fs::path dir = study_dir("d9_child", two_variants("1.0", "2e-5", 1));
  const pid_t study = start_study(dir);
  const std::vector<pid_t> kids = wait_for_children(study, 1, {dir / "study_results" / "a_n13.h5"});
  REQUIRE(kids.size() == 1);
  ::kill(kids.front(), SIGKILL);
  CHECK(wait_exit(study) == 0); // the study goes on with b
  const std::string printed = read_text(dir / "study.out");
  INFO(printed);
  CHECK(printed.find("a n13: stopped (exit 137), not recorded") != std::string::npos);
  auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 2);
  CHECK(rows[1][0] == "b");
  std::ofstream(dir / "study.toml") << "scene = \"" OTMPM_SOURCE_DIR "/examples/dyka.toml\"\ncsv = \"study.csv\"\n"
                                    << two_variants("2e-5", "2e-5", 1);
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  CHECK(out.find("1 to do") != std::string::npos);
  rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 3);
  CHECK(rows[2][0] == "a");
  CHECK(rows[2][column(rows[0], "status")] == "ok");
  fs::remove_all(dir);
}

TEST_CASE("study (D10): duplicate variant or mesh names, or names mapping to one file, are refused naming both") {
  expect_refused("d10_same_file",
                 "[[variant]]\nname = \"fe a\"\nset = [\"simulation.integrator=fe\"]\n"
                 "[[variant]]\nname = \"fe/a\"\nset = [\"simulation.integrator=npc\"]\n" +
                     std::string(kMeshN13),
                 {"study.toml:6: key 'variant.fe/a'", "\"fe/a\"", "study.toml:3", "same result file", "fe_a_n13.h5"});
  expect_refused("d10_duplicate",
                 "[[variant]]\nname = \"x\"\nset = [\"simulation.integrator=fe\"]\n"
                 "[[variant]]\nname = \"x\"\nset = [\"simulation.integrator=npc\"]\n" +
                     std::string(kMeshN13),
                 {"study.toml:6:", "variant name \"x\" is used twice", "study.toml:3"});
  expect_refused("d10_sweep", std::string("[sweep]\n\"simulation.cfl\" = [0.5, 0.5]\n") + kMeshN13,
                 {"sweep.simulation.cfl", "\"0.5\" is used twice"});
  expect_refused("d10_mesh", std::string(kMeshN13) + kMeshN13, {"mesh name \"n13\" is used twice"});
}

TEST_CASE("study (D14): a results path that is an existing file is refused with exit 2") {
  const fs::path dir = study_dir("d14", std::string("results = \"taken.txt\"\n") + kMeshN13);
  std::ofstream(dir / "taken.txt") << "not a folder\n";
  std::string out;
  CHECK(run_study(dir, out) == 2);
  INFO(out);
  CHECK(out.find("study.toml:3: key 'results'") != std::string::npos);
  CHECK(out.find("exists and is not a directory") != std::string::npos);
  CHECK(read_text(dir / "taken.txt") == "not a folder\n");
  fs::remove_all(dir);
}

TEST_CASE("study (D15): the common set list is checked like a variant's") {
  expect_refused("d15", std::string("set = [\"simulation.t_end\"]\n") + kMeshN13,
                 {"study.toml:3: key 'set'", "'simulation.t_end' is not KEY=VALUE"});
  expect_refused("d15_type", std::string("set = [1]\n") + kMeshN13, {"key 'set'", "expected a string"});
  expect_refused("d15_key", std::string("set = [\"a..b=1\"]\n") + kMeshN13, {"'a..b=1' is not KEY=VALUE"});
  expect_refused("d15_mesh", "[[mesh]]\nname = \"m\"\nh = 0.01\nset = [\"=3\"]\n", {"key 'mesh.m.set'"});
}

TEST_CASE("study (D16): a cut-off last CSV row is dropped and redone, and the next row starts on its own line") {
  const fs::path dir = make_study_dir("d16");
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  const std::string full = read_text(dir / "study.csv");
  // A study killed while writing its last row: half of that row, no newline.
  const std::size_t last = full.rfind('\n', full.size() - 2) + 1;
  std::ofstream(dir / "study.csv", std::ios::trunc) << full.substr(0, last + (full.size() - last) / 2);
  REQUIRE(run_study(dir, out) == 0);
  INFO(out);
  CHECK(out.find("the last row was cut off") != std::string::npos);
  CHECK(out.find("1 to do") != std::string::npos);
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 5);
  std::set<std::string> runs;
  for (const auto& row : rows) {
    CHECK(row.size() == rows[0].size());
    runs.insert(row[0] + "@" + row[1]);
  }
  CHECK(runs.size() == 5); // header + four distinct runs
  fs::remove_all(dir);
}

TEST_CASE("study (D20): a directory given as the study file or as its scene gets a clear message") {
  const fs::path dir = study_dir("d20", kMeshN13);
  std::string out;
  CHECK(run_command("'" OTMPM_BINARY "' study '" + dir.string() + "'", out) == 2);
  CHECK(out.find("is a directory, not a study file") != std::string::npos);
  std::ofstream(dir / "study.toml") << "scene = \"" << dir.string() << "\"\n" << kMeshN13;
  CHECK(run_study(dir, out) == 2);
  INFO(out);
  CHECK(out.find("study.toml:1: key 'scene'") != std::string::npos);
  CHECK(out.find("is a directory, not a scene file") != std::string::npos);
  fs::remove_all(dir);
}
