// bench_fixed_bar: the fixed bar of the methods table alone (512 nodes,
// examples/fixed_bar.toml; MPM-linear, unified and OTM-maxent as
// bench_table runs them), whole runs on one thread, interleaved; prints
// the medians of the wall time and of each phase per method, and the
// ratios to MPM-linear (medians of the per-round ratios).
//
//   OMP_NUM_THREADS=1 build-bench/bench/bench_fixed_bar [--rounds R] [--no-otm]
//
// Quicker than bench_table for work on these rows, and with the phase
// times beside the wall time (docs/performance-log-2026.md, "The unified step").
#include "otmpm/openmp_wait.hpp"
#include "bench_run.hpp"

#include <cstdio>
#include <string>
#include <vector>

using namespace otmpm;
using namespace otmpm::bench;

namespace {

/// examples/fixed_bar.toml on 512 nodes with a method's overrides.
Scene fixed_bar(std::vector<std::string> overrides) {
  overrides.push_back("grid.cells=[511]");
  overrides.push_back("output.every=0");
  return load_scene(OTMPM_SOURCE_DIR "/examples/fixed_bar.toml", overrides);
}

/// One method's scene and its timings per round.
struct Method {
  std::string name;
  Scene scene;
  std::vector<Timing> runs;
};

void print(const Method& m, const Method& reference) {
  std::vector<double> wall, ratio;
  std::vector<std::vector<double>> phase(phase_names.size());
  for (std::size_t r = 0; r < m.runs.size(); ++r) {
    wall.push_back(m.runs[r].wall);
    ratio.push_back(m.runs[r].wall / reference.runs[r].wall);
    for (std::size_t i = 0; i < phase_names.size(); ++i) phase[i].push_back(m.runs[r].phases.seconds[i]);
  }
  std::printf("%-12s wall %.5f s  / MPM-linear %.3f  phases", m.name.c_str(), median(wall), median(ratio));
  for (std::size_t i = 0; i < phase_names.size(); ++i)
    std::printf(" %s %.5f", std::string(phase_names[i]).c_str(), median(phase[i]));
  std::printf("\n");
}

} // namespace

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv);
  int rounds = 15;
  bool otm = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--rounds" && i + 1 < argc) rounds = std::stoi(argv[++i]);
    else if (a == "--no-otm") otm = false;
    else {
      std::fprintf(stderr, "usage: bench_fixed_bar [--rounds R] [--no-otm]\n");
      return 2;
    }
  }
  if (rounds < 1) {
    std::fprintf(stderr, "bench_fixed_bar: --rounds must be at least 1\n");
    return 2;
  }
  std::vector<Method> methods;
  methods.push_back({"MPM-linear", fixed_bar({"simulation.mode=mpm", "simulation.integrator=fe",
                                              "simulation.mass=lumped", "basis.kind=linear"}), {}});
  methods.push_back({"unified", fixed_bar({"simulation.mode=ul", "simulation.integrator=unified",
                                           "simulation.mass=consistent", "basis.kind=bspline2"}), {}});
  if (otm)
    methods.push_back({"OTM-maxent", fixed_bar({"simulation.mode=ul", "simulation.integrator=otm",
                                                "simulation.mass=consistent", "basis.kind=maxent", "basis.d_max=2"}),
                       {}});
  for (int r = 0; r < rounds; ++r)
    for (Method& m : methods) m.runs.push_back(time_whole_run(m.scene, 1));
  std::printf("fixed bar, 512 nodes (%ld particles, %ld steps), %d interleaved rounds of whole runs, one thread; "
              "medians (s)\n",
              methods[0].runs[0].particles, methods[0].runs[0].steps, rounds);
  for (const Method& m : methods) print(m, methods[0]);
  return 0;
}
