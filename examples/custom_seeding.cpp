//                    otmpm example: particles placed by your own code
//
// Compile:  part of the otmpm build (target example_custom_seeding), or in your
//           own CMake project with find_package(otmpm) and otmpm::otmpm.
//
// Sample runs:  build/bin/example_custom_seeding
//               build/bin/example_custom_seeding 64 ul     (64 rings, nodes advected)
//
// Description:  A spinning elastic disk (2D plane strain, rubber-like
//               neo-Hookean material) whose particles lie on concentric rings
//               - a layout no scene file can describe, since scene bodies are
//               seeded on the grid lattice. The disk turns at omega = 20 rad/s
//               inside a fixed grid (MPM) or on nodes that move with it (UL);
//               without loads its angular momentum L = sum m (x v_y - y v_x)
//               is a conserved quantity, which the program reports:
//
//               1. the node lattice and the linear basis on it,
//               2. the particles: ring k (radius (k + 1/2) dr) holds
//                  round(2 pi (k + 1/2)) particles, each with the area of
//                  its sector of the ring, mass rho V, rigid rotation
//                  velocity v = omega (-y, x),
//               3. the material (neo-Hookean) with F tracked,
//               4. the step settings (MUSL, CFL 0.2),
//               5. the engine, stepped to t_end,
//               6. the angular momentum and kinetic energy at the start
//                  and at the end.
#include "otmpm/engine/engine.hpp"
#include "otmpm/integrators/integrator.hpp"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

using namespace otmpm;

namespace {

/// Angular momentum about the origin and kinetic energy of the particles.
void momenta(const Particles<2>& P, double& L, double& kinetic) {
  L = kinetic = 0.0;
  for (int p = 0; p < P.size(); ++p) {
    L += P.m[p] * (P.x[p][0] * P.v[p][1] - P.x[p][1] * P.v[p][0]);
    kinetic += 0.5 * P.m[p] * P.v[p].squaredNorm();
  }
}

/// Step 2: particles on `rings` concentric rings of a disk of radius R
/// centred at the origin, rotating rigidly at omega.
Particles<2> ring_particles(int rings, double R, double rho, double omega) {
  const double dr = R / rings;
  AlignedVector<Vec<2>> x;
  std::vector<double> area;
  for (int k = 0; k < rings; ++k) {
    const double r = (k + 0.5) * dr;
    const int n = std::max(1, static_cast<int>(std::lround(2 * std::numbers::pi * (k + 0.5))));
    for (int j = 0; j < n; ++j) {
      const double phi = 2 * std::numbers::pi * (j + 0.5 * (k % 2)) / n;
      x.push_back(Vec<2>(r * std::cos(phi), r * std::sin(phi)));
      area.push_back(2 * std::numbers::pi * r * dr / n); // the sector of ring k
    }
  }
  Particles<2> P;
  P.resize(static_cast<int>(x.size()));
  for (int p = 0; p < P.size(); ++p) {
    P.x[p] = P.X[p] = x[p];
    P.V[p] = P.V0[p] = area[static_cast<std::size_t>(p)];
    P.rho[p] = rho;
    P.m[p] = rho * P.V[p];
    P.length0[p] = Vec<2>(dr, dr);
    P.v[p] = omega * Vec<2>(-x[p][1], x[p][0]);
  }
  return P;
}

} // namespace

int main(int argc, char** argv) {
  // 0. Options: rings across the radius, node mode.
  const int rings = argc > 1 ? std::stoi(argv[1]) : 32;
  const bool ul = argc > 2 && std::string(argv[2]) == "ul";
  const double R = 0.5, rho = 1000.0, E = 1.0e6, nu = 0.3, omega = 20.0, t_end = 0.05;
  const double h = R / rings * 2; // two rings per cell
  EngineParts<2> parts;

  // 1. The nodes: a fixed grid around the disk with one spare cell (MPM), or
  //    a lattice over the disk's box that moves with it (UL).
  const int cells = static_cast<int>(std::ceil(2 * R / h)) + (ul ? 0 : 2);
  CartesianGrid<2> grid;
  grid.lower = Vec<2>::Constant(-0.5 * cells * h);
  grid.upper = Vec<2>::Constant(0.5 * cells * h);
  grid.cells = {cells, cells};
  BasisOptions basis;
  basis.kind = "linear";
  parts.basis = make_basis<2>(basis, NodeSet<2>::cartesian(grid));
  parts.mode = ul ? NodeMode<2>::advected() : NodeMode<2>::fixed_grid(grid.lower, grid.upper);

  // 2. The particles, on rings.
  parts.particles = ring_particles(rings, R, rho, omega);

  // 3. The material: neo-Hookean (wobbes eq. 11), objective under the rotation.
  parts.materials.push_back(make_material<2>(
      {.name = "rubber", .model = "neo_hookean", .density = rho, .young = E, .poisson = nu, .extra = {}}));

  // 4. The step settings: MUSL (wobbes sect. 4) with the lumped mass, CFL 0.2.
  //    The engine allocates the particle fields the integrator and the
  //    material keep (here F, for the finite-strain material).
  const IntegratorKind& kind = integrator_kind("musl");
  parts.settings.step = kind.step<2>();
  parts.settings.parameters = kind.default_parameters();
  parts.settings.t_end = t_end;
  parts.settings.cfl = 0.2;
  parts.settings.h = h;

  double L0 = 0.0, K0 = 0.0;
  momenta(parts.particles, L0, K0);

  // 5. The engine, stepped to t_end.
  Engine<2> engine(std::move(parts));
  while (engine.time() < t_end * (1 - 1e-9)) engine.step();

  // 6. What the rotation kept.
  double L1 = 0.0, K1 = 0.0;
  momenta(engine.particles(), L1, K1);
  std::printf("spinning disk, %d particles on %d rings, linear musl %s: %ld steps to t = %.4g s\n",
              engine.particles().size(), rings, ul ? "ul" : "mpm", engine.steps(), engine.time());
  std::printf("angular momentum %.6g -> %.6g kg m^2/s (%.2f%%), kinetic energy %.6g -> %.6g J (%.2f%%)\n", L0, L1,
              100 * (L1 - L0) / L0, K0, K1, 100 * (K1 - K0) / K0);
  return 0;
}
