// bench_table: every row of the performance tables of docs/performance.md
// (throughput: the 2D block and the Dyka strip; methods: the methods' relative
// cost, the fixed bar, the 3D block; plastic: the 3D j2 block against
// neo_hookean and the full 3D Taylor bar) in one run; --table threads: each
// case of the targets on one and two threads, the speed-up (not in "all");
// --table targets: the current round's targets (the 10^6-particle block in
// fe and musl, the LME rows, then the plastic and the threads tables; not in
// "all").
//
//   OMP_NUM_THREADS=2 build-bench/bench/bench_table [--repeat R]
//       [--table throughput|methods|lme|plastic|threads|targets|all]
//       [--quick] [--scaling-csv FILE] [--scaling3d-csv FILE]
//
// Cases that are compared (linear vs LME, ul vs mpm, 2 threads vs 1, the
// fixed bar's methods) run interleaved, one repetition of each in turn, so
// that a change of machine load hits all of them alike; ratios are medians of
// the per-repetition ratios, rates use the median time. The memory row runs in
// a child process (peak RSS of a process that does only the linear block
// run). Prints each table in markdown (target, measured, met or not), the
// phase shares of each case, and the time per step against the particle count
// for the scaling plots (2D block with --scaling-csv, 3D block with
// --scaling3d-csv). --quick: small sizes, short runs and one repetition, to
// check that every row runs (its figures mean nothing). The output row of
// the methods table (result file bytes and write share) is scripts/bench-output.sh.
// --table lme: only the methods table's LME rows (the 2D and the 3D block,
// LME npc and LME with the box support (lme_box) npc against linear fe,
// interleaved).
#include "otmpm/openmp_wait.hpp"
#include "bench_run.hpp"
#include "bench_scenes.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <string>
#include <utility>
#include <vector>

using namespace otmpm;
using namespace otmpm::bench;

namespace {

/// A named case of an interleaved comparison: `run` times one repetition.
struct Case {
  Case() = default;
  Case(std::string n, std::function<Timing()> r) : name(std::move(n)), run(std::move(r)) {}
  std::string name;
  std::function<Timing()> run;
  std::vector<double> per_step; ///< per repetition
  std::vector<double> cpu_per_step; ///< the calling thread's CPU time per step, per repetition
  Timing last;
};

/// Runs `repeat` rounds of the cases, one repetition of each in turn.
void interleave(std::vector<Case*> cases, int repeat) {
  for (int r = 0; r < repeat; ++r)
    for (Case* c : cases) {
      c->last = c->run();
      c->per_step.push_back(c->last.per_step);
      c->cpu_per_step.push_back(c->last.cpu / double(c->last.steps));
    }
}

/// Median over the repetitions of a's time per step / b's.
double ratio(const Case& a, const Case& b) {
  std::vector<double> q;
  for (std::size_t r = 0; r < a.per_step.size(); ++r) q.push_back(a.per_step[r] / b.per_step[r]);
  return median(q);
}

/// Particle-steps per second at the median time per step.
double rate(const Case& c) { return double(c.last.particles) / median(c.per_step); }

/// One row of a printed table.
struct Row {
  std::string figure, target, measured;
  bool met;
};

std::string fmt(const char* format, double v) {
  char buf[128];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

void print_table(const char* title, const std::vector<Row>& rows) {
  std::printf("| %s | target | measured | met |\n|---|---|---|---|\n", title);
  for (const Row& r : rows)
    std::printf("| %s | %s | %s | %s |\n", r.figure.c_str(), r.target.c_str(), r.measured.c_str(),
                r.met ? "met" : "**not met**");
}

/// The phase shares and median times of the cases that ran (--table leaves some out).
void print_cases(std::vector<const Case*> cases) {
  std::erase_if(cases, [](const Case* c) { return c->per_step.empty(); });
  std::printf("\nphase shares (last repetition):\n");
  for (const Case* c : cases) std::printf("  %-48s %s\n", c->name.c_str(), phase_shares(c->last.phases).c_str());
  std::printf("\nmedian time per particle-step (wall; the calling thread's CPU time, which on one thread leaves out "
              "the moments it waited for a core):\n");
  for (const Case* c : cases)
    std::printf("  %-48s %.3f us, CPU %.3f us (%ld particles, %ld steps%s)\n", c->name.c_str(),
                1e6 * median(c->per_step) / double(c->last.particles),
                1e6 * median(c->cpu_per_step) / double(c->last.particles), c->last.particles, c->last.steps,
                c->last.nodes_per_particle > 0 ? fmt(", %.1f nodes per particle", c->last.nodes_per_particle).c_str()
                                               : "");
}

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
  const Timing t = time_run<2>(scene, 100, 1);
  std::printf("%ld %.0f %.0f\n", t.particles, peak_rss_bytes(), before);
  return 0;
}

/// The 2D Dyka strip (examples/dyka_2d.toml) of `cells` cells along the bar.
Scene dyka_strip(int cells, const std::vector<std::string>& extra) {
  return load_scene(OTMPM_SOURCE_DIR "/examples/dyka_2d.toml", dyka_strip_overrides(cells, extra));
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

/// Time per step of the linear fe mpm block, one thread, at each size (cells
/// per axis): median of `rounds` timings of about `particle_steps` each
/// (3 to 200 steps).
/// Writes particles,seconds_per_step to `csv` when not empty; returns the
/// particle counts and times.
template <int D>
std::pair<std::vector<double>, std::vector<double>> scaling(const std::vector<int>& sizes, int rounds,
                                                            long particle_steps, const std::string& csv) {
  std::vector<double> n_p, t_step;
  for (int c : sizes) {
    const Scene s = parse_scene(block_scene(D, c, "linear", "fe", "mpm", 3.0), "block.toml");
    set_threads(1);
    Engine<D> e = assemble<D>(s);
    e.step();
    std::vector<double> per;
    const long steps = std::clamp(particle_steps / long(e.particles().size()), 3L, 200L); // the block falls: not too far
    for (int r = 0; r < rounds; ++r) per.push_back(time_steps(e, steps, 1, s.simulation.t_end).per_step);
    n_p.push_back(double(e.particles().size()));
    t_step.push_back(median(per));
  }
  if (!csv.empty()) {
    std::ofstream out(csv);
    out << "particles,seconds_per_step\n";
    for (std::size_t i = 0; i < n_p.size(); ++i) out << n_p[i] << ',' << t_step[i] << '\n';
  }
  return {n_p, t_step};
}

/// The fixed bar of wobbes et al. (examples/fixed_bar.toml) on 512 nodes with
/// the method's overrides (scripts/wobbes_figures.py, METHODS).
Scene fixed_bar(const std::vector<std::string>& method) {
  std::vector<std::string> o = method;
  o.push_back("grid.cells=[511]");
  o.push_back("output.every=0");
  return load_scene(OTMPM_SOURCE_DIR "/examples/fixed_bar.toml", o);
}

/// A case that steps one of engine_cases' engines: its name, the engine
/// (index into the scenes), threads and steps per repetition.
struct EngineCase {
  std::string name;
  int engine = 0, threads = 1;
  long steps = 1;
};

/// One engine per scene (assembled on two threads), `settle` untimed steps
/// each (the first basis evaluation, a plastic block's flow), then `repeat`
/// interleaved repetitions of the cases in turn; returns the timed cases
/// (their engines end here).
template <int D>
std::vector<Case> engine_cases(const std::vector<Scene>& scenes, long settle, const std::vector<EngineCase>& specs,
                               int repeat) {
  set_threads(2);
  std::vector<Engine<D>> engines;
  engines.reserve(scenes.size());
  for (const Scene& s : scenes) engines.push_back(assemble<D>(s));
  for (Engine<D>& e : engines)
    for (long i = 0; i < settle; ++i) e.step();
  std::vector<Case> cases;
  for (const EngineCase& c : specs)
    cases.emplace_back(c.name, [&engines, &scenes, c] {
      return time_steps(engines[c.engine], c.steps, c.threads, scenes[c.engine].simulation.t_end);
    });
  std::vector<Case*> order;
  for (Case& c : cases) order.push_back(&c);
  interleave(order, repeat);
  for (Case& c : cases) c.run = nullptr;
  return cases;
}

/// The 3D block of `cells3`^3 cells, linear fe and LME npc (and linear fe
/// on 2 threads when lin3_2 is set): one engine per basis, built once and
/// stepped on by each of `repeat` interleaved repetitions.
/// With box3 set, LME with the box support (lme_box) npc as well.
void block3d_cases(int cells3, bool quick, int repeat, Case& lin3, Case& lme3, Case* lin3_2,
                   Case* box3 = nullptr) {
  const std::vector<Scene> scenes{
      parse_scene(block_scene(3, cells3, "linear", "fe", "mpm", 3.0), "block3d.toml"),
      parse_scene(block_scene(3, cells3, "lme", "npc", "mpm", 3.0), "block3d.toml"),
      parse_scene(block_scene(3, cells3, "lme_box", "npc", "mpm", 3.0), "block3d.toml")};
  const long n_lin = quick ? 2 : 4, n_lme = quick ? 1 : 2;
  std::vector<EngineCase> specs{{"3D block linear fe mpm, 1 thread", 0, 1, n_lin},
                                {"3D block lme npc mpm, 1 thread", 1, 1, n_lme}};
  if (lin3_2) specs.push_back({"3D block linear fe mpm, 2 threads", 0, 2, n_lin});
  if (box3) specs.push_back({"3D block lme_box npc mpm, 1 thread", 2, 1, n_lme});
  const std::vector<Case> cases = engine_cases<3>(scenes, 1, specs, repeat);
  lin3 = cases[0], lme3 = cases[1];
  if (lin3_2) *lin3_2 = cases[2];
  if (box3) *box3 = cases.back();
}

/// The 3D block's name in the rows: its cells and particles.
std::string block3d_name(int cells3, const Case& lin3) {
  return "3D block " + std::to_string(cells3) + "^3 cells" + fmt(" (%.0f particles)", double(lin3.last.particles));
}

/// The methods table's LME rows: the 2D block's and the 3D block's (`block3`
/// names it) LME npc / linear fe time per step.
/// The box support's rows (`box`, `box3`: lme_box npc / linear fe) follow
/// when given.
std::vector<Row> lme_rows(double lme_lin, double lme3_r, const std::string& block3, double box = -1.0,
                          double box3 = -1.0) {
  std::vector<Row> rows{{"2D block, LME gamma_lme = 3, npc: time per step / linear fe", "<= 2.5",
                         fmt("%.2f", lme_lin), lme_lin <= 2.5},
                        {block3 + ", LME gamma_lme = 3, npc: time per step / linear fe", "<= 3",
                         fmt("%.2f", lme3_r), lme3_r <= 3}};
  if (box >= 0.0)
    rows.insert(rows.end(),
                {{"2D block, LME box support (lme_box), gamma_lme = 3, npc: time per step / linear fe",
                  "<= 2.5", fmt("%.2f", box), box <= 2.5},
                 {block3 + ", lme_box gamma_lme = 3, npc: time per step / linear fe", "<= 3",
                  fmt("%.2f", box3), box3 <= 3}});
  return rows;
}

/// The 3D block (block_scene) of `cells` cells per axis, linear basis, npc,
/// made of `material`.
Scene block3(int cells, const std::string& material) {
  return parse_scene(block_scene(3, cells, "linear", "npc", "mpm", 3.0, material), "block3d.toml");
}

/// The 2D block (block_scene) of `cells`^2 cells.
Scene block2(int cells, const char* basis, const char* integrator, const char* mode = "mpm") {
  return parse_scene(block_scene(cells, basis, integrator, mode, 3.0), "block.toml");
}

/// A case that times `n` steps of a fresh engine of `s` on `threads` threads.
Case stepped(std::string name, const Scene& s, long n, int threads) {
  return Case{std::move(name), [s, n, threads] { return time_run<2>(s, n, threads); }};
}

/// The plastic table: the 3D block in j2 plastic flow against the same block
/// of neo_hookean, time per step (interleaved, one engine each, 100 steps
/// of settling first), and the full 3D Taylor bar, whole runs.
void plastic_table(int repeat, bool quick) {
  const int cells = quick ? 8 : 32;
  // yield_stress 1 Pa: under its weight (about 1e4 Pa at the base) the block flows almost everywhere.
  const Scene j2 = block3(cells, "model = \"j2\"\nyield_stress = 1.0"), nh = block3(cells, "model = \"neo_hookean\"");
  set_threads(1);
  Engine<3> e_j2 = assemble<3>(j2), e_nh = assemble<3>(nh);
  for (int i = 0; i < (quick ? 5 : 100); ++i) e_j2.step(), e_nh.step();
  const std::vector<double> eps0 = e_j2.particles().find_state("plastic_strain")->values;
  const long n = quick ? 2 : 10;
  Case c_j2{"3D block j2 plastic npc, 1 thread", [&] { return time_steps(e_j2, n, 1, j2.simulation.t_end); }};
  Case c_nh{"3D block neo_hookean npc, 1 thread", [&] { return time_steps(e_nh, n, 1, nh.simulation.t_end); }};
  interleave({&c_j2, &c_nh}, repeat);
  const std::vector<double>& eps1 = e_j2.particles().find_state("plastic_strain")->values;
  long flowed = 0;
  for (std::size_t i = 0; i < eps0.size(); ++i) flowed += eps1[i] > eps0[i];
  Case taylor{"Taylor bar cylinder j2 npc, 1 thread",
              [s = parse_scene(taylor_bar_cylinder_scene(), "taylor_bar.toml"), quick]() mutable {
                if (quick) s.simulation.t_end = 2e-6;
                return time_whole_run(s, 1);
              }};
  interleave({&taylor}, repeat);
  const double r = ratio(c_j2, c_nh);
  char block[96];
  std::snprintf(block, sizeof block, "3D block %d^3 cells (%ld particles, %.0f%% flowing)", cells, c_j2.last.particles,
                100.0 * double(flowed) / double(eps0.size()));
  print_table("plastic figure",
              {{std::string(block) + ", npc: j2 plastic / neo_hookean time per step, one core", "<= 1.3",
                fmt("%.2f", r), r <= 1.3},
               {fmt("Taylor bar, full 3D cylinder, h = R/4 (%.0f particles), j2, wall, npc linear, to 80 us: "
                    "particle-steps/s, whole run, one core",
                    double(taylor.last.particles)),
                ">= 1.2e7", fmt("%.3g", rate(taylor)), rate(taylor) >= 1.2e7}});
  print_cases({&c_j2, &c_nh, &taylor});
}

/// One case of the threads table, stepped on one and on two threads in
/// turn: one engine, built from `scene`, `settle` untimed steps (the first
/// basis evaluation, a plastic block's flow), then `repeat` interleaved
/// repetitions of `steps` steps on each thread count.
template <int D>
std::pair<Case, Case> thread_cases(const std::string& name, const Scene& scene, long settle, long steps, int repeat) {
  const std::vector<Case> c =
      engine_cases<D>({scene}, settle, {{name + ", 1 thread", 0, 1, steps}, {name + ", 2 threads", 0, 2, steps}}, repeat);
  return {c[0], c[1]};
}

/// The threads table: each case of the performance targets on one and on
/// two threads, interleaved, and the speed-up (the median of the
/// per-repetition ratios) against the target 1.85.
void threads_table(int repeat, bool quick) {
  const int big = quick ? 60 : 500, mid = quick ? 40 : 200, cube = quick ? 10 : 64, small_cube = quick ? 8 : 32;
  const long steps = quick ? 2 : 10;
  // linear fe, LME npc (the methods table's pairing); not block3() below, which is linear npc
  auto cube_scene = [](int cells, const char* basis, const std::string& material) {
    return parse_scene(block_scene(3, cells, basis, std::string(basis) == "lme" ? "npc" : "fe", "mpm", 3.0, material),
                       "block3d.toml");
  };
  std::vector<std::pair<Case, Case>> pairs;
  const std::string b2 = "2D block " + std::to_string(big) + "^2 cells", m2 = "2D block " + std::to_string(mid) + "^2 cells";
  const std::string c3 = "3D block " + std::to_string(cube) + "^3 cells";
  const std::string s3 = "3D block " + std::to_string(small_cube) + "^3 cells";
  pairs.push_back(thread_cases<2>(b2 + ", linear fe", block2(big, "linear", "fe"), 1, steps, repeat));
  pairs.push_back(thread_cases<2>(b2 + ", linear musl", block2(big, "linear", "musl"), 1, steps, repeat));
  pairs.push_back(thread_cases<2>(m2 + ", LME npc", block2(mid, "lme", "npc"), 1, steps, repeat));
  pairs.push_back(thread_cases<3>(c3 + ", linear fe", cube_scene(cube, "linear", kBlockLinearElastic), 1, steps / 2, repeat));
  pairs.push_back(thread_cases<3>(s3 + ", LME npc", cube_scene(small_cube, "lme", kBlockLinearElastic), 1, steps / 5 + 1,
                                  repeat));
  // yield_stress 1 Pa: the block flows almost everywhere after settling (plastic table)
  pairs.push_back(thread_cases<3>(s3 + ", j2 plastic fe", cube_scene(small_cube, "linear", "model = \"j2\"\nyield_stress = 1.0"),
                                  quick ? 5 : 100, steps, repeat));
  Scene taylor = parse_scene(taylor_bar_cylinder_scene(), "taylor_bar.toml");
  if (quick) taylor.simulation.t_end = 2e-6;
  Case t1{"Taylor bar cylinder j2 npc, 1 thread", [&] { return time_whole_run(taylor, 1); }};
  Case t2{"Taylor bar cylinder j2 npc, 2 threads", [&] { return time_whole_run(taylor, 2); }};
  interleave({&t1, &t2}, repeat);
  pairs.emplace_back(t1, t2);
  std::vector<Row> rows;
  std::vector<const Case*> cases;
  for (const auto& [one, two] : pairs) {
    const double speedup = ratio(one, two);
    const std::string name = one.name.substr(0, one.name.size() - std::string(", 1 thread").size());
    rows.push_back({name + fmt(" (%.0f particles): speed-up, 2 threads / 1", double(one.last.particles)),
                    ">= 1.85", fmt("%.2f", speedup), speedup >= 1.85});
    cases.insert(cases.end(), {&one, &two});
  }
  std::printf("%d interleaved repetitions; medians\n\n", repeat);
  print_table("threads figure", rows);
  print_cases(cases);
}

/// The 2D block of 10^6 particles (500^2 cells), linear basis, `fe` and
/// `musl` on one core: one engine each, a settling step, then `repeat`
/// interleaved repetitions of a few steps.
std::pair<Case, Case> big_block_cases(int repeat, bool quick) {
  const int cells = quick ? 60 : 500;
  const long steps = quick ? 2 : 10;
  const std::string name = "2D block " + std::to_string(cells) + "^2 cells linear ";
  const std::vector<Case> c = engine_cases<2>({block2(cells, "linear", "fe"), block2(cells, "linear", "musl")}, 1,
                                              {{name + "fe, 1 thread", 0, 1, steps}, {name + "musl, 1 thread", 1, 1, steps}},
                                              repeat);
  return {c[0], c[1]};
}

/// Cells per axis of the tables' 2D and 3D blocks (fewer with --quick) and
/// the steps of each timing of the 2D block.
constexpr int block_cells(bool quick) { return quick ? 60 : 200; }
constexpr int block3_cells(bool quick) { return quick ? 12 : 64; }
constexpr long block_steps(bool quick) { return quick ? 5 : 20; }

/// The LME rows' cases (the 2D block 200^2 and the 3D block 64^3, LME npc
/// against linear fe, each pair interleaved) and the rows (lme_rows).
struct LmeCases {
  Case lin, lme, box, lin3, lme3, box3;
  std::vector<Row> rows;
};
LmeCases lme_cases(int repeat, bool quick) {
  const int cells = block_cells(quick), cells3 = block3_cells(quick);
  const long steps = block_steps(quick);
  LmeCases c;
  c.lin = stepped("2D block linear fe mpm, 1 thread", block2(cells, "linear", "fe"), steps, 1);
  c.lme = stepped("2D block lme npc mpm, 1 thread", block2(cells, "lme", "npc"), steps / 2, 1);
  c.box = stepped("2D block lme_box npc mpm, 1 thread", block2(cells, "lme_box", "npc"), steps / 2, 1);
  interleave({&c.lin, &c.lme, &c.box}, repeat);
  block3d_cases(cells3, quick, repeat, c.lin3, c.lme3, nullptr, &c.box3);
  c.rows = lme_rows(ratio(c.lme, c.lin), ratio(c.lme3, c.lin3), block3d_name(cells3, c.lin3),
                    ratio(c.box, c.lin), ratio(c.box3, c.lin3));
  return c;
}

/// The targets of the current performance round that one process measures:
/// the 10^6-particle block's rate in `fe` and `musl`, the LME / linear time
/// per step of the 2D and the 3D block; then the plastic table (j2 against
/// neo_hookean, the full Taylor bar) and the threads table (every case on
/// two threads). The bytes per particle-step are cachegrind's
/// (scripts/roofline.sh, which scripts/bench.sh --table targets runs after).
void targets_table(int repeat, bool quick) {
  const auto [fe, musl] = big_block_cases(repeat, quick);
  const LmeCases l = lme_cases(repeat, quick);
  std::vector<Row> rows{{fmt("2D block (%.0f particles), linear fe: particle-steps/s, one core", double(fe.last.particles)),
                         ">= 6e7", fmt("%.3g", rate(fe)), rate(fe) >= 6e7},
                        {"same, linear musl", ">= 6e7", fmt("%.3g", rate(musl)), rate(musl) >= 6e7}};
  rows.insert(rows.end(), l.rows.begin(), l.rows.end());
  std::printf("%d interleaved repetitions; medians\n\n", repeat);
  print_table("target figure", rows);
  print_cases({&fe, &musl, &l.lin, &l.lme, &l.box, &l.lin3, &l.lme3, &l.box3});
  std::printf("\n");
  plastic_table(repeat, quick);
  std::printf("\n");
  threads_table(repeat, quick);
}

} // namespace

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv); // as the otmpm command waits (openmp_wait.hpp)
  int repeat = 5;
  bool quick = false;
  std::string scaling_csv, scaling3d_csv, table = "all";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--memory-child") return memory_child();
    if (a == "--repeat" && i + 1 < argc) repeat = std::stoi(argv[++i]);
    else if (a == "--scaling-csv" && i + 1 < argc) scaling_csv = argv[++i];
    else if (a == "--scaling3d-csv" && i + 1 < argc) scaling3d_csv = argv[++i];
    else if (a == "--table" && i + 1 < argc) table = argv[++i];
    else if (a == "--quick") quick = true;
    else {
      std::fprintf(stderr, "usage: bench_table [--repeat R] [--table throughput|methods|lme|plastic|threads|targets|all] "
                           "[--quick] [--scaling-csv FILE] [--scaling3d-csv FILE]\n");
      return 2;
    }
  }
  if (table != "throughput" && table != "methods" && table != "lme" && table != "plastic" && table != "threads" &&
      table != "targets" && table != "all") {
    std::fprintf(stderr,
                 "bench_table: --table must be throughput, methods, lme, plastic, threads, targets or all, not '%s'\n",
                 table.c_str());
    return 2;
  }
  if (repeat < 1) {
    std::fprintf(stderr, "bench_table: --repeat must be at least 1\n");
    return 2;
  }
  if (table == "plastic") {
    plastic_table(repeat, quick);
    return 0;
  }
  if (table == "threads") {
    threads_table(repeat, quick);
    return 0;
  }
  if (table == "targets") {
    targets_table(repeat, quick);
    return 0;
  }
  if (table == "lme") {
    const LmeCases l = lme_cases(repeat, quick);
    const int cells = block_cells(quick);
    std::printf("2D block %dx%d cells (%ld particles), %d interleaved repetitions; medians\n\n", cells, cells,
                l.lin.last.particles, repeat);
    print_table("method figure", l.rows);
    print_cases({&l.lin, &l.lme, &l.box, &l.lin3, &l.lme3, &l.box3});
    return 0;
  }
  const bool throughput = table == "throughput" || table == "all", methods = table == "methods" || table == "all";

  // The 2D block and the Dyka strip: rows of both tables.
  const int cells = block_cells(quick);
  const long steps = block_steps(quick);
  Case lin = stepped("2D block linear fe mpm, 1 thread", block2(cells, "linear", "fe"), steps, 1);
  Case lme = stepped("2D block lme npc mpm, 1 thread", block2(cells, "lme", "npc"), steps / 2, 1);
  Case lme_ul = stepped("2D block lme npc ul, 1 thread", block2(cells, "lme", "npc", "ul"), steps / 2, 1);
  Case lin2 = stepped("2D block linear fe mpm, 2 threads", block2(cells, "linear", "fe"), steps, 2);
  Case dyka = stepped("dyka strip 160 lme npc, 1 thread", dyka_strip(160, {"basis.gamma_lme=3.0"}), quick ? 200 : 0, 1);
  std::vector<Case*> block_cases{&lin, &lme};
  if (throughput) block_cases.insert(block_cases.end(), {&lme_ul, &lin2});
  block_cases.push_back(&dyka);
  interleave(block_cases, repeat);
  std::printf("2D block %dx%d cells (%ld particles), %d interleaved repetitions; medians\n\n", cells, cells,
              lin.last.particles, repeat);

  if (throughput) {
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
    const auto [n_p, t_step] = scaling<2>(quick ? std::vector<int>{20, 40, 60} : std::vector<int>{50, 100, 158, 250, 354, 500},
                                          std::max(3, repeat / 2), 2000000L, scaling_csv);
    const double slope = loglog_slope(n_p, t_step);
    std::vector<Row> rows{
        {"block, linear, fe, mpm: particle-steps/s, one core", ">= 1e7", fmt("%.3g", rate(lin)), rate(lin) >= 1e7},
        {"block, LME gamma_lme = 3, npc: time per step / linear fe", "<= 1.5", fmt("%.2f", ratio(lme, lin)),
         ratio(lme, lin) <= 1.5},
        {"2D Dyka strip, 160 cells, LME npc to t_end: particle-steps/s", ">= 3e6", fmt("%.3g", rate(dyka)),
         rate(dyka) >= 3e6},
        {"block, ul / mpm (LME npc)", "<= 1.3", fmt("%.2f", ratio(lme_ul, lme)), ratio(lme_ul, lme) <= 1.3},
        {"block, linear fe, speed-up 2 threads vs 1", ">= 1.8", fmt("%.2f", 1.0 / ratio(lin2, lin)),
         1.0 / ratio(lin2, lin) >= 1.8}};
    if (mem_particles > 0)
      rows.push_back({"linear block run: peak RSS / particle (whole process)", "<= 400 B",
                      fmt("%.0f B", rss / double(mem_particles)) + fmt(" (%.1f MB peak, ", rss / 1e6) +
                          fmt("%.1f MB before the scene)", rss_before / 1e6),
                      rss / double(mem_particles) <= 400});
    rows.push_back({fmt("scaling exponent, %.0e", n_p.front()) + fmt("..%.0e particles (linear fe)", n_p.back()),
                    "<= 1.05", fmt("%.3f", slope), slope <= 1.05});
    print_table("throughput figure", rows);
    std::printf("\n");
  }
  if (throughput && !methods) {
    print_cases({&lin, &lme, &lme_ul, &lin2, &dyka});
    return 0;
  }
  const int cells3 = block3_cells(quick);

  // The fixed bar, 512 nodes, whole runs on one thread (scripts/wobbes_figures.py's timing).
  auto whole = [](const Scene& s) { return [s] { return time_whole_run(s, 1); }; };
  const std::vector<std::string> mpm = {"simulation.mode=mpm", "simulation.integrator=fe", "simulation.mass=lumped"};
  const std::vector<std::string> otm = {"simulation.mode=ul", "simulation.integrator=otm", "simulation.mass=consistent"};
  auto with = [](std::vector<std::string> a, const std::vector<std::string>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
  };
  Case fb_mpm{"fixed bar 512 MPM-linear", whole(fixed_bar(with(mpm, {"basis.kind=linear"})))};
  Case fb_otm{"fixed bar 512 OTM-maxent", whole(fixed_bar(with(otm, {"basis.kind=maxent", "basis.d_max=2"})))};
  Case fb_uni{"fixed bar 512 unified", whole(fixed_bar({"simulation.mode=ul", "simulation.integrator=unified",
                                                        "simulation.mass=consistent", "basis.kind=bspline2"}))};
  interleave({&fb_mpm, &fb_otm, &fb_uni}, quick ? 1 : 3 * repeat);

  // The 2D Dyka strip of 1332 cells, linear musl, whole run to t_end.
  Case dyka_big{"dyka strip 1332 linear musl, 1 thread",
                whole(dyka_strip(1332, quick ? std::vector<std::string>{"basis.kind=linear", "simulation.integrator=musl",
                                                                        "simulation.t_end=2e-6"}
                                             : std::vector<std::string>{"basis.kind=linear", "simulation.integrator=musl"}))};
  interleave({&dyka_big}, repeat);

  Case lin3, lme3, lin3_2;
  block3d_cases(cells3, quick, repeat, lin3, lme3, &lin3_2);
  const auto [n3, t3] = scaling<3>(quick ? std::vector<int>{6, 9, 12} : std::vector<int>{16, 20, 25, 32, 40, 50, 64},
                                   std::max(3, repeat / 2), 8000000L, scaling3d_csv);

  const double lme_lin = ratio(lme, lin), fb_otm_r = ratio(fb_otm, fb_mpm), fb_uni_r = ratio(fb_uni, fb_mpm);
  const double lme3_r = ratio(lme3, lin3), speedup3 = 1.0 / ratio(lin3_2, lin3);
  const std::string block3 = block3d_name(cells3, lin3);
  const std::vector<Row> lme_row = lme_rows(lme_lin, lme3_r, block3);
  print_table(
      "method figure",
      {lme_row[0],
       {"2D Dyka strip, 160 cells, LME npc: particle-steps/s", ">= 5e6", fmt("%.3g", rate(dyka)), rate(dyka) >= 5e6},
       {"fixed bar, 512 nodes: OTM-maxent / MPM-linear wall time", "<= 2.5", fmt("%.2f", fb_otm_r), fb_otm_r <= 2.5},
       {"fixed bar, 512 nodes: unified / MPM-linear wall time", "<= 1.5", fmt("%.2f", fb_uni_r), fb_uni_r <= 1.5},
       {fmt("2D Dyka strip, 1332 cells (%.0f particles), linear musl, to t_end: particle-steps/s, whole run",
            double(dyka_big.last.particles)),
        ">= 1.5e7", fmt("%.3g", rate(dyka_big)), rate(dyka_big) >= 1.5e7},
       {block3 + ", linear fe: particle-steps/s, one core", ">= 6e6", fmt("%.3g", rate(lin3)), rate(lin3) >= 6e6},
       lme_row[1],
       {"same, linear fe, speed-up 2 threads vs 1", ">= 1.8", fmt("%.2f", speedup3), speedup3 >= 1.8}});
  std::printf("(3D scaling, linear fe, one thread: t ~ n^%.3f over %.0f..%.0f particles; the output row: "
              "scripts/bench-output.sh)\n",
              loglog_slope(n3, t3), n3.front(), n3.back());
  print_cases({&lin, &lme, &lme_ul, &lin2, &dyka, &fb_mpm, &fb_otm, &fb_uni, &dyka_big, &lin3, &lme3, &lin3_2});
  if (table == "all") {
    std::printf("\n");
    plastic_table(repeat, quick);
  }
  return 0;
}
