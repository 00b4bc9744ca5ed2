// External loads (engine/loads.hpp, docs/theory.md sect. 7): a traction is a
// force per unit area of the loaded surface, carried by the surface
// particles in its box, so the total force is traction x area whatever the
// particles per cell, their placement or the depth of the box; a box with no
// surface particle is refused.
#include "otmpm/assembly/assembler.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <string>

using namespace otmpm;

namespace {

/// A unit cube body (in D dimensions) on a grid of h = 0.25 with a traction
/// of 5 Pa along x on the faces in the box x in [x0, 1.05] (the whole face at x = 1
/// and, when x0 < 0, the face at x = 0).
std::string traction_scene(int D, int ppc, const std::string& placement, double x0) {
  auto vec = [&](double a, double b) {
    std::string s = "[" + std::to_string(a);
    for (int k = 1; k < D; ++k) s += ", " + std::to_string(b);
    return s + "]";
  };
  return "[simulation]\ndimension = " + std::to_string(D) + "\nintegrator = \"fe\"\nt_end = 1.0\n"
         "[basis]\nkind = \"linear\"\n"
         "[grid]\nlower = " + vec(-0.5, -0.5) + "\nupper = " + vec(1.5, 1.5) + "\ncells = " + std::to_string(8) +
         "\n[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1.0\nyoung = 1.0\npoisson = 0.0\n"
         "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = " + vec(0, 0) + "\nupper = " + vec(1, 1) +
         "\nparticles_per_cell = " + std::to_string(ppc) + "\nplacement = \"" + placement + "\"\n"
         "[[traction]]\nlower = " + vec(x0, -0.5) + "\nupper = " + vec(1.05, 1.5) + "\nvalue = " + vec(5, 0) + "\n";
}

/// The total external force of the assembled loads at t = 0.
template <int D> Vec<D> total_force(const Scene& scene) {
  const EngineParts<D> parts = assemble_parts<D>(scene);
  AlignedVector<Vec<D>> f;
  parts.loads.particle_forces(0.0, parts.particles, f);
  Vec<D> sum = Vec<D>::Zero();
  for (const Vec<D>& fp : f) sum += fp;
  return sum;
}

template <int D> void check_total_force() {
  for (const char* placement : {"gauss", "cell_centres"})
    for (int ppc = 1; ppc <= 12; ++ppc)
      for (double x0 : {0.75, 0.5, 0.2}) { // the last cell, two cells, a deep box
        INFO(D << "D, " << std::string(placement) << ", ppc " << ppc << ", box from x = " << x0);
        const Vec<D> f = total_force<D>(parse_scene(traction_scene(D, ppc, placement, x0), "traction.toml"));
        // 5 Pa on the unit face; the areas are sums of cell shares (round-off only).
        CHECK(std::abs(f[0] - 5.0) <= 1e-12 * 5.0);
        for (int k = 1; k < D; ++k) CHECK(f[k] == 0.0);
      }
}

} // namespace

TEST_CASE("traction: the total force is traction x area for 1..12 particles per cell (1D, 2D, 3D)") {
  check_total_force<1>();
  check_total_force<2>();
  check_total_force<3>();
}

TEST_CASE("traction: a box holding both ends of a column loads both faces") {
  // The box covers the whole body: the faces at x = 0 and x = 1 each carry 5 Pa.
  const Vec<2> f = total_force<2>(parse_scene(traction_scene(2, 3, "gauss", -0.05), "traction.toml"));
  CHECK(std::abs(f[0] - 10.0) <= 1e-12 * 10.0);
}

TEST_CASE("traction: a box that selects no surface particle is refused with its line") {
  const Scene scene = parse_scene(traction_scene(2, 4, "gauss", 0.3), "traction.toml");
  Scene inner = scene;
  inner.tractions[0].upper[0] = 0.7; // x in [0.3, 0.7]: interior particles only
  try {
    assemble_parts<2>(inner);
    FAIL("no InputError");
  } catch (const InputError& e) {
    const std::string m = e.what();
    CHECK(m.find("traction.toml:") != std::string::npos);
    CHECK(m.find("selects no surface particle") != std::string::npos);
  }
}

TEST_CASE("traction: `axis` chooses the loaded faces for a shear traction") {
  // A shear traction along y on the face x = 1: axis = 0 names the face normal.
  std::string text = traction_scene(2, 2, "gauss", 0.75);
  text.replace(text.find("value = [5.000000, 0.000000]"), 28, "value = [0.0, 3.0]\naxis = 0");
  const Vec<2> f = total_force<2>(parse_scene(text, "traction.toml"));
  CHECK(f[0] == 0.0);
  CHECK(std::abs(f[1] - 3.0) <= 1e-12 * 3.0);
}
