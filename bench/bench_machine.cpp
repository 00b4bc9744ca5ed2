// bench_machine: the limits of one core that a particle-step is measured
// against (docs/performance.md, "Against the machine").
//
//   build/bench/bench_machine [--repeat R] [--mb M]
//
// Prints, best of R runs each:
// - triad_gb_s: a[i] = b[i] + 3 c[i] over three arrays of M MB (default
//   256: far beyond the caches), counted as STREAM counts it, 24 bytes per
//   element (the write-allocate read of a is not counted);
// - clock_ghz: a chain of dependent integer adds, one per cycle;
// - max_ipc: instructions per cycle of eight independent add chains, the
//   most simple integer instructions this core retires per cycle (x86-64
//   only; elsewhere 0, not measured);
// - max_ginstr_s: clock_ghz x max_ipc, the instruction rate a step can
//   approach at best.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// Best triad rate over `repeat` passes, GB/s (24 bytes per element).
double triad_gb_s(std::size_t n, int repeat) {
  std::vector<double> a(n, 0.0), b(n, 1.0), c(n, 2.0);
  double best = 0.0;
  for (int r = 0; r < repeat; ++r) {
    const auto t0 = Clock::now();
    double* __restrict pa = a.data();
    const double* __restrict pb = b.data();
    const double* __restrict pc = c.data();
    for (std::size_t i = 0; i < n; ++i) pa[i] = pb[i] + 3.0 * pc[i];
    best = std::max(best, 24.0 * static_cast<double>(n) / seconds_since(t0) * 1e-9);
  }
  if (a[n / 2] != 7.0) std::fprintf(stderr, "bench_machine: triad gave %g, not 7\n", a[n / 2]);
  return best;
}

#if defined(__x86_64__)
/// Seconds for `loops` iterations of 16 adds: one dependent chain (one add
/// per cycle) or eight independent chains (as many adds per cycle as the
/// core issues).
double adds(long loops, bool independent) {
  long r[8] = {};
  const auto t0 = Clock::now();
  if (!independent)
    for (long i = 0; i < loops; ++i)
      asm volatile("add $1, %0\n\tadd $1, %0\n\tadd $1, %0\n\tadd $1, %0\n\t"
                   "add $1, %0\n\tadd $1, %0\n\tadd $1, %0\n\tadd $1, %0\n\t"
                   "add $1, %0\n\tadd $1, %0\n\tadd $1, %0\n\tadd $1, %0\n\t"
                   "add $1, %0\n\tadd $1, %0\n\tadd $1, %0\n\tadd $1, %0"
                   : "+r"(r[0]));
  else
    for (long i = 0; i < loops; ++i)
      asm volatile("add $1, %0\n\tadd $1, %1\n\tadd $1, %2\n\tadd $1, %3\n\t"
                   "add $1, %4\n\tadd $1, %5\n\tadd $1, %6\n\tadd $1, %7\n\t"
                   "add $1, %0\n\tadd $1, %1\n\tadd $1, %2\n\tadd $1, %3\n\t"
                   "add $1, %4\n\tadd $1, %5\n\tadd $1, %6\n\tadd $1, %7"
                   : "+r"(r[0]), "+r"(r[1]), "+r"(r[2]), "+r"(r[3]), "+r"(r[4]), "+r"(r[5]), "+r"(r[6]), "+r"(r[7]));
  const double s = seconds_since(t0);
  if (r[0] + r[1] + r[2] + r[3] + r[4] + r[5] + r[6] + r[7] != 16 * loops)
    std::fprintf(stderr, "bench_machine: the adds gave the wrong sum\n");
  return s;
}
#endif

} // namespace

int main(int argc, char** argv) {
  int repeat = 5;
  double mb = 256.0;
  for (int i = 1; i < argc; i += 2) {
    const std::string a = argv[i];
    char* end = nullptr;
    const double value = i + 1 < argc ? std::strtod(argv[i + 1], &end) : 0.0;
    const bool number = end && *end == '\0' && value >= 1.0;
    if (number && a == "--repeat") repeat = static_cast<int>(value);
    else if (number && a == "--mb") mb = value;
    else {
      std::fprintf(stderr, "bench_machine: '%s'%s: usage: bench_machine [--repeat R] [--mb M] (R, M >= 1)\n", argv[i],
                   i + 1 < argc ? "" : " without a value");
      return 2;
    }
  }
  const auto n = static_cast<std::size_t>(mb * 1e6 / 8.0);
  std::printf("triad_gb_s %.2f\n", triad_gb_s(n, repeat));
#if defined(__x86_64__)
  const long loops = 200000000; // 3.2e9 adds: about a second at 3 GHz
  // The two loops back to back in each round, so that both see the same
  // clock (a virtual core's speed moves between rounds): the adds per cycle
  // of a round is their time ratio, the best round counts.
  double chain = 1e30, ipc = 0.0;
  for (int r = 0; r < repeat; ++r) {
    const double c = adds(loops, false), w = adds(loops, true);
    chain = std::min(chain, c);
    // Each iteration of the wide loop retires its 16 adds and the loop's
    // increment, compare and branch (counted as 3 instructions).
    ipc = std::max(ipc, 19.0 / 16.0 * c / w);
  }
  const double ghz = 16.0 * loops / chain * 1e-9;
  std::printf("clock_ghz %.3f\nmax_ipc %.2f\nmax_ginstr_s %.2f\n", ghz, ipc, ghz * ipc);
#else
  std::printf("clock_ghz 0\nmax_ipc 0\nmax_ginstr_s 0\n");
#endif
  return 0;
}
