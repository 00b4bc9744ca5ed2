// A request to stop (the flag otmpm run's SIGINT/SIGTERM handler sets) seen
// inside the long loops of a set-up while an InterruptPolling watches it: a
// particle file (CSV and HDF5) stops at the next block of rows, a body's
// seeding (box cells, a shape's lattice, a mesh's elements) at the next row
// of cells, a checkpoint's reading at the next chunk or array (the file
// untouched); without a polling, or with its flag clear, nothing changes.
// test_cli_setup sends the signal to `otmpm run` itself.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/assembly/seeding.hpp"
#include "otmpm/interrupt.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/io/particle_file.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/scene/scene.hpp"

#include "h5_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <atomic>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

using namespace otmpm;

namespace {

constexpr int kRows = 5 * static_cast<int>(kParticleChunk) / 2; // two and a half blocks

/// kRows particles in a row along x (volume 1e-6 each) as CSV or HDF5.
void write_rows(const std::string& path) {
  std::vector<double> x, volume(kRows, 1e-6);
  for (int i = 0; i < kRows; ++i) x.push_back(0.1 + 0.8 * i / kRows), x.push_back(0.5);
  if (path.ends_with(".csv")) {
    std::ofstream out(path);
    out << "x, y, volume\n";
    for (int i = 0; i < kRows; ++i) out << x[2 * i] << ", " << x[2 * i + 1] << ", " << volume[i] << "\n";
  } else {
    test::write_datasets(path, {{"x", kRows, 2, x}, {"volume", kRows, 0, volume}});
  }
}

/// A 2D scene of one body: `body` holds its shape's keys.
std::string scene_text(const std::string& body) {
  return "[simulation]\ndimension = 2\nintegrator = \"musl\"\nt_end = 1e-4\n[basis]\nkind = \"linear\"\n"
         "[grid]\nlower = [0.0, 0.0]\nupper = [1.0, 1.0]\ncells = [40, 40]\n[[material]]\nname = \"m\"\n"
         "model = \"linear_elastic\"\ndensity = 1000.0\nyoung = 1.0e6\npoisson = 0.3\n[[body]]\nname = \"b\"\n"
         "material = \"m\"\n" + body + "[output]\nevery = 1e-4\n";
}

} // namespace

TEST_CASE("a particle file stops at the block of rows after the flag is raised, CSV and HDF5") {
  test::TempDir dir("setup_interrupt_file");
  for (const char* name : {"rows.csv", "rows.h5"}) {
    CAPTURE(name);
    const std::string path = dir.file(name);
    write_rows(path);
    std::atomic<bool> flag{false};
    int blocks = 0;
    const auto each = [&](const ParticleColumns&, const ParticleRows&) {
      ++blocks;
      flag = true; // raised while the first block is handed over
    };
    stream_particle_file(path, 2, each); // not polled: every block
    CHECK(blocks == 3);
    flag = false, blocks = 0;
    const InterruptPolling polling(&flag);
    CHECK_THROWS_AS(stream_particle_file(path, 2, each), InterruptedError);
    CHECK(blocks == 1);
    CHECK_THROWS_WITH_AS(read_particle_file(path, 2), "interrupted while reading a particle file", InterruptedError);
    flag = false;
    CHECK(read_particle_file(path, 2).size() == kRows); // a clear flag changes nothing
  }
}

TEST_CASE("a body's seeding stops when the flag is raised: box, sphere and file bodies") {
  test::TempDir dir("setup_interrupt_seed");
  write_rows(dir.file("rows.csv"));
  const std::vector<std::string> bodies = {"lower = [0.2, 0.2]\nupper = [0.8, 0.8]\n",
                                           "shape = \"sphere\"\ncenter = [0.5, 0.5]\nradius = 0.3\n",
                                           "shape = \"file\"\nfile = \"" + dir.file("rows.csv") + "\"\n"};
  for (const std::string& body : bodies) {
    CAPTURE(body);
    const Scene scene = parse_scene(scene_text(body), "s.toml");
    const CartesianGrid<2> grid = node_grid<2>(scene);
    std::atomic<bool> flag{true};
    CHECK(seed_bodies<2>(scene, grid.h(), grid).particles.size() > 0); // raised, not polled
    const InterruptPolling polling(&flag);
    CHECK_THROWS_AS(seed_bodies<2>(scene, grid.h(), grid), InterruptedError);
    CHECK_THROWS_AS(seed_bodies_where<2>(scene, grid.h(), grid, [](long long, const Vec<2>&) { return true; }, nullptr),
                    InterruptedError);
    flag = false;
    CHECK(seed_bodies<2>(scene, grid.h(), grid).particles.size() > 0);
  }
}

TEST_CASE("reading a checkpoint stops when the flag is raised, and leaves the checkpoint as it was") {
  test::TempDir dir("setup_interrupt_checkpoint");
  Scene scene = parse_scene(scene_text("lower = [0.2, 0.2]\nupper = [0.8, 0.8]\n"), dir.file("s.toml"));
  scene.output.checkpoint_every = 1;
  scene.simulation.t_end = 1e-3; // several steps: checkpoints after each but the last
  RunOptions options;
  options.out_file = dir.file("r.h5");
  REQUIRE(run_scene(scene, options).exit_code == 0);
  const std::string ck = dir.file("r.checkpoint.h5");
  const auto bytes = [&] {
    std::ifstream in(ck, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  const std::string before = bytes();
  REQUIRE(before.size() > 0);
  std::atomic<bool> flag{true};
  const Checkpoint whole = read_checkpoint(ck); // raised, not polled
  {
    const InterruptPolling polling(&flag);
    CHECK_THROWS_WITH_AS(read_checkpoint(ck), "interrupted while reading a checkpoint", InterruptedError);
    flag = false;
    CHECK(read_checkpoint(ck).groups.size() == whole.groups.size()); // a clear flag changes nothing
  }
  CHECK(bytes() == before);
}
