// What otmpm promises about the files a run writes (docs/stability.md,
// "What otmpm guarantees about your files"), checked through the library API:
// the names derived from the result file, collisions refused before anything
// is written, otmpm's own locks, the rules for replacing existing files, run
// ids and the restart's choice of previous results, checkpoint integrity, an
// unwritable checkpoint location found at start, an instability at t = 0,
// names that become HDF5 paths, memory and step estimates, diagnosis format
// and validate_scene for scenes built in code.
#include "otmpm/run/run.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/io/vtk.hpp"
#include "otmpm/scene/resources.hpp"
#include "otmpm/scene/validate.hpp"

#include "run_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

using namespace otmpm;
namespace fs = std::filesystem;
using otmpm::test::input_error_of;
using otmpm::test::small_scene;
using otmpm::test::TempDir;

namespace {

const fs::path kSource = OTMPM_SOURCE_DIR;

RunOptions to(const std::string& out, bool force = false) {
  RunOptions o;
  o.out_file = out;
  o.force = force;
  return o;
}

/// The names in a directory (hidden ones too), sorted.
std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void write_text(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

int frames_in(const std::string& path) {
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(f >= 0);
  const hid_t g = H5Gopen2(f, "frames", H5P_DEFAULT);
  hsize_t n = 0;
  H5Gget_num_objs(g, &n);
  H5Gclose(g);
  H5Fclose(f);
  return static_cast<int>(n);
}

} // namespace

// ---------------------------------------------------------------- names

TEST_CASE("output names: the sidecar, checkpoint and VTK files derive from the result path") {
  CHECK(output_base("dir/run.h5") == "dir/run");
  CHECK(output_base("run.txt") == "run.txt");
  CHECK(xdmf_path("run.h5") == "run.xdmf");
  CHECK(xdmf_path("x.txt") == "x.txt.xdmf"); // never the sidecar x.xdmf of another run's x.h5
  CHECK(default_checkpoint_path("run.h5") == "run.checkpoint.h5");
  const OutputFiles f = output_files("a/run.h5", "", "vtp");
  CHECK(f.pvd == "a/run.pvd");
  CHECK(f.vtk_dir == "a/run_vtk");
  CHECK(lock_path("a/run.h5") == (fs::absolute("a") / ".run.h5.otmpm-lock").string()); // made absolute
}

TEST_CASE("a result path with a sidecar's extension is refused before anything is written, on every route") {
  TempDir t("d1");
  for (const char* ext : {".xdmf", ".XMF", ".pvd", ".vtp", ".vtu"}) {
    const std::string res = t.file(std::string("res") + ext);
    INFO(res);
    CHECK(contains(input_error_of([&] { output_files(res, "", ""); }), res));
    CHECK(contains(input_error_of([&] { ResultWriter w(res, "", 1); }), res));
    CHECK(contains(input_error_of([&] { run_scene(small_scene(), to(res)); }), res));
    CHECK(contains(input_error_of([&] { run_scene(small_scene({"output.file=\"" + res + "\""})); }), res));
  }
  CHECK(listing(t.dir).empty());
}

TEST_CASE("a sidecar that resolves to the result file (a link) is refused") {
  TempDir t("d1link");
  const std::string res = t.file("a.h5");
  write_text(res, "not yet");
  fs::create_symlink(res, t.file("a.xdmf"));
  const std::string msg = input_error_of([&] { ResultWriter w(res, "", 1); });
  CHECK(contains(msg, "XDMF sidecar"));
  CHECK(contains(msg, "same file"));
  CHECK(slurp(res) == "not yet");
}

TEST_CASE("a checkpoint that resolves to the result file or its sidecar is refused, naming both") {
  TempDir t("d2");
  const std::string res = t.file("same.h5");
  auto refused = [&](const std::string& checkpoint, const std::string& part) {
    INFO(checkpoint);
    const Scene s = small_scene({"output.checkpoint_file=\"" + checkpoint + "\"", "output.checkpoint_every=50"});
    const std::string msg = input_error_of([&] { run_scene(s, to(res)); });
    CHECK(contains(msg, "same file"));
    CHECK(contains(msg, checkpoint));
    CHECK(contains(msg, part));
  };
  refused(res, "result file");
  refused((t.dir / "." / "same.h5").string(), "result file");
  refused(t.file("same.xdmf"), "XDMF sidecar");
  refused(t.file("same.xdmf.tmp"), "XDMF sidecar");
  fs::create_symlink(res, t.file("link.h5"));
  refused(t.file("link.h5"), "result file");
  CHECK(listing(t.dir) == std::set<std::string>{"link.h5"});
  // The same through output.file instead of RunOptions::out_file.
  const Scene s = small_scene({"output.file=\"" + res + "\"", "output.checkpoint_file=\"" + t.file("link.h5") + "\"",
                               "output.checkpoint_every=50"});
  CHECK(contains(input_error_of([&] { run_scene(s); }), "output.file"));
}

TEST_CASE("a hard link between result and checkpoint is the same file (same inode)") {
  TempDir t("d2hard");
  const std::string a = t.file("a.h5"), b = t.file("b.h5");
  write_text(a, "x");
  fs::create_hard_link(a, b);
  CHECK(same_file(a, b));
  CHECK_FALSE(same_file(a, t.file("c.h5")));
  OutputFiles f = output_files(a, b, "");
  CHECK_THROWS_AS(check_distinct(f), InputError);
}

// ---------------------------------------------------------------- locks

TEST_CASE("otmpm's lock refuses a second holder, names it, and does not depend on HDF5 locking") {
  TempDir t("lock");
  const std::string res = t.file("run.h5");
  ::setenv("HDF5_USE_FILE_LOCKING", "FALSE", 1);
  {
    OutputLock first({res});
    CHECK(fs::exists(lock_path(res)));
    const std::string msg = input_error_of([&] { OutputLock second({t.file("other.h5"), res}); });
    CHECK(contains(msg, res));
    CHECK(contains(msg, "process " + std::to_string(::getpid())));
    CHECK(contains(msg, "nothing was changed"));
    // The failed attempt took nothing: other.h5's lock is free again.
    CHECK_NOTHROW(OutputLock({t.file("other.h5")}));
    // A run writing res is refused before it changes anything.
    CHECK(contains(input_error_of([&] { run_scene(small_scene(), to(res)); }), "is being written by process"));
    CHECK_FALSE(fs::exists(res));
  }
  ::unsetenv("HDF5_USE_FILE_LOCKING");
  CHECK_FALSE(fs::exists(lock_path(res))); // released and removed
  CHECK_NOTHROW(OutputLock({res}));
}

TEST_CASE("one lock per file however its path is spelt: a relative, an absolute and a linked name share it") {
  TempDir t("lockname");
  const std::string res = t.file("run.h5"), link = t.file("link.h5");
  fs::create_symlink(res, link);
  const fs::path cwd = fs::current_path();
  fs::current_path(t.dir);
  {
    // One holder naming the file three ways takes one lock (a restart whose
    // --out names the checkpoint's result file relative to the directory).
    OutputLock one({"run.h5", res, link});
    CHECK(lock_path("run.h5") == lock_path(res));
    CHECK(lock_path(link) == lock_path(res));
    // Another holder is refused under any of the names.
    const pid_t child = ::fork();
    REQUIRE(child >= 0);
    if (child == 0) {
      int refused = 0;
      for (const std::string& name : {std::string("run.h5"), res, link}) {
        try {
          OutputLock other({name});
        } catch (const InputError&) {
          ++refused;
        }
      }
      ::_exit(refused == 3 ? 0 : 1);
    }
    int status = 0;
    REQUIRE(::waitpid(child, &status, 0) == child);
    CHECK((WIFEXITED(status) && WEXITSTATUS(status) == 0));
  }
  fs::current_path(cwd);
  CHECK_FALSE(fs::exists(lock_path(res)));
}

TEST_CASE("a lock whose holder died is free: lock_holder_of says so and the next holder takes it") {
  TempDir t("lockdead");
  const std::string res = t.file("run.h5");
  CHECK(lock_holder_of(res).empty()); // no lock file
  {
    OutputLock mine({res});
    CHECK(lock_holder_of(res).rfind("process " + std::to_string(::getpid()) + " on host ", 0) == 0);
  }
  // A holder killed while it holds the lock: its lock file stays, unlocked.
  const pid_t child = ::fork();
  REQUIRE(child >= 0);
  if (child == 0) {
    OutputLock held({res});
    ::_exit(0); // no destructor: the lock file is left behind, as by SIGKILL
  }
  int status = 0;
  REQUIRE(::waitpid(child, &status, 0) == child);
  REQUIRE(WIFEXITED(status));
  CHECK(fs::exists(lock_path(res)));
  CHECK(lock_holder_of(res).empty());
  CHECK_NOTHROW(OutputLock({res}));
}

TEST_CASE("a run removes its lock files and leaves only its outputs") {
  TempDir t("lockclean");
  const RunSummary s = run_scene(small_scene({"output.checkpoint_every=50", "output.format=[\"hdf5\", \"vtp\"]"}),
                                 to(t.file("run.h5")));
  CHECK(s.exit_code == 0);
  CHECK(listing(t.dir) ==
        std::set<std::string>{"run.h5", "run.xdmf", "run.checkpoint.h5", "run.pvd", "run_vtk"});
}

// ---------------------------------------------------------------- replacing

TEST_CASE("an existing result is replaced only for the identical scene or with force") {
  TempDir t("replace");
  const std::string res = t.file("run.h5");
  REQUIRE(run_scene(small_scene(), to(res)).exit_code == 0);
  const std::string first = slurp(res);
  // The identical scene reproduces the file: replaced.
  CHECK(run_scene(small_scene(), to(res)).exit_code == 0);
  // Another scene would lose it: refused, the file unchanged.
  const std::string again = slurp(res);
  const std::string msg = input_error_of([&] { run_scene(small_scene({"simulation.cfl=0.2"}), to(res)); });
  CHECK(contains(msg, "holds the results of another scene"));
  CHECK(contains(msg, "--force"));
  CHECK(slurp(res) == again);
  // With force it is replaced.
  CHECK(run_scene(small_scene({"simulation.cfl=0.2"}), to(res, true)).exit_code == 0);
  CHECK(contains(read_string_attribute(res, "scene"), "cfl = 0.2"));
  CHECK(first.size() > 0);
}

TEST_CASE("a file that is not otmpm's result is never replaced without force") {
  TempDir t("foreign");
  const std::string res = t.file("data.h5");
  write_text(res, "precious bytes");
  CHECK(contains(input_error_of([&] { run_scene(small_scene(), to(res)); }), "is not an otmpm result file"));
  CHECK(slurp(res) == "precious bytes");
  // An HDF5 file of someone else's.
  const hid_t f = H5Fcreate(res.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  H5Fclose(f);
  const std::string hdf5 = slurp(res);
  CHECK(contains(input_error_of([&] { run_scene(small_scene(), to(res)); }), "not written by otmpm"));
  CHECK(slurp(res) == hdf5);
  CHECK(listing(t.dir) == std::set<std::string>{"data.h5"});
}

TEST_CASE("--out x.txt does not touch another run's x.xdmf, a foreign sidecar is kept") {
  TempDir t("sidecar");
  REQUIRE(run_scene(small_scene(), to(t.file("x.h5"))).exit_code == 0);
  const std::string sidecar = slurp(t.file("x.xdmf"));
  REQUIRE(run_scene(small_scene(), to(t.file("x.txt"))).exit_code == 0);
  CHECK(slurp(t.file("x.xdmf")) == sidecar);
  CHECK(fs::exists(t.file("x.txt.xdmf")));
  // A result without extension would take x.xdmf: it belongs to x.h5's run, so it is refused.
  CHECK(contains(input_error_of([&] { run_scene(small_scene(), to(t.file("x"))); }), "x.xdmf"));
  CHECK(slurp(t.file("x.xdmf")) == sidecar);
  // A hand-written x2.xdmf (no otmpm run id) is not replaced either.
  write_text(t.file("y.xdmf"), "<Xdmf>mine</Xdmf>");
  CHECK(contains(input_error_of([&] { run_scene(small_scene(), to(t.file("y.h5"))); }), "y.xdmf"));
  CHECK(slurp(t.file("y.xdmf")) == "<Xdmf>mine</Xdmf>");
  CHECK_FALSE(fs::exists(t.file("y.h5")));
}

TEST_CASE("replacing: an otmpm sidecar whose result file is gone holds no data and is replaced") {
  TempDir t("orphan");
  REQUIRE(run_scene(small_scene(), to(t.file("r.h5"))).exit_code == 0);
  fs::remove(t.file("r.h5"));
  CHECK(run_scene(small_scene({"simulation.cfl=0.2"}), to(t.file("r.h5"))).exit_code == 0);
}

// ---------------------------------------------------------------- run ids

TEST_CASE("every run has its own run id, in the result file, the sidecar, the .pvd and the checkpoint") {
  TempDir t("runid");
  const Scene s = small_scene({"output.checkpoint_every=50", "output.format=[\"hdf5\", \"vtu\"]"});
  REQUIRE(run_scene(s, to(t.file("a.h5"))).exit_code == 0);
  REQUIRE(run_scene(s, to(t.file("b.h5"))).exit_code == 0);
  const std::string a = result_run_id(t.file("a.h5")), b = result_run_id(t.file("b.h5"));
  CHECK(std::regex_match(a, std::regex("[0-9a-f]{32}")));
  CHECK(a != b);
  CHECK(xml_run_id(t.file("a.xdmf")) == a);
  CHECK(xml_run_id(t.file("a.pvd")) == a);
  CHECK(xml_run_id(t.file("a_vtk/frame_000000.vtu")) == a);
  CHECK(checkpoint_run_id(t.file("a.checkpoint.h5")) == a);
  CHECK(read_checkpoint(t.file("a.checkpoint.h5")).run_id == a);
  CHECK(checkpoint_run_id(t.file("a.h5")) == ""); // a result file is not a checkpoint
}

TEST_CASE("a restart copies frames only from a result file of the checkpoint's run") {
  TempDir t("d3");
  const Scene s = small_scene({"output.checkpoint_every=50"});
  const std::string res = t.file("run.h5"), ck = t.file("run.checkpoint.h5");
  REQUIRE(run_scene(s, to(res)).exit_code == 0);
  const Checkpoint checkpoint = read_checkpoint(ck);
  // The result path now holds another run of the same scene (another run id).
  REQUIRE(run_scene(s, to(t.file("other.h5"))).exit_code == 0);
  fs::copy_file(t.file("other.h5"), res, fs::copy_options::overwrite_existing);
  const std::string before = slurp(res);
  const std::string msg = input_error_of([&] { restart_run(checkpoint); });
  CHECK(contains(msg, "not the result file of the checkpoint's run"));
  CHECK(slurp(res) == before); // not renamed, not changed
  CHECK(listing(t.dir) == std::set<std::string>{"run.h5", "run.xdmf", "run.checkpoint.h5", "other.h5", "other.xdmf",
                                                "other.checkpoint.h5"});
}

TEST_CASE("the real partial results are preferred to a stale .before-restart copy of the same run") {
  TempDir t("aside");
  const Scene s = small_scene({"output.checkpoint_every=50"});
  const std::string res = t.file("run.h5"), ck = t.file("run.checkpoint.h5");
  REQUIRE(run_scene(s, to(res)).exit_code == 0);
  const Checkpoint checkpoint = read_checkpoint(ck);
  const std::string aside = before_restart_path(res, checkpoint.run_id);
  fs::copy_file(res, aside);
  // The stale copy differs from the real file in frame 0's velocities.
  {
    const hid_t f = H5Fopen(aside.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    const hid_t d = H5Dopen2(f, "frames/000000/v", H5P_DEFAULT);
    std::vector<double> v(76, 123.0);
    H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
    H5Dclose(d);
    H5Fclose(f);
  }
  const RunSummary r = restart_run(checkpoint);
  REQUIRE(r.exit_code == 0);
  const hid_t f = H5Fopen(res.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t d = H5Dopen2(f, "frames/000000/v", H5P_DEFAULT);
  std::vector<double> v(76);
  H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
  H5Dclose(d);
  H5Fclose(f);
  CHECK(std::none_of(v.begin(), v.end(), [](double x) { return x == 123.0; }));
  CHECK_FALSE(fs::exists(aside));
}

TEST_CASE("a restart killed while copying continues from its .before-restart copy") {
  TempDir t("aside2");
  const Scene s = small_scene({"output.checkpoint_every=50"});
  const std::string res = t.file("run.h5"), ck = t.file("run.checkpoint.h5");
  REQUIRE(run_scene(s, to(res)).exit_code == 0);
  const Checkpoint checkpoint = read_checkpoint(ck);
  const int needed = static_cast<int>(checkpoint.group("recorder").integer("frames"));
  REQUIRE(needed >= 2);
  // As a killed restart leaves them: the full file set aside, a new file with no frames yet.
  fs::rename(res, before_restart_path(res, checkpoint.run_id));
  { ResultWriter w(res, checkpoint.scene, 1, ResultOptions{checkpoint.run_id, ""}); }
  REQUIRE(restart_run(checkpoint).exit_code == 0);
  CHECK(frames_in(res) == 6);
}

TEST_CASE("a path stored in a checkpoint never makes otmpm rename an unrelated file") {
  TempDir t("d3path");
  const Scene s = small_scene({"output.checkpoint_every=50"});
  REQUIRE(run_scene(s, to(t.file("run.h5"))).exit_code == 0);
  Checkpoint ck = read_checkpoint(t.file("run.checkpoint.h5"));
  const std::string victim = t.file("thesis.h5");
  write_text(victim, "years of work");
  ck.group("recorder").strings["result_file"] = victim;
  write_checkpoint(t.file("evil.checkpoint.h5"), ck); // a valid, sealed checkpoint naming the victim
  const std::string msg = input_error_of([&] { restart_run(read_checkpoint(t.file("evil.checkpoint.h5"))); });
  CHECK(contains(msg, victim));
  CHECK(slurp(victim) == "years of work");
  for (const std::string& name : listing(t.dir)) CHECK_FALSE(contains(name, "before-restart"));
}

// ---------------------------------------------------------------- checkpoints

TEST_CASE("every single-bit flip of a checkpoint is an InputError, found before HDF5 parses it") {
  TempDir t("flips");
  REQUIRE(run_scene(small_scene({"output.checkpoint_every=50"}), to(t.file("run.h5"))).exit_code == 0);
  const std::string good = slurp(t.file("run.checkpoint.h5"));
  const std::string damaged = t.file("damaged.h5");
  CHECK_NOTHROW(read_checkpoint(t.file("run.checkpoint.h5")));
  INFO(good.size() << " bytes");
  write_text(damaged, good);
  std::fstream file(damaged, std::ios::in | std::ios::out | std::ios::binary);
  REQUIRE(file);
  int refused = 0;
  for (std::size_t i = 0; i < good.size(); ++i) { // every byte, a different bit each time, flipped in place
    const char flipped = static_cast<char>(good[i] ^ (1 << (i % 8)));
    file.seekp(static_cast<std::streamoff>(i));
    file.put(flipped).flush();
    try {
      read_checkpoint(damaged);
    } catch (const InputError&) {
      ++refused;
    }
    file.seekp(static_cast<std::streamoff>(i));
    file.put(good[i]).flush();
  }
  file.close();
  CHECK(refused == static_cast<int>(good.size()));
  CHECK(slurp(damaged) == good);
  // Truncated by one byte, or one byte longer.
  write_text(damaged, good.substr(0, good.size() - 1));
  CHECK_THROWS_AS(read_checkpoint(damaged), InputError);
  write_text(damaged, good + "x");
  CHECK_THROWS_AS(read_checkpoint(damaged), InputError);
}

TEST_CASE("an unwritable checkpoint location is an InputError at start, before the result file exists") {
  TempDir t("d13");
  write_text(t.file("plain"), "a file, not a directory");
  for (const std::string& where : {t.file("plain/ck.h5"), std::string("/proc/otmpm_ck.h5"), t.file("nodir/ck.h5")}) {
    INFO(where);
    const Scene s = small_scene({"output.checkpoint_file=\"" + where + "\"", "output.checkpoint_every=50"});
    const std::string msg = input_error_of([&] { run_scene(s, to(t.file("run.h5"))); });
    CHECK(contains(msg, "output.checkpoint_file"));
    CHECK_FALSE(fs::exists(t.file("run.h5")));
  }
  CHECK(listing(t.dir) == std::set<std::string>{"plain"});
}

// ---------------------------------------------------------------- instability, names

TEST_CASE("an instability at t = 0 ends with a diagnosis naming step and time and the file's status set") {
  TempDir t("d7");
  const std::string res = t.file("run.h5");
  const RunSummary s = run_scene(small_scene({"body.bar.velocity=[1e300]"}), to(res));
  CHECK(s.exit_code == 1);
  CHECK(s.status.rfind("unstable: step 0, t = 0 s: ", 0) == 0);
  CHECK(read_string_attribute(res, "status") == s.status);
  CHECK(contains(summary_line(s), "UNSTABLE: "));
}

TEST_CASE("diagnoses give times with significant digits (never %f) and always step and time") {
  TempDir t("d18");
  // At 1e6 m/s the bar leaves the grid within nanoseconds: %f would print t = 0.000000.
  const RunSummary s = run_scene(small_scene({"initial_velocity.0.velocity=[-1e6]"}), to(t.file("run.h5")));
  REQUIRE(s.exit_code == 1);
  INFO(s.status);
  CHECK(std::regex_search(s.status, std::regex("^unstable: step [0-9]+, t = [0-9.]+e-[0-9]+ s: ")));
  CHECK_FALSE(contains(s.status, "0.000000"));
}

TEST_CASE("probe names that cannot be HDF5 names are refused by the reader at their key") {
  for (const std::string name : {"a/b", "a.b", ".", "..", "a\\u0000b", " a", "a ", "tab\\tname"}) {
    INFO(name);
    const std::string text = slurp((kSource / "tests/scenes/good_minimal.toml").string());
    const std::string bad = std::regex_replace(text, std::regex("name = \"A\""), "name = \"" + name + "\"");
    REQUIRE(bad != text);
    const std::string msg = input_error_of([&] { parse_scene(bad, "probe.toml"); });
    CHECK(std::regex_search(msg, std::regex("^probe\\.toml:[0-9]+: key 'output\\.probes.*name'")));
    CHECK(contains(msg, "cannot name a probe"));
  }
  CHECK(invalid_name_reason("point A-1_(x)") == "");
  CHECK(invalid_name_reason(std::string(256, 'a')) != "");
}

TEST_CASE("output.format: hdf5 always, at most one of vtp and vtu, read with FILE:LINE") {
  auto msg = [](const std::string& value) {
    return input_error_of([&] {
      load_scene((kSource / "tests/scenes/good_minimal.toml").string(), {"output.format=" + value});
    });
  };
  CHECK(contains(msg("[\"vtp\"]"), "must contain \"hdf5\""));
  CHECK(contains(msg("[\"hdf5\", \"vtp\", \"vtu\"]"), "choose one"));
  CHECK(contains(msg("[\"hdf5\", \"vtk\"]"), "unknown format"));
  CHECK(contains(msg("[\"hdf5\", \"hdf5\"]"), "twice"));
  CHECK(contains(msg("3"), "expected an array of strings"));
  const Scene s = load_scene((kSource / "tests/scenes/good_minimal.toml").string(), {"output.format=[\"hdf5\", \"vtu\"]"});
  CHECK(vtk_format(s.output) == "vtu");
  CHECK(vtk_format(small_scene().output) == "");
}

// ---------------------------------------------------------------- resources

TEST_CASE("a run whose memory estimate exceeds the limit is refused before it allocates") {
  const Scene s = small_scene({"simulation.memory_limit=1e6"});
  const std::string msg = input_error_of([&] { RunOptions o;
    o.write_results = false;
    run_scene(s, o); });
  CHECK(contains(msg, "simulation.memory_limit"));
  CHECK(contains(msg, "would need about"));
  CHECK(contains(msg, "1 MB"));
  // Under the particle cap (1e8) but far beyond this machine's memory.
  const Scene big = small_scene({"grid.cells=[1000000]", "body.bar.particles_per_cell=99"});
  const ResourceEstimate e = estimate_resources(big);
  CHECK(e.particles > 9e7);
  CHECK(e.bytes > 9e7 * 70);
  if (e.bytes > available_memory()) CHECK_THROWS_AS(check_resources(big), InputError);
  // The estimate stays above what a run measured (docs/stability.md): 1D LME, 1.28e6 particles, 406 MB.
  const Scene measured = small_scene({"grid.cells=[400000]", "body.bar.particles_per_cell=4"});
  CHECK(estimate_resources(measured).bytes > 406e6);
}

TEST_CASE("a run whose step estimate exceeds simulation.max_steps is refused, the key raises the limit") {
  auto msg = [](const std::vector<std::string>& sets) { return input_error_of([&] { check_resources(small_scene(sets)); }); };
  CHECK(contains(msg({"material.steel.young=1e308"}), "simulation.cfl"));
  CHECK(contains(msg({"material.steel.young=1e308"}), "max_steps"));
  CHECK(contains(msg({"simulation.dt=1e-30"}), "1e+25 steps"));
  CHECK_NOTHROW(check_resources(small_scene({"simulation.dt=1e-10", "simulation.max_steps=200000"})));
  CHECK(estimate_resources(small_scene({"simulation.dt=1e-10"})).steps == 100000);
  // The CFL estimate is t_end over the engine's first step; later steps differ
  // as the wave speed changes. On the Dyka bar: within 10 %.
  TempDir t("d12");
  const RunSummary run = run_scene(small_scene(), to(t.file("run.h5")));
  CHECK(std::abs(estimate_resources(small_scene()).steps - run.steps) <= 0.1 * run.steps);
}

// ---------------------------------------------------------------- validate_scene

TEST_CASE("validate_scene makes every check of the reader on a Scene built in code") {
  const Scene good = small_scene();
  CHECK_NOTHROW(validate_scene(good, 1));
  auto refused = [&](auto change, const std::string& key) {
    Scene s = good;
    s.where.clear(); // as built in code: messages name the key only
    change(s);
    const std::string msg = input_error_of([&] { validate_scene(s, 1); });
    INFO(msg);
    CHECK(contains(msg, "key '" + key));
  };
  refused([](Scene& s) { s.bodies[0].particles_per_cell = 3000000; }, "body.bar.particles_per_cell");
  refused([](Scene& s) { s.output.fields.push_back("pressure"); }, "output.fields");
  refused([](Scene& s) { s.output.fields.push_back("v"); }, "output.fields");
  refused([](Scene& s) { s.output.probes[0].particle = "middle"; }, "output.probes.A.particle");
  refused([](Scene& s) { s.output.probes[0].name = "a/b"; }, "output.probes.a/b.name");
  refused([](Scene& s) { s.output.probes.push_back(s.output.probes[0]); }, "output.probes.A.name");
  refused([](Scene& s) { s.simulation.energy_limit = INFINITY; }, "simulation.energy_limit");
  refused([](Scene& s) { s.simulation.max_steps = 0; }, "simulation.max_steps");
  refused([](Scene& s) { s.simulation.memory_limit = -1; }, "simulation.memory_limit");
  refused([](Scene& s) { s.simulation.integrator = "otm"; }, "simulation.integrator");
  refused([](Scene& s) { s.output.file = ""; }, "output.file");
  refused([](Scene& s) { s.output.checkpoint_every = -1; }, "output.checkpoint_every");
  refused([](Scene& s) { s.output.checkpoint_file = s.output.file; }, "output.checkpoint_file");
  refused([](Scene& s) { s.output.formats = {"vtp"}; }, "output.format");
  refused([](Scene& s) { s.materials.push_back(s.materials[0]); }, "material.steel.name");
  refused(
      [](Scene& s) {
        TractionSection traction;
        traction.function = "sine";
        s.tractions.push_back(traction);
      },
      "traction.0.function");
  refused([](Scene& s) { s.grid.cells[0] = 200000000; }, "grid.cells");
  refused([](Scene& s) { s.basis.kind = "ugimp"; s.grid.kind = "perturbed"; }, "basis.kind");
}

// ---------------------------------------------------------------- sidecar and VTK content

TEST_CASE("the sidecar gives each Polyvertex topology its connectivity (ParaView's Xdmf3 readers need it)") {
  TempDir t("xdmf");
  REQUIRE(run_scene(small_scene(), to(t.file("run.h5"))).exit_code == 0);
  const std::string xdmf = slurp(t.file("run.xdmf"));
  CHECK(contains(xdmf, "<Topology TopologyType=\"Polyvertex\" NumberOfElements=\"76\" NodesPerElement=\"1\">"));
  CHECK(contains(xdmf, "NumberType=\"Int\" Precision=\"8\" Format=\"HDF\">run.h5:/xdmf/vertices_76</DataItem>"));
  const hid_t f = H5Fopen(t.file("run.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t d = H5Dopen2(f, "xdmf/vertices_76", H5P_DEFAULT);
  std::vector<long long> ids(76);
  H5Dread(d, H5T_NATIVE_LLONG, H5S_ALL, H5S_ALL, H5P_DEFAULT, ids.data());
  H5Dclose(d);
  H5Fclose(f);
  for (int i = 0; i < 76; ++i) CHECK(ids[static_cast<std::size_t>(i)] == i);
}

TEST_CASE("VTK output: one file per frame with the frame's fields, listed with its time in the .pvd") {
  TempDir t("vtk");
  REQUIRE(run_scene(small_scene({"output.format=[\"hdf5\", \"vtp\"]"}), to(t.file("run.h5"))).exit_code == 0);
  const std::string pvd = slurp(t.file("run.pvd"));
  for (int i = 0; i < 6; ++i) {
    const std::string name = "run_vtk/frame_00000" + std::to_string(i) + ".vtp";
    CHECK(contains(pvd, "file=\"" + name + "\""));
    const std::string vtp = slurp(t.file(name));
    CHECK(contains(vtp, "<VTKFile type=\"PolyData\""));
    CHECK(contains(vtp, "NumberOfPoints=\"76\" NumberOfVerts=\"76\""));
    CHECK(contains(vtp, "Name=\"v\" NumberOfComponents=\"1\""));
    CHECK(contains(vtp, "Name=\"stress\" NumberOfComponents=\"1\""));
  }
  CHECK(contains(pvd, "timestep=\"0\""));
  CHECK(std::regex_search(pvd, std::regex("timestep=\"1(\\.0000000000000001)?e-05\"")));
  CHECK_FALSE(fs::exists(t.file("run_vtk/frame_000006.vtp")));
}
