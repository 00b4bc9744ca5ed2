// `otmpm run --restart`: a run with output.checkpoint_every is
// killed with SIGKILL by the test once a checkpoint exists, restarted from
// the checkpoint alone, and its result file - every frame dataset, every probe
// sample, the summary attributes and the errors, everything but wall times -
// must equal that of an uninterrupted run bit for bit. A completed run
// restarted from its last checkpoint must reproduce the frames it wrote after
// that checkpoint. A missing or damaged checkpoint, a missing result file of
// the interrupted run and wrong options give exit status 2 and a message
// naming the file. SIGINT and SIGTERM stop a run (and a pair) cleanly: exit
// status 130/143, a valid result file with status "interrupted", a last
// checkpoint when checkpointing is on, from which the restart equals the
// uninterrupted run.
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/io/results.hpp"

#include "cli_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>


namespace fs = std::filesystem;
using otmpm::test::CliResult;
using otmpm::test::TempDir;

namespace {

const fs::path kSource = OTMPM_SOURCE_DIR;
const std::string kBinary = OTMPM_BINARY;
/// Every particle field a frame can hold, so that the whole final state is compared.
const std::string kAllFields =
    "output.fields=[\"x\", \"v\", \"a\", \"stress\", \"strain\", \"F\", \"density\", \"volume\", \"mass\", "
    "\"displacement\"]";


/// Starts `otmpm ARGS` (one OpenMP thread), stdout to /dev/null and stderr to `err_file`; returns its pid.
pid_t spawn(const std::vector<std::string>& args, const std::string& err_file) {
  return otmpm::test::spawn_process(kBinary, args, "/dev/null", err_file);
}

/// Runs `otmpm ARGS` to completion: exit status and stderr.
otmpm::test::CliResult run_cli(const TempDir& dir, const std::vector<std::string>& args) {
  return otmpm::test::run_process(kBinary, args, dir.dir);
}

/// Everything in an HDF5 file by path ("/frames/000003/x", "/@steps"): the
/// bytes of each dataset (with its shape) and of each attribute, except the
/// wall times, which differ between any two runs.
using Snapshot = std::map<std::string, std::string>;

/// Attributes that differ between any two runs: wall times, and the run id
/// (an interrupted and restarted run keeps its id; the uninterrupted run has its own).
bool is_wall_time(const std::string& attribute) {
  return attribute == "wall_seconds" || attribute.rfind("seconds_", 0) == 0 || attribute == "run_id";
}

template <class T> std::string bytes_of(const T* data, std::size_t n) {
  return std::string(reinterpret_cast<const char*>(data), n * sizeof(T));
}

void snapshot_attributes(hid_t object, const std::string& path, const std::string& file, Snapshot& s) {
  for (const std::string& a : otmpm::h5::attribute_names(object, file)) {
    if (is_wall_time(a)) continue;
    if (otmpm::h5::attribute_class(object, a, file) == H5T_STRING) {
      s[path + "@" + a] = otmpm::h5::read_string(object, a, file);
    } else {
      const double v = otmpm::h5::read_double(object, a, file);
      s[path + "@" + a] = bytes_of(&v, 1);
    }
  }
}

void snapshot_group(hid_t group, const std::string& path, const std::string& file, Snapshot& s) {
  snapshot_attributes(group, path, file, s);
  for (const std::string& name : otmpm::h5::link_names(group, file)) {
    const hid_t object = H5Oopen(group, name.c_str(), H5P_DEFAULT);
    REQUIRE(object >= 0);
    const std::string child = path + "/" + name;
    if (H5Iget_type(object) == H5I_GROUP) {
      snapshot_group(object, child, file, s);
    } else {
      snapshot_attributes(object, child, file, s);
      if (otmpm::h5::dataset_class(group, name, file) == H5T_INTEGER) { // the sidecar's vertex ids
        const auto m = otmpm::h5::read_integer_matrix(group, name, file);
        const hsize_t shape[2] = {m.rows, m.cols};
        s[child] = bytes_of(shape, 2) + bytes_of(m.values.data(), m.values.size());
      } else {
        const auto m = otmpm::h5::read_double_matrix(group, name, file);
        const hsize_t shape[2] = {m.rows, m.cols};
        s[child] = bytes_of(shape, 2) + bytes_of(m.values.data(), m.values.size());
      }
    }
    H5Oclose(object);
  }
}

Snapshot snapshot(const std::string& file) {
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE_MESSAGE(f >= 0, "cannot open " << file);
  Snapshot s;
  snapshot_group(f, "", file, s);
  H5Fclose(f);
  return s;
}

/// The two result files hold the same frames, probes and summary, bit for bit.
void check_same_results(const std::string& expected_file, const std::string& actual_file) {
  const Snapshot expected = snapshot(expected_file), actual = snapshot(actual_file);
  REQUIRE(expected.count("@status") == 1);
  CHECK(expected.at("@status") == "ok");
  CHECK(expected.size() == actual.size());
  for (const auto& [key, bytes] : expected) {
    const std::string& what = key; // INFO captures a variable, not a binding (clang 14)
    INFO(what);
    REQUIRE(actual.count(key) == 1);
    CHECK((actual.at(key) == bytes));
  }
}

/// Number of frames in a result file, and an integer root attribute of an HDF5 file.
std::size_t frame_count(const std::string& file) {
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(f >= 0);
  const hid_t g = H5Gopen2(f, "frames", H5P_DEFAULT);
  const std::size_t n = otmpm::h5::link_names(g, file).size();
  H5Gclose(g);
  H5Fclose(f);
  return n;
}

std::int64_t checkpoint_integer(const std::string& file, const std::string& group, const std::string& name) {
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(f >= 0);
  const hid_t g = H5Gopen2(f, group.c_str(), H5P_DEFAULT);
  const std::int64_t v = otmpm::h5::read_integer(g, name, file);
  H5Gclose(g);
  H5Fclose(f);
  return v;
}

using otmpm::test::wait_for_file;

std::vector<std::string> with(std::vector<std::string> args, const std::vector<std::string>& more) {
  args.insert(args.end(), more.begin(), more.end());
  return args;
}

/// The manufactured-solution plate (ul, unified, bspline2, 2D) at 8 x 8
/// cells: 35 steps, checkpoints after 10, 20 and 30, frames every 2.5e-4 s,
/// every output field, and the `more` arguments.
std::vector<std::string> checkpointed_plate(const std::vector<std::string>& more) {
  return with({"run", (kSource / "examples/mms_plate.toml").string(), "--quiet", "--set", "grid.cells=[8, 8]", "--set",
               "output.every=2.5e-4", "--set", "output.checkpoint_every=10", "--set", kAllFields},
              more);
}

} // namespace

TEST_CASE("otmpm run killed by SIGKILL and restarted equals an uninterrupted run, bit for bit") {
  TempDir dir("kill");
  // Dyka bar, h = L/133: 5043 steps (about 1 s), a frame every 50 steps, probe A, exact errors.
  const std::vector<std::string> scene{"run", (kSource / "examples/dyka/dyka_n133.toml").string(), "--quiet",
                                       "--set", "output.checkpoint_every=500", "--set", kAllFields};
  const std::string full = dir.file("full.h5"), run = dir.file("run.h5");
  REQUIRE(run_cli(dir, with(scene, {"--out", full})).status == 0);

  const std::string checkpoint = dir.file("run.checkpoint.h5");
  const pid_t pid = spawn(with(scene, {"--out", run}), dir.file("killed.txt"));
  const bool started = wait_for_file(checkpoint, pid, std::chrono::seconds(300));
  std::this_thread::sleep_for(std::chrono::milliseconds(50)); // let it write frames past the checkpoint
  ::kill(pid, SIGKILL);
  int wstatus = 0;
  REQUIRE(waitpid(pid, &wstatus, 0) == pid);
  REQUIRE_MESSAGE(started, "the run ended before it wrote a checkpoint");
  REQUIRE_MESSAGE(WIFSIGNALED(wstatus), "the run finished before the test could kill it");
  CHECK(WTERMSIG(wstatus) == SIGKILL);
  otmpm::roll_back_interrupted_flush(run); // what every otmpm reader does first: a flush the kill cut is undone
  const auto step = checkpoint_integer(checkpoint, "engine", "step");
  const auto frames = checkpoint_integer(checkpoint, "recorder", "frames");
  const std::size_t written = frame_count(run);
  INFO("checkpoint at step " << step << " with " << frames << " frames; the killed run wrote " << written);
  CHECK(step % 500 == 0);
  CHECK(step < 5043);
  CHECK(written >= static_cast<std::size_t>(frames));

  // Restart from the checkpoint alone: the result file is continued in place.
  const otmpm::test::CliResult r = run_cli(dir, {"run", "--restart", checkpoint, "--quiet"});
  INFO(r.err);
  REQUIRE(r.status == 0);
  check_same_results(full, run);
  CHECK_FALSE(fs::exists(run + ".before-restart"));
}

TEST_CASE("a completed run restarted from its last checkpoint rewrites the later frames identically") {
  TempDir dir("completed");
  // The manufactured-solution plate (ul, unified, bspline2, 2D) at 8 x 8 cells:
  // 35 steps, checkpoints after 10, 20 and 30, frames every 2.5e-4 s.
  const std::vector<std::string> scene =
      checkpointed_plate({"--set", "output.probes=[{name = \"c\", particle = \"nearest\", at = [0.5, 0.5]}]"});
  const std::string full = dir.file("plate.h5"), again = dir.file("again.h5");
  REQUIRE(run_cli(dir, with(scene, {"--out", full})).status == 0);
  const std::string checkpoint = dir.file("plate.checkpoint.h5");
  REQUIRE(checkpoint_integer(checkpoint, "engine", "step") == 30);
  CHECK(frame_count(full) > static_cast<std::size_t>(checkpoint_integer(checkpoint, "recorder", "frames")));
  const otmpm::test::CliResult r = run_cli(dir, {"run", "--restart", checkpoint, "--out", again, "--quiet"});
  INFO(r.err);
  REQUIRE(r.status == 0);
  check_same_results(full, again);
  CHECK(fs::exists(full)); // --out elsewhere: the interrupted run's file is left as it was
}

TEST_CASE("a restart whose --out names the interrupted run's file by another spelling continues it in place") {
  TempDir dir("respelt");
  // The first run names its file relatively; the checkpoint records it absolute.
  const std::vector<std::string> scene = checkpointed_plate({});
  REQUIRE(otmpm::test::otmpm_in(dir, with(scene, {"--out", "plate.h5"})).status == 0);
  const std::string full = dir.file("full.h5");
  fs::copy_file(dir.file("plate.h5"), full);
  for (const std::string& out : {std::string("plate.h5"), std::string("./plate.h5"), dir.file("plate.h5")}) {
    INFO("--out " << out);
    const otmpm::test::CliResult r =
        otmpm::test::otmpm_in(dir, {"run", "--restart", "plate.checkpoint.h5", "--out", out, "--quiet"});
    INFO(r.err);
    REQUIRE(r.status == 0); // it was refused: "is being written by process <its own pid>"
    check_same_results(full, dir.file("plate.h5"));
  }
}

TEST_CASE("a result file written before the impact and friction series existed is continued, those read as 0") {
  TempDir dir("oldseries");
  // The Taylor bar at h = R/2 on its frictionless wall (1147 steps), a checkpoint every 500 steps.
  const std::string scene = (kSource / "examples/taylor_bar.toml").string();
  const std::string run = dir.file("run.h5"), full = dir.file("full.h5");
  REQUIRE(run_cli(dir, {"run", scene, "--quiet", "--out", run, "--set", "output.checkpoint_every=500", "--set",
                        "body.bar.file=" + (kSource / "examples/taylor_bar/quarter_h1.6.csv").string(), "--set",
                        "grid.lower=[0, 0, -0.0032]", "--set", "grid.upper=[0.0144, 0.0144, 0.0368]", "--set",
                        "grid.cells=[9, 9, 25]"})
              .status == 0);
  fs::copy_file(run, full);
  const std::string checkpoint = dir.file("run.checkpoint.h5");
  const auto frames = static_cast<std::size_t>(checkpoint_integer(checkpoint, "recorder", "frames"));
  REQUIRE(frames > 0);
  { // the file as an older otmpm wrote it: /energy without the two columns
    const hid_t f = H5Fopen(run.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    REQUIRE(f >= 0);
    CHECK(H5Ldelete(f, "energy/impact", H5P_DEFAULT) >= 0);
    CHECK(H5Ldelete(f, "energy/friction", H5P_DEFAULT) >= 0);
    H5Fclose(f);
  }
  const otmpm::test::CliResult r = run_cli(dir, {"run", "--restart", checkpoint, "--quiet"});
  INFO(r.err);
  REQUIRE(r.status == 0);
  const Snapshot expected = snapshot(full), actual = snapshot(run);
  CHECK(expected.size() == actual.size());
  for (const auto& [key, bytes] : expected) {
    const std::string& what = key;
    INFO(what);
    REQUIRE(actual.count(key) == 1);
    if (key != "/energy/impact" && key != "/energy/friction") CHECK((actual.at(key) == bytes));
  }
  const hid_t a = H5Fopen(run.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), e = H5Fopen(full.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  for (const char* column : {"energy/impact", "energy/friction"}) {
    INFO(column);
    const auto got = otmpm::h5::read_double_matrix(a, column, run), want = otmpm::h5::read_double_matrix(e, column, full);
    REQUIRE(got.values.size() == want.values.size());
    for (std::size_t i = 0; i < got.values.size(); ++i)
      CHECK(got.values[i] == (i < frames ? 0.0 : want.values[i])); // the restart books from its checkpoint's value
  }
  H5Fclose(a), H5Fclose(e);
}

TEST_CASE("a single-precision file with symmetric tensors is continued by a restart with the same layout and bits") {
  TempDir dir("completed_single");
  // As above, with output.precision = "single" and output.symmetric_tensors:
  // the frames copied from the first file keep their float values and the
  // components attribute (check_same_results compares attributes too).
  const std::vector<std::string> scene =
      checkpointed_plate({"--set", "output.precision=single", "--set", "output.symmetric_tensors=true"});
  const std::string full = dir.file("plate.h5"), again = dir.file("again.h5");
  REQUIRE(run_cli(dir, with(scene, {"--out", full})).status == 0);
  const std::string checkpoint = dir.file("plate.checkpoint.h5");
  REQUIRE(checkpoint_integer(checkpoint, "recorder", "frames") > 0);
  const otmpm::test::CliResult r = run_cli(dir, {"run", "--restart", checkpoint, "--out", again, "--quiet"});
  INFO(r.err);
  REQUIRE(r.status == 0);
  check_same_results(full, again);
  const hid_t file = H5Fopen(again.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(file >= 0);
  const hid_t set = H5Dopen2(file, "/frames/000000/stress", H5P_DEFAULT); // a copied frame
  REQUIRE(set >= 0);
  const hid_t type = H5Dget_type(set);
  CHECK(H5Tget_size(type) == 4);
  CHECK(otmpm::h5::read_string(set, "components", again) == "xx xy yy zz"); // 2D: and plane strain's sigma_zz
  H5Tclose(type);
  H5Dclose(set);
  H5Fclose(file);
}

TEST_CASE("a compressed result file killed by SIGKILL is readable, and its restart equals the uninterrupted run") {
  TempDir dir("kill_compressed");
  // As the first test, with output.compression = 6: the killed run's file
  // opens with every frame it wrote, the restart copies the chunked, filtered
  // frames (their values) into a new compressed file, and the result equals
  // the uninterrupted compressed run bit for bit.
  const std::vector<std::string> scene{"run", (kSource / "examples/dyka/dyka_n133.toml").string(), "--quiet",
                                       "--set", "output.checkpoint_every=500", "--set", kAllFields,
                                       "--set", "output.compression=6"};
  const std::string full = dir.file("full.h5"), run = dir.file("run.h5");
  REQUIRE(run_cli(dir, with(scene, {"--out", full})).status == 0);
  const std::string checkpoint = dir.file("run.checkpoint.h5");
  const pid_t pid = spawn(with(scene, {"--out", run}), dir.file("killed.txt"));
  const bool started = wait_for_file(checkpoint, pid, std::chrono::seconds(300));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ::kill(pid, SIGKILL);
  int wstatus = 0;
  REQUIRE(waitpid(pid, &wstatus, 0) == pid);
  REQUIRE_MESSAGE(started, "the run ended before it wrote a checkpoint");
  REQUIRE_MESSAGE(WIFSIGNALED(wstatus), "the run finished before the test could kill it");
  const auto frames = checkpoint_integer(checkpoint, "recorder", "frames");
  REQUIRE(frames > 0);
  CHECK(!otmpm::result_run_id(run).empty()); // an otmpm reader: it undoes a flush the kill cut first
  CHECK(frame_count(run) >= static_cast<std::size_t>(frames));
  char last[64];
  std::snprintf(last, sizeof last, "/frames/%06lld/stress", static_cast<long long>(frames - 1));
  CHECK(snapshot(run).count(last) == 1); // the killed file reads back, its frames' values included
  const otmpm::test::CliResult r = run_cli(dir, {"run", "--restart", checkpoint, "--quiet"});
  INFO(r.err);
  REQUIRE(r.status == 0);
  check_same_results(full, run);
  // A copied frame is stored compressed like the frames the restart computed.
  const hid_t file = H5Fopen(run.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(file >= 0);
  for (const std::string frame : {"000000", "000001"}) {
    const hid_t set = H5Dopen2(file, ("/frames/" + frame + "/x").c_str(), H5P_DEFAULT);
    REQUIRE(set >= 0);
    const hid_t dcpl = H5Dget_create_plist(set);
    CHECK(H5Pget_layout(dcpl) == H5D_CHUNKED);
    unsigned flags = 0;
    std::size_t n = 1;
    unsigned level = 0;
    CHECK(H5Pget_nfilters(dcpl) == 2);
    CHECK(H5Pget_filter_by_id2(dcpl, H5Z_FILTER_DEFLATE, &flags, &n, &level, 0, nullptr, nullptr) >= 0);
    CHECK(level == 6);
    H5Pclose(dcpl);
    H5Dclose(set);
  }
  H5Fclose(file);
}

TEST_CASE("restart errors: exit status 2 and a message naming the file or option") {
  TempDir dir("errors");
  const std::string result = dir.file("bar.h5");
  REQUIRE(run_cli(dir, {"run", (kSource / "examples/dyka.toml").string(), "--quiet", "--out", result, "--set",
                        "output.checkpoint_every=200"})
              .status == 0);
  const std::string checkpoint = dir.file("bar.checkpoint.h5");
  REQUIRE(fs::exists(checkpoint));

  auto expect_error = [&](const std::vector<std::string>& args, const std::string& text) {
    const otmpm::test::CliResult r = run_cli(dir, args);
    INFO(r.err);
    CHECK(r.status == 2);
    CHECK(r.err.find(text) != std::string::npos);
  };
  const std::string missing = dir.file("missing.checkpoint.h5");
  expect_error({"run", "--restart", missing}, missing);

  const std::string truncated = dir.file("truncated.checkpoint.h5");
  fs::copy_file(checkpoint, truncated);
  fs::resize_file(truncated, fs::file_size(checkpoint) / 2);
  expect_error({"run", "--restart", truncated, "--out", dir.file("t.h5")}, truncated);

  const std::string scene_file = (kSource / "examples/dyka.toml").string();
  // CLI11's messages: a restart takes neither a scene nor --set.
  expect_error({"run", "--restart", checkpoint, "--set", "simulation.cfl=0.2"}, "excludes");
  expect_error({"run", scene_file, "--restart", checkpoint}, "excludes");
  expect_error({"pair", "--restart", checkpoint}, "--restart");

  // The interrupted run's result file holds the frames before the checkpoint.
  fs::remove(result);
  expect_error({"run", "--restart", checkpoint}, result + ": the result file of the interrupted run is missing");
}

namespace {

/// Status attribute of a result file, read while nothing else has it open.
std::string status_of(const std::string& file) {
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE_MESSAGE(f >= 0, "cannot open " << file);
  const std::string status = otmpm::h5::read_string(f, "status", file);
  H5Fclose(f);
  return status;
}

/// Starts `otmpm ARGS`, waits until `file` exists, sends `sig`; returns the exit status.
int interrupt_when(const TempDir& dir, const std::vector<std::string>& args, const std::string& file, int sig) {
  const pid_t pid = spawn(args, dir.file("interrupted.txt"));
  const bool started = wait_for_file(file, pid, std::chrono::seconds(300));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ::kill(pid, sig);
  int wstatus = 0;
  REQUIRE(waitpid(pid, &wstatus, 0) == pid);
  REQUIRE_MESSAGE(started, "the run ended before " << file << " appeared");
  REQUIRE(WIFEXITED(wstatus));
  return WEXITSTATUS(wstatus);
}

} // namespace

TEST_CASE("SIGINT: exit 130, status interrupted, a last checkpoint, and the restart equals an uninterrupted run") {
  TempDir dir("sigint");
  const std::vector<std::string> scene{"run", (kSource / "examples/dyka/dyka_n133.toml").string(), "--quiet",
                                       "--set", "output.checkpoint_every=500", "--set", kAllFields};
  const std::string full = dir.file("full.h5"), run = dir.file("run.h5");
  REQUIRE(run_cli(dir, with(scene, {"--out", full})).status == 0);
  const std::string checkpoint = dir.file("run.checkpoint.h5");
  const int status = interrupt_when(dir, with(scene, {"--out", run}), checkpoint, SIGINT);
  CHECK(status == 130);
  CHECK(status_of(run) == "interrupted");
  // The last checkpoint is the state at the interruption, not the last multiple of 500.
  const auto step = checkpoint_integer(checkpoint, "engine", "step");
  CHECK(static_cast<double>(step) == otmpm::read_double_attribute(run, "steps"));
  CHECK(step < 5043);
  CHECK(frame_count(run) == static_cast<std::size_t>(checkpoint_integer(checkpoint, "recorder", "frames")));
  const CliResult r = run_cli(dir, {"run", "--restart", checkpoint, "--quiet"});
  INFO(r.err);
  REQUIRE(r.status == 0);
  check_same_results(full, run);
}

TEST_CASE("SIGTERM without checkpoints: exit 143, a readable result file with status interrupted and its frames") {
  TempDir dir("sigterm");
  const std::string run = dir.file("run.h5");
  const int status = interrupt_when(
      dir, {"run", (kSource / "examples/dyka/dyka_n133.toml").string(), "--out", run}, run, SIGTERM);
  CHECK(status == 143);
  CHECK(status_of(run) == "interrupted");
  CHECK(frame_count(run) >= 1);
  CHECK_FALSE(fs::exists(dir.file("run.checkpoint.h5")));
  std::ifstream err(dir.file("interrupted.txt"));
  std::stringstream text;
  text << err.rdbuf();
  CHECK(text.str().find("interrupted by SIGTERM") != std::string::npos);
  CHECK(text.str().find("status \"interrupted\"") != std::string::npos);
}

TEST_CASE("SIGINT during otmpm pair: the running half stops (status interrupted), the other is not started") {
  TempDir dir("pair");
  const std::string scene = dir.file("bar.toml");
  fs::copy_file(kSource / "examples/dyka/dyka_n133.toml", scene);
  const std::string mpm = dir.file("bar_mpm.h5");
  const int status = interrupt_when(dir, {"pair", scene, "--set", "output.file=\"" + dir.file("bar.h5") + "\""}, mpm,
                                    SIGINT);
  CHECK(status == 130);
  CHECK(status_of(mpm) == "interrupted");
  CHECK_FALSE(fs::exists(dir.file("bar_ul.h5")));
}
