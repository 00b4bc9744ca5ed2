#pragma once
// The scenes of the benchmarks (bench_step, bench_models, bench_table): the
// elastic block in 2D and 3D, the Dyka strip of examples/dyka_2d.toml at any
// cell count and the full 3D Taylor bar.
#include <cstdio>
#include <string>
#include <vector>

namespace otmpm::bench {

/// The material of the block: the model line and the model's own keys.
inline const std::string kBlockLinearElastic = "model = \"linear_elastic\"";

/// A TOML array of `dim` numbers: the first `dim - 1` are `horizontal`, the
/// last `vertical` (full precision, so the scene reads back the same doubles).
inline std::string toml_vector(int dim, double horizontal, double vertical) {
  std::string out = "[";
  char buf[40];
  for (int i = 0; i < dim; ++i) {
    std::snprintf(buf, sizeof buf, "%.17g", i + 1 < dim ? horizontal : vertical);
    out += buf;
    out += i + 1 < dim ? ", " : "]";
  }
  return out;
}

/// An elastic block (E = 10 MPa, rho = 1000, nu = 0.3; plane strain in 2D)
/// filling the unit square (2D) or cube (3D) with `cells` cells along each
/// axis and 2 particles per cell along each axis, inside a grid with two
/// spare cells on each side (at the top only along the vertical, last, axis),
/// falling under gravity with its base fixed - every stage of a step runs.
/// `material`: the model line and its keys (default linear_elastic).
inline std::string block_scene(int dim, int cells, const std::string& basis, const std::string& integrator,
                               const std::string& mode, double gamma_lme,
                               const std::string& material = kBlockLinearElastic) {
  const double h = 1.0 / cells, lo = -2 * h, hi = 1 + 2 * h;
  const std::string grid_cells = dim == 3 ? "[" + std::to_string(cells + 4) + ", " + std::to_string(cells + 4) +
                                                ", " + std::to_string(cells + 2) + "]"
                                          : "[" + std::to_string(cells + 4) + ", " + std::to_string(cells + 2) + "]";
  char gamma[40];
  std::snprintf(gamma, sizeof gamma, "%g", gamma_lme);
  return "\n[simulation]\ndimension = " + std::to_string(dim) + "\nmode = \"" + mode + "\"\nintegrator = \"" +
         integrator + "\"\nt_end = 1.0\ncfl = 0.3\n[basis]\nkind = \"" + basis + "\"\ngamma_lme = " + gamma +
         "\n[grid]\nlower = " + toml_vector(dim, lo, 0.0) + "\nupper = " + toml_vector(dim, hi, hi) +
         "\ncells = " + grid_cells + "\n[[material]]\nname = \"m\"\n" + material +
         "\ndensity = 1000.0\nyoung = 1.0e7\npoisson = 0.3\n[[body]]\nname = \"block\"\nmaterial = \"m\"\nlower = " +
         toml_vector(dim, 0.0, 0.0) + "\nupper = " + toml_vector(dim, 1.0, 1.0) +
         "\nparticles_per_cell = 2\nvelocity = " + toml_vector(dim, 0.0, 0.0) +
         "\n[[boundary]]\nname = \"base\"\nlower = " + toml_vector(dim, lo, 0.0) + "\nupper = " +
         toml_vector(dim, hi, 0.0) + "\nfix = " + (dim == 3 ? "[true, true, true]" : "[true, true]") +
         "\n[body_force]\nvalue = " + toml_vector(dim, 0.0, -9.81) + "\n";
}

/// The 2D block of the throughput table (block_scene in two dimensions).
inline std::string block_scene(int cells, const std::string& basis, const std::string& integrator,
                               const std::string& mode, double gamma_lme,
                               const std::string& material = kBlockLinearElastic) {
  return block_scene(2, cells, basis, integrator, mode, gamma_lme, material);
}

/// The Taylor bar as a full 3D cylinder (docs/benchmarks.md, "Taylor bar"):
/// copper, L = 32.4 mm, R = 3.2 mm, j2 (yield 400 MPa, linear hardening
/// 100 MPa), 227 m/s onto the frictionless wall z = 0, h = 0.8 mm = R/4 with
/// 2 x 2 x 2 particles per cell (16 848 particles), npc, linear basis, to
/// 80 us, no output frames.
inline std::string taylor_bar_cylinder_scene() {
  return R"(
[simulation]
dimension = 3
mode = "mpm"
integrator = "npc"
t_end = 8.0e-5
cfl = 0.2
[basis]
kind = "linear"
[grid]
lower = [-0.0144, -0.0144, -0.0032]
upper = [0.0144, 0.0144, 0.0368]
cells = [36, 36, 50]
[[material]]
name = "copper"
model = "j2"
density = 8930.0
young = 117.0e9
poisson = 0.35
yield_stress = 400.0e6
hardening_modulus = 100.0e6
[[body]]
name = "bar"
material = "copper"
shape = "cylinder"
center = [0.0, 0.0, 0.0]
radius = 0.0032
axis = [0.0, 0.0, 1.0]
length = 0.0324
particles_per_cell = 2
velocity = [0.0, 0.0, -227.0]
[[wall]]
name = "target"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[output]
every = 0.0
)";
}

/// The overrides that turn examples/dyka_2d.toml (L = 0.1333 m) into a strip
/// of `cells` square cells along the bar (h = L / cells, one row, 2 x 2
/// particles per cell) with two spare cells on the left, without output
/// frames; `extra` overrides are appended.
inline std::vector<std::string> dyka_strip_overrides(int cells, const std::vector<std::string>& extra = {}) {
  const double L = 0.1333, h = L / cells;
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", h);
  const std::string y = buf;
  std::snprintf(buf, sizeof buf, "%.17g", -2 * h);
  std::vector<std::string> o{"grid.lower=[" + std::string(buf) + ", 0.0]",
                             "grid.upper=[0.1333, " + y + "]",
                             "grid.cells=[" + std::to_string(cells + 2) + ", 1]",
                             "body.bar.upper=[0.1333, " + y + "]",
                             "initial_velocity.0.upper=[0.033325, " + y + "]",
                             "boundary.right_end.upper=[0.1333, " + y + "]",
                             "output.every=0"};
  o.insert(o.end(), extra.begin(), extra.end());
  return o;
}

} // namespace otmpm::bench
