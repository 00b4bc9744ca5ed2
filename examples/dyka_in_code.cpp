//                    otmpm example: the Dyka bar built in code
//
// Compile:  part of the otmpm build (target example_dyka_in_code), or in your
//           own CMake project with find_package(otmpm) and otmpm::otmpm
//           (examples/consumer/ shows the CMake side).
//
// Sample runs:  build/bin/example_dyka_in_code
//               build/bin/example_dyka_in_code 133          (h = L/133)
//               build/bin/example_dyka_in_code 40 fe        (forward Euler)
//               build/bin/example_dyka_in_code 40 npc ul    (nodes advected with the bar)
//
// Description:  A steel bar [0, L], L = 0.1333 m, free at x = 0 and fixed at
//               x = L; its left quarter starts at -5 m/s (Dyka's bar, molinos
//               et al. sect. 3.1). The run uses the Local Max-Ent basis
//               (gamma_lme = 4), the explicit Newmark predictor-corrector and,
//               by default, a fixed grid (MPM) - the same run as
//               `otmpm run examples/dyka.toml`, built here without any scene
//               file, through the parts an engine is made of:
//
//               1. the node lattice and the basis on it,
//               2. the particles seeded in the bar (2 per cell, Gauss points),
//               3. the material,
//               4. the Dirichlet set at the fixed end,
//               5. the step settings (integrator, CFL, end time),
//               6. the engine, stepped to t_end,
//               7. the errors against the exact solution (characteristics).
//
//               It prints the RMS velocity error at t_end and the velocity of
//               the leftmost particle, the numbers `otmpm run` reports.
#include "otmpm/engine/engine.hpp"
#include "otmpm/geometry/box_cells.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/reference/solutions.hpp"

#include <cmath>
#include <cstdio>
#include <string>

using namespace otmpm;

int main(int argc, char** argv) {
  // 0. Options: cells along the bar (h = L/n), integrator, node mode.
  const int n = argc > 1 ? std::stoi(argv[1]) : 40;
  const std::string integrator = argc > 2 ? argv[2] : "npc";
  const bool ul = argc > 3 && std::string(argv[3]) == "ul";
  const double L = 0.1333, rho = 7833.0, E = 200.0e9, v0 = -5.0, t_end = 1.0e-4;
  const double h = L / n;

  EngineParts<1> parts;

  // 1. The node lattice: in MPM a fixed grid from two cells left of the
  //    free end to the fixed end (the free end moves left); in UL the nodes
  //    cover the bar only and move with it. The basis lives on the nodes.
  CartesianGrid<1> grid;
  grid.lower = Vec<1>(ul ? 0.0 : -2 * h);
  grid.upper = Vec<1>(L);
  grid.cells = {ul ? n : n + 2};
  BasisOptions basis;
  basis.kind = "lme";
  basis.values["gamma_lme"] = 4.0;
  parts.basis = make_basis<1>(basis, NodeSet<1>::cartesian(grid));
  parts.mode = ul ? NodeMode<1>::advected() : NodeMode<1>::fixed_grid(grid.lower, grid.upper);

  // 2. The particles: n cells of the bar, 2 particles each at the Gauss
  //    points, mass = rho V; the left quarter moves at v0.
  Particles<1>& P = parts.particles;
  AlignedVector<Vec<1>> x, length;
  std::vector<double> volume;
  seed_box_cells<1>(Vec<1>(0.0), Vec<1>(L), {n}, 2, "gauss", [&](const Vec<1>& xp, double V, const Vec<1>& l) {
    x.push_back(xp);
    volume.push_back(V);
    length.push_back(l);
  });
  P.resize(static_cast<int>(x.size()));
  for (int p = 0; p < P.size(); ++p) {
    P.x[p] = P.X[p] = x[p];
    P.V[p] = P.V0[p] = volume[p];
    P.rho[p] = rho;
    P.m[p] = rho * volume[p];
    P.length0[p] = length[p];
    P.v[p] = Vec<1>(x[p][0] <= L / 4 ? v0 : 0.0);
  }

  // 3. The material: small-strain linear elasticity (index 0 for every particle).
  parts.materials.push_back(make_material<1>({.name = "steel", .model = "linear_elastic", .density = rho,
                                              .young = E, .poisson = 0.0, .extra = {}}));

  // 4. The fixed end: the node at x = L held at zero velocity.
  const NodeSet<1>& nodes = parts.basis->nodes();
  for (int I = 0; I < nodes.size(); ++I)
    if (std::abs(nodes.position(I)[0] - L) < 1e-9 * h) {
      parts.dirichlet.node.push_back(I);
      parts.dirichlet.fix.push_back({true, false, false});
      parts.dirichlet.value.push_back({0.0, 0.0, 0.0});
    }

  // 5. The step settings: the integrator from the table (its step function
  //    and what it needs: the engine allocates the particle fields it keeps,
  //    such as a_p for npc, and refuses a run that lacks the rest), its
  //    parameters at their defaults, CFL 0.1 on the nodal spacing h.
  const IntegratorKind& kind = integrator_kind(integrator);
  parts.settings.step = kind.step<1>();
  parts.settings.parameters = kind.default_parameters(); // gamma = 0.5 for npc
  parts.settings.t_end = t_end;
  parts.settings.cfl = 0.1;
  parts.settings.h = h;
  parts.settings.consistent_mass = kind.consistent_by_default;

  // 6. The engine, stepped to t_end.
  Engine<1> engine(std::move(parts));
  while (engine.time() < t_end * (1 - 1e-9)) engine.step();

  // 7. Errors against the exact solution of the bar (characteristics).
  const DykaBar<1> exact(L, E, rho, v0, L / 4);
  const Particles<1>& Q = engine.particles();
  double sum = 0.0;
  int leftmost = 0;
  for (int p = 0; p < Q.size(); ++p) {
    sum += (Q.v[p] - exact.velocity(Q.X[p], engine.time())).squaredNorm();
    if (Q.X[p][0] < Q.X[leftmost][0]) leftmost = p;
  }
  std::printf("Dyka bar, h = L/%d, lme %s %s: %ld steps to t = %.6g s\n", n, integrator.c_str(), ul ? "ul" : "mpm",
              engine.steps(), engine.time());
  std::printf("rms_velocity_error = %.4g m/s, point A velocity %.6g m/s (exact %.6g)\n",
              std::sqrt(sum / Q.size()), Q.v[leftmost][0], exact.velocity(Q.X[leftmost], engine.time())[0]);
  return 0;
}
