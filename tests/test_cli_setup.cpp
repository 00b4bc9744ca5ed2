// The set-up of `otmpm run` under hostile input (label scene): `run --check`
// makes the run's checks with the run's estimate before it allocates
// anything (a scene of over 1 TB is refused in under a second, so are a
// fixed step of 1e-30 s, a memory limit below the estimate and particle
// densities that make the first step 1e-155 s), a particle file's columns
// meet the ranges of the scene keys of the same quantity, a SIGTERM during
// the set-up stops the run before its initial frame, a SIGINT while a large
// particle file is read or seeded stops it within a block of rows, and a restart whose
// file body's particle file changed says so.
#include "cli_support.hpp"
#include "h5_support.hpp"
#include "otmpm/io/hdf5.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

namespace fs = std::filesystem;
using otmpm::test::CliResult;
using otmpm::test::TempDir;

namespace {

const std::string kBinary = OTMPM_BINARY;
const fs::path kExamples = fs::path(OTMPM_SOURCE_DIR) / "examples";

/// `otmpm ARGS` run in `dir`, with the seconds it took.
std::pair<CliResult, double> timed_in(const TempDir& dir, const std::vector<std::string>& args) {
  const fs::path cwd = fs::current_path();
  fs::current_path(dir.dir);
  const auto start = std::chrono::steady_clock::now();
  const CliResult r = otmpm::test::run_process(kBinary, args, dir.dir);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  fs::current_path(cwd);
  return {r, seconds};
}

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

/// A 2D elastic block scene (20 x 20 cells of [0, 1]^2) whose body is the
/// particle file `file` ("" : a box).
std::string block_scene(const std::string& file) {
  return "[simulation]\ndimension = 2\nintegrator = \"musl\"\nt_end = 0.002\ncfl = 0.3\n[basis]\nkind = \"linear\"\n"
         "[grid]\nlower = [0.0, 0.0]\nupper = [1.0, 1.0]\ncells = [20, 20]\n[[material]]\nname = \"m\"\n"
         "model = \"linear_elastic\"\ndensity = 1000.0\nyoung = 1.0e6\npoisson = 0.3\n[[body]]\nname = \"f\"\n"
         "material = \"m\"\n" +
         (file.empty() ? std::string("lower = [0.3, 0.3]\nupper = [0.6, 0.6]\n")
                       : "shape = \"file\"\nfile = \"" + file + "\"\n") +
         "velocity = [0.0, -1.0]\n[output]\nevery = 0.001\n";
}

/// n x n particles on [0.3, 0.6]^2 with the extra column `column` = `value` in every row.
void write_block(const std::string& path, int n, const std::string& column = "", const std::string& value = "") {
  std::ofstream out(path);
  out << "x, y, volume" << (column.empty() ? "" : ", " + column) << "\n";
  const double h = 0.3 / n;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      out << 0.3 + h * (i + 0.5) << ", " << 0.3 + h * (j + 0.5) << ", " << h * h
          << (column.empty() ? "" : ", " + value) << "\n";
}

/// The number after "about " on the line of stdout that starts with `label` (--check's report).
std::string about(const std::string& out, const std::string& label) {
  const auto line = out.find(label);
  REQUIRE(line != std::string::npos);
  const auto at = out.find("about ", line) + 6;
  return out.substr(at, out.find(' ', out.find(' ', at) + 1) - at);
}

} // namespace

TEST_CASE("run --check refuses at once what the run refuses, with the run's message and estimate") {
  TempDir dir("cli_check");
  std::ofstream(dir.file("block.toml")) << block_scene("");
  // Over 1 TB: 6.4e7 nodes of a consistent mass matrix (and 6e7 particles).
  const std::vector<std::string> huge{"--set", "grid.cells=[8000, 8000]", "--set", "simulation.mass=\"consistent\""};
  const std::vector<std::vector<std::string>> refused{
      huge, {"--set", "simulation.dt=1e-30"}, {"--set", "simulation.memory_limit=1e3"}};
  for (const auto& sets : refused) {
    CAPTURE(sets[1]);
    std::vector<std::string> check{"run", "--check", "block.toml"}, run{"run", "block.toml", "--quiet"};
    check.insert(check.end(), sets.begin(), sets.end());
    run.insert(run.end(), sets.begin(), sets.end());
    const auto checked = timed_in(dir, check), ran = timed_in(dir, run); // no structured bindings: clang captures none
    CHECK(checked.first.status == 2);
    CHECK(checked.second < 1.0); // nothing allocated
    CHECK(ran.first.status == 2);
    CHECK(checked.first.err == ran.first.err); // the run's check, its message
  }
  // The memory --check reports is the run's estimate: the one the run names when it refuses.
  const auto ok = timed_in(dir, {"run", "--check", "block.toml"});
  REQUIRE(ok.first.status == 0);
  const auto low = timed_in(dir, {"run", "block.toml", "--set", "simulation.memory_limit=1e3"});
  CHECK(has(low.first.err, "the run would need about " + about(ok.first.out, "  memory") + " of memory"));
}

TEST_CASE("a particle file's densities decide the first step: --check and the run refuse a 1e-155 s step") {
  // density 1e-300 in every row: the waves 1e151 times faster than the
  // material's; before, the run went on for ever at 0 % and --check said ok.
  TempDir dir("cli_density");
  std::ofstream(dir.file("s.toml")) << block_scene("tiny.csv");
  write_block(dir.file("tiny.csv"), 12, "density", "1e-300");
  for (const std::vector<std::string>& args : {std::vector<std::string>{"run", "--check", "s.toml"},
                                              std::vector<std::string>{"run", "s.toml", "--quiet"}}) {
    const auto run = timed_in(dir, args);
    const CliResult& r = run.first;
    CAPTURE(r.err);
    CHECK(r.status == 2);
    CHECK(run.second < 5.0);
    CHECK(has(r.err, "more than simulation.max_steps"));
  }
  // negative and zero densities, a negative plastic strain: exit 2 naming file, line and column
  for (const auto& bad : {std::tuple{"density", "-1000.0", "linear_elastic"}, std::tuple{"density", "0", "linear_elastic"},
                          std::tuple{"plastic_strain", "-5", "j2"}, std::tuple{"elastic_energy", "-1e6", "j2"}}) {
    const std::string column = std::get<0>(bad), value = std::get<1>(bad);
    CAPTURE(column);
    CAPTURE(value);
    write_block(dir.file("bad.csv"), 12, column, value);
    std::vector<std::string> args{"run", "s.toml", "--quiet", "--set", "body.f.file=\"bad.csv\""};
    if (std::string(std::get<2>(bad)) == "j2")
      args.insert(args.end(), {"--set", "material.m.model=\"j2\"", "--set", "material.m.yield_stress=1e5"});
    const CliResult r = timed_in(dir, args).first;
    CHECK(r.status == 2);
    CHECK(has(r.err, "bad.csv:2: column '" + std::string(column) + "': must be "));
    CHECK(!fs::exists(dir.file("out.h5")));
  }
}

TEST_CASE("SIGTERM during the set-up stops the run before its initial frame: exit 143, no frame written") {
  // 640,000 particles read from a file take seconds to set up; the signal
  // comes half a second after the start. Before, the run finished the
  // set-up, wrote the initial frame of every particle and only then stopped.
  TempDir dir("cli_setup_signal");
  std::ofstream(dir.file("s.toml")) << block_scene("big.csv");
  write_block(dir.file("big.csv"), 800);
  const std::string out = dir.file("stdout.txt"), err = dir.file("stderr.txt");
  const fs::path cwd = fs::current_path();
  fs::current_path(dir.dir);
  const pid_t pid = otmpm::test::spawn_process(kBinary, {"run", "s.toml", "--out", "r.h5"}, out, err);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ::kill(pid, SIGTERM);
  const CliResult r = otmpm::test::wait_process(pid, out, err);
  fs::current_path(cwd);
  CAPTURE(r.err);
  CHECK(r.status == 143);
  // in the scene reader's pass over the file, or after it (the seeding's)
  CHECK((has(r.err, "otmpm: interrupted while reading a particle file (SIGTERM); no result file was written") ||
         has(r.err, "otmpm: interrupted by SIGTERM at t = 0 s (step 0)")));
  if (fs::exists(dir.file("r.h5"))) { // interrupted after the file was created: no frame, status set
    const hid_t id = H5Fopen(dir.file("r.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    REQUIRE(id >= 0);
    const otmpm::h5::Handle file(id, H5Fclose);
    CHECK(otmpm::h5::read_string(file.get(), "status", "r.h5") == "interrupted");
    CHECK(otmpm::h5::link_names(otmpm::h5::open_group(file.get(), "frames", "r.h5").get(), "r.h5").empty());
  }
}

TEST_CASE("SIGINT while a large particle file is read or seeded ends the run within a block of rows: exit 130") {
  // 2.25e6 rows (about 55 MB): the scene reader's pass and the seeding's
  // each take seconds; before, a signal was acted on only after both. The
  // signal comes at 0.3, 1.5 and 3 s; the process must end within 4 s of it
  // (it takes one block of 65536 rows, milliseconds) and write nothing.
  TempDir dir("cli_setup_sigint");
  std::ofstream(dir.file("s.toml")) << block_scene("big.csv");
  write_block(dir.file("big.csv"), 1500);
  for (const int ms : {300, 1500, 3000}) {
    CAPTURE(ms);
    const std::string out = dir.file("stdout.txt"), err = dir.file("stderr.txt");
    const fs::path cwd = fs::current_path();
    fs::current_path(dir.dir);
    const pid_t pid = otmpm::test::spawn_process(kBinary, {"run", "s.toml", "--out", "r.h5"}, out, err);
    std::this_thread::sleep_for(std::chrono::milliseconds(ms));
    const auto sent = std::chrono::steady_clock::now();
    ::kill(pid, SIGINT);
    const CliResult r = otmpm::test::wait_process(pid, out, err);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
    fs::current_path(cwd);
    CAPTURE(r.err);
    CHECK(r.status == 130);
    CHECK(seconds < 4.0);
    CHECK(has(r.err, "otmpm: interrupted"));
    CHECK(!fs::exists(dir.file("r.h5")));
    CHECK(!fs::exists(dir.file("r.xdmf")));
  }
}

TEST_CASE("a restart whose file body's particle file changed or is gone says so, naming the body's key") {
  TempDir dir("cli_restart_file");
  std::ofstream(dir.file("s.toml")) << block_scene("p.csv");
  write_block(dir.file("p.csv"), 12);
  REQUIRE(timed_in(dir, {"run", "s.toml", "--quiet", "--out", "r.h5", "--set", "output.checkpoint_every=2"})
              .first.status == 0);
  // Unchanged: the restart runs.
  CHECK(timed_in(dir, {"run", "--restart", "r.checkpoint.h5", "--quiet", "--out", "a.h5"}).first.status == 0);
  write_block(dir.file("p.csv"), 6); // another mesh written over the file
  const CliResult changed = timed_in(dir, {"run", "--restart", "r.checkpoint.h5", "--quiet", "--out", "b.h5"}).first;
  CHECK(changed.status == 2);
  CHECK(has(changed.err, "key 'body.f.file': the particle file changed since the checkpoint was written (the "
                         "interrupted run read 144 particles"));
  fs::remove(dir.file("p.csv"));
  const CliResult gone = timed_in(dir, {"run", "--restart", "r.checkpoint.h5", "--quiet", "--out", "c.h5"}).first;
  CHECK(gone.status == 2);
  CHECK(has(gone.err, "no such particle file - a restart seeds the file bodies from their particle files again"));
}
