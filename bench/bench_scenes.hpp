#pragma once
// The scenes of the issue-7 benchmarks (bench_step, bench_table).
#include <cstdio>
#include <string>

namespace otmpm::bench {

/// The material of the block: the model line and the model's own keys.
inline const std::string kBlockLinearElastic = "model = \"linear_elastic\"";

/// A 2D elastic block (plane strain, E = 10 MPa, rho = 1000, nu = 0.3) of
/// `cells` x `cells` cells of the unit square with 2 x 2 particles per cell,
/// inside a grid with two spare cells on each side, falling under gravity with
/// its base fixed - every stage of a step runs. `material`: the model line
/// and its keys (default linear_elastic).
inline std::string block_scene(int cells, const std::string& basis, const std::string& integrator,
                               const std::string& mode, double gamma_lme,
                               const std::string& material = kBlockLinearElastic) {
  const double h = 1.0 / cells;
  char buf[2048];
  std::snprintf(buf, sizeof buf, R"(
[simulation]
dimension = 2
mode = "%s"
integrator = "%s"
t_end = 1.0
cfl = 0.3
[basis]
kind = "%s"
gamma_lme = %g
[grid]
lower = [%.17g, %.17g]
upper = [%.17g, %.17g]
cells = [%d, %d]
[[material]]
name = "m"
%s
density = 1000.0
young = 1.0e7
poisson = 0.3
[[body]]
name = "block"
material = "m"
lower = [0.0, 0.0]
upper = [1.0, 1.0]
particles_per_cell = 2
velocity = [0.0, 0.0]
[[boundary]]
name = "base"
lower = [%.17g, 0.0]
upper = [%.17g, 0.0]
fix = [true, true]
[body_force]
value = [0.0, -9.81]
)",
                mode.c_str(), integrator.c_str(), basis.c_str(), gamma_lme, -2 * h, 0.0, 1 + 2 * h, 1 + 2 * h,
                cells + 4, cells + 2, material.c_str(), -2 * h, 1 + 2 * h);
  return buf;
}

} // namespace otmpm::bench
