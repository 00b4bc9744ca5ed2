// bench_step: whole-step throughput of the engine (docs/performance.md).
//
//   OMP_NUM_THREADS=1 build/bench/bench_step [--cells N] [--steps S] [--repeat R]
//       [--basis linear|lme|...] [--integrator fe|npc] [--mode mpm|ul] [--gamma-lme G] [--dim 2|3]
//
// A 2D elastic block (plane strain, E = 10 MPa, rho = 1000, nu = 0.3) of
// N x N cells with 2 x 2 particles per cell, inside a grid with two spare cells
// on each side, falling under gravity with its base fixed - every stage of a
// step runs. With --dim 3 the 3D block of the methods table (N^3 cells,
// 2 x 2 x 2 particles per cell). Prints the median over R repetitions of particle-steps per second
// and the share of each phase.
#include "otmpm/openmp_wait.hpp"
#include "bench_run.hpp"
#include "bench_scenes.hpp"

#include <cstdio>
#include <string>
#include <vector>

using namespace otmpm;
using namespace otmpm::bench;

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv); // as the otmpm command waits (openmp_wait.hpp)
  int cells = 200, steps = 100, repeat = 5;
  std::string basis = "linear", integrator = "fe", mode = "mpm";
  double gamma_lme = 3.0;
  int dim = 2;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (a == "--cells") cells = std::stoi(v);
    else if (a == "--steps") steps = std::stoi(v);
    else if (a == "--repeat") repeat = std::stoi(v);
    else if (a == "--basis") basis = v;
    else if (a == "--integrator") integrator = v;
    else if (a == "--mode") mode = v;
    else if (a == "--gamma-lme") gamma_lme = std::stod(v);
    else if (a == "--dim") dim = std::stoi(v);
  }
  if (dim != 2 && dim != 3) {
    std::fprintf(stderr, "bench_step: --dim must be 2 or 3\n");
    return 2;
  }
  const Scene scene = parse_scene(block_scene(dim, cells, basis, integrator, mode, gamma_lme), "bench_step.toml");
  std::vector<double> rates;
  Timing last;
  for (int r = 0; r < repeat; ++r) {
    last = dim == 3 ? time_run<3>(scene, steps, 0) : time_run<2>(scene, steps, 0); // threads: OMP_NUM_THREADS
    rates.push_back(double(last.particles) / last.per_step);
  }
  const double rate = median(rates);
  std::printf("block %d^%d cells, %ld particles, %s %s %s: median %.3e particle-steps/s (of %d runs), %.3f us/step/particle\n",
              cells, dim, last.particles, mode.c_str(), basis.c_str(), integrator.c_str(), rate, repeat, 1e6 / rate);
  std::printf("phases: %s\n", phase_shares(last.phases).c_str());
  return 0;
}
