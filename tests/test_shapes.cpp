// Bodies of any shape (geometry/shapes.hpp, assembly/seeding.cpp): the
// shapes themselves, the volume of seeded disks, spheres, cylinders and
// polygons against the exact volume, overlapping bodies, and bodies read
// from CSV and HDF5 particle files, with their input errors.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/geometry/shapes.hpp"

#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <cmath>
#include <fstream>
#include <numbers>
#include <string>

using namespace otmpm;

namespace {

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

/// A scene in `dim` dimensions on the grid [-1, 1]^dim with `cells` cells
/// per axis and the given body tables (one material "m").
std::string scene_of(int dim, int cells, const std::string& bodies, const std::string& mode = "mpm") {
  auto v = [&](double x) {
    std::string s = "[";
    for (int k = 0; k < dim; ++k) s += (k ? ", " : "") + std::to_string(x);
    return s + "]";
  };
  return "[simulation]\ndimension = " + std::to_string(dim) + "\nmode = \"" + mode +
         "\"\nintegrator = \"npc\"\nt_end = 1.0\n[basis]\nkind = \"linear\"\n[grid]\nlower = " + v(-1) +
         "\nupper = " + v(1) + "\ncells = " + std::to_string(cells) +
         "\n[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 2.0\nyoung = 1.0\npoisson = 0.0\n" +
         bodies;
}

template <int D> double seeded_volume(const std::string& text, int* count = nullptr) {
  const Scene s = parse_scene(text, "shapes.toml");
  Vec<D> h = Vec<D>::Constant(2.0 / s.grid.cells[0]);
  const Particles<D> P = seed_particles<D>(s, h);
  if (count) *count = P.size();
  double V = 0.0;
  for (double v : P.V) V += v;
  return V;
}

std::string error_of(const std::string& text, int dim) {
  try {
    const Scene s = parse_scene(text, "shapes.toml");
    if (dim == 2) assemble_parts<2>(s);
    else if (dim == 3) assemble_parts<3>(s);
    else assemble_parts<1>(s);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

} // namespace

TEST_CASE("shapes: contains, bounds and exact measures") {
  const auto disk = make_sphere<2>(Vec<2>(0.5, -0.25), 0.5);
  CHECK(disk->contains(Vec<2>(0.5, 0.25)));
  CHECK_FALSE(disk->contains(Vec<2>(0.5, 0.2501)));
  CHECK(disk->measure() == doctest::Approx(std::numbers::pi * 0.25).epsilon(1e-15));
  Vec<2> lo, hi;
  disk->bounds(lo, hi);
  CHECK(lo == Vec<2>(0.0, -0.75));
  CHECK(hi == Vec<2>(1.0, 0.25));
  const auto cyl = make_cylinder(Vec<3>(0, 0, 0), Vec<3>(0, 0, 2), 0.5, 1.0); // the axis is normalised
  CHECK(cyl->contains(Vec<3>(0.3, 0.3, 0.9)));
  CHECK_FALSE(cyl->contains(Vec<3>(0.0, 0.0, 1.01)));
  CHECK_FALSE(cyl->contains(Vec<3>(0.4, 0.4, 0.5))); // 0.566 from the axis
  CHECK(cyl->measure() == doctest::Approx(std::numbers::pi * 0.25).epsilon(1e-15));
  // An L-shaped polygon, given clockwise: Boost.Geometry's orientation is fixed internally.
  const auto L = make_polygon({Vec<2>(0, 0), Vec<2>(0, 2), Vec<2>(1, 2), Vec<2>(1, 1), Vec<2>(2, 1), Vec<2>(2, 0)});
  CHECK(L->measure() == doctest::Approx(3.0).epsilon(1e-15));
  CHECK(L->boundary_measure() == doctest::Approx(8.0).epsilon(1e-15));
  CHECK(L->contains(Vec<2>(0.5, 1.5)));
  CHECK_FALSE(L->contains(Vec<2>(1.5, 1.5)));
}

TEST_CASE("shapes: invalid shapes are input errors that say why") {
  CHECK_THROWS_WITH_AS(make_polygon({Vec<2>(0, 0), Vec<2>(1, 1), Vec<2>(1, 0), Vec<2>(0, 1)}),
                       doctest::Contains("simple polygon"), InputError); // a bow tie
  CHECK_THROWS_WITH_AS(make_polygon({Vec<2>(0, 0), Vec<2>(1, 1)}), doctest::Contains("at least 3"), InputError);
  CHECK_THROWS_WITH_AS(make_cylinder(Vec<3>::Zero(), Vec<3>::Zero(), 1.0, 1.0), doctest::Contains("axis"),
                       InputError);
  CHECK_THROWS_WITH_AS(make_sphere<3>(Vec<3>::Zero(), -1.0), doctest::Contains("radius"), InputError);
}

// The seeded volume is that of the particles whose points lie in the shape:
// it differs from the exact volume by at most the band of one particle
// spacing (h / ppc) along the boundary, |V - V_exact| <= boundary x h / ppc.
TEST_CASE("seeding: a disk, a sphere, a tilted cylinder and a polygon hold their exact volume within a particle band") {
  const double h = 2.0 / 40;
  for (int ppc : {1, 2, 3, 4}) {
    CAPTURE(ppc);
    const std::string n = "particles_per_cell = " + std::to_string(ppc) + "\n";
    {
      const auto disk = make_sphere<2>(Vec<2>(0.1, -0.2), 0.63);
      const double V = seeded_volume<2>(scene_of(2, 40, "[[body]]\nmaterial = \"m\"\nshape = \"sphere\"\n"
                                                        "center = [0.1, -0.2]\nradius = 0.63\n" + n));
      CHECK(std::abs(V - disk->measure()) <= disk->boundary_measure() * h / ppc);
    }
    {
      const auto poly = make_polygon({Vec<2>(-0.8, -0.7), Vec<2>(0.9, -0.5), Vec<2>(0.2, 0.85)});
      const double V = seeded_volume<2>(scene_of(2, 40, "[[body]]\nmaterial = \"m\"\nshape = \"polygon\"\n"
                                                        "vertices = [[-0.8, -0.7], [0.9, -0.5], [0.2, 0.85]]\n" + n));
      CHECK(std::abs(V - poly->measure()) <= poly->boundary_measure() * h / ppc);
    }
  }
  for (int ppc : {1, 2}) {
    const std::string n = "particles_per_cell = " + std::to_string(ppc) + "\n";
    const double h3 = 2.0 / 24;
    const auto ball = make_sphere<3>(Vec<3>(0.0, 0.1, -0.1), 0.7);
    const double V = seeded_volume<3>(scene_of(3, 24, "[[body]]\nmaterial = \"m\"\nshape = \"sphere\"\n"
                                                      "center = [0.0, 0.1, -0.1]\nradius = 0.7\n" + n));
    CHECK(std::abs(V - ball->measure()) <= ball->boundary_measure() * h3 / ppc);
    const auto cyl = make_cylinder(Vec<3>(-0.5, -0.4, -0.6), Vec<3>(1, 1, 1.5), 0.3, 1.2);
    const double Vc = seeded_volume<3>(scene_of(3, 24, "[[body]]\nmaterial = \"m\"\nshape = \"cylinder\"\n"
                                                       "center = [-0.5, -0.4, -0.6]\naxis = [1, 1, 1.5]\n"
                                                       "radius = 0.3\nlength = 1.2\n" + n));
    CHECK(std::abs(Vc - cyl->measure()) <= cyl->boundary_measure() * h3 / ppc);
  }
}

TEST_CASE("overlapping bodies are an input error naming both, unless the later one says overlap = \"first\"") {
  const std::string first = "[[body]]\nname = \"plate\"\nmaterial = \"m\"\nlower = [-0.5, -0.5]\nupper = [0.5, 0.0]\n";
  const std::string disk = "[[body]]\nname = \"ball\"\nmaterial = \"m\"\nshape = \"sphere\"\ncenter = [0.0, 0.2]\n"
                           "radius = 0.3\n";
  const std::string m = error_of(scene_of(2, 40, first + disk), 2);
  CHECK(contains(m, "shapes.toml:"));
  CHECK(contains(m, "body 'ball' overlaps body 'plate'"));
  int n_both = 0, n_plate = 0, n_ball = 0;
  const double V = seeded_volume<2>(scene_of(2, 40, first + disk + "overlap = \"first\"\n"), &n_both);
  seeded_volume<2>(scene_of(2, 40, first), &n_plate);
  seeded_volume<2>(scene_of(2, 40, disk), &n_ball);
  CHECK(n_both < n_plate + n_ball); // the shared region belongs to the plate only
  // The plate and the part of the disk above y = 0: pi r^2 minus the segment
  // below, r^2 acos(d/r) - d sqrt(r^2 - d^2) with d = 0.2, r = 0.3.
  const double segment = 0.09 * std::acos(0.2 / 0.3) - 0.2 * std::sqrt(0.09 - 0.04);
  CHECK(V == doctest::Approx(0.5 + std::numbers::pi * 0.09 - segment).epsilon(0.01));
  // Boxes that only touch do not overlap.
  CHECK_NOTHROW(seeded_volume<2>(scene_of(2, 40, first + "[[body]]\nmaterial = \"m\"\nlower = [-0.5, 0.0]\n"
                                                        "upper = [0.5, 0.5]\n")));
}

TEST_CASE("shape keys: wrong dimension, missing values and keys of another shape are input errors") {
  CHECK(contains(error_of(scene_of(2, 10, "[[body]]\nmaterial = \"m\"\nshape = \"cylinder\"\ncenter = [0, 0]\n"), 2),
                 "three-dimensional"));
  CHECK(contains(error_of(scene_of(3, 10, "[[body]]\nmaterial = \"m\"\nshape = \"polygon\"\nvertices = [[0, 0], [1, 0], [0, 1]]\n"), 3),
                 "two-dimensional"));
  CHECK(contains(error_of(scene_of(2, 10, "[[body]]\nmaterial = \"m\"\nshape = \"sphere\"\ncenter = [0, 0]\n"), 2),
                 "key 'body.0.radius'"));
  CHECK(contains(error_of(scene_of(2, 10, "[[body]]\nmaterial = \"m\"\nlower = [0, 0]\nupper = [1, 1]\nradius = 1\n"), 2),
                 "unknown key"));
  CHECK(contains(error_of(scene_of(2, 10, "[[body]]\nmaterial = \"m\"\nshape = \"sphere\"\ncenter = [0, 0]\n"
                                          "radius = 0.01\n"), 2),
                 "holds no particle"));
  CHECK(contains(error_of(scene_of(2, 10, "[[body]]\nmaterial = \"m\"\nshape = \"polygon\"\n"
                                          "vertices = [[0, 0], [1, 1], [1, 0], [0, 1]]\n"), 2),
                 "simple polygon"));
}

TEST_CASE("a sphere in ul mode: the nodes cover its bounding box") {
  const Scene s = parse_scene(scene_of(2, 40, "[[body]]\nmaterial = \"m\"\nshape = \"sphere\"\ncenter = [0.1, 0.0]\n"
                                              "radius = 0.5\n", "ul"), "shapes.toml");
  const Engine<2> e = assemble<2>(s);
  Vec<2> lo = e.basis().nodes().position(0), hi = lo;
  for (const Vec<2>& x : e.basis().nodes().positions()) lo = lo.cwiseMin(x), hi = hi.cwiseMax(x);
  CHECK(lo.isApprox(Vec<2>(-0.4, -0.5), 1e-12));
  CHECK(hi.isApprox(Vec<2>(0.6, 0.5), 1e-12));
}

TEST_CASE("a body from a CSV file: positions, volumes, velocities, density and a state variable") {
  test::TempDir tmp("csvbody");
  std::ofstream(tmp.file("p.csv")) << "# three particles\nx, y, volume, vx, vy, density, plastic_strain\n"
                                      "0.1, 0.1, 0.01, 1.0, 0.0, 3.0, 0.5\n0.3, 0.1, 0.01, 2.0, 0.0, 3.0, 0.0\n"
                                      "0.5, 0.1, 0.02, 3.0, 0.5, 4.0, 0.25\n";
  std::string text = scene_of(2, 20, "[[body]]\nmaterial = \"m\"\nshape = \"file\"\nfile = \"p.csv\"\n");
  text.replace(text.find("model = \"linear_elastic\""), 24,
               "model = \"j2\"\nyield_stress = 1.0\nhardening_modulus = 0.0");
  const Scene s = parse_scene(text, tmp.file("scene.toml")); // the file is found next to the scene
  const EngineParts<2> parts = assemble_parts<2>(s);
  const Particles<2>& P = parts.particles;
  REQUIRE(P.size() == 3);
  CHECK(P.x[2] == Vec<2>(0.5, 0.1));
  CHECK(P.V[2] == 0.02);
  CHECK(P.v[1] == Vec<2>(2.0, 0.0));
  CHECK(P.m[2] == 4.0 * 0.02);
  CHECK(P.find_state("plastic_strain")->values == std::vector<double>{0.5, 0.0, 0.25});
}

TEST_CASE("particle files: errors name the file and the line, column or dataset") {
  test::TempDir tmp("badfile");
  auto csv_error = [&](const std::string& content) {
    std::ofstream(tmp.file("p.csv")) << content;
    return error_of(scene_of(2, 20, "[[body]]\nmaterial = \"m\"\nshape = \"file\"\nfile = \"" + tmp.file("p.csv") +
                                        "\"\n"),
                    2);
  };
  CHECK(contains(csv_error("x, y\n0, 0\n"), "p.csv:1: the header has no column 'volume'"));
  CHECK(contains(csv_error("x, y, volume\n0, 0, 1e-3\n0, zero, 1e-3\n"), "p.csv:3: column 'y'"));
  CHECK(contains(csv_error("x, y, volume\n0, 0, -1\n"), "p.csv:2: column 'volume': must be > 0 (got -1)"));
  CHECK(contains(csv_error("x, y, volume\n0, 0\n"), "p.csv:2: 2 values"));
  CHECK(contains(csv_error("x, y, volume, colour\n0, 0, 1e-3, 1\n"), "column 'colour'"));
  CHECK(contains(csv_error("x, y, volume\n"), "no particles"));
  CHECK(contains(error_of(scene_of(2, 20, "[[body]]\nmaterial = \"m\"\nshape = \"file\"\nfile = \"none.h5\"\n"), 2),
                 "no such particle file"));
  // HDF5: x (n x 2) but volume with a wrong length.
  const std::string h5 = tmp.file("p.h5");
  const hid_t f = H5Fcreate(h5.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  const double x[4] = {0.1, 0.1, 0.3, 0.1}, V[1] = {0.01};
  const hsize_t dx[2] = {2, 2}, dv[1] = {1};
  const hid_t sx = H5Screate_simple(2, dx, nullptr), sv = H5Screate_simple(1, dv, nullptr);
  const hid_t ax = H5Dcreate2(f, "x", H5T_IEEE_F64LE, sx, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  const hid_t av = H5Dcreate2(f, "volume", H5T_IEEE_F64LE, sv, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  H5Dwrite(ax, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, x);
  H5Dwrite(av, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, V);
  H5Dclose(ax), H5Dclose(av), H5Sclose(sx), H5Sclose(sv), H5Fclose(f);
  CHECK(contains(error_of(scene_of(2, 20, "[[body]]\nmaterial = \"m\"\nshape = \"file\"\nfile = \"" + h5 + "\"\n"), 2),
                 "2 positions but 1 volumes"));
}
