// bench_sim_step: the cost of Simulation::step() in a C++ loop, the
// reference of the Python per-step overhead (bench/bench_python.py).
//
//   build/bench/bench_sim_step SCENE.toml [--steps N] [--repeat R]
//
// Builds a Simulation of the scene without a result file, then times N
// calls of step() (R times, each on a fresh simulation after one untimed
// step) and prints the median time per step in nanoseconds:
//   cxx_ns_per_step MEDIAN (of R: MIN .. MAX)
#include "otmpm/openmp_wait.hpp"
#include "otmpm/run/simulation.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv); // as the otmpm command waits (openmp_wait.hpp)
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_sim_step SCENE.toml [--steps N] [--repeat R]\n");
    return 2;
  }
  long steps = 10000;
  int repeat = 9;
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (a == "--steps") steps = std::stol(v);
    else if (a == "--repeat") repeat = std::stoi(v);
  }
  const otmpm::Scene scene = otmpm::load_scene(argv[1]);
  otmpm::RunOptions options;
  options.write_results = false;
  std::vector<double> ns;
  for (int r = 0; r < repeat; ++r) {
    otmpm::Simulation sim(scene, options);
    sim.step(); // untimed: first basis evaluation, buffers grow
    const auto t0 = std::chrono::steady_clock::now();
    for (long s = 0; s < steps; ++s) sim.step();
    ns.push_back(std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count() / steps);
  }
  std::sort(ns.begin(), ns.end());
  std::printf("cxx_ns_per_step %.1f (of %d: %.1f .. %.1f)\n", ns[ns.size() / 2], repeat, ns.front(), ns.back());
  return 0;
}
