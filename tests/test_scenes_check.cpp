// check_scene() (otmpm run --check): the sizes and the first time step are
// those of the run, the estimated step count is the run's when dt does not
// change, a scene that only the engine refuses is refused, a scene the run
// refuses for its memory or step count is refused with the run's message
// before anything is allocated, and the memory it reports - the run's own
// estimate - stays above the peak resident memory a run really adds
// (measured with /proc/self/clear_refs and VmHWM; runs with one thread).
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/scene/resources.hpp"
#include "otmpm/scene/scene.hpp"

#include "input_error.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

#include <malloc.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

using namespace otmpm;
namespace fs = std::filesystem;

namespace {

const std::string kExamples = std::string(OTMPM_SOURCE_DIR) + "/examples/";

/// A field of /proc/self/status in bytes ("VmRSS", "VmHWM").
double status_bytes(const std::string& field) {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind(field + ":", 0) == 0) return 1024.0 * std::stod(line.substr(field.size() + 1));
  FAIL("no " << field << " in /proc/self/status");
  return 0.0;
}

/// Peak resident memory a run of the scene adds to this process, in bytes.
double measured_peak(const Scene& scene) {
  malloc_trim(0); // memory freed by an earlier run goes back to the system, or this run would reuse it unseen
  { std::ofstream("/proc/self/clear_refs") << "5"; } // VmHWM := VmRSS
  const double before = status_bytes("VmRSS");
  REQUIRE(status_bytes("VmHWM") < before * 1.01 + 1e6); // the reset worked
  RunOptions opt;
  opt.write_results = false;
  REQUIRE(run_scene(scene, opt).exit_code == 0);
  return status_bytes("VmHWM") - before;
}

/// A 3D cube of 18^3 cells of 27 particles (157,464 particles) on a 30^3 grid.
const char* kCube = R"(
[simulation]
dimension = 3
t_end = 2e-4
[basis]
kind = "linear"
[grid]
lower = [0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0]
cells = [30, 30, 30]
[[material]]
name = "m"
model = "linear_elastic"
density = 1000.0
young = 1e6
poisson = 0.3
[[body]]
material = "m"
lower = [0.2, 0.2, 0.2]
upper = [0.8, 0.8, 0.8]
particles_per_cell = 3
velocity = [1.0, 0.0, 0.0]
[output]
fields = []
)";

} // namespace

TEST_CASE("check_scene: sizes, first dt and step count of the Dyka bar are the run's") {
  const Scene scene = load_scene(kExamples + "dyka/dyka_n40.toml");
  const SceneCheck c = check_scene(scene);
  Engine<1> e = assemble<1>(scene);
  CHECK(c.dimension == 1);
  CHECK(c.particles == e.particles().size());
  CHECK(c.particles == 80); // 40 cells of h = L/40, 2 particles each
  CHECK(c.nodes == e.basis().nodes().size());
  e.step();
  CHECK(c.dt == e.last_dt()); // the same cfl rule at t = 0, bit for bit
  RunOptions opt;
  opt.write_results = false;
  const RunSummary s = run_scene(scene, opt);
  // The bar's fastest wave does not change: dt stays as at t = 0.
  CHECK(c.estimated_steps == static_cast<double>(s.steps));
  CHECK(c.memory_bytes == estimate_resources(scene).bytes); // the run's estimate, the one it checks
  CHECK(c.memory_limit == memory_limit(scene));
  CHECK(c.out_file == scene.output.file);
}

TEST_CASE("check_scene: a scene only the engine refuses is refused, naming the key") {
  // ul mode: the nodes cover the body alone, so a boundary at the grid's end selects none.
  const Scene scene = load_scene(std::string(OTMPM_SOURCE_DIR) + "/tests/scenes/good_minimal.toml",
                                 {"simulation.mode=ul", "boundary.0.lower=[-0.0067]", "boundary.0.upper=[-0.0067]"});
  CHECK_THROWS_WITH_AS(check_scene(scene), doctest::Contains("selects no node"), InputError);
}

using test::input_error_of;

TEST_CASE("check_scene: what the run refuses before it allocates, --check refuses at once with the run's message") {
  // A scene of more than 1 TB (6.4e7 nodes of a consistent mass matrix), a
  // fixed step of 1e-30 s, a memory limit of 1 kB.
  const std::vector<std::pair<Scene, std::string>> refused{
      {parse_scene(kCube, "cube.toml",
                   {"grid.cells=[400, 400, 400]", "simulation.mass=consistent", "body.0.upper=[0.21, 0.21, 0.21]"}),
       "of memory"},
      {parse_scene(kCube, "cube.toml", {"simulation.dt=1e-30"}), "more than simulation.max_steps"},
      {parse_scene(kCube, "cube.toml", {"simulation.memory_limit=1e3"}), "more than the limit of 1 kB"}};
  CHECK(estimate_resources(refused.front().first).bytes > 1e12);
  for (const auto& item : refused) { // no structured binding: clang captures none in a lambda
    const Scene& scene = item.first;
    const std::string& expected = item.second;
    CAPTURE(expected);
    const auto start = std::chrono::steady_clock::now();
    const std::string check = input_error_of([&] { check_scene(scene); });
    CHECK(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() < 1.0); // nothing allocated
    CHECK(check.find(expected) != std::string::npos);
    RunOptions opt;
    opt.write_results = false;
    CHECK(input_error_of([&] { run_scene(scene, opt); }) == check);
  }
}

TEST_CASE("check_output_names: --check refuses the output names the run refuses, with the run's message") {
  test::TempDir dir("check_names");
  const std::string long_name = dir.file(std::string(300, 'r') + ".h5");
  const std::vector<std::pair<std::vector<std::string>, std::string>> refused{
      {{"output.file=\"" + long_name + "\""}, "the file name of the result file is 303 bytes long"},
      {{"output.file=\"" + dir.file("r.xdmf") + "\""}, "may not end in .xdmf"},
      {{"output.file=\"" + dir.file("r.h5") + "\"", "output.checkpoint_every=10",
        "output.checkpoint_file=\"" + dir.file("r.xdmf") + "\""},
       "r.xdmf"}};
  for (const auto& item : refused) {
    const std::string& expected = item.second;
    CAPTURE(expected);
    const Scene scene = parse_scene(kCube, "cube.toml", item.first);
    const std::string check = input_error_of([&] { check_output_names(scene, ""); });
    CHECK(check.find(expected) != std::string::npos);
    RunOptions opt;
    CHECK(input_error_of([&] { run_scene(scene, opt); }) == check);
  }
  CHECK(fs::is_empty(dir.dir));
  CHECK_NOTHROW(check_output_names(parse_scene(kCube, "cube.toml", {"output.file=\"" + dir.file("r.h5") + "\""}), ""));
}

TEST_CASE("check_scene: the step count of a particle file's densities is the run's first step") {
  // The material's density gives 40 steps; the file's densities (1e-30 of
  // it) make the waves 1e15 times faster: the scene reader's pass over the
  // file gives the estimate, the seeded particles the engine's first step,
  // and both are refused above simulation.max_steps.
  test::TempDir dir("check_file_density");
  for (const double rho : {1000.0, 1e-27}) {
    CAPTURE(rho);
    {
      std::ofstream csv(dir.file("bar.csv"));
      csv << "x, volume, density\n";
      for (int i = 0; i < 40; ++i) csv << 0.0125 + 0.025 * i << ", 0.025, " << rho << "\n";
    }
    const Scene scene = parse_scene(
        "[simulation]\ndimension = 1\nt_end = 1e-4\n[basis]\nkind = \"linear\"\n[grid]\nlower = [0.0]\n"
        "upper = [1.0]\ncells = [40]\n[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1000.0\n"
        "young = 1e6\npoisson = 0.0\n[[body]]\nmaterial = \"m\"\nshape = \"file\"\nfile = \"" +
            dir.file("bar.csv") + "\"\n",
        "bar.toml");
    const std::string why = input_error_of([&] { check_scene(scene); });
    if (rho > 1.0) {
      CHECK(why.empty());
      CHECK(check_scene(scene).dt == doctest::Approx(estimate_resources(scene).dt));
    } else {
      CHECK(why.find("more than simulation.max_steps") != std::string::npos);
      CHECK(estimate_resources(scene).steps > 1e8);
    }
  }
}

TEST_CASE("check_scene: the run's memory estimate stays above the peak a run adds, per basis family and mass") {
#ifdef OTMPM_HAVE_OPENMP
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
#endif
  // The lumped runs' estimate is fitted to measured peaks of runs with a
  // basis table (docs/stability.md, "What a run may cost"; here 1.4 to 1.9
  // times them). `linear` and `lme_box` on the lattice keep compact rows
  // instead (28 B and 332 B per particle in 3D where their tables take 292
  // B and about 3 kB), on every path of their particle-to-node sums, and
  // the estimate counts those rows and a scatter plan; F-bar, which always
  // builds the table, checks the bound of the table's runs.
  // The consistent mass matrix's factor is bounded by the lattice's
  // profile, which the fill of the ordered factor stays far below in 3D
  // (here 9.3 times).
  struct Case {
    std::vector<std::string> sets;
    double most; ///< the largest estimate / peak allowed
  };
  for (const Case& c : std::vector<Case>{
           {{"basis.kind=linear"}, 2.5},
           {{"basis.kind=lme_box"}, 3.0},
           {{"basis.kind=linear", "simulation.volumetric=fbar"}, 2.5},
           {{"basis.kind=bspline2"}, 2.5},
           {{"basis.kind=lme", "grid.cells=[20, 20, 20]"}, 2.5},
           {{"basis.kind=linear", "simulation.mass=consistent", "body.0.particles_per_cell=2"}, 10.0}}) {
    const Scene scene = parse_scene(kCube, "cube.toml", c.sets);
    const double estimate = check_scene(scene).memory_bytes, peak = measured_peak(scene);
    INFO(c.sets.front() << (c.sets.size() > 1 ? " " + c.sets[1] : "") << ": estimate " << estimate / 1e6
                        << " MB, measured " << peak / 1e6 << " MB");
    CHECK(peak > 20e6);     // large enough that the run's own arrays dominate
    CHECK(estimate > peak); // an upper bound: it refuses runs
    CHECK(estimate < c.most * peak);
  }
#ifdef OTMPM_HAVE_OPENMP
  omp_set_num_threads(threads);
#endif
}

// The cube's particles written to a particle file in a random order, on a
// grid ten times as long: the blocks' node ranges then outgrow twice the
// entries of `linear`, and its particle-to-node sums take the gather over
// the transposed rows (`lme_box`, with about ten times the entries, takes
// the sparse blocked sums, whose slot maps take at most two ints per
// entry). Both read the compact rows too (the lattice rows of `linear`, the
// product rows of `lme_box`), so the run adds its plan (8 B per entry) to
// the ordered run's peak, not the basis table (292 B per particle for
// `linear`, 64 to 125 entries of 36 B for `lme_box`); the run's estimate,
// which counts a plan of 14 B per entry, stays above that peak.
TEST_CASE("a linear or lme_box run whose particles are in no spatial order builds no basis table") {
#ifdef OTMPM_HAVE_OPENMP
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
#endif
  test::TempDir dir("disordered");
  std::vector<std::array<double, 3>> x;
  const double s = 1.0 / 90.0; // 3 particles per cell of h = 1/30 in [0.2, 0.8]^3, as kCube
  for (int i = 0; i < 54; ++i)
    for (int j = 0; j < 54; ++j)
      for (int k = 0; k < 54; ++k)
        x.push_back({0.2 + (i + 0.5) * s, 0.2 + (j + 0.5) * s, 0.2 + (k + 0.5) * s});
  std::shuffle(x.begin(), x.end(), std::mt19937(7));
  {
    std::ofstream csv(dir.file("cube.csv"));
    csv.precision(17);
    csv << "x, y, z, volume, vx, vy, vz\n";
    for (const auto& p : x)
      csv << p[0] << ", " << p[1] << ", " << p[2] << ", " << s * s * s << ", 1.0, 0.0, 0.0\n";
  }
  std::string file_cube = kCube;
  const std::string box = "lower = [0.2, 0.2, 0.2]\nupper = [0.8, 0.8, 0.8]\nparticles_per_cell = "
                          "3\nvelocity = [1.0, 0.0, 0.0]\n";
  REQUIRE(file_cube.find(box) != std::string::npos);
  file_cube.replace(file_cube.find(box), box.size(),
                    "shape = \"file\"\nfile = \"" + dir.file("cube.csv") + "\"\n");
  struct Case {
    std::string kind;
    double table_row; ///< bytes per particle of its basis table
    bool column;      ///< the sums take the gather over the transposed rows
  };
  for (const auto& [kind, table_row, column] :
       {Case{"linear", 292.0, true}, Case{"lme_box", 64 * 36.0, false}}) {
    const std::vector<std::string> wide{"grid.upper=[10.0, 1.0, 1.0]", "grid.cells=[300, 30, 30]",
                                        "basis.kind=" + kind};
    const Scene ordered = parse_scene(kCube, "cube.toml", wide),
                shuffled = parse_scene(file_cube, "cube.toml", wide);
    {
      Engine<3> e = assemble<3>(shuffled);
      REQUIRE(e.particles().size() == 157464);
      e.step();
      CHECK(e.scatter_blocked() == !column);
    }
    const double table = table_row * 157464, base = measured_peak(ordered), peak = measured_peak(shuffled);
    INFO(kind << ": ordered " << base / 1e6 << " MB, shuffled " << peak / 1e6 << " MB, a table "
              << table / 1e6 << " MB");
    CHECK(peak < base + 0.5 * table);
    CHECK(check_scene(shuffled).memory_bytes > peak);
    CHECK(check_scene(ordered).memory_bytes > base);
  }
#ifdef OTMPM_HAVE_OPENMP
  omp_set_num_threads(threads);
#endif
}
