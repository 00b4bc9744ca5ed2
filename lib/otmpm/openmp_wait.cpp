/// \file openmp_wait.cpp
/// The default OpenMP wait of otmpm's programs (openmp_wait.hpp).
#include "otmpm/openmp_wait.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <string>
#include <unistd.h>
#include <vector>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif
#ifdef __linux__
#include <sched.h>
#endif

namespace otmpm {

namespace {

constexpr int kCalibrationSpins = 2048;
constexpr int kCalibrationRounds = 3;
constexpr long long kMinSpins = 100;
constexpr long long kMaxSpins = 10000000;
/// Seconds of a spin on the processors with the slowest pause (about 50 ns).
constexpr double kSlowestSpin = 5e-8;

/// The processor's spin-wait hint, as libgomp's cpu_relax.
inline void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__)
  __asm__ __volatile__("yield" ::: "memory");
#else
  __asm__ __volatile__("" ::: "memory");
#endif
}

/// Seconds of one spin of libgomp's wait loop: a relaxed load of a flag that
/// never changes, then the hint.
double seconds_per_spin() {
  static std::atomic<int> flag{0};
  double best = 1.0;
  for (int round = 0; round < kCalibrationRounds; ++round) {
    const auto start = std::chrono::steady_clock::now();
    for (int i = 0; i < kCalibrationSpins; ++i) {
      if (flag.load(std::memory_order_relaxed) != 0) break;
      cpu_relax();
    }
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    best = std::min(best, s / kCalibrationSpins);
  }
  return best;
}

} // namespace

std::vector<int> openmp_place_cpus() {
  std::vector<int> cpus;
#ifdef OTMPM_HAVE_OPENMP
  std::vector<int> ids;
  for (int p = 0; p < omp_get_num_places(); ++p) {
    ids.resize(static_cast<std::size_t>(std::max(0, omp_get_place_num_procs(p))));
    omp_get_place_proc_ids(p, ids.data());
    for (const int id : ids)
      if (id >= 0) cpus.push_back(id);
  }
  std::sort(cpus.begin(), cpus.end());
  cpus.erase(std::unique(cpus.begin(), cpus.end()), cpus.end());
#endif
  return cpus;
}

void allow_every_place() {
#ifdef __linux__
  const std::vector<int> cpus = openmp_place_cpus();
  if (cpus.empty()) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  for (const int id : cpus)
    if (id < CPU_SETSIZE) CPU_SET(id, &set);
  if (CPU_COUNT(&set) > 0) sched_setaffinity(0, sizeof set, &set); // on failure the mask stays as it is
#endif
}

long long spin_count_for(double seconds) {
  double per_spin = seconds_per_spin();
  // a clock too coarse to see 2048 spins: take the slowest pause known (~50 ns)
  if (!(per_spin > 0.0)) per_spin = kSlowestSpin;
  return std::clamp(static_cast<long long>(seconds / per_spin), kMinSpins, kMaxSpins);
}

bool under_valgrind() {
  const char* preload = std::getenv("LD_PRELOAD");
  return preload && std::strstr(preload, "vgpreload") != nullptr;
}

void default_openmp_wait(char** argv) {
#ifdef OTMPM_HAVE_OPENMP
  if (std::getenv("OMP_WAIT_POLICY") || std::getenv("GOMP_SPINCOUNT") || under_valgrind()) return;
  const std::string spins = std::to_string(spin_count_for(kDefaultSpinSeconds));
  if (setenv("GOMP_SPINCOUNT", spins.c_str(), 1) != 0 || setenv("OMP_WAIT_POLICY", "passive", 1) != 0) return;
  allow_every_place();
  execv("/proc/self/exe", argv);
  // exec failed (no /proc): go on with libgomp's default wait.
#else
  (void)argv;
#endif
}

} // namespace otmpm
