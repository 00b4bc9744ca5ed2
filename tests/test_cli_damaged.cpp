// Damaged HDF5 files given to the otmpm command (docs/user-guide.md,
// "Damaged files"): a result file truncated, with a block zeroed or with a
// value that is not finite, and a particle file truncated. A restart from
// such a result file and a run over it without --force exit 2 naming it; with
// --force the run replaces it; a restart that finds the damage while copying
// leaves its new result file valid, its status saying why. The result file of
// a killed run (tests/scenes/killed_run.h5, whose half-written link table
// crashed libhdf5 when listed in name order) is drawn by `otmpm render`.
// The damaged copies are made here from files the test writes;
// scripts/h5damage.py runs the whole damage matrix.
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/results.hpp"

#include "cli_support.hpp"
#include "h5_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using otmpm::test::CliResult;
using otmpm::test::TempDir;

namespace {

const std::string kBinary = OTMPM_BINARY;
const std::string kScene = OTMPM_SOURCE_DIR "/examples/dyka.toml";

/// A short run: 21 frames, a checkpoint after step 60 of about 120.
std::vector<std::string> small_run(const std::string& out) {
  return {"run",       kScene,
          "--out",     out,
          "--threads", "1",
          "--set",     "grid.cells=[15]",
          "--set",     "simulation.t_end=2e-5",
          "--set",     "output.every=1e-6",
          "--set",     "output.checkpoint_every=60"};
}

CliResult otmpm_cli(const std::vector<std::string>& args, const TempDir& dir) {
  return otmpm::test::run_process(kBinary, args, dir.dir);
}

std::string bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

/// A damaged copy: `bytes` cut at `cut`, or with `zeroed` bytes from `at` set to 0.
std::string damaged(std::string bytes, std::size_t cut, std::size_t at = 0, std::size_t zeroed = 0) {
  bytes.resize(std::min(cut, bytes.size()));
  for (std::size_t i = at; i < std::min(at + zeroed, bytes.size()); ++i) bytes[i] = '\0';
  return bytes;
}

/// Sets value `row` of the frame dataset `name` to NaN (raw data HDF5 keeps no checksum of).
void poison(const std::string& path, const std::string& name, hsize_t row) {
  otmpm::h5::silence();
  const otmpm::h5::Handle file(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose);
  REQUIRE(file.valid());
  const otmpm::h5::Handle set(H5Dopen2(file.get(), name.c_str(), H5P_DEFAULT), H5Dclose);
  REQUIRE(set.valid());
  const otmpm::h5::Handle space(H5Dget_space(set.get()), H5Sclose);
  const hsize_t start[2] = {row, 0}, count[2] = {1, 1};
  REQUIRE(H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr) >= 0);
  const otmpm::h5::Handle memory(H5Screate_simple(2, count, nullptr), H5Sclose);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  REQUIRE(H5Dwrite(set.get(), H5T_NATIVE_DOUBLE, memory.get(), space.get(), H5P_DEFAULT, &nan) >= 0);
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

} // namespace

TEST_CASE("damaged result file: a restart from it exits 2 naming it, its new result file stays valid") {
  TempDir dir("cli_damaged_restart");
  const std::string res = dir.file("res.h5"), checkpoint = dir.file("res.checkpoint.h5"),
                    again = dir.file("again.h5");
  REQUIRE(otmpm_cli(small_run(res), dir).status == 0);
  const std::string intact = bytes_of(res);
  REQUIRE(intact.size() > 50000);
  const std::vector<std::string> restart = {"run", "--restart", checkpoint, "--out", again, "--threads", "1"};
  // The intact file restarts (the damage below is what makes the difference).
  REQUIRE(otmpm_cli(restart, dir).status == 0);
  fs::remove(again);

  SUBCASE("truncated: refused before anything is written") {
    for (const std::size_t cut : {std::size_t{0}, std::size_t{100}, intact.size() / 2}) {
      CAPTURE(cut);
      write_bytes(res, damaged(intact, cut));
      const CliResult r = otmpm_cli(restart, dir);
      CHECK(r.signal == 0);
      CHECK(r.status == 2);
      CHECK(contains(r.err, "otmpm: error: " + res +
                                ": the result file of the interrupted run cannot be opened by "
                                "HDF5 (truncated or damaged"));
      CHECK(!fs::exists(again));
    }
  }
  SUBCASE("a block of its first frames zeroed, or a value that is not finite: refused while copying") {
    // The frames of the 107 kB file lie beyond its first 30 kB (metadata
    // and the first frames): 4 kB zeroed there break a frame's group.
    for (int damage = 0; damage < 2; ++damage) {
      CAPTURE(damage);
      if (damage == 0)
        write_bytes(res, damaged(intact, intact.size(), 40000, 4096));
      else {
        write_bytes(res, intact);
        poison(res, "frames/000003/v", 5);
      }
      const CliResult r = otmpm_cli(restart, dir);
      CHECK(r.signal == 0);
      CHECK(r.status == 2);
      CHECK(contains(r.err, "otmpm: error: " + res + ": cannot copy the results of the interrupted run"));
      if (damage == 1) CHECK(contains(r.err, "frames/000003/v: row 5 is not finite"));
      // The new file is a valid result file that says why it stopped.
      const std::string status = otmpm::read_string_attribute(again, "status");
      CHECK(status.rfind("input error: " + res + ": cannot copy the results", 0) == 0);
      fs::remove(again);
      fs::remove(dir.file("again.xdmf"));
    }
  }
}

TEST_CASE("damaged result file: a run over it is refused naming it, and replaces it with --force") {
  TempDir dir("cli_damaged_replace");
  const std::string res = dir.file("res.h5");
  REQUIRE(otmpm_cli(small_run(res), dir).status == 0);
  const std::string intact = bytes_of(res);
  write_bytes(res, damaged(intact, intact.size() / 3));
  const CliResult refused = otmpm_cli(small_run(res), dir);
  CHECK(refused.signal == 0);
  CHECK(refused.status == 2);
  CHECK(
      contains(refused.err, "otmpm: error: " + res +
                                ": the result file exists and is not an otmpm result file "
                                "(HDF5 cannot open it: another kind of file, or one truncated or damaged)"));
  CHECK(bytes_of(res) == damaged(intact, intact.size() / 3)); // untouched
  std::vector<std::string> forced = small_run(res);
  forced.push_back("--force");
  const CliResult replaced = otmpm_cli(forced, dir);
  CHECK(replaced.status == 0);
  CHECK(otmpm::read_string_attribute(res, "status") == "ok");
}

TEST_CASE("damaged particle file: exit 2 naming it") {
  TempDir dir("cli_damaged_particles");
  const std::string particles = dir.file("particles.h5");
  {
    const otmpm::h5::Handle file = otmpm::test::new_h5_file(dir, "particles.h5").file;
    std::vector<double> x(40), volume(40, 0.1 / 40);
    for (std::size_t i = 0; i < x.size(); ++i) x[i] = (static_cast<double>(i) + 0.5) * 0.1 / 40;
    otmpm::h5::write_matrix(file.get(), "x", 40, 1, x.data(), particles);
    otmpm::h5::write_matrix(file.get(), "volume", 40, 1, volume.data(), particles);
  }
  std::ofstream(dir.file("scene.toml"))
      << "[simulation]\ndimension = 1\nt_end = 2.0e-6\n[basis]\nkind = \"linear\"\n[grid]\nlower = [-0.01]\n"
         "upper = [0.11]\ncells = [12]\n[[material]]\nname = \"steel\"\nmodel = \"linear_elastic\"\n"
         "density = 7833.0\nyoung = 200.0e9\npoisson = 0.0\n[[body]]\nmaterial = \"steel\"\nshape = "
         "\"file\"\n"
         "file = \"particles.h5\"\n[output]\nfile = \"p.h5\"\n";
  const std::vector<std::string> run = {"run", dir.file("scene.toml"), "--threads", "1"};
  REQUIRE(otmpm_cli(run, dir).status == 0);
  const std::string intact = bytes_of(particles);
  for (const std::size_t cut : {std::size_t{0}, std::size_t{200}, intact.size() / 2, intact.size() - 8}) {
    CAPTURE(cut);
    write_bytes(particles, damaged(intact, cut));
    const CliResult r = otmpm_cli(run, dir);
    CHECK(r.signal == 0);
    CHECK(r.status == 2);
    CHECK(contains(r.err, "otmpm: error: "));
    CHECK(contains(r.err, particles));
  }
}

TEST_CASE("otmpm render draws the frames of a killed run's half-written result file") {
  TempDir dir("cli_damaged_render");
  const std::string res = dir.file("killed.h5"), png = dir.file("k.png");
  fs::copy_file(OTMPM_SOURCE_DIR "/tests/scenes/killed_run.h5", res);
  const CliResult r = otmpm_cli({"render", res, "--field", "v", "--out", png}, dir);
  CHECK(r.signal == 0); // libhdf5 crashed in h5py listing /frames in name order
  CHECK(r.status == 0);
  CHECK(contains(r.err, "group /frames records 206 links but holds 205"));
  CHECK(fs::file_size(png) > 1000);
}
