// bench_two_phase: the cost of a saturated body's particle-step against a dry
// one with the same basis and integrator (docs/benchmarks.md, "Saturated soil").
//
//   OMP_NUM_THREADS=1 build/bench/bench_two_phase [--cells N] [--steps S] [--repeat R]
//       [--basis linear|bspline2|...] [--integrator fe|musl] [--dim 2|3]
//
// The elastic block of bench_step (N^D cells, 2^D particles per cell, falling
// under gravity on its fixed base), dry and saturated (the same skeleton with
// porosity 0.4, permeability 1e-10 m^2 and water: the liquid's nodal sums and
// solve, its particle update and the pore pressure). The saturated step is
// shorter (the water's stiffness sets it), so both are timed per step: the
// median over R repetitions of particle-steps per second of each, and their
// ratio - the cost of a two-phase particle-step in single-phase ones. The
// dry and saturated runs alternate and are timed by the thread's CPU time
// (run it with one thread), so that a busy machine moves both alike.
#include "otmpm/openmp_wait.hpp"
#include "bench_run.hpp"
#include "bench_scenes.hpp"

#include <cstdio>
#include <string>
#include <vector>

using namespace otmpm;
using namespace otmpm::bench;

namespace {

const std::string kSaturated = kBlockLinearElastic + "\nporosity = 0.4\npermeability = 1.0e-10\nfluid_density = 1000.0"
                                                     "\nfluid_bulk_modulus = 2.2e9\nfluid_viscosity = 1.0e-3";

/// Particle-steps per CPU second of the calling thread (one thread: the time
/// the thread ran, not the moments a busy machine took its core).
double rate(const Scene& scene, int dim, int steps, Timing& t) {
  t = dim == 3 ? time_run<3>(scene, steps, 0) : time_run<2>(scene, steps, 0); // threads: OMP_NUM_THREADS
  return double(t.particles) * double(t.steps) / t.cpu;
}

} // namespace

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv); // as the otmpm command waits (openmp_wait.hpp)
  int cells = 100, steps = 100, repeat = 5, dim = 2;
  std::string basis = "linear", integrator = "fe";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (a == "--cells") cells = std::stoi(v);
    else if (a == "--steps") steps = std::stoi(v);
    else if (a == "--repeat") repeat = std::stoi(v);
    else if (a == "--basis") basis = v;
    else if (a == "--integrator") integrator = v;
    else if (a == "--dim") dim = std::stoi(v);
  }
  if (dim != 2 && dim != 3) {
    std::fprintf(stderr, "bench_two_phase: --dim must be 2 or 3\n");
    return 2;
  }
  const Scene dry_scene = parse_scene(block_scene(dim, cells, basis, integrator, "mpm", 3.0), "dry.toml");
  const Scene wet_scene = parse_scene(block_scene(dim, cells, basis, integrator, "mpm", 3.0, kSaturated), "wet.toml");
  Timing dry_t, wet_t;
  std::vector<double> dry_rates, wet_rates, ratios;
  for (int r = 0; r < repeat; ++r) { // side by side, so that both see the machine's load alike
    dry_rates.push_back(rate(dry_scene, dim, steps, dry_t));
    wet_rates.push_back(rate(wet_scene, dim, steps, wet_t));
    ratios.push_back(dry_rates.back() / wet_rates.back());
  }
  const double dry = median(dry_rates), wet = median(wet_rates);
  std::printf("block %d^%d cells, %ld particles, mpm %s %s (median of %d pairs of runs of %d steps, CPU time):\n", cells, dim,
              dry_t.particles, basis.c_str(), integrator.c_str(), repeat, steps);
  std::printf("  dry       %.3e particle-steps/s (%.3f us/step/particle)\n", dry, 1e6 / dry);
  std::printf("  saturated %.3e particle-steps/s (%.3f us/step/particle)\n", wet, 1e6 / wet);
  std::printf("  a saturated particle-step costs %.2f dry ones (median of the pairs' ratios; target <= 2.5)\n",
              median(ratios));
  return 0;
}
