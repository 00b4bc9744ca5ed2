// --threads of the otmpm command (the default OpenMP wait: otmpm/openmp_wait.hpp).
#include "cli.hpp"

#include <cstdlib>
#include <sched.h>
#include <thread>
#include <unistd.h>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

namespace otmpm::cli {

namespace {
/// Upper bound of --threads: far above any machine's cores, low enough that a
/// typo (--threads 1000000) is refused instead of creating a million threads.
constexpr int kMaxThreads = 4096;
} // namespace

CLI::Option* add_threads_option(CLI::App& sub, int& threads, const std::string& what) {
  return sub
      .add_option("--threads", threads,
                  what.empty() ? "OpenMP threads (default: OMP_NUM_THREADS, else one per core)" : what)
      ->check(CLI::Range(1, kMaxThreads))
      ->type_name("N");
}

void set_threads(int threads) {
#ifdef OTMPM_HAVE_OPENMP
  if (threads > 0) omp_set_num_threads(threads);
#else
  (void)threads;
#endif
}

bool core_free_for_writer() {
  int cores = static_cast<int>(std::thread::hardware_concurrency());
#ifdef __linux__
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) cores = CPU_COUNT(&set); // taskset, cgroups' cpusets
#endif
#ifdef OTMPM_HAVE_OPENMP
  const int threads = omp_get_max_threads();
#else
  const int threads = 1;
#endif
  return cores > threads;
}

} // namespace otmpm::cli
