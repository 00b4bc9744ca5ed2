// The promises about files (docs/stability.md, "What otmpm guarantees about
// your files") through the `otmpm` command, as a user meets them: each
// case's command line, its exit status (0 ok, 1 unstable, 2 bad input,
// 4 output failed; never a signal) and what is left on disk.
// The library-level checks of the same rules are in test_output_files.cpp.
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/io/results.hpp"

#include "cli_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <sys/file.h>
#include <sys/wait.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <set>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using otmpm::test::CliResult;
using otmpm::test::expect_exit;
using otmpm::test::has;
using otmpm::test::listing;
using otmpm::test::otmpm_in;
using otmpm::test::TempDir;

namespace {

const fs::path kSource = OTMPM_SOURCE_DIR;
const std::string kBinary = OTMPM_BINARY;
const std::string kDyka = (kSource / "examples/dyka.toml").string();

/// The number of frames and the status of a result file (HDF5 must open it).
std::pair<int, std::string> frames_and_status(const std::string& path) {
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE_MESSAGE(f >= 0, "cannot open " << path);
  const hid_t g = H5Gopen2(f, "frames", H5P_DEFAULT);
  hsize_t n = 0;
  H5Gget_num_objs(g, &n);
  H5Gclose(g);
  H5Fclose(f);
  return {static_cast<int>(n), otmpm::read_string_attribute(path, "status")};
}

int count(const std::string& text, const std::string& part) {
  int n = 0;
  for (auto at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++n;
  return n;
}

} // namespace

TEST_CASE("otmpm run --out res.xdmf (or output.file) exits 2 and writes nothing") {
  TempDir t("cli_d1");
  const CliResult a = otmpm_in(t, {"run", kDyka, "--quiet", "--out", "res.xdmf"});
  expect_exit(a, 2);
  CHECK(has(a.err, "res.xdmf"));
  const CliResult b = otmpm_in(t, {"run", kDyka, "--quiet", "--set", "output.file=res.xdmf"});
  expect_exit(b, 2);
  CHECK(listing(t.dir).empty());
}

TEST_CASE("a checkpoint resolving to the result file exits 2 naming both, before anything is written") {
  TempDir t("cli_d2");
  const CliResult a = otmpm_in(t, {"run", kDyka, "--quiet", "--out", "same.h5", "--set",
                                   "output.checkpoint_file=same.h5", "--set", "output.checkpoint_every=50"});
  expect_exit(a, 2);
  CHECK(has(a.err, "'same.h5' (RunOptions::out_file, otmpm run --out)"));
  CHECK(has(a.err, "'same.h5' (--set output.checkpoint_file)"));
  const CliResult b = otmpm_in(t, {"run", kDyka, "--quiet", "--out", "dyka.h5", "--set",
                                   "output.checkpoint_file=./dyka.h5", "--set", "output.checkpoint_every=50"});
  expect_exit(b, 2);
  CHECK(has(b.err, "same file"));
  CHECK(listing(t.dir).empty());
}

TEST_CASE("another scene's result and another run's sidecar survive, the same scene is re-run") {
  TempDir t("cli_replace");
  expect_exit(otmpm_in(t, {"run", kDyka, "--quiet", "--out", "x.h5"}), 0);
  const std::string h5 = otmpm::test::read_text(t.file("x.h5")), xdmf = otmpm::test::read_text(t.file("x.xdmf"));
  const CliResult other = otmpm_in(t, {"run", kDyka, "--quiet", "--out", "x.h5", "--set", "simulation.cfl=0.2"});
  expect_exit(other, 2);
  CHECK(has(other.err, "x.h5: the result file holds the results of another scene"));
  CHECK(otmpm::test::read_text(t.file("x.h5")) == h5);
  expect_exit(otmpm_in(t, {"run", kDyka, "--quiet", "--out", "x.txt"}), 0);
  CHECK(otmpm::test::read_text(t.file("x.xdmf")) == xdmf); // x.txt's sidecar is x.txt.xdmf
  expect_exit(otmpm_in(t, {"run", kDyka, "--quiet", "--out", "x.h5"}), 0); // identical scene: replaced
}

TEST_CASE("a result file an HDF5 writer holds gives a message that says it is locked") {
  TempDir t("cli_hdf5lock");
  const std::string path = t.file("held.h5");
  const hid_t f = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT); // HDF5 locks it
  REQUIRE(f >= 0);
  const CliResult r = otmpm_in(t, {"run", kDyka, "--quiet", "--out", "held.h5"});
  H5Fclose(f);
  expect_exit(r, 2);
  CHECK(has(r.err, "held.h5: the result file is locked by another process"));
}

TEST_CASE("a second run or a --restart of a running run exits 2 and changes nothing") {
  for (const bool hdf5_locking : {true, false}) {
    INFO("HDF5 file locking " << (hdf5_locking ? "on" : "off (HDF5_USE_FILE_LOCKING=FALSE)"));
    TempDir t(hdf5_locking ? "cli_d4" : "cli_d17");
    const std::vector<std::string> env = hdf5_locking ? std::vector<std::string>{}
                                                      : std::vector<std::string>{"HDF5_USE_FILE_LOCKING=FALSE"};
    // The Dyka bar at h = L/133 with frames every 2e-7 s: a few seconds.
    const std::vector<std::string> run{"run", (kSource / "examples/dyka/dyka_n133.toml").string(), "--quiet", "--out",
                                       t.file("run.h5"), "--set", "output.checkpoint_every=200", "--set",
                                       "output.every=2e-7"};
    std::vector<std::string> env_all = env;
    const pid_t first = otmpm::test::spawn_process(kBinary, run, t.file("first.out"), t.file("first.err"), env_all);
    REQUIRE(otmpm::test::wait_for_file(t.file("run.checkpoint.h5"), first, std::chrono::seconds(300)));
    const CliResult second = otmpm_in(t, run, env);
    const CliResult restart = otmpm_in(t, {"run", "--restart", t.file("run.checkpoint.h5"), "--quiet"}, env);
    const CliResult done = otmpm::test::wait_process(first, t.file("first.out"), t.file("first.err"));
    INFO("first run: " << done.err);
    REQUIRE(done.status == 0); // it was not disturbed
    expect_exit(second, 2);
    CHECK(has(second.err, "is being written by process " + std::to_string(first)));
    expect_exit(restart, 2);
    CHECK(has(restart.err, "is being written by process " + std::to_string(first)));
    const auto [frames, status] = frames_and_status(t.file("run.h5"));
    CHECK(status == "ok");
    CHECK(frames == 501);
    for (const std::string& name : listing(t.dir)) {
      CHECK_FALSE(has(name, "before-restart"));
      CHECK_FALSE(has(name, "otmpm-lock"));
      CHECK_FALSE(has(name, "otmpm-undo")); // the result file's undo journal ends with the run
    }
  }
}

TEST_CASE("--restart refuses a result file of another run at the recorded path and leaves it as it is") {
  TempDir t("cli_d3");
  expect_exit(otmpm_in(t, {"run", kDyka, "--quiet", "--out", "run.h5", "--set", "output.checkpoint_every=500"}), 0);
  expect_exit(otmpm_in(t, {"run", kDyka, "--quiet", "--out", "other.h5", "--set", "output.checkpoint_every=500"}), 0);
  fs::copy_file(t.file("other.h5"), t.file("run.h5"), fs::copy_options::overwrite_existing);
  const std::string before = otmpm::test::read_text(t.file("run.h5"));
  const CliResult r = otmpm_in(t, {"run", "--restart", t.file("run.checkpoint.h5"), "--quiet"});
  expect_exit(r, 2);
  CHECK(has(r.err, "is not the result file of the checkpoint's run"));
  CHECK(otmpm::test::read_text(t.file("run.h5")) == before);
}

TEST_CASE("a file size limit (ulimit -f, SIGXFSZ ignored: EFBIG) ends with exit 4 and a valid shorter file") {
  // No root needed: the shell lowers RLIMIT_FSIZE for otmpm alone.
  TempDir t("cli_d5");
  const std::string cmd = "trap '' XFSZ; ulimit -f 400; exec '" + kBinary + "' run '" + kDyka +
                          "' --quiet --out limited.h5 --set output.every=1e-6";
  const fs::path scratch = t.dir.parent_path() / "d5_io";
  fs::create_directories(scratch);
  const fs::path here = fs::current_path();
  fs::current_path(t.dir);
  const CliResult limited = otmpm::test::run_process("/bin/sh", {"-c", cmd}, scratch);
  fs::current_path(here);
  fs::remove_all(scratch);
  expect_exit(limited, 4);
  CHECK(std::regex_search(limited.err, std::regex("limited\\.h5: the file size limit of this process \\(RLIMIT_FSIZE, "
                                                  "ulimit -f\\) is [0-9]+ bytes")));
  CHECK(has(limited.out, "OUTPUT FAILED: "));
  const auto [frames, status] = frames_and_status(t.file("limited.h5"));
  CHECK(frames > 1);
  CHECK(frames < 101);
  CHECK(status.rfind("output error: step ", 0) == 0);
  CHECK(count(otmpm::test::read_text(t.file("limited.xdmf")), "<Time ") == frames);
}

TEST_CASE("a full file system (a 300 kB tmpfs in a user namespace: ENOSPC) ends with exit 4 and a valid file") {
  TempDir t("cli_d5fs");
  const std::string mnt = t.file("mnt");
  fs::create_directories(mnt);
  const std::string cmd = "mount -t tmpfs -o size=300k none '" + mnt + "' && cd '" + mnt + "' && '" + kBinary +
                          "' run '" + kDyka +
                          "' --quiet --out full.h5 --set output.every=1e-6; s=$?; "
                          "cp full.h5 full.xdmf ..; exit $s";
  if (std::system("unshare -rm true >/dev/null 2>&1") != 0) {
    MESSAGE("SKIPPED: unshare -rm (an unprivileged mount namespace) is not available here; "
            "the ulimit -f test covers the same path");
    return;
  }
  const fs::path scratch = t.dir.parent_path() / "d5fs_io";
  fs::create_directories(scratch);
  const CliResult full = otmpm::test::run_process("/usr/bin/unshare", {"-rm", "/bin/sh", "-c", cmd}, scratch);
  fs::remove_all(scratch);
  expect_exit(full, 4);
  CHECK(has(full.err, "free on its file system"));
  const auto [frames, status] = frames_and_status(t.file("full.h5"));
  CHECK(frames > 1);
  CHECK(status.rfind("output error: ", 0) == 0);
  CHECK(count(otmpm::test::read_text(t.file("full.xdmf")), "<Time ") == frames);
}

TEST_CASE("300 single-bit flips of a checkpoint: --restart exits 2 every time, never a signal") {
  TempDir t("cli_d6");
  expect_exit(otmpm_in(t, {"run", kDyka, "--quiet", "--out", "run.h5", "--set", "output.checkpoint_every=500"}), 0);
  const std::string good = otmpm::test::read_text(t.file("run.checkpoint.h5"));
  std::mt19937 rng(20);
  std::uniform_int_distribution<std::size_t> byte(0, good.size() - 1);
  int exit2 = 0;
  for (int i = 0; i < 300; ++i) {
    std::string bytes = good;
    const std::size_t at = byte(rng);
    bytes[at] = static_cast<char>(bytes[at] ^ (1 << (i % 8)));
    std::ofstream(t.file("flipped.checkpoint.h5"), std::ios::binary) << bytes;
    const CliResult r = otmpm_in(t, {"run", "--restart", t.file("flipped.checkpoint.h5"), "--quiet", "--out", "x.h5"});
    INFO("byte " << at << ": " << r.err);
    CHECK(r.signal == 0);
    exit2 += r.status == 2;
  }
  CHECK(exit2 == 300);
}

TEST_CASE("an instability at t = 0 prints the summary line, exits 1 and sets the status") {
  TempDir t("cli_d7");
  const CliResult r = otmpm_in(t, {"run", kDyka, "--quiet", "--out", "d7.h5", "--set", "body.bar.velocity=[1e300]"});
  expect_exit(r, 1);
  CHECK(has(r.out, "UNSTABLE: mpm npc lme: 0 steps, t = 0 s"));
  CHECK(otmpm::read_string_attribute(t.file("d7.h5"), "status").rfind("unstable: step 0, t = 0 s: ", 0) == 0);
}

TEST_CASE("a probe name with '/', '.' or NUL exits 2 naming the key") {
  TempDir t("cli_d8");
  for (const std::string name : {"a/b", "a.b", "a\\u0000b"}) {
    const CliResult r = otmpm_in(
        t, {"run", kDyka, "--quiet", "--set", "output.probes=[{name = \"" + name + "\", particle = \"leftmost\"}]"});
    expect_exit(r, 2);
    CHECK(has(r.err, "--set output.probes"));
    CHECK(has(r.err, "cannot name a probe"));
  }
  CHECK(listing(t.dir).empty());
}

TEST_CASE("a scene beyond memory exits 2 naming estimate and limit, otmpm basis --cells 1e9 too") {
  TempDir t("cli_d11");
  // 1e6 cells x 99 particles: under the 1e8 particle cap, about 30 GB.
  const CliResult big = otmpm_in(t, {"run", kDyka, "--quiet", "--set", "grid.cells=[1000000]", "--set",
                                     "grid.lower=[0.0]", "--set", "body.bar.particles_per_cell=99", "--set",
                                     "simulation.memory_limit=8e9"});
  expect_exit(big, 2);
  CHECK(has(big.err, "the run would need about"));
  CHECK(has(big.err, "more than the limit of 8 GB set by simulation.memory_limit"));
  const CliResult basis = otmpm_in(t, {"basis", "--kind", "linear", "--cells", "1000000000", "--out", "b.csv"});
  expect_exit(basis, 2);
  CHECK(has(basis.err, "--cells"));
  CHECK(listing(t.dir).empty());
}

TEST_CASE("young = 1e308 or dt = 1e-30 exits 2 naming the step estimate and simulation.max_steps") {
  TempDir t("cli_d12");
  const CliResult stiff = otmpm_in(t, {"run", kDyka, "--quiet", "--set", "material.steel.young=1e308"});
  expect_exit(stiff, 2);
  CHECK(has(stiff.err, "simulation.max_steps"));
  const CliResult tiny = otmpm_in(t, {"run", kDyka, "--quiet", "--set", "simulation.dt=1e-30"});
  expect_exit(tiny, 2);
  CHECK(has(tiny.err, "the run would take about 1e+26 steps"));
  CHECK(listing(t.dir).empty());
}

TEST_CASE("an unwritable checkpoint location exits 2 before the first step") {
  TempDir t("cli_d13");
  const CliResult r = otmpm_in(t, {"run", kDyka, "--quiet", "--out", "run.h5", "--set",
                                   "output.checkpoint_file=/proc/otmpm.checkpoint.h5", "--set",
                                   "output.checkpoint_every=50"});
  expect_exit(r, 2);
  CHECK(has(r.err, "--set output.checkpoint_file: cannot write checkpoints to '/proc/otmpm.checkpoint.h5'"));
  CHECK(listing(t.dir).empty());
}
