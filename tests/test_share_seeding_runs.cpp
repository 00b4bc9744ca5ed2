// The counting pass of a distributed set-up counts the particles of whole
// runs of seeding cells without generating them (TakeRun: runs inside the
// body's shape, in no earlier body, behind no wall), and the cells that cut
// a boundary particle by particle. Its counts must be those of generating
// every particle: per body the particles generated and placed and the volume
// factor (bits), and, over the ranks, the decomposition, the particles per
// rank and each kept particle's global id and position - on boxes aligned and
// not with the lattice, a sphere, a rotated cylinder, a polygon, a
// triangulated surface (STL), a particle file, bodies overlapping (overlap =
// "first") and walls, and the same error where the scene is refused.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/assembly/seeding.hpp"
#include "otmpm/distributed/share_seeding.hpp"

#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <fstream>
#include <mutex>
#include <string>
#include <vector>

using namespace otmpm;

namespace {

const std::string kMaterial =
    "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1000.0\nyoung = 1.0e6\npoisson = 0.3\n";

std::string head(int D, const std::string& grid) {
  return "[simulation]\ndimension = " + std::to_string(D) +
         "\nmode = \"mpm\"\nintegrator = \"fe\"\nt_end = 1.0e-4\ncfl = 0.3\n[basis]\nkind = \"linear\"\n" + grid +
         kMaterial;
}

/// A scene to count, its dimension, and whether its seeding is refused.
struct Case {
  std::string name;
  int D;
  std::string text;
  bool refused = false;
};

std::vector<Case> cases() {
  const std::string grid3 = "[grid]\nlower = [-0.2, -0.2, -0.2]\nupper = [1.2, 1.2, 1.2]\ncells = [14, 14, 14]\n";
  const std::string grid2 = "[grid]\nlower = [-0.2, -0.2]\nupper = [1.6, 1.2]\ncells = [36, 28]\n";
  std::vector<Case> c;
  c.push_back({"3D box on the lattice's cells", 3,
               head(3, grid3) + "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.0, 0.0, 0.0]\nupper = [1.0, 1.0, 1.0]\n"});
  c.push_back({"3D box across the lattice's cells, 3 gauss points per axis", 3,
               head(3, grid3) + "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.03, 0.07, -0.01]\n"
                                "upper = [0.93, 0.87, 0.99]\nparticles_per_cell = 3\n"});
  c.push_back({"3D sphere (volume exact) and a box over it, overlap first", 3,
               head(3, grid3) + "[[body]]\nname = \"ball\"\nmaterial = \"m\"\nshape = \"sphere\"\n"
                                "center = [0.52, 0.47, 0.5]\nradius = 0.41\nvolume = \"exact\"\nparticles_per_cell = 3\n"
                                "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.0, 0.0, 0.0]\nupper = [1.0, 1.0, 0.6]\n"
                                "overlap = \"first\"\nplacement = \"cell_centres\"\n"});
  c.push_back({"3D rotated cylinder after a box, overlap first, a wall at the box's foot", 3,
               head(3, grid3) + "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.0, 0.0, 0.0]\nupper = [1.0, 1.0, 0.3]\n"
                                "[[body]]\nname = \"rod\"\nmaterial = \"m\"\nshape = \"cylinder\"\ncenter = [0.1, 0.15, 0.35]\n"
                                "axis = [1.0, 0.8, 0.9]\nradius = 0.2\nlength = 1.1\noverlap = \"first\"\n"
                                "[[wall]]\nname = \"floor\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n"});
  const std::string stl_grid = "[grid]\nlower = [-0.009, -0.009, -0.001]\nupper = [0.009, 0.009, 0.025]\n"
                               "cells = [36, 36, 52]\n";
  c.push_back({"3D triangulated surface (the impactor's STL) and a box over it, overlap first", 3,
               head(3, stl_grid) + "[[body]]\nname = \"impactor\"\nmaterial = \"m\"\nshape = \"stl\"\nfile = \"" +
                   std::string(OTMPM_SOURCE_DIR) + "/examples/geometry/impactor.stl\"\n"
                   "translate = [0.0003, -0.0002, 0.005]\nparticles_per_cell = 2\n"
                   "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [-0.006, -0.006, 0.0]\nupper = [0.006, 0.006, 0.008]\n"
                   "overlap = \"first\"\n"});
  c.push_back({"2D polygon, a disk and a box, overlap first", 2,
               head(2, grid2) + "[[body]]\nname = \"p\"\nmaterial = \"m\"\nshape = \"polygon\"\n"
                                "vertices = [[0.0, 0.0], [1.0, 0.1], [1.3, 0.9], [0.6, 0.5], [0.1, 1.0]]\n"
                                "particles_per_cell = 4\n"
                                "[[body]]\nname = \"disk\"\nmaterial = \"m\"\nshape = \"sphere\"\ncenter = [0.9, 0.5]\n"
                                "radius = 0.35\noverlap = \"first\"\n"
                                "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.0, 0.0]\nupper = [1.4, 0.45]\n"
                                "overlap = \"first\"\n"
                                "[[wall]]\nname = \"side\"\npoint = [-0.05, 0.0]\nnormal = [1.0, 0.2]\n"});
  c.push_back({"2D particle file and a box over it, overlap first", 2,
               head(2, grid2) + "[[body]]\nname = \"f\"\nmaterial = \"m\"\nshape = \"file\"\nfile = \"rows.csv\"\n"
                                "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.0, 0.0]\nupper = [1.4, 1.0]\n"
                                "overlap = \"first\"\n"});
  c.push_back({"3D box behind a wall: refused", 3,
               head(3, grid3) + "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.0, 0.0, 0.0]\nupper = [1.0, 1.0, 1.0]\n"
                                "[[wall]]\nname = \"cut\"\npoint = [0.0, 0.0, 0.55]\nnormal = [0.0, 0.3, 1.0]\n",
               true});
  c.push_back({"2D box in a disk, overlap error: refused", 2,
               head(2, grid2) + "[[body]]\nname = \"disk\"\nmaterial = \"m\"\nshape = \"sphere\"\ncenter = [0.5, 0.5]\n"
                                "radius = 0.4\n[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.6, 0.0]\n"
                                "upper = [1.4, 1.0]\n",
               true});
  return c;
}

/// The rows of the particle file: 12 x 10 particles, 0.05 apart.
void write_rows(const test::TempDir& dir) {
  std::ofstream csv(dir.file("rows.csv"));
  csv << "x, y, volume\n";
  for (int j = 0; j < 10; ++j)
    for (int i = 0; i < 12; ++i) csv << 0.8 + 0.05 * i << ", " << 0.3 + 0.05 * j << ", 0.0025\n";
}

/// What the counting pass of a pass over the bodies gives, with or without
/// taking runs: the tallies, the particles placed one by one and in runs.
template <int D> struct Tallies {
  std::vector<BodyTally> tally;
  long long one_by_one = 0, in_runs = 0;
  std::string error;
};

template <int D> Tallies<D> tallies(const Scene& scene, bool runs) {
  const Vec<D> h = grid_spacing<D>(scene);
  const CartesianGrid<D> lattice = node_grid<D>(scene);
  Tallies<D> t;
  TakeRun<D> take;
  if (runs)
    take = [&t](const CellRun<D>& run) {
      t.in_runs += run.cells * run.per_cell;
      return true;
    };
  try {
    t.tally = seed_cells_where<D>(
        scene, h, lattice, [](int) { CellRange<D> all; all.hi.fill(1 << 30); return all; },
        [&t](const SeedSpot&, const Vec<D>&) { return ++t.one_by_one, -1LL; }, nullptr, nullptr, nullptr, take);
  } catch (const InputError& e) {
    t.error = e.what();
  }
  return t;
}

/// What the ranks of a distributed set-up hold: the decomposition's boxes,
/// the particles per rank, the kept particles' ids and positions in rank
/// order (or the error every rank throws).
template <int D> struct Shares {
  std::vector<std::vector<int>> boxes;
  std::vector<std::int64_t> per_rank;
  long long particles = 0;
  std::vector<std::vector<long long>> ids;
  std::vector<std::vector<double>> x;
  std::string error;
};

template <int D> Shares<D> shares(const Scene& scene, int ranks, distributed::CountBy by) {
  Shares<D> s;
  s.ids.resize(static_cast<std::size_t>(ranks)), s.x.resize(static_cast<std::size_t>(ranks));
  std::mutex m;
  try {
    distributed::Comm::run_local(ranks, [&](const distributed::Comm& comm) {
      distributed::ShareSeeding<D> out;
      const SeededBodies<D> mine = distributed::share_seeding<D>(scene, comm, grid_spacing<D>(scene),
                                                                  node_grid<D>(scene), out, nullptr, by);
      const std::size_t r = static_cast<std::size_t>(comm.rank());
      s.ids[r] = mine.ids;
      for (int p = 0; p < mine.particles.size(); ++p)
        for (int k = 0; k < D; ++k) s.x[r].push_back(mine.particles.x[p][k]);
      if (!comm.root()) return;
      std::lock_guard<std::mutex> lock(m);
      s.per_rank = out.per_rank, s.particles = out.particles;
      for (int q = 0; q < ranks; ++q) {
        const auto& b = out.decomposition.box(q);
        s.boxes.emplace_back(b.lo.begin(), b.lo.end());
        s.boxes.back().insert(s.boxes.back().end(), b.hi.begin(), b.hi.end());
      }
    });
  } catch (const InputError& e) {
    s.error = e.what();
  }
  return s;
}

template <int D> void compare(const Case& c) {
  test::TempDir dir("share_seeding_runs");
  write_rows(dir);
  const Scene scene = parse_scene(c.text, dir.file("scene.toml"));
  const Tallies<D> runs = tallies<D>(scene, true), seeds = tallies<D>(scene, false);
  CHECK(runs.error == seeds.error); // walls are the caller's (WallSides): not an error of this pass
  if (runs.error.empty()) {
    CHECK(runs.in_runs > 0);                            // the runs are taken whole ...
    CHECK(runs.in_runs + runs.one_by_one == seeds.one_by_one); // ... and count what generating them counts
    REQUIRE(runs.tally.size() == seeds.tally.size());
    for (std::size_t b = 0; b < runs.tally.size(); ++b) {
      CAPTURE(b);
      CHECK(runs.tally[b].generated == seeds.tally[b].generated);
      CHECK(runs.tally[b].placed == seeds.tally[b].placed);
      // the volume factor (of the seeded volume, added in the same order: the same bits)
      CHECK(body_volume_factor<D>(scene.bodies[b], runs.tally[b].seeded) ==
            body_volume_factor<D>(scene.bodies[b], seeds.tally[b].seeded));
    }
  }
  for (int ranks : {1, 3, 7}) {
    CAPTURE(ranks);
    const Shares<D> a = shares<D>(scene, ranks, distributed::CountBy::runs);
    const Shares<D> b = shares<D>(scene, ranks, distributed::CountBy::seeds);
    CHECK(a.error == b.error);
    CHECK(a.error.empty() != c.refused);
    CHECK(a.particles == b.particles);
    CHECK(a.per_rank == b.per_rank);
    CHECK(a.boxes == b.boxes);
    CHECK(a.ids == b.ids);
    CHECK(a.x == b.x);
  }
}

} // namespace

TEST_CASE("counting runs of seeding cells whole gives the counts of generating every particle") {
  for (const Case& c : cases()) {
    CAPTURE(c.name);
    if (c.D == 2) compare<2>(c);
    else compare<3>(c);
  }
}
