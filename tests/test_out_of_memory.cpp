// Memory running out while a run steps (std::bad_alloc): the run stops with
// status "out of memory: step N, t = T s: ...", exit code 4 (the command's
// exit status), the summary line "OUT OF MEMORY: ...", and a valid result
// file keeping the frames written before - wherever in a step the
// allocation fails. This executable replaces the global operator new: once
// armed, the K-th allocation made by the stepping thread outside any OpenMP
// region throws std::bad_alloc (an exception cannot leave an OpenMP region,
// and a real machine fails those the same way: by ending the process).
#include "otmpm/io/output_files.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/run/simulation.hpp"

#include "temp_dir.hpp"

#include <doctest/doctest.h>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <new>
#include <string>
#include <thread>

using namespace otmpm;
using test::TempDir;

namespace {

/// Allocations left before the one that fails (-1: not armed).
std::atomic<long> g_countdown{-1};
/// The thread whose allocations may fail (the test's, which steps the run).
std::thread::id g_stepping;

bool outside_parallel_regions() {
#ifdef OTMPM_HAVE_OPENMP
  return omp_get_level() == 0;
#else
  return true;
#endif
}

/// Makes the `k`-th allocation from now of the stepping thread, outside OpenMP regions, fail.
void arm(long k) {
  g_stepping = std::this_thread::get_id();
  g_countdown.store(k);
}

void disarm() { g_countdown.store(-1); }

} // namespace

void* operator new(std::size_t n) {
  if (g_countdown.load(std::memory_order_relaxed) >= 0 && std::this_thread::get_id() == g_stepping &&
      outside_parallel_regions() && g_countdown.fetch_sub(1) == 0)
    throw std::bad_alloc();
  if (void* p = std::malloc(n > 0 ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace {

const std::string kDyka = OTMPM_SOURCE_DIR "/examples/dyka.toml";

/// A short Dyka run writing a frame after every few steps, with a checkpoint every 3 steps.
Scene scene() {
  return load_scene(kDyka, {"simulation.t_end=3e-6", "output.every=1e-7", "output.checkpoint_every=3"});
}

/// The checks of a run stopped by memory running out.
void check_stopped(const RunSummary& s, const std::string& result) {
  CHECK(s.exit_code == kOutputErrorExit);
  CHECK(s.status.rfind("out of memory: step ", 0) == 0);
  CHECK(summary_line(s).rfind("OUT OF MEMORY: ", 0) == 0);
  CHECK(read_string_attribute(result, "status") == s.status);
  CHECK_FALSE(std::filesystem::exists(lock_path(result)));
}

} // namespace

TEST_CASE("memory running out at any allocation of a step stops the run with status 'out of memory', "
          "exit code 4") {
  TempDir t("out_of_memory");
  const Scene s = scene();
  long failed = 0;
  for (long k = 0;; k += k < 32 ? 1 : k / 8) { // the first 32 allocations, then a sample of the later ones
    CAPTURE(k);
    const std::string result = t.file("run" + std::to_string(k) + ".h5");
    RunOptions opt;
    opt.out_file = result;
    Simulation sim(s, opt);
    sim.step(); // a frame and a first step without failures
    bool threw = false;
    arm(k);
    try {
      for (int i = 0; i < 3 && !sim.finished(); ++i) sim.step(); // the frames and the checkpoint of step 3
    } catch (const std::bad_alloc&) {
      threw = true;
    }
    disarm();
    if (!threw) break; // every allocation of these steps has failed once
    ++failed;
    CHECK(sim.finished());
    CHECK_THROWS_AS(sim.step(), std::logic_error);
    check_stopped(sim.finish(), result);
  }
  CHECK(failed > 40); // the steps, frames and the checkpoint allocate hundreds of times
}

TEST_CASE("run_scene returns the out-of-memory summary (exit code 4) and never lets std::bad_alloc out") {
  TempDir t("out_of_memory_run");
  RunOptions opt;
  opt.out_file = t.file("run.h5");
  opt.progress = [](double, double, long steps) {
    if (steps == 2) arm(5);
  };
  const RunSummary s = run_scene(scene(), opt);
  disarm();
  check_stopped(s, opt.out_file);
  CHECK(s.steps >= 2);
}
