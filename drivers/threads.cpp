// --threads of the otmpm command (the default OpenMP wait: otmpm/openmp_wait.hpp).
#include "cli.hpp"

#include "otmpm/openmp_wait.hpp"

#include <algorithm>
#include <cstdlib>
#include <sched.h>
#include <string>
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

namespace {
/// The CPUs this process may run on: with bound threads those of the OpenMP
/// places (libgomp bound this thread to the first place when it was
/// loaded), else its affinity mask (taskset, a cgroup's cpuset, a
/// launcher's binding), else the machine's.
int usable_cpus() {
  if (const std::size_t places = openmp_place_cpus().size(); places > 0) return static_cast<int>(places);
  int cpus = static_cast<int>(std::thread::hardware_concurrency());
#ifdef __linux__
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) cpus = CPU_COUNT(&set);
#endif
  return std::max(cpus, 1);
}

int openmp_threads() {
#ifdef OTMPM_HAVE_OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}
} // namespace

bool core_free_for_writer() { return usable_cpus() > openmp_threads(); }

std::string threads_line() {
  const int threads = openmp_threads(), cpus = usable_cpus();
  std::string line = std::to_string(threads) + (threads == 1 ? " OpenMP thread" : " OpenMP threads") +
                     " on " + std::to_string(cpus) + (cpus == 1 ? " CPU" : " CPUs") + " this process may use";
  if (threads > cpus) {
    const std::string n = std::to_string(threads), c = std::to_string(cpus);
    line += ": more threads than CPUs take turns, no faster than " + c + " would be (the CPUs are this";
    line += " process's affinity mask: taskset, a cgroup, or mpirun or srun binding each rank to one";
    line += " core; give each rank a core per thread, e.g. mpirun --map-by slot:pe=" + n;
    line += " or srun --cpus-per-task=" + n + ")";
  }
  return line;
}

} // namespace otmpm::cli
