// bench_table: every row of the issue-7 performance table in one run.
//
//   OMP_NUM_THREADS=2 build-rel/bench/bench_table [--repeat R] [--scaling-csv FILE] [--quick]
//
// Cases that are compared (linear vs LME, ul vs mpm, 2 threads vs 1) run
// interleaved, one repetition of each in turn, so that a change of machine
// load hits all of them alike; ratios are medians of the per-repetition
// ratios. The memory row runs in a child process (peak RSS of a process that
// does only the linear block run). Prints a markdown table, the phase shares
// of each case, and (with --scaling-csv) the time per step against the
// particle count for the scaling plot.
#include "bench_scenes.hpp"
#include "otmpm/assembly/assembler.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

using namespace otmpm;
using otmpm::bench::block_scene;

namespace {

/// Seconds per step and phase times of one timed run.
struct Timing {
  double per_step = 0.0;
  long particles = 0;
  long steps = 0;
  PhaseTimers phases;
};

void set_threads(int threads) {
#ifdef OTMPM_HAVE_OPENMP
  omp_set_num_threads(threads);
#else
  (void)threads;
#endif
}

/// Builds the engine, takes one untimed step (first basis evaluation, cold
/// LME start, buffers grow), then times `steps` steps (0: up to t_end).
Timing time_run(const Scene& scene, long steps, int threads) {
  set_threads(threads);
  Engine<2> e = assemble<2>(scene);
  e.step();
  e.timers() = PhaseTimers{};
  const auto t0 = std::chrono::steady_clock::now();
  long done = 0;
  for (; steps > 0 ? done < steps : e.time() < scene.simulation.t_end; ++done) e.step();
  Timing t;
  t.per_step = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / double(done);
  t.particles = e.particles().size();
  t.steps = done;
  t.phases = e.timers();
  return t;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string phase_shares(const PhaseTimers& p) {
  double total = 0;
  for (double s : p.seconds) total += s;
  std::string out;
  char buf[64];
  for (std::size_t i = 0; i < phase_names.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%s %.0f%%%s", std::string(phase_names[i]).c_str(),
                  total > 0 ? 100 * p.seconds[i] / total : 0.0, i + 1 < phase_names.size() ? ", " : "");
    out += buf;
  }
  return out;
}

/// A named case of the interleaved comparison.
struct Case {
  std::string name;
  Scene scene;
  long steps;
  int threads;
  std::vector<double> per_step;
  Timing last;
};

/// Peak RSS in bytes of this process so far.
double peak_rss_bytes() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) * 1024.0;
}

/// The memory child: the linear block run alone, then its peak RSS.
int memory_child() {
  const double before = peak_rss_bytes();
  const Scene scene = parse_scene(block_scene(200, "linear", "fe", "mpm", 3.0), "block.toml");
  const Timing t = time_run(scene, 100, 1);
  std::printf("%ld %.0f %.0f\n", t.particles, peak_rss_bytes(), before);
  return 0;
}

/// The 2D Dyka strip of issue 7: examples/dyka_2d.toml with 160 cells along
/// the bar (plus two spare cells on the left), LME gamma_lme = 3, NPC.
Scene dyka_strip() {
  const double L = 0.1333, h = L / 160;
  return load_scene(OTMPM_SOURCE_DIR "/examples/dyka_2d.toml",
                    {"grid.lower=[" + std::to_string(-2 * h) + ", 0.0]", "grid.upper=[0.1333, " + std::to_string(h) + "]",
                     "grid.cells=[162, 1]", "body.bar.upper=[0.1333, " + std::to_string(h) + "]",
                     "initial_velocity.0.upper=[0.033325, " + std::to_string(h) + "]",
                     "boundary.right_end.upper=[0.1333, " + std::to_string(h) + "]", "basis.gamma_lme=3.0",
                     "output.every=0"});
}

/// Least-squares slope of log(y) against log(x).
double loglog_slope(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = double(x.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double a = std::log(x[i]), b = std::log(y[i]);
    sx += a, sy += b, sxx += a * a, sxy += a * b;
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

} // namespace

int main(int argc, char** argv) {
  int repeat = 5;
  bool quick = false;
  std::string scaling_csv;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--memory-child") return memory_child();
    if (a == "--repeat" && i + 1 < argc) repeat = std::stoi(argv[++i]);
    else if (a == "--scaling-csv" && i + 1 < argc) scaling_csv = argv[++i];
    else if (a == "--quick") quick = true;
    else {
      std::fprintf(stderr, "usage: bench_table [--repeat R] [--scaling-csv FILE] [--quick]\n");
      return 2;
    }
  }
  const int cells = quick ? 60 : 200;
  const long steps = quick ? 5 : 20;
  auto block = [&](const char* basis, const char* integrator, const char* mode) {
    return parse_scene(block_scene(cells, basis, integrator, mode, 3.0), "block.toml");
  };
  std::vector<Case> cases{{"linear fe mpm, 1 thread", block("linear", "fe", "mpm"), steps, 1, {}, {}},
                          {"lme npc mpm, 1 thread", block("lme", "npc", "mpm"), steps / 2, 1, {}, {}},
                          {"lme npc ul, 1 thread", block("lme", "npc", "ul"), steps / 2, 1, {}, {}},
                          {"linear fe mpm, 2 threads", block("linear", "fe", "mpm"), steps, 2, {}, {}},
                          {"dyka strip lme npc, 1 thread", dyka_strip(), quick ? 200 : 0, 1, {}, {}}};
  for (int r = 0; r < repeat; ++r)
    for (Case& c : cases) {
      c.last = time_run(c.scene, c.steps, c.threads);
      c.per_step.push_back(c.last.per_step);
    }
  auto ratio = [&](int a, int b) {
    std::vector<double> q;
    for (int r = 0; r < repeat; ++r) q.push_back(cases[a].per_step[r] / cases[b].per_step[r]);
    return median(q);
  };
  auto rate = [&](int a) { return double(cases[a].last.particles) / median(cases[a].per_step); };

  // memory: a child process that runs only the linear block
  double rss = 0, rss_before = 0;
  long mem_particles = 0;
  if (!quick) {
    // The shell popen starts is /proc/self/exe in its own process: resolve ours first.
    char exe[4096] = {};
    const ssize_t len = readlink("/proc/self/exe", exe, sizeof exe - 1);
    const std::string cmd = std::string(len > 0 ? exe : argv[0]) + " --memory-child";
    if (FILE* f = popen(cmd.c_str(), "r")) {
      if (std::fscanf(f, "%ld %lf %lf", &mem_particles, &rss, &rss_before) != 3) mem_particles = 0;
      pclose(f);
    }
  }

  // scaling: time per step of the linear block from 1e4 to 1e6 particles
  std::vector<double> n_p, t_step;
  const std::vector<int> sizes = quick ? std::vector<int>{20, 40, 60} : std::vector<int>{50, 100, 158, 250, 354, 500};
  for (int c : sizes) {
    const Scene s = parse_scene(block_scene(c, "linear", "fe", "mpm", 3.0), "block.toml");
    std::vector<double> per;
    long np = 0;
    for (int r = 0; r < std::max(3, repeat / 2); ++r) {
      const Timing t = time_run(s, std::max(3L, 2000000L / (4L * c * c)), 1);
      per.push_back(t.per_step);
      np = t.particles;
    }
    n_p.push_back(double(np));
    t_step.push_back(median(per));
  }
  if (!scaling_csv.empty()) {
    std::ofstream out(scaling_csv);
    out << "particles,seconds_per_step\n";
    for (std::size_t i = 0; i < n_p.size(); ++i) out << n_p[i] << ',' << t_step[i] << '\n';
  }

  std::printf("block %dx%d cells (%ld particles), %d interleaved repetitions; medians\n\n", cells, cells,
              cases[0].last.particles, repeat);
  std::printf("| issue 7 figure | target | measured |\n|---|---|---|\n");
  std::printf("| block, linear, fe, mpm: particle-steps/s, one core | >= 1e7 | %.3g |\n", rate(0));
  std::printf("| block, LME gamma_lme = 3, npc: time per step / linear fe | <= 1.5 | %.2f |\n", ratio(1, 0));
  std::printf("| 2D Dyka strip, 160 cells, LME npc to t_end: particle-steps/s | >= 3e6 | %.3g (%ld particles, %ld steps) |\n",
              rate(4), cases[4].last.particles, cases[4].last.steps);
  std::printf("| block, ul / mpm (LME npc) | <= 1.3 | %.2f |\n", ratio(2, 1));
  std::printf("| block, linear fe, speed-up 2 threads vs 1 | >= 1.8 | %.2f |\n", 1.0 / ratio(3, 0));
  if (mem_particles > 0)
    std::printf("| linear block run: peak RSS / particle (whole process) | <= 400 B | %.0f B (%.1f MB peak, %.1f MB before the scene) |\n",
                rss / double(mem_particles), rss / 1e6, rss_before / 1e6);
  std::printf("| scaling exponent, %.0e..%.0e particles (linear fe) | <= 1.05 | %.3f |\n", n_p.front(), n_p.back(),
              loglog_slope(n_p, t_step));
  std::printf("\nphase shares (last repetition):\n");
  for (const Case& c : cases) std::printf("  %-30s %s\n", c.name.c_str(), phase_shares(c.last.phases).c_str());
  std::printf("\nmedian time per particle-step:\n");
  for (const Case& c : cases)
    std::printf("  %-30s %.3f us\n", c.name.c_str(), 1e6 * median(c.per_step) / double(c.last.particles));
  return 0;
}
