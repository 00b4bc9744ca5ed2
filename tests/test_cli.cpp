// The `otmpm` command (docs/user-guide.md, "Command line"): exit status 2 with a
// message naming file and line for every malformed scene, 0 and a readable
// HDF5 file with status "ok" for a good one, 1 and a diagnosis for a run that
// becomes unstable, 2 for an unknown --set key or an unknown command.
#include "cli_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <sched.h>
#include <sys/wait.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using otmpm::test::quote;
using otmpm::test::read_text;
using otmpm::test::TempDir;

namespace {

const fs::path kSource = OTMPM_SOURCE_DIR;
const std::string kBinary = OTMPM_BINARY;

struct CliResult {
  int status = -1;
  std::string err;
  std::string out;
};

/// Runs `otmpm ARGS` (one thread, so the run does not depend on how busy the
/// machine is), returning the exit status and what it wrote to stdout and stderr.
CliResult run_cli(const TempDir& dir, const std::vector<std::string>& args) {
  const fs::path err_file = dir.dir / "stderr.txt", out_file = dir.dir / "stdout.txt";
  // Appended piece by piece: g++ 12 at -O3 warns (-Wrestrict, a known false
  // positive) on `"literal" + std::string`.
  std::string cmd = "OMP_NUM_THREADS=1 ";
  cmd += quote(kBinary);
  for (const auto& a : args) {
    cmd += ' ';
    cmd += quote(a);
  }
  cmd += " >";
  cmd += quote(out_file.string());
  cmd += " 2>";
  cmd += quote(err_file.string());
  const int rc = std::system(cmd.c_str());
  CliResult r;
  r.status = rc != -1 && WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  r.err = read_text(err_file);
  r.out = read_text(out_file);
  return r;
}

/// A string attribute of the root group of an HDF5 file ("" and a failed
/// check when it cannot be read).
std::string root_string_attribute(const fs::path& file, const std::string& name) {
  std::string value;
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(f >= 0);
  const hid_t attr = H5Aopen_by_name(f, "/", name.c_str(), H5P_DEFAULT, H5P_DEFAULT);
  CHECK(attr >= 0);
  if (attr >= 0) {
    const hid_t type = H5Aget_type(attr);
    CHECK(H5Tget_class(type) == H5T_STRING);
    CHECK(H5Tis_variable_str(type) == 0); // fixed-length, as results.cpp writes it
    std::vector<char> buf(H5Tget_size(type) + 1, '\0');
    CHECK(H5Aread(attr, type, buf.data()) >= 0);
    value = buf.data();
    H5Tclose(type);
    H5Aclose(attr);
  }
  H5Fclose(f);
  return value;
}

/// A double attribute of the root group of an HDF5 file (NaN when it cannot be read).
double root_double_attribute(const fs::path& file, const std::string& name) {
  double value = std::nan("");
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(f >= 0);
  const hid_t attr = H5Aopen_by_name(f, "/", name.c_str(), H5P_DEFAULT, H5P_DEFAULT);
  CHECK(attr >= 0);
  if (attr >= 0) {
    CHECK(H5Aread(attr, H5T_NATIVE_DOUBLE, &value) >= 0);
    H5Aclose(attr);
  }
  H5Fclose(f);
  return value;
}

/// True when s contains ":<digits>:" (the "FILE:LINE:" of a message). Written
/// by hand: std::regex trips GCC 12's -Wmaybe-uninitialized under the sanitizers.
bool has_line_number(const std::string& s) {
  for (std::size_t i = s.find(':'); i != std::string::npos; i = s.find(':', i + 1)) {
    std::size_t j = i + 1;
    while (j < s.size() && s[j] >= '0' && s[j] <= '9') ++j;
    if (j > i + 1 && j < s.size() && s[j] == ':') return true;
  }
  return false;
}

std::vector<fs::path> bad_scenes() {
  std::vector<fs::path> out;
  for (const auto& entry : fs::directory_iterator(kSource / "tests" / "scenes" / "bad"))
    if (entry.path().extension() == ".toml") out.push_back(entry.path());
  std::sort(out.begin(), out.end());
  return out;
}

} // namespace

TEST_CASE("cli: every malformed scene exits with 2 and names file and line") {
  TempDir dir("cli");
  const std::vector<fs::path> scenes = bad_scenes();
  REQUIRE(scenes.size() >= 10); // the directory is really there
  for (const fs::path& scene : scenes) {
    INFO("scene " << scene.filename().string());
    const fs::path out = dir.dir / (scene.stem().string() + ".h5");
    const CliResult r = run_cli(dir, {"run", scene.string(), "--out", out.string(), "--quiet"});
    INFO("stderr: " << r.err);
    CHECK(r.status == 2);
    CHECK(r.err.find(scene.filename().string()) != std::string::npos);
    CHECK((r.err.find("line") != std::string::npos || has_line_number(r.err)));
    // Nothing runs on a half-read scene: no result file.
    CHECK(!fs::exists(out));
  }
}

TEST_CASE("cli: a good scene exits with 0 and writes an HDF5 file with status ok") {
  TempDir dir("cli");
  const fs::path out = dir.dir / "good.h5";
  const CliResult r =
      run_cli(dir, {"run", (kSource / "tests" / "scenes" / "good_minimal.toml").string(), "--out", out.string(), "--quiet"});
  INFO("stderr: " << r.err);
  CHECK(r.status == 0);
  REQUIRE(fs::exists(out));
  CHECK(H5Fis_hdf5(out.c_str()) > 0);
  CHECK(root_string_attribute(out, "status") == "ok");
  // The resolved scene is stored too (docs/user-guide.md, "Result file").
  CHECK(root_string_attribute(out, "scene").find("[simulation]") != std::string::npos);
}

TEST_CASE("cli: a run that leaves the grid exits with 1 and leaves a valid file with the diagnosis") {
  TempDir dir("cli");
  const fs::path out = dir.dir / "unstable.h5";
  const CliResult r = run_cli(
      dir, {"run", (kSource / "tests" / "scenes" / "engine" / "leaves_grid.toml").string(), "--out", out.string(), "--quiet"});
  INFO("stderr: " << r.err);
  CHECK(r.status == 1);
  CHECK(r.err.find("would leave the grid") != std::string::npos);
  REQUIRE(fs::exists(out));
  const std::string status = root_string_attribute(out, "status");
  CHECK(status.rfind("unstable", 0) == 0);
  CHECK(status.find("would leave the grid") != std::string::npos);
}

TEST_CASE("cli: --set of an unknown key exits with 2 and names the key") {
  TempDir dir("cli");
  const std::string good = (kSource / "tests" / "scenes" / "good_minimal.toml").string();
  for (const char* key : {"simulation.no_such_key=1", "no_such_table.value=1", "material.steel.yuong=1e9"}) {
    INFO("--set " << key);
    const fs::path out = dir.dir / "set.h5";
    const CliResult r = run_cli(dir, {"run", good, "--set", key, "--out", out.string(), "--quiet"});
    INFO("stderr: " << r.err);
    CHECK(r.status == 2);
    const std::string path = std::string(key).substr(0, std::string(key).find('='));
    CHECK(r.err.find(path.substr(path.rfind('.') + 1)) != std::string::npos); // the offending key
    CHECK(!fs::exists(out));
  }
}

TEST_CASE("cli: a bad field of simulation.initial_equilibrium is named, from the file or from --set") {
  TempDir dir("cli");
  const fs::path dike = kSource / "examples" / "dike_rising.toml";
  const std::string given = "initial_equilibrium = { time = 20.0, tolerance = 1.0e-4 }";
  std::string text = read_text(dike);
  const std::size_t at = text.find(given);
  REQUIRE(at != std::string::npos);
  const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
  const fs::path bad = dir.dir / "dike_bad.toml";
  std::ofstream(bad) << text.replace(at, given.size(), "initial_equilibrium = { time = 20.0, damping = 2 }");
  const std::string field = "simulation.initial_equilibrium.damping";
  struct Case {
    std::string scene, set, where;
  };
  for (const Case& c : {Case{bad.string(), "", "dike_bad.toml:" + std::to_string(line) + ": key '" + field + "'"},
                        Case{dike.string(), field + "=2", "--set " + field},
                        Case{dike.string(), "simulation.initial_equilibrium={time=20.0, damping=2}",
                             "--set simulation.initial_equilibrium: key '" + field + "'"}}) {
    std::vector<std::string> args{"run", c.scene, "--check"};
    if (!c.set.empty()) args.insert(args.end(), {"--set", c.set});
    const CliResult r = run_cli(dir, args);
    INFO("stderr: " << r.err);
    CHECK(r.status == 2);
    CHECK(r.err.find(c.where + ": must be in [0, 1) (got 2)") != std::string::npos);
  }
}

TEST_CASE("cli: the line-number detector used above") {
  CHECK(has_line_number("otmpm: error: a.toml:14: key 'x'"));
  CHECK(has_line_number("b.toml:21:11: syntax error"));
  CHECK(!has_line_number("otmpm: error: a.toml: key 'x'"));
  CHECK(!has_line_number("12:"));
}

TEST_CASE("cli: an unknown command or no command exits with 2") {
  TempDir dir("cli");
  const CliResult r = run_cli(dir, {"frobnicate"});
  CHECK(r.status == 2);
  CHECK(r.err.find("frobnicate") != std::string::npos);
  CHECK(run_cli(dir, {}).status == 2);
  const CliResult help = run_cli(dir, {"--help"});
  CHECK(help.status == 0);
  // every exit status the command uses is listed
  for (const char* status : {"0 ok", "1 the simulation", "2 bad input", "3 internal", "4 the results", "130/143"})
    CHECK_MESSAGE(help.out.find(status) != std::string::npos, status);
}

TEST_CASE("cli: a process a launcher started among others it cannot join says so and exits with 2") {
  // PMI_SIZE = 3 without the launcher: this process cannot reach two peers,
  // as a build without MPI (or with another MPI) under mpirun cannot
  const otmpm::test::ShellResult r =
      otmpm::test::shell("PMI_SIZE=3 PMI_RANK=0 OMP_NUM_THREADS=1 " + quote(kBinary) + " --version");
  CHECK(r.status == 2);
  CHECK(r.output.find("started by mpirun or srun as one of 3 processes, but this otmpm cannot join them as ranks") !=
        std::string::npos);
  const otmpm::test::ShellResult quiet = otmpm::test::shell("PMI_SIZE=3 PMI_RANK=1 " + quote(kBinary) + " --version");
  CHECK(quiet.status == 2);
  CHECK(quiet.output.empty()); // one message for all processes: the launcher's first prints it
}

TEST_CASE("cli: basis options that are not an int (out of range, fractional, negative seed) exit with 2") {
  TempDir dir("cli");
  const std::string out = (dir.dir / "basis.csv").string();
  for (const char* bad : {"--cells=1e20", "--cells=2.5", "--samples=-1e300", "--seed=-3"}) {
    INFO(bad);
    const std::string arg(bad);
    const std::string opt = arg.substr(0, arg.find('='));
    const CliResult r = run_cli(dir, {"basis", "--kind", "linear", opt, arg.substr(arg.find('=') + 1), "--out", out});
    INFO("stderr: " << r.err);
    CHECK(r.status == 2);
    CHECK(r.err.find(opt) != std::string::npos);
  }
  CHECK(run_cli(dir, {"basis", "--kind", "linear", "--cells", "4", "--samples", "3", "--out", out}).status == 0);
}

// ---------------------------------------------------------------- CLI11 front end

TEST_CASE("cli: --help and -h work on otmpm and every command, and list the real options") {
  TempDir dir("cli");
  const std::vector<std::pair<std::string, std::vector<std::string>>> commands{
      {"", {"run", "pair", "study", "basis", "render", "--version"}},
      {"run", {"--set", "--out", "--restart", "--check", "--threads", "--force", "--quiet", "--progress-interval"}},
      {"pair", {"--set", "--threads", "--force", "--quiet"}},
      {"study", {"--threads", "--scripts", "--python"}},
      {"basis", {"--kind", "--dim", "--lower", "--upper", "--cells", "--perturb", "--seed", "--gamma-lme",
                 "--tolerance", "--d-max", "--ppc", "--samples", "--out", "--threads"}},
      {"render", {"--field", "--frame", "--all", "--stride", "--out", "--component", "--view", "--fps", "--scripts",
                  "--python"}}};
  for (const auto& entry : commands)
    for (const char* help : {"--help", "-h"}) {
      const auto& command = entry.first; // plain references: INFO captures them (clang refuses a binding)
      const auto& options = entry.second;
      INFO("otmpm " << command << " " << help);
      const CliResult r = command.empty() ? run_cli(dir, {help}) : run_cli(dir, {command, help});
      CHECK(r.status == 0);
      CHECK(r.out.find("Usage: otmpm") != std::string::npos);
      for (const std::string& o : options) {
        INFO(o);
        CHECK(r.out.find(o) != std::string::npos);
      }
    }
}

TEST_CASE("cli: --version prints the version") {
  TempDir dir("cli");
  const CliResult r = run_cli(dir, {"--version"});
  CHECK(r.status == 0);
  CHECK(r.out.rfind("otmpm 0.", 0) == 0);
}

TEST_CASE("cli: a bad option exits with 2 and CLI11's message, in every command") {
  TempDir dir("cli");
  const std::string good = (kSource / "tests" / "scenes" / "good_minimal.toml").string();
  for (const auto& args : std::vector<std::vector<std::string>>{{"run", good, "--frobnicate"},
                                                                {"run", good, "--threads", "0"},
                                                                {"run", good, "--threads=two"},
                                                                {"run", good, "--out"},
                                                                {"run", "--restart", "c.h5", good},
                                                                {"run", "--restart", "c.h5", "--set", "a=1"},
                                                                {"pair"},
                                                                {"pair", good, "--out", "x.h5"},
                                                                {"study", "--frobnicate", "s.toml"},
                                                                {"study"},
                                                                {"basis", "--kind", "cubic", "--out", "b.csv"},
                                                                {"basis", "--kind", "linear"},
                                                                {"basis", "--dim=4", "--out", "b.csv"},
                                                                {"render", "r.h5", "--field", "v", "--out", "r.jpg"},
                                                                {"render", "r.h5", "--out", "r.png"},
                                                                {"render", "r.h5", "--field", "v", "--out", "r.gif",
                                                                 "--all", "--frame", "2"}}) {
    std::string line;
    for (const auto& a : args) line += a + " ";
    INFO("otmpm " << line);
    const CliResult r = run_cli(dir, args);
    INFO("stderr: " << r.err);
    CHECK(r.status == 2);
    CHECK(r.err.find("--help") != std::string::npos); // CLI11: "Run with --help for more information."
  }
}

TEST_CASE("cli: --opt=value and --opt value are the same in every command") {
  TempDir dir("cli");
  const std::string good = (kSource / "tests" / "scenes" / "good_minimal.toml").string();
  const fs::path a = dir.dir / "a.h5", b = dir.dir / "b.h5";
  CHECK(run_cli(dir, {"run", good, "--out", a.string(), "--set", "simulation.t_end=1e-6", "--threads", "1", "-q"})
            .status == 0);
  CHECK(run_cli(dir, {"run", good, "--out=" + b.string(), "--set=simulation.t_end=1e-6", "--threads=1", "--quiet"})
            .status == 0);
  CHECK(root_string_attribute(a, "scene") == root_string_attribute(b, "scene"));
  const fs::path c1 = dir.dir / "c1.csv", c2 = dir.dir / "c2.csv";
  CHECK(run_cli(dir, {"basis", "--kind", "ugimp", "--ppc", "3", "--cells", "4", "--seed", "2", "--out", c1.string()})
            .status == 0);
  CHECK(run_cli(dir, {"basis", "--kind=ugimp", "--ppc=3", "--cells=4", "--seed=2", "--out=" + c2.string()}).status ==
        0);
  CHECK(read_text(c1) == read_text(c2));
  CHECK(!read_text(c1).empty());
}

TEST_CASE("cli: --threads does not change the result") {
  TempDir dir("cli");
  const std::string scene = (kSource / "examples" / "dyka_2d.toml").string();
  const fs::path one = dir.dir / "one.h5", two = dir.dir / "two.h5";
  for (const auto& [file, threads] : {std::pair{one, "1"}, std::pair{two, "2"}}) {
    const CliResult r = run_cli(dir, {"run", scene, "--set", "simulation.t_end=2e-5", "--threads", threads, "--out",
                                      file.string(), "-q"});
    REQUIRE(r.status == 0);
  }
  CHECK(root_string_attribute(one, "status") == "ok");
  for (const char* attr : {"rms_velocity_error", "rms_stress_error", "max_energy_ratio"}) {
    INFO(attr);
    CHECK(root_double_attribute(one, attr) == root_double_attribute(two, attr)); // bitwise, for any thread count
  }
}

TEST_CASE("cli: OpenMP threads wait passively after a short spin by default, and a user's own setting is kept") {
  // libgomp prints its settings at start-up with OMP_DISPLAY_ENV=verbose;
  // the otmpm process that does the work is the last one to print them.
  TempDir dir("cli");
  const fs::path err = dir.dir / "env.txt";
  // how many processes printed (2: otmpm set the defaults and started itself again)
  int printed = 0;
  auto last_setting = [&](const std::string& env, const std::string& name) {
    const std::string cmd = env + " OMP_DISPLAY_ENV=verbose " + quote(kBinary) + " --version >/dev/null 2>" +
                            quote(err.string());
    CHECK(std::system(cmd.c_str()) == 0);
    const std::string text = read_text(err);
    printed = 0;
    for (auto at = text.find("OPENMP DISPLAY ENVIRONMENT BEGIN"); at != std::string::npos;
         at = text.find("OPENMP DISPLAY ENVIRONMENT BEGIN", at + 1))
      ++printed;
    const std::string key = name + " = '";
    const auto at = text.rfind(key);
    REQUIRE(at != std::string::npos);
    const auto from = at + key.size();
    return text.substr(from, text.find('\'', from) - from);
  };
  const std::string neither = "env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT";
  // libgomp prints PASSIVE for its own default too: the second process shows that otmpm set it
  CHECK(last_setting(neither, "OMP_WAIT_POLICY") == "PASSIVE");
  CHECK(printed == 2);
  // about 0.2 ms of spinning: 100 to 10^7 spins on any processor (a pause
  // takes from ~1 to ~100 ns; this machine's: docs/performance-log-2026.md), not
  // libgomp's 300 000 when nothing is set nor its 0 for passive alone
  const long long spins = std::stoll(last_setting(neither, "GOMP_SPINCOUNT"));
  CHECK(spins >= 100);
  CHECK(spins <= 10000000);
  CHECK(spins != 300000);
  CHECK(last_setting("env -u GOMP_SPINCOUNT OMP_WAIT_POLICY=active", "OMP_WAIT_POLICY") == "ACTIVE");
  CHECK(printed == 1); // a user's setting: no second start
  CHECK(last_setting("env -u GOMP_SPINCOUNT OMP_WAIT_POLICY=passive", "GOMP_SPINCOUNT") == "0"); // libgomp's passive
  CHECK(printed == 1);
  CHECK(last_setting("env -u OMP_WAIT_POLICY GOMP_SPINCOUNT=1234", "GOMP_SPINCOUNT") == "1234");
  CHECK(printed == 1);
}

TEST_CASE("cli: with bound threads (OMP_PROC_BIND, OMP_PLACES) the process started again keeps every place") {
  // libgomp binds the first thread to the first place when it is loaded;
  // the process otmpm starts again for its wait must still see every CPU
  // (else all its threads would run on the first one)
  TempDir dir("cli");
  const fs::path err = dir.dir / "env.txt";
  for (const char* bind : {"OMP_PROC_BIND=true", "OMP_PLACES=cores", "OMP_PROC_BIND=spread"}) {
    INFO(bind);
    const std::string cmd = std::string("env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT ") + bind +
                            " OMP_DISPLAY_ENV=true " + quote(kBinary) + " --version >/dev/null 2>" +
                            quote(err.string());
    REQUIRE(std::system(cmd.c_str()) == 0);
    const std::string text = read_text(err);
    const std::string key = "OMP_PLACES = '";
    const auto first = text.find(key), last = text.rfind(key);
    REQUIRE(first != std::string::npos);
    REQUIRE(last != first); // two processes printed: otmpm started itself again
    const auto places = [&](std::size_t at) {
      const auto from = at + key.size();
      return text.substr(from, text.find('\'', from) - from);
    };
    CHECK(places(first) != "");
    CHECK(places(last) == places(first));
  }
}

TEST_CASE("cli: run --check validates, prints the size, dt, steps and memory, and runs nothing") {
  TempDir dir("cli");
  const fs::path out = dir.dir / "checked.h5";
  const CliResult r =
      run_cli(dir, {"run", "--check", (kSource / "examples" / "dyka" / "dyka_n40.toml").string(), "--out", out.string()});
  INFO(r.out << r.err);
  CHECK(r.status == 0);
  CHECK(r.out.find("particles  80\n") != std::string::npos); // 40 cells of h = L/40, 2 particles each
  CHECK(r.out.find("nodes      43\n") != std::string::npos);
  CHECK(r.out.find("about 1517 (t_end = 0.0001 s)") != std::string::npos); // the run takes 1517 steps
  CHECK(r.out.find("memory     about") != std::string::npos);
  CHECK(r.out.find("dt         6.595") != std::string::npos);
  CHECK(!fs::exists(out));
  // A scene only the engine refuses (in ul mode the nodes cover the body
  // alone, so the boundary at the grid's end selects none) is refused by --check too.
  const CliResult bad = run_cli(dir, {"run", "--check", (kSource / "tests" / "scenes" / "good_minimal.toml").string(),
                                      "--set", "simulation.mode=ul", "--set", "boundary.0.lower=[-0.0067]", "--set",
                                      "boundary.0.upper=[-0.0067]"});
  INFO(bad.err);
  CHECK(bad.status == 2);
}

TEST_CASE(
    "cli: with bound threads the result file's writer thread may run on every place, not on the first one") {
  // libgomp binds the first thread to the first place; the writer thread it
  // starts (one OpenMP thread, a CPU left free) must not share that core
  cpu_set_t mask;
  REQUIRE(sched_getaffinity(0, sizeof mask, &mask) == 0);
  if (CPU_COUNT(&mask) < 2) {
    MESSAGE("one CPU: nothing to spread over");
    return;
  }
  TempDir dir("cli");
  const std::string out = (dir.dir / "out.txt").string(), err = (dir.dir / "err.txt").string();
  const pid_t pid = otmpm::test::spawn_process(
      kBinary,
      {"run", (kSource / "examples" / "taylor_bar" / "full_cylinder.toml").string(), "--threads", "1",
       "--set", "output.every=2e-6", "--out", (dir.dir / "tb.h5").string(), "-q"},
      out, err, {"OMP_PROC_BIND=true"});
  const auto cpus_of = [](const fs::path& task) { // its Cpus_allowed_list
    std::ifstream in(task / "status");
    for (std::string line; std::getline(in, line);)
      if (line.rfind("Cpus_allowed_list:", 0) == 0) return line.substr(line.find_first_not_of(" \t", 18));
    return std::string();
  };
  const fs::path tasks = fs::path("/proc") / std::to_string(pid) / "task";
  std::string first, other; // the first thread's CPUs, and another thread's that differ
  for (int i = 0; i < 600 && other.empty(); ++i) { // up to 30 s for the writer to start
    first = cpus_of(tasks / std::to_string(pid));
    std::error_code ec;
    for (const auto& t : fs::directory_iterator(tasks, ec))
      if (t.path().filename() != std::to_string(pid) && cpus_of(t.path()) != first) other = cpus_of(t.path());
    if (other.empty()) usleep(50000);
  }
  kill(pid, SIGTERM);
  otmpm::test::wait_process(pid, out, err);
  INFO("first thread: " << first);
  CHECK(first.find_first_of(",-") == std::string::npos); // bound to one CPU
  CHECK(other.find_first_of(",-") != std::string::npos); // the writer: more than one
}

TEST_CASE(
    "cli: run --check prints the threads and the CPUs the process may use, and says when threads share one") {
  // taskset gives the process one CPU (as mpirun's default binding gives each rank of two one core)
  const std::string scene = quote((kSource / "examples" / "dyka" / "dyka_n40.toml").string());
  const auto check = [&](const std::string& threads) {
    return otmpm::test::shell("taskset -c 0 " + quote(kBinary) + " run --check " + scene + " --threads " +
                              threads);
  };
  const otmpm::test::ShellResult one = check("1"), two = check("2");
  INFO(one.output << two.output);
  REQUIRE(one.status == 0);
  REQUIRE(two.status == 0);
  CHECK(one.output.find("threads    1 OpenMP thread on 1 CPU this process may use\n") != std::string::npos);
  CHECK(
      two.output.find("threads    2 OpenMP threads on 1 CPU this process may use: more threads than CPUs") !=
      std::string::npos);
  CHECK(two.output.find("mpirun --map-by slot:pe=2 or srun --cpus-per-task=2") != std::string::npos);
}

TEST_CASE("cli: a directory given as the scene or checkpoint file gets a clear message (run, pair, check, restart)") {
  TempDir dir("cli");
  for (const auto& args : std::vector<std::vector<std::string>>{{"run", dir.dir.string()},
                                                                {"run", "--check", dir.dir.string()},
                                                                {"pair", dir.dir.string()}}) {
    const CliResult r = run_cli(dir, args);
    INFO(args[0] << ": " << r.err);
    CHECK(r.status == 2);
    CHECK(r.err.find("is a directory, not a scene file") != std::string::npos);
  }
  const CliResult r = run_cli(dir, {"run", "--restart", dir.dir.string()});
  CHECK(r.status == 2);
  CHECK(r.err.find("is a directory, not a checkpoint file") != std::string::npos);
}

TEST_CASE("cli: progress lines every interval with step, t, elapsed and ETA when stderr is not a terminal") {
  TempDir dir("cli");
  const std::string scene = (kSource / "examples" / "dyka" / "dyka_n133.toml").string();
  const fs::path out = dir.dir / "p.h5";
  const CliResult r = run_cli(dir, {"run", scene, "--out", out.string(), "--progress-interval", "0.02", "--set",
                                    "output.every=0"});
  INFO(r.err);
  REQUIRE(r.status == 0);
  std::size_t lines = 0;
  std::stringstream ss(r.err);
  for (std::string line; std::getline(ss, line);) {
    if (line.rfind("otmpm: step ", 0) != 0) continue;
    ++lines;
    CHECK(line.find(" t = ") != std::string::npos);
    CHECK(line.find("elapsed ") != std::string::npos);
    CHECK(line.find("ETA ") != std::string::npos);
  }
  CHECK(lines >= 1); // the run takes 5043 steps, far more than 0.02 s
  CHECK(r.err.find('\r') == std::string::npos); // no terminal bar in a log
  // --quiet: no progress at all.
  const CliResult q = run_cli(dir, {"run", scene, "--out", out.string(), "--progress-interval", "0.02", "--quiet",
                                    "--force"});
  CHECK(q.err.find("otmpm: step") == std::string::npos);
}

TEST_CASE("cli: every option that --help prints is documented in docs/user-guide.md") {
  TempDir dir("cli");
  const std::string guide = read_text(kSource / "docs" / "user-guide.md");
  REQUIRE(guide.size() > 10000);
  std::size_t options = 0;
  for (const char* command : {"run", "pair", "study", "basis", "render"}) {
    const CliResult r = run_cli(dir, {command, "--help"});
    REQUIRE(r.status == 0);
    std::stringstream words(r.out);
    for (std::string w; words >> w;) {
      if (w.rfind("--", 0) != 0 || w.size() < 3 || !std::isalpha(static_cast<unsigned char>(w[2]))) continue;
      const std::string option = w.substr(0, w.find_first_not_of("abcdefghijklmnopqrstuvwxyz-", 2));
      if (option == "--help") continue;
      ++options;
      INFO("otmpm " << command << " " << option);
      CHECK(guide.find("`" + option) != std::string::npos);
    }
  }
  CHECK(options >= 30);
}
