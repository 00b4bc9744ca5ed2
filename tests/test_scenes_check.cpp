// check_scene() and estimate_memory_bytes() (otmpm run --check): the sizes and
// the first time step are those of the run, the estimated step count is the
// run's when dt does not change, a scene that only the engine refuses is
// refused, and the memory estimate is within a factor 2 of the peak
// resident memory a run really adds (measured with /proc/self/clear_refs and
// VmHWM; runs with one thread).
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/scene/scene.hpp"

#include <doctest/doctest.h>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

#include <malloc.h>

#include <fstream>
#include <string>

using namespace otmpm;

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
  CHECK(c.memory_bytes == estimate_memory_bytes(scene));
  CHECK(c.out_file == scene.output.file);
}

TEST_CASE("check_scene: a scene only the engine refuses is refused, naming the key") {
  // ul mode: the nodes cover the body alone, so a boundary at the grid's end selects none.
  const Scene scene = load_scene(std::string(OTMPM_SOURCE_DIR) + "/tests/scenes/good_minimal.toml",
                                 {"simulation.mode=ul", "boundary.0.lower=[-0.0067]", "boundary.0.upper=[-0.0067]"});
  CHECK_THROWS_WITH_AS(check_scene(scene), doctest::Contains("selects no node"), InputError);
}

TEST_CASE("estimate_memory_bytes: within a factor 2 of the measured peak, per basis family and mass") {
#ifdef OTMPM_HAVE_OPENMP
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
#endif
  for (const auto& sets : std::vector<std::vector<std::string>>{{"basis.kind=linear"},
                                                                {"basis.kind=bspline2"},
                                                                {"basis.kind=lme", "grid.cells=[20, 20, 20]"},
                                                                {"basis.kind=linear", "simulation.mass=consistent",
                                                                 "body.0.particles_per_cell=2"}}) {
    const Scene scene = parse_scene(kCube, "cube.toml", sets);
    const double estimate = estimate_memory_bytes(scene), peak = measured_peak(scene);
    INFO(sets.front() << (sets.size() > 1 ? " " + sets[1] : "") << ": estimate " << estimate / 1e6 << " MB, measured "
                      << peak / 1e6 << " MB");
    CHECK(peak > 20e6); // large enough that the run's own arrays dominate
    CHECK(estimate / peak > 0.5); // measured: 0.71 (bspline2) to 1.22 (linear)
    CHECK(estimate / peak < 2.0);
  }
#ifdef OTMPM_HAVE_OPENMP
  omp_set_num_threads(threads);
#endif
}
