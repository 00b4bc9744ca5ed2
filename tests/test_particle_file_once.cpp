// How often set-up reads a particle file (particle_file_passes): the scene
// reader once (for the body's bounds and particle count), then each seeding
// pass once - a distributed rank's counting and keeping passes
// (seed_bodies_where) and the serial seeding (seed_bodies) - also when an
// earlier file body's shape is built for the later bodies' boxes (the later
// file body's box is the bounds the scene reader found, not a pass over its
// rows). The particles are those of the serial seeding, bit for bit.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/assembly/seeding.hpp"
#include "otmpm/io/particle_file.hpp"

#include "h5_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <fstream>
#include <functional>
#include <string>
#include <vector>

using namespace otmpm;

namespace {

/// The blob's rows: 10 x 10 particles at 0.925 + 0.05 i (its first `moved`
/// rows shifted by `shift` along x), plastic_strain and density per row.
void write_blob(const std::string& path, int moved = 0, double shift = 0.0) {
  std::vector<double> x, volume, eps, rho;
  for (int j = 0, row = 0; j < 10; ++j)
    for (int i = 0; i < 10; ++i, ++row) {
      x.push_back(0.925 + 0.05 * i + (row < moved ? shift : 0.0)), x.push_back(0.925 + 0.05 * j);
      volume.push_back(0.0025), eps.push_back(0.5 + 1e-3 * row), rho.push_back(2000.0 + j);
    }
  test::write_datasets(path, {{"x", 100, 2, x}, {"volume", 100, 0, volume}, {"plastic_strain", 100, 0, eps},
                              {"density", 100, 0, rho}});
}

/// A 2D scene of two file bodies (a CSV block, an HDF5 blob overlapping it
/// with overlap = "first"), then a box and a sphere overlapping them, as in
/// test_mpi's file-body case; its files in `dir`.
Scene two_file_bodies(const test::TempDir& dir, double blob_shift = 0.0) {
  {
    std::ofstream csv(dir.file("block.csv"));
    csv << "x, y, volume, vx, vy, plastic_strain\n";
    for (int j = 0, row = 0; j <= 20; ++j)
      for (int i = 0; i <= 20; ++i, ++row)
        csv << 0.025 + 0.05 * i << ", " << 0.025 + 0.05 * j << ", 0.0025, " << 0.01 * i << ", 0, " << 1e-4 * row << "\n";
  }
  write_blob(dir.file("blob.h5"), blob_shift != 0.0 ? 100 : 0, blob_shift);
  const std::string text =
      "[simulation]\ndimension = 2\nmode = \"mpm\"\nintegrator = \"fe\"\nt_end = 4.0e-3\ncfl = 0.3\n"
      "[basis]\nkind = \"linear\"\n[grid]\nlower = [-0.2125, -0.2125]\nupper = [1.5875, 1.5875]\ncells = [36, 36]\n"
      "[[material]]\nname = \"m\"\nmodel = \"j2\"\ndensity = 1000.0\nyoung = 1.0e6\npoisson = 0.3\n"
      "yield_stress = 5.0e3\nhardening_modulus = 1.0e5\n"
      "[[body]]\nname = \"block\"\nmaterial = \"m\"\nshape = \"file\"\nfile = \"block.csv\"\n"
      "[[body]]\nname = \"blob\"\nmaterial = \"m\"\nshape = \"file\"\nfile = \"blob.h5\"\noverlap = \"first\"\n"
      "[[body]]\nname = \"plate\"\nmaterial = \"m\"\nlower = [0.825, 0.825]\nupper = [1.325, 1.325]\n"
      "particles_per_cell = 1\noverlap = \"first\"\n"
      "[[body]]\nname = \"ball\"\nmaterial = \"m\"\nshape = \"sphere\"\ncenter = [1.2, 0.3]\nradius = 0.25\n"
      "overlap = \"first\"\n";
  return parse_scene(text, dir.file("scene.toml"));
}

/// The passes begun over each file body's file so far, e.g. "block 1, blob 1"
/// (a string, which doctest prints when a check fails).
std::string passes(const Scene& scene) {
  std::string n;
  for (const BodySection& b : scene.bodies)
    if (b.shape == "file") n += (n.empty() ? "" : ", ") + b.name + " " + std::to_string(particle_file_passes(b.file));
  return n;
}

/// What a seeding gives per particle: position, volume, mass, velocity,
/// body, and its state values (plastic_strain) as bits to compare.
std::vector<double> flat(const SeededBodies<2>& s) {
  std::vector<double> out;
  const Particles<2>& P = s.particles;
  for (int p = 0; p < P.size(); ++p) {
    out.insert(out.end(), {P.x[p][0], P.x[p][1], P.V[p], P.m[p], P.v[p][0], P.v[p][1], double(P.body[p])});
    for (const FileState& f : s.file_state)
      if (f.body == P.body[p]) out.push_back(f.values[static_cast<std::size_t>(s.file_row[static_cast<std::size_t>(p)])]);
  }
  return out;
}

/// The store pass of seed_bodies_where keeping the particles `keep` accepts.
SeededBodies<2> store_pass(const Scene& scene, const std::function<bool(long long, const Vec<2>&)>& keep,
                           long long* count = nullptr) {
  const CartesianGrid<2> grid = node_grid<2>(scene);
  SeededBodies<2> mine;
  const long long n = seed_bodies_where<2>(scene, grid.h(), grid, keep, &mine);
  if (count) *count = n;
  return mine;
}

} // namespace

TEST_CASE("particle files: the scene reader and then each seeding pass read a file body's file once") {
  test::TempDir dir("pfile_once");
  const Scene scene = two_file_bodies(dir);
  REQUIRE(scene.bodies[0].file_particles == 441);
  REQUIRE(scene.bodies[1].file_particles == 100);
  CHECK(passes(scene) == "block 1, blob 1"); // the scene reader's pass
  const CartesianGrid<2> grid = node_grid<2>(scene);

  // a rank's counting pass (nothing kept): the block's shape is built for
  // the blob's box, which comes from the scene, not from a pass over blob.h5
  std::vector<long long> ids;
  const long long n = seed_bodies_where<2>(
      scene, grid.h(), grid, [&ids](long long id, const Vec<2>&) { ids.push_back(id); return false; }, nullptr);
  CHECK(passes(scene) == "block 2, blob 2");
  CHECK(static_cast<long long>(ids.size()) == n);

  // a rank's keeping pass: every third particle
  long long again = 0;
  const SeededBodies<2> share = store_pass(scene, [](long long id, const Vec<2>&) { return id % 3 == 0; }, &again);
  CHECK(passes(scene) == "block 3, blob 3");
  CHECK(again == n);
  CHECK(share.particles.size() == (n + 2) / 3);

  // the serial seeding
  const SeededBodies<2> serial = seed_bodies<2>(scene, grid.h(), grid);
  CHECK(passes(scene) == "block 4, blob 4");
  CHECK(serial.particles.size() == n);

  // the same particles, bit for bit: all kept, and the share
  const SeededBodies<2> all = store_pass(scene, [](long long, const Vec<2>&) { return true; });
  CHECK(passes(scene) == "block 5, blob 5");
  CHECK(flat(all) == flat(serial));
  const std::vector<double> every = flat(serial), part = flat(share);
  CHECK(part.size() < every.size());
  // some particles of the blob are dropped by the block, some kept
  CHECK(all.particles.size() > 441 + 30);
  CHECK(all.particles.size() < 441 + 100 + 100 + 400);
}

TEST_CASE("particle files: a scene built in code (no reader's bounds) seeds the same particles, each file once") {
  test::TempDir dir("pfile_once_code");
  Scene scene = two_file_bodies(dir);
  const CartesianGrid<2> grid = node_grid<2>(scene);
  const SeededBodies<2> serial = seed_bodies<2>(scene, grid.h(), grid);
  for (BodySection& b : scene.bodies)
    if (b.shape == "file") // as a scene built in code: no count, bounds that are not the file's
      b.file_particles = 0, b.lower = Vec3{0, 0, 0}, b.upper = Vec3{0.1, 0.1, 0};
  REQUIRE(passes(scene) == "block 2, blob 2"); // the scene reader's and the serial seeding's
  const SeededBodies<2> all = store_pass(scene, [](long long, const Vec<2>&) { return true; });
  CHECK(passes(scene) == "block 3, blob 3");
  CHECK(flat(all) == flat(serial));
}

TEST_CASE("particle files: a later file body that left the bounds the scene read is refused, naming the file and row") {
  // The block's shape holds only the cubes near the blob's bounds read with
  // the scene: a blob row outside them (the file rewritten since) could
  // miss a cube of the block, so it is an input error, not a wrong overlap.
  test::TempDir dir("pfile_once_changed");
  const Scene scene = two_file_bodies(dir);
  write_blob(dir.file("blob.h5"), 1, -0.9); // row 0 moves into the block
  std::string message;
  try {
    store_pass(scene, [](long long, const Vec<2>&) { return true; });
  } catch (const InputError& e) {
    message = e.what();
  }
  CAPTURE(message);
  CHECK(message.find("blob.h5: row 0: position") != std::string::npos);
  CHECK(message.find("the file changed after the scene was read") != std::string::npos);
  CHECK(message.find("scene.toml:30: key 'body.blob.file': ") != std::string::npos); // the scene's line
  write_blob(dir.file("blob.h5"), 100, 0.01); // inside the bounds read (each cube's half side 0.025): accepted
  CHECK_NOTHROW(store_pass(scene, [](long long, const Vec<2>&) { return true; }));
}

TEST_CASE("particle files: a CSV file read whole is reserved for the rows the caller expects") {
  // More rows than a block (kParticleChunk): without the count the vectors
  // grow block by block (doubling); with it they hold the rows exactly.
  test::TempDir dir("pfile_reserve");
  const int n = static_cast<int>(kParticleChunk) + 4464;
  {
    std::ofstream csv(dir.file("p.csv"));
    csv << "x, y, volume, vx, vy\n";
    for (int r = 0; r < n; ++r) csv << 0.001 * r << ", 0.5, 1e-6, 1, 0\n";
  }
  const ParticleFile grown = read_particle_file(dir.file("p.csv"), 2);
  const ParticleFile reserved = read_particle_file(dir.file("p.csv"), 2, n);
  REQUIRE(reserved.size() == n);
  CHECK(reserved.volume == grown.volume);
  CHECK(reserved.x == grown.x);
  CHECK(reserved.v == grown.v);
  CHECK(reserved.volume.capacity() == static_cast<std::size_t>(n));
  CHECK(reserved.x.capacity() == 2 * static_cast<std::size_t>(n));
  CHECK(reserved.v.capacity() == 2 * static_cast<std::size_t>(n));
  CHECK(grown.volume.capacity() > static_cast<std::size_t>(n));
  // a hint below the rows only starts the growth later
  const ParticleFile low = read_particle_file(dir.file("p.csv"), 2, 10);
  CHECK(low.x == grown.x);
}

TEST_CASE("particle files: a file body pointed at another file in code is seeded from that file, not refused") {
  // The scene read blob.h5's bounds; the code then names another file whose
  // rows lie elsewhere (inside the block). Those bounds are not that file's:
  // the block's shape keeps every cube, and the particles are those of a
  // scene that names the other file.
  test::TempDir dir("pfile_once_swapped"), other("pfile_once_other");
  const Scene moved = two_file_bodies(other, -0.6);
  Scene scene = two_file_bodies(dir);
  scene.bodies[1].file = other.file("blob.h5");
  SeededBodies<2> swapped;
  CHECK_NOTHROW(swapped = store_pass(scene, [](long long, const Vec<2>&) { return true; }));
  const CartesianGrid<2> grid = node_grid<2>(moved);
  CHECK(flat(swapped) == flat(seed_bodies<2>(moved, grid.h(), grid)));
  CHECK(flat(swapped) == flat(seed_bodies<2>(scene, grid.h(), grid)));
}
