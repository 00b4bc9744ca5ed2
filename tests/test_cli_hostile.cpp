// Hostile use of the `otmpm` command: result names that XML
// cannot quote, pictures written over results, render on files of other
// programs, FIFOs and devices where otmpm reads or writes files, an output
// directory removed during a run, memory running out at set-up, --set values
// with a line break, output.fields without x, 10 MB names, particle files
// with a byte-order mark. Each case is the command a user types, its exit
// status (never a signal, never a hang: commands that could block run under
// `timeout`) and what is left on disk.
#include "otmpm/io/results.hpp"

#include "cli_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <sys/stat.h>
#include <sys/wait.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using otmpm::test::CliResult;
using otmpm::test::expect_exit;
using otmpm::test::has;
using otmpm::test::listing;
using otmpm::test::otmpm_in;
using otmpm::test::quote;
using otmpm::test::TempDir;

namespace {

const fs::path kSource = OTMPM_SOURCE_DIR;
const std::string kBinary = OTMPM_BINARY;
const std::string kDyka = (kSource / "examples/dyka.toml").string();
/// A command that could block (a FIFO) is ended after this long: exit status 124.
constexpr int kTimeoutSeconds = 30;

/// Runs `otmpm ARGS` in `dir` through /bin/sh under timeout(1) (exit status
/// 124 when it blocks), after the shell commands `before` (e.g. "ulimit -v N; ").
CliResult otmpm_limited(const TempDir& dir, const std::vector<std::string>& args, const std::string& before = "") {
  std::string cmd = "cd " + quote(dir.dir.string()) + " && " + before + "exec timeout " +
                    std::to_string(kTimeoutSeconds) + " " + quote(kBinary);
  for (const std::string& a : args) cmd += " " + quote(a);
  const fs::path scratch = dir.dir.parent_path() / (dir.dir.filename().string() + "_io");
  fs::create_directories(scratch);
  CliResult r = otmpm::test::run_process("/bin/sh", {"-c", cmd}, scratch);
  fs::remove_all(scratch);
  return r;
}

/// True when python3's XML parser reads every file (the VTK files up to their raw appended data).
bool well_formed_xml(const std::vector<std::string>& files) {
  std::string cmd = "/usr/bin/python3 -c 'import sys, xml.etree.ElementTree as E\n"
                    "for f in sys.argv[1:]:\n"
                    "    raw = open(f, \"rb\").read()\n"
                    "    cut = raw.find(b\"<AppendedData\")\n"
                    "    E.fromstring(raw if cut < 0 else raw[:cut] + b\"</VTKFile>\")' ";
  for (const std::string& f : files) cmd += " " + quote(f);
  const otmpm::test::ShellResult r = otmpm::test::shell(cmd);
  INFO(r.output);
  return r.status == 0;
}

void write_file(const fs::path& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

} // namespace

TEST_CASE("result names with --, &, <, quotes and non-ASCII give well-formed XML files that name their run") {
  TempDir t("cli_e10");
  const std::string name = "run--2 &<>\"q' \xc3\xa9";
  const CliResult a = otmpm_in(t, {"run", kDyka, "--quiet", "--out", name + ".h5", "--set", "output.every=5e-5",
                                   "--set", "output.format=[\"hdf5\", \"vtp\"]"});
  expect_exit(a, 0);
  std::vector<std::string> xml{t.file(name + ".pvd"), t.file(name + ".xdmf")};
  for (const auto& e : fs::directory_iterator(t.dir / (name + "_vtk"))) xml.push_back(e.path().string());
  CHECK(xml.size() == 5); // the .pvd, the sidecar and three frames
  CHECK(well_formed_xml(xml));
  for (const std::string& f : xml) CHECK_FALSE(has(otmpm::test::read_text(f), "<!--"));
  // The same run again replaces its own files (it reads its run id back from every one of them) ...
  expect_exit(otmpm_in(t, {"run", kDyka, "--quiet", "--out", name + ".h5", "--set", "output.every=5e-5", "--set",
                           "output.format=[\"hdf5\", \"vtp\"]"}),
              0);
  // ... and another run whose sidecar would be this run's (result "NAME" without .h5) is refused: the
  // sidecar names its result file, escaped, and the escaped name is read back as the real one.
  const CliResult b = otmpm_in(t, {"run", kDyka, "--quiet", "--out", name, "--set", "simulation.cfl=0.2"});
  expect_exit(b, 2);
  CHECK(has(b.err, "does not belong to the result file"));
}

TEST_CASE("a result or checkpoint path with ':' in its name, a control character or non-UTF-8 "
          "exits 2, writing nothing") {
  TempDir t("cli_e10_refused");
  for (const std::string& out : {std::string("co:lon.h5"), std::string("ctl\x01.h5"), std::string("new\nline.h5"),
                                 std::string("tab\t.h5"), std::string("bad\xff.h5"), std::string("del\x7f.h5")}) {
    INFO(otmpm::test::quote(out));
    const CliResult r = otmpm_in(t, {"run", kDyka, "--quiet", "--out", out});
    expect_exit(r, 2);
    CHECK((has(r.err, "control character") || has(r.err, "':'") || has(r.err, "not UTF-8")));
    CHECK(has(r.err, "nothing was written"));
  }
  // From the scene: output.file and output.checkpoint_file with NUL or a line break name the key.
  for (const std::string& set : {std::string("output.file=\"a\\u0000b.h5\""), std::string("output.file=\"a\\nb.h5\""),
                                 std::string("output.checkpoint_file=\"c\\u0000k.h5\"")}) {
    INFO(set);
    const CliResult r = otmpm_in(t, {"run", kDyka, "--quiet", "--set", set, "--set", "output.checkpoint_every=100"});
    expect_exit(r, 2);
    CHECK(has(r.err, "--set output."));
    CHECK(has(r.err, "must not contain a control character"));
  }
  CHECK(listing(t.dir).empty());
}

TEST_CASE("render --out naming the result file or a link to it exits 2 and keeps the results") {
  TempDir t("cli_e11");
  expect_exit(otmpm_in(t, {"run", kDyka, "--quiet", "--out", "r.h5", "--set", "output.every=5e-5"}), 0);
  const std::string before = otmpm::test::read_text(t.file("r.h5"));
  fs::create_symlink("r.h5", t.dir / "pic.png");
  fs::create_hard_link(t.dir / "r.h5", t.dir / "hard.gif");
  for (const std::string out : {"pic.png", "hard.gif"}) {
    INFO(out);
    const CliResult r = otmpm_in(t, {"render", "r.h5", "--field", "v", "--out", out});
    expect_exit(r, 2);
    CHECK(has(r.err, "is the result file r.h5"));
  }
  CHECK(otmpm::test::read_text(t.file("r.h5")) == before);
  // A result file named like a picture is refused before anything is written.
  const CliResult png = otmpm_in(t, {"run", kDyka, "--quiet", "--out", "res.png"});
  expect_exit(png, 2);
  CHECK(has(png.err, "may not end in .png"));
  CHECK_FALSE(fs::exists(t.dir / "res.png"));
}

TEST_CASE("render on files of other programs, --fps nan, a Python that fails, --scripts without "
          "render.py exit 2") {
  TempDir t("cli_e16");
  expect_exit(otmpm_in(t, {"run", kDyka, "--quiet", "--out", "r.h5", "--set", "output.every=5e-5"}), 0);
  // HDF5 files of another program: /frames a dataset; the dimension or a frame's time an array.
  const otmpm::test::ShellResult made = otmpm::test::shell(
      "cd " + quote(t.dir.string()) +
      " && /usr/bin/python3 -c 'import h5py, shutil\n"
      "h5py.File(\"dataset.h5\", \"w\")[\"frames\"] = [1, 2, 3]\n"
      "for name in (\"dimension\", \"time\"):\n"
      "    shutil.copy(\"r.h5\", name + \".h5\")\n"
      "    with h5py.File(name + \".h5\", \"a\") as f:\n"
      "        where = f if name == \"dimension\" else f[\"frames\"][sorted(f[\"frames\"])[-1]]\n"
      "        del where.attrs[name]\n"
      "        where.attrs[name] = [1, 2]'");
  INFO(made.output);
  REQUIRE(made.status == 0);
  for (const std::string file : {"dataset.h5", "dimension.h5", "time.h5"}) {
    INFO(file);
    const CliResult r = otmpm_in(t, {"render", file, "--field", "v", "--out", "a.png"});
    expect_exit(r, 2);
    CHECK(has(r.err, file + ": "));
    CHECK_FALSE(has(r.err, "Traceback"));
    CHECK_FALSE(has(r.err, "internal error"));
  }
  const CliResult fps = otmpm_in(t, {"render", "r.h5", "--field", "v", "--all", "--fps", "nan", "--out", "a.gif"});
  expect_exit(fps, 2);
  CHECK(has(fps.err, "--fps"));
  const CliResult python = otmpm_in(t, {"render", "r.h5", "--field", "v", "--out", "a.png", "--python", "/bin/false"});
  expect_exit(python, 2);
  CHECK(has(python.err, "--python"));
  fs::create_directories(t.dir / "empty");
  const CliResult scripts = otmpm_in(t, {"render", "r.h5", "--field", "v", "--out", "a.png", "--scripts", "empty"});
  expect_exit(scripts, 2);
  CHECK(has(scripts.err, "no render.py"));
  CHECK_FALSE(fs::exists(t.dir / "a.png"));
  CHECK_FALSE(fs::exists(t.dir / "a.gif"));
}

TEST_CASE("a FIFO or a device where otmpm reads or writes a file exits 2 at once (with --force too)") {
  TempDir t("cli_e27");
  expect_exit(otmpm_in(t, {"run", kDyka, "--quiet", "--out", "r.h5", "--set", "output.every=5e-5"}), 0);
  for (const std::string fifo : {"fifo.h5", "fifo.toml", "fifo.png", "side.xdmf", "ck.fifo", "fifo.csv"})
    REQUIRE(::mkfifo(t.file(fifo).c_str(), 0644) == 0);
  write_file(t.dir / "study.toml", "scene = \"" + kDyka + "\"\ncsv = \"fifo.csv\"\n[[variant]]\nname = \"a\"\n");
  write_file(t.dir / "scene_fifo.toml", "scene = \"fifo.toml\"\n[[variant]]\nname = \"a\"\n");
  const std::vector<std::vector<std::string>> commands = {
      {"run", kDyka, "--quiet", "--out", "fifo.h5"},
      {"run", kDyka, "--quiet", "--out", "fifo.h5", "--force"},
      {"run", kDyka, "--quiet", "--out", "side.h5", "--force"}, // its sidecar side.xdmf
      {"run", kDyka, "--quiet", "--out", "c.h5", "--force", "--set", "output.checkpoint_file=\"ck.fifo\"", "--set",
       "output.checkpoint_every=100"},
      {"run", kDyka, "--quiet", "--out", "/dev/null", "--force"},
      {"run", "--restart", "fifo.h5", "--quiet"},
      {"run", "fifo.toml", "--quiet"},
      {"run", "--check", "fifo.toml"},
      {"render", "fifo.h5", "--field", "v", "--out", "a.png"},
      {"render", "r.h5", "--field", "v", "--out", "fifo.png"},
      {"basis", "--kind", "linear", "--out", "fifo.csv"},
      {"study", "study.toml"},
      {"study", "scene_fifo.toml"},
  };
  for (const auto& args : commands) {
    std::string line;
    for (const std::string& a : args) line += a + " ";
    INFO(line);
    const CliResult r = otmpm_limited(t, args);
    expect_exit(r, 2);
    CHECK((has(r.err, "a FIFO (named pipe)") || has(r.err, "a character device")));
  }
  CHECK(listing(t.dir) == std::set<std::string>{"ck.fifo", "fifo.csv", "fifo.h5", "fifo.png", "fifo.toml", "r.h5",
                                                 "r.xdmf", "scene_fifo.toml", "side.xdmf", "study.toml"});
}

TEST_CASE("an output directory removed during a run ends it with exit status 4, not 2") {
  TempDir t("cli_e29");
  fs::create_directories(t.dir / "sub");
  // Long enough to be running when the directory goes: 100 frames and a checkpoint every 500 steps.
  const std::vector<std::string> args{"run", kDyka, "--quiet", "--out", "sub/r.h5", "--set", "simulation.t_end=5e-3",
                                      "--set", "output.every=5e-5", "--set", "output.checkpoint_every=500"};
  const fs::path here = fs::current_path();
  fs::current_path(t.dir);
  const pid_t pid = otmpm::test::spawn_process(kBinary, args, t.file("out.txt"), t.file("err.txt"));
  const bool started = otmpm::test::wait_for_file(t.file("sub/r.checkpoint.h5"), pid, std::chrono::seconds(60));
  std::error_code ec; // the run may be adding a file meanwhile: try again until the folder is gone
  for (int attempt = 0; attempt < 100 && fs::exists(t.dir / "sub"); ++attempt) fs::remove_all(t.dir / "sub", ec);
  const CliResult r = otmpm::test::wait_process(pid, t.file("out.txt"), t.file("err.txt"));
  fs::current_path(here);
  REQUIRE(started);
  expect_exit(r, 4);
  CHECK(has(r.out, "OUTPUT FAILED: "));
  CHECK(has(r.err, "sub/r."));
}

TEST_CASE("memory running out while the run is set up exits 2 with an out-of-memory message, not 3") {
  TempDir t("cli_e17");
  // 2e6 particles on 101^3 nodes: otmpm's estimate (about 7.6 GB) passes the limit set, the address
  // space given to the process (3 GB) does not.
  write_file(t.dir / "big.toml", "[simulation]\ndimension = 3\nmode = \"mpm\"\nintegrator = \"fe\"\n"
                                 "t_end = 1e-6\ncfl = 0.3\nmemory_limit = 1e13\n[basis]\nkind = \"linear\"\n"
                                 "[grid]\nlower = [0.0, 0.0, 0.0]\nupper = [1.0, 1.0, 1.0]\ncells = [100, 100, 100]\n"
                                 "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1000.0\n"
                                 "young = 1.0e6\npoisson = 0.3\n[[body]]\nname = \"b\"\nmaterial = \"m\"\n"
                                 "lower = [0.0, 0.0, 0.0]\nupper = [1.0, 1.0, 1.0]\nparticles_per_cell = 2\n"
                                 "[output]\nfile = \"big.h5\"\n");
  const CliResult r = otmpm_limited(t, {"run", "big.toml", "--quiet"}, "ulimit -v 3000000; ");
  expect_exit(r, 2);
  CHECK(has(r.err, "big.toml: out of memory while setting up the run"));
  CHECK(has(r.err, "simulation.memory_limit"));
  CHECK_FALSE(has(r.err, "internal error"));
  CHECK_FALSE(fs::exists(t.dir / "big.h5"));
}

TEST_CASE("a --set value with a line break exits 2 instead of dropping what follows it") {
  TempDir t("cli_e18");
  for (const std::string& set : {std::string("simulation.t_end=1e-5\nsimulation.cfl=5"),
                                 std::string("simulation.t_end=1e-5\r"), std::string("output.file=a\nb.h5")}) {
    INFO(quote(set));
    const CliResult r = otmpm_in(t, {"run", kDyka, "--quiet", "--set", set});
    expect_exit(r, 2);
    CHECK(has(r.err, "line break"));
  }
  CHECK(listing(t.dir).empty());
}

TEST_CASE("output.fields without x (frames no viewer can show) exits 2, [] stays for history-only runs") {
  TempDir t("cli_e21");
  const CliResult vtk = otmpm_in(t, {"run", kDyka, "--quiet", "--out", "a.h5", "--set",
                                     "output.fields=[\"v\"]", "--set", "output.format=[\"hdf5\", \"vtu\"]"});
  expect_exit(vtk, 2);
  CHECK(has(vtk.err, "--set output.fields: must include \"x\""));
  const CliResult none = otmpm_in(t, {"run", kDyka, "--quiet", "--out", "a.h5", "--set", "output.fields=[]", "--set",
                                      "output.format=[\"hdf5\", \"vtp\"]"});
  expect_exit(none, 2);
  CHECK(has(none.err, "--set output.format: \"vtp\" and \"vtu\" need \"x\""));
  CHECK(listing(t.dir).empty());
  expect_exit(otmpm_in(t, {"run", kDyka, "--quiet", "--out", "h.h5", "--set", "output.fields=[]"}), 0);
}

TEST_CASE("a 10 MB name gives a message of at most a few kB that says how long the name is") {
  TempDir t("cli_e30");
  std::string scene = otmpm::test::read_text(kDyka);
  const std::string huge(10'000'000, 'n');
  const auto at = scene.find("name = \"steel\"");
  REQUIRE(at != std::string::npos);
  scene.replace(at, 14, "name = \"" + huge + "\"");
  write_file(t.dir / "long.toml", scene);
  const CliResult r = otmpm_in(t, {"run", "long.toml", "--quiet", "--out", "r.h5"});
  expect_exit(r, 2);
  CHECK(r.err.size() < 4096);
  CHECK(has(r.err, "(10000000 bytes)"));
  CHECK(has(r.err, "longer than 255 bytes"));
}

TEST_CASE("a CSV particle file with a UTF-8 byte-order mark is read, a UTF-16 one is refused saying so") {
  TempDir t("cli_e26");
  std::string rows = "x,volume\n";
  for (int i = 0; i < 20; ++i) rows += std::to_string(0.0025 + 0.005 * i) + ",0.005\n";
  write_file(t.dir / "plain.csv", rows);
  write_file(t.dir / "bom.csv", "\xEF\xBB\xBF" + rows);
  write_file(t.dir / "utf16.csv", std::string("\xFF\xFE", 2) + "x\0,\0" + std::string(8, '\0'));
  write_file(t.dir / "bar.toml",
             "[simulation]\ndimension = 1\nmode = \"mpm\"\nintegrator = \"musl\"\nt_end = 1e-6\n"
             "cfl = 0.3\n[basis]\nkind = \"linear\"\n[grid]\nlower = [-0.05]\nupper = [0.15]\n"
             "cells = [40]\n[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\n"
             "density = 1000.0\nyoung = 1.0e6\npoisson = 0.3\n[[body]]\nname = \"f\"\n"
             "material = \"m\"\nshape = \"file\"\nfile = \"plain.csv\"\n[output]\nfile = \"p.h5\"\n");
  expect_exit(otmpm_in(t, {"run", "bar.toml", "--quiet"}), 0);
  expect_exit(otmpm_in(t, {"run", "bar.toml", "--quiet", "--out", "b.h5", "--set", "body.f.file=\"bom.csv\""}), 0);
  CHECK(otmpm::read_string_attribute(t.file("b.h5"), "status") == "ok");
  // The same particles: the frames of both runs are equal (the scenes differ only in the file's name).
  const otmpm::test::ShellResult same = otmpm::test::shell(
      "/usr/bin/python3 -c 'import sys, h5py, numpy\n"
      "a, b = (h5py.File(f)[\"frames/000000/x\"][:] for f in sys.argv[1:])\n"
      "sys.exit(0 if a.shape == (20, 1) and numpy.array_equal(a, b) else 1)' " +
      quote(t.file("p.h5")) + " " + quote(t.file("b.h5")));
  CHECK(same.status == 0);
  const CliResult utf16 =
      otmpm_in(t, {"run", "bar.toml", "--quiet", "--out", "u.h5", "--set", "body.f.file=\"utf16.csv\""});
  expect_exit(utf16, 2);
  CHECK(has(utf16.err, "UTF-16"));
}

TEST_CASE("otmpm basis --perturb NaN or negative exits 2 instead of taking it as 0") {
  TempDir t("cli_e19");
  for (const std::string perturb : {"nan", "-1", "0.5"}) {
    INFO(perturb);
    const CliResult r = otmpm_in(t, {"basis", "--kind", "linear", "--perturb", perturb, "--out", "b.csv"});
    expect_exit(r, 2);
    CHECK(has(r.err, "fraction must be in [0, 0.5)"));
  }
  CHECK_FALSE(fs::exists(t.dir / "b.csv"));
  expect_exit(otmpm_in(t, {"basis", "--kind", "linear", "--perturb", "0.2", "--out", "b.csv"}), 0);
}
