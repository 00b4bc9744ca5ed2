// to_toml(const Scene&): every example scene read, written back with
// to_toml and read again gives the same Scene values (compared with ==: the
// text holds every double with enough digits to read back bit for bit), and a
// run of a Scene built in code stores a scene text in its result file that
// reads back to that scene.
#include "otmpm/run/run.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/scene/scene.hpp"
#include "otmpm/basis/kinds.hpp"

#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

using namespace otmpm;
namespace fs = std::filesystem;

namespace {

const fs::path kSource = OTMPM_SOURCE_DIR;

/// Every scene file under examples/ (not the study files) and the test scenes that run.
std::vector<fs::path> scene_files() {
  std::vector<fs::path> out;
  for (const auto& e : fs::recursive_directory_iterator(kSource / "examples"))
    if (e.path().extension() == ".toml" && e.path().parent_path().filename() != "studies") out.push_back(e.path());
  out.push_back(kSource / "tests" / "scenes" / "good_minimal.toml");
  std::sort(out.begin(), out.end());
  return out;
}

void same_time(const TimeFunction& a, const TimeFunction& b) {
  CHECK(a.kind == b.kind);
  CHECK(a.period == b.period);
}

/// CHECKs that two scenes hold the same values (not file, text or source locations).
void check_same(const Scene& a, const Scene& b) {
  const SimulationSection &s = a.simulation, &t = b.simulation;
  CHECK(s.dimension == t.dimension);
  CHECK(s.mode == t.mode);
  CHECK(s.integrator == t.integrator);
  CHECK(s.parameters == t.parameters);
  CHECK(s.mass == t.mass);
  CHECK(s.t_end == t.t_end);
  CHECK(s.dt == t.dt);
  if (!s.dt) CHECK(s.cfl == t.cfl);
  CHECK(s.mass_tolerance == t.mass_tolerance);
  CHECK(s.energy_limit == t.energy_limit);
  CHECK(s.max_steps == t.max_steps);
  CHECK(s.memory_limit == t.memory_limit);
  CHECK(a.output.formats == b.output.formats);
  CHECK(a.basis.kind == b.basis.kind);
  for (const ParameterSpec* p : basis_parameters()) CHECK(a.basis.value(*p) == b.basis.value(*p));
  CHECK(a.basis.metric == b.basis.metric);
  CHECK(a.basis.particle_half_width == b.basis.particle_half_width);
  CHECK(a.grid.kind == b.grid.kind);
  CHECK(a.grid.lower == b.grid.lower);
  CHECK(a.grid.upper == b.grid.upper);
  CHECK(a.grid.cells == b.grid.cells);
  CHECK(a.grid.perturbation == b.grid.perturbation);
  CHECK(a.grid.seed == b.grid.seed);
  REQUIRE(a.materials.size() == b.materials.size());
  for (std::size_t i = 0; i < a.materials.size(); ++i) {
    const MaterialSection &m = a.materials[i], &n = b.materials[i];
    CHECK(m.name == n.name);
    CHECK(m.model == n.model);
    CHECK(m.density == n.density);
    CHECK(m.young == n.young);
    CHECK(m.poisson == n.poisson);
    CHECK(m.extra == n.extra);
  }
  REQUIRE(a.bodies.size() == b.bodies.size());
  for (std::size_t i = 0; i < a.bodies.size(); ++i) {
    const BodySection &p = a.bodies[i], &q = b.bodies[i];
    CHECK(p.name == q.name);
    CHECK(p.material == q.material);
    CHECK(p.shape == q.shape);
    CHECK(p.lower == q.lower);
    CHECK(p.upper == q.upper);
    CHECK(p.center == q.center);
    CHECK(p.radius == q.radius);
    CHECK(p.axis == q.axis);
    CHECK(p.length == q.length);
    CHECK(p.vertices == q.vertices);
    CHECK(p.file_particles == q.file_particles);
    CHECK(p.overlap == q.overlap);
    CHECK(p.particles_per_cell == q.particles_per_cell);
    CHECK(p.placement == q.placement);
    CHECK(p.velocity == q.velocity);
    CHECK(p.velocity_profile == q.velocity_profile);
  }
  REQUIRE(a.initial_velocities.size() == b.initial_velocities.size());
  for (std::size_t i = 0; i < a.initial_velocities.size(); ++i) {
    CHECK(a.initial_velocities[i].lower == b.initial_velocities[i].lower);
    CHECK(a.initial_velocities[i].upper == b.initial_velocities[i].upper);
    CHECK(a.initial_velocities[i].velocity == b.initial_velocities[i].velocity);
  }
  REQUIRE(a.boundaries.size() == b.boundaries.size());
  for (std::size_t i = 0; i < a.boundaries.size(); ++i) {
    const BoundarySection &p = a.boundaries[i], &q = b.boundaries[i];
    CHECK(p.name == q.name);
    CHECK(p.lower == q.lower);
    CHECK(p.upper == q.upper);
    CHECK(p.fix == q.fix);
    CHECK(p.value == q.value);
  }
  REQUIRE(a.walls.size() == b.walls.size());
  for (std::size_t i = 0; i < a.walls.size(); ++i) {
    const WallSection &p = a.walls[i], &q = b.walls[i];
    CHECK(p.name == q.name);
    CHECK(p.point == q.point);
    CHECK(p.normal == q.normal);
    CHECK(p.velocity == q.velocity);
    CHECK(p.friction == q.friction);
  }
  REQUIRE(a.contact.has_value() == b.contact.has_value());
  if (a.contact) CHECK(a.contact->friction == b.contact->friction);
  REQUIRE(a.body_force.has_value() == b.body_force.has_value());
  if (a.body_force) {
    CHECK(a.body_force->value == b.body_force->value);
    same_time(a.body_force->time, b.body_force->time);
  }
  REQUIRE(a.tractions.size() == b.tractions.size());
  for (std::size_t i = 0; i < a.tractions.size(); ++i) {
    const TractionSection &p = a.tractions[i], &q = b.tractions[i];
    CHECK(p.lower == q.lower);
    CHECK(p.upper == q.upper);
    CHECK(p.value == q.value);
    CHECK(p.function == q.function);
    CHECK(p.axis == q.axis);
    same_time(p.time, q.time);
  }
  const OutputSection &o = a.output, &r = b.output;
  CHECK(o.file == r.file);
  CHECK(o.every == r.every);
  CHECK(o.fields == r.fields);
  CHECK(o.checkpoint_every == r.checkpoint_every);
  CHECK(o.checkpoint_file == r.checkpoint_file);
  REQUIRE(o.probes.size() == r.probes.size());
  for (std::size_t i = 0; i < o.probes.size(); ++i) {
    CHECK(o.probes[i].name == r.probes[i].name);
    CHECK(o.probes[i].particle == r.probes[i].particle);
    CHECK(o.probes[i].at == r.probes[i].at);
  }
  CHECK(a.reference.solution == b.reference.solution);
}

} // namespace

TEST_CASE("to_toml: every example scene reads back to the same values") {
  const std::vector<fs::path> files = scene_files();
  REQUIRE(files.size() >= 20); // examples/*.toml, dyka/, extreme/
  for (const fs::path& f : files) {
    INFO(f.string());
    const Scene a = load_scene(f.string());
    const std::string text = to_toml(a);
    INFO(text);
    const Scene b = parse_scene(text, "to_toml.toml");
    check_same(a, b);
    CHECK(to_toml(b) == text); // a fixed point
  }
}

TEST_CASE("to_toml: the keys a file may leave out or set in rarer forms read back too") {
  // --set reaches the optional sections and values the examples do not use:
  // a fixed dt, a ramp, a nearest probe, checkpoints, a perturbed grid.
  const Scene a = load_scene((kSource / "examples" / "dyka_2d.toml").string(),
                             {"simulation.dt=1e-7", "grid.kind=perturbed", "grid.perturbation=0.1", "grid.seed=7",
                              "body_force={value = [0.0, -9.81], time = {kind = \"ramp\", period = 1e-5}}",
                              "output.probes=[{name = \"P\", particle = \"nearest\", at = [0.01, 0.002]}]",
                              "output.checkpoint_every=10", "output.checkpoint_file=c.h5",
                              "simulation.mass=consistent", "body.0.velocity_profile=sin_x",
                              "simulation.max_steps=5e5", "simulation.memory_limit=2e9",
                              "output.format=[\"hdf5\", \"vtu\"]"});
  REQUIRE(a.simulation.dt.has_value());
  REQUIRE(a.body_force.has_value());
  REQUIRE(a.output.formats.size() == 2);
  const Scene b = parse_scene(to_toml(a), "to_toml.toml");
  check_same(a, b);
}

TEST_CASE("to_toml: plastic materials, body shapes, walls, contact and integrator parameters read back") {
  // What the example scenes do not use yet: a j2 material with a
  // [material.johnson_cook] sub-table, Drucker-Prager, sphere and polygon
  // bodies with overlap = "first", a moving wall with friction, body contact
  // with friction, a traction with an explicit axis, and explicit_alpha's rho_inf.
  const std::string text = R"(
[simulation]
dimension = 2
integrator = "explicit_alpha"
rho_inf = 0.3
t_end = 1e-5
[basis]
kind = "linear"
[grid]
lower = [0.0, 0.0]
upper = [1.0, 1.0]
cells = [10, 10]
[[material]]
name = "steel"
model = "j2"
density = 7800.0
young = 200e9
poisson = 0.3
yield_stress = 3e8
hardening_modulus = 1e9
[material.johnson_cook]
B = 1e8
n = 0.5
C = 0.01
reference_strain_rate = 1.0
[[material]]
name = "sand"
model = "drucker_prager"
density = 1800.0
young = 1e7
poisson = 0.3
friction_angle = 30.0
cohesion = 10.0
[[body]]
name = "disk"
material = "steel"
shape = "sphere"
center = [0.3, 0.5]
radius = 0.15
velocity = [1.0, 0.0]
[[body]]
name = "wedge"
material = "sand"
shape = "polygon"
vertices = [[0.3, 0.1], [0.9, 0.1], [0.9, 0.6]]
overlap = "first"
[[wall]]
name = "floor"
point = [0.0, 0.05]
normal = [0.0, 1.0]
velocity = [0.0, 0.1]
friction = 0.25
[contact]
friction = 0.35
[[traction]]
lower = [0.85, 0.1]
upper = [0.95, 0.6]
value = [-1e3, 0.0]
axis = 0
[output]
file = "shapes.h5"
)";
  const Scene a = parse_scene(text, "shapes.toml");
  REQUIRE(a.materials.size() == 2);
  REQUIRE(a.materials[0].extra.count("johnson_cook.B") == 1);
  REQUIRE(a.simulation.parameters.count("rho_inf") == 1);
  REQUIRE(a.walls.size() == 1);
  REQUIRE(a.contact.has_value());
  REQUIRE(a.tractions.at(0).axis.has_value());
  const std::string written = to_toml(a);
  INFO(written);
  const Scene b = parse_scene(written, "to_toml.toml");
  check_same(a, b);
  CHECK(to_toml(b) == written);
}

TEST_CASE("to_toml: a run of a Scene built in code stores a scene text that reads back to it") {
  Scene scene = load_scene((kSource / "tests" / "scenes" / "good_minimal.toml").string());
  scene.text.clear(); // as if built in code
  scene.simulation.t_end = 1e-6;
  test::TempDir dir("scene_toml");
  RunOptions opt;
  opt.out_file = dir.file("code.h5");
  const RunSummary s = run_scene(scene, opt);
  REQUIRE(s.exit_code == 0);
  const std::string stored = read_string_attribute(opt.out_file, "scene");
  CHECK(stored == to_toml(scene));
  check_same(scene, parse_scene(stored, "stored.toml"));
}
