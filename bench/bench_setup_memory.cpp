// bench_setup_memory: the memory of a distributed run's set-up and steps,
// per rank (docs/performance-log-2026.md, "Distributed runs", set-up memory).
//
//   mpirun -np N build/bench/bench_setup_memory SCENE.toml [STEPS]
//
// Each rank builds its share of the scene (distributed::rank_parts, as
// `otmpm run` does), then its engine, then takes STEPS steps (default 5),
// and prints one line (the ranks in turn):
//   rank R/N: particles LOCAL of GLOBAL, set-up S s, set-up peak A MB (rss B MB), engine peak C MB,
//   stepping peak D MB (rss E MB)
// set-up: wall time of rank_parts; peaks: getrusage ru_maxrss since the
// process started (the MPI runtime included); rss: VmRSS of
// /proc/self/status at that moment.
#include "otmpm/openmp_wait.hpp"
#include "otmpm/distributed/local_parts.hpp"
#include "otmpm/scene/scene.hpp"

#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>

namespace {

double peak_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;
}

double rss_mb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0.0;
}

template <int D> int measure(const otmpm::Scene& scene, long steps) {
  namespace dist = otmpm::distributed;
  const dist::Comm& comm = dist::Comm::world();
  const auto start = std::chrono::steady_clock::now();
  otmpm::EngineParts<D> parts = dist::rank_parts<D>(scene, comm);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double setup_peak = peak_mb(), setup_rss = rss_mb();
  otmpm::Engine<D> e(std::move(parts));
  const double engine_peak = peak_mb();
  for (long s = 0; s < steps; ++s) e.step();
  const double step_peak = peak_mb(), step_rss = rss_mb();
  const dist::Domain<D>* d = dist::domain_of(e);
  const long long global = d ? d->global_particles() : e.particles().size();
  for (int r = 0; r < comm.size(); ++r) {
    if (r == comm.rank())
      std::printf("rank %d/%d: particles %d of %lld, set-up %.2f s, set-up peak %.1f MB (rss %.1f MB), "
                  "engine peak %.1f MB, "
                  "stepping peak %.1f MB (rss %.1f MB)\n",
                  r, comm.size(), e.particles().size(), global, seconds, setup_peak, setup_rss, engine_peak, step_peak,
                  step_rss);
    std::fflush(stdout);
    comm.max(0.0); // the ranks in turn
  }
  return 0;
}

} // namespace

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv); // as the otmpm command waits (openmp_wait.hpp)
  otmpm::distributed::Session mpi(argc, argv);
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_setup_memory SCENE.toml [STEPS]\n");
    return 2;
  }
  const long steps = argc > 2 ? std::stol(argv[2]) : 5;
  const otmpm::Scene scene = otmpm::load_scene(argv[1]);
  switch (scene.simulation.dimension) {
  case 1: return measure<1>(scene, steps);
  case 2: return measure<2>(scene, steps);
  default: return measure<3>(scene, steps);
  }
}
