// Scene reader tests: a valid scene gives the right values, --set overrides
// reach every kind of key, and each class of mistake is an InputError that
// names the file, the line and the key (docs/user-guide.md, "Scene file").
//
// Values read from the file are compared with ==: the reader converts the same
// decimal literal the test writes, so the doubles are bit-identical.
#include "otmpm/scene/scene.hpp"

#include "otmpm/assembly/assembler.hpp"
#include "otmpm/scene/validate.hpp"

#include "input_error.hpp"

#include <doctest/doctest.h>

#include <string>
#include <vector>

using namespace otmpm;

namespace {

const std::string kScenes = std::string(OTMPM_SOURCE_DIR) + "/tests/scenes/";
const std::string kGood = kScenes + "good_minimal.toml";

std::string bad(const std::string& name) { return kScenes + "bad/" + name + ".toml"; }

using test::input_error_of;

/// The message of the InputError that loading `path` throws ("" if none).
std::string error_of(const std::string& path, const std::vector<std::string>& overrides = {}) {
  return input_error_of([&] { load_scene(path, overrides); });
}

/// Checks that the message contains every fragment (and says which is missing).
void check_message(const std::string& message, const std::vector<std::string>& fragments) {
  INFO("message: " << message);
  REQUIRE_FALSE(message.empty());
  for (const auto& f : fragments) CHECK(message.find(f) != std::string::npos);
}

/// A small 2D scene as text, used by the tests that need geometry in 2D.
const char* kPlate2D = R"(
[simulation]
dimension = 2
t_end = 1.0
[basis]
kind = "linear"
[grid]
lower = [0.0, 0.0]
upper = [4.0, 2.0]
h = 0.5
[[material]]
name = "rubber"
model = "neo_hookean"
density = 1.0
young = 10
poisson = 0.3
[[body]]
material = "rubber"
lower = [1.0, 0.5]
upper = [3.0, 1.5]
[[boundary]]
name = "base"
lower = [0.0, 0.0]
upper = [4.0, 0.0]
fix = [false, true]
)";

} // namespace

TEST_CASE("the minimal good scene has the values written in it") {
  const Scene s = load_scene(kGood);
  CHECK(s.file == kGood);
  CHECK(s.simulation.dimension == 1);
  CHECK(s.simulation.mode == "mpm");
  CHECK(s.simulation.integrator == "npc");
  CHECK(s.simulation.t_end == 1.0e-4);
  CHECK(s.simulation.cfl == 0.1);
  CHECK_FALSE(s.simulation.dt.has_value());
  CHECK(s.basis.kind == "lme");
  CHECK(s.basis.value("gamma_lme") == 4.0);
  CHECK(s.grid.lower[0] == -0.0067);
  CHECK(s.grid.upper[0] == 0.1333);
  CHECK(s.grid.cells[0] == 40);
  REQUIRE(s.materials.size() == 1);
  CHECK(s.materials[0].name == "steel");
  CHECK(s.materials[0].density == 7833.0);
  CHECK(s.materials[0].young == 200.0e9);
  CHECK(s.materials[0].poisson == 0.0);
  REQUIRE(s.bodies.size() == 1);
  CHECK(s.bodies[0].name == "bar");
  CHECK(s.bodies[0].material == "steel");
  CHECK(s.bodies[0].upper[0] == 0.1333);
  CHECK(s.bodies[0].particles_per_cell == 2);
  CHECK(s.bodies[0].placement == "gauss");
  REQUIRE(s.initial_velocities.size() == 1);
  CHECK(s.initial_velocities[0].velocity[0] == -5.0);
  REQUIRE(s.boundaries.size() == 1);
  CHECK(s.boundaries[0].name == "right_end");
  CHECK(s.boundaries[0].fix[0]);
  CHECK(s.output.file == "dyka.h5");
  CHECK(s.output.every == 1.0e-6);
  REQUIRE(s.output.probes.size() == 1);
  CHECK(s.output.probes[0].name == "A");
  CHECK(s.output.probes[0].particle == "leftmost");
  CHECK(s.reference.solution == "dyka");
  CHECK_FALSE(s.body_force.has_value());
}

TEST_CASE("every key read remembers its line") {
  const Scene s = load_scene(kGood);
  CHECK(s.locate("material.steel.density").line == 22);
  CHECK(s.locate("material.steel.density").describe() == kGood + ":22: key 'material.steel.density'");
  CHECK(s.bodies[0].where.line == 26); // the [[body]] header
  CHECK(s.locate("output.probes.A.particle").line == 47);
  CHECK(s.locate("no.such.key").line == 0);
}

TEST_CASE("a key left to its default is located at the table around it, so a check on it names a line") {
  const Scene s = load_scene(kGood);
  REQUIRE(s.where.count("simulation.mass") == 0); // the file leaves the mass to its default
  CHECK(s.locate("simulation.mass").line == s.simulation.where.line);
  CHECK(s.locate("simulation.mass").key == "simulation.mass");
  CHECK(s.locate("body.bar.k0").line == s.bodies[0].where.line);
  CHECK(s.locate("body.sand.k0").line == 0); // no such element
  const Scene whole = load_scene(kGood, {"simulation={dimension=1, t_end=1e-4}"});
  CHECK(whole.locate("simulation.mass").describe() == "--set simulation: key 'simulation.mass'");
}

TEST_CASE("an unnamed table's keys are found under the name the reader gives it, for the validator's messages") {
  // the reader records the plate's unnamed [[body]] as body.0; the validator names it body.body0
  const Scene s = parse_scene(kPlate2D, "plate.toml");
  CHECK(s.bodies[0].name == "body0");
  CHECK(s.locate("body.body0.lower").line == s.locate("body.0.lower").line);
  CHECK(s.locate("body.body0.lower").line > 0);
  CHECK(s.locate("body.bodyx.lower").line == 0);
}

TEST_CASE("--set overrides scalars, arrays of tables by name and bare-word strings") {
  const Scene s = load_scene(kGood, {"material.steel.young=70e9", "body.bar.velocity=[1.5]", "simulation.mode=ul",
                                     "simulation.integrator=\"otm\"", "basis.gamma_lme = 2"});
  CHECK(s.materials[0].young == 70e9);
  CHECK(s.bodies[0].velocity[0] == 1.5);
  CHECK(s.simulation.mode == "ul");
  CHECK(s.simulation.integrator == "otm");
  CHECK(s.basis.value("gamma_lme") == 2.0);
  CHECK(s.locate("material.steel.young").describe() == "--set material.steel.young");
}

TEST_CASE("--set can add keys and tables the file does not have") {
  const Scene s = load_scene(kGood, {"simulation.dt=1e-7", "body_force.value=[-9.81]"});
  REQUIRE(s.simulation.dt.has_value());
  CHECK(*s.simulation.dt == 1e-7);
  REQUIRE(s.body_force.has_value());
  CHECK(s.body_force->value[0] == -9.81);
  CHECK(s.body_force->time.kind == "constant");
}

TEST_CASE("grid.h replaces grid.cells, also from --set") {
  const Scene s = load_scene(kGood, {"grid.h=0.0035"});
  CHECK(s.grid.cells[0] == 40);
  check_message(error_of(kGood, {"grid.h=0.0036"}), {"--set grid.h", "whole cells"});
  const Scene plate = parse_scene(kPlate2D, "plate.toml");
  CHECK(plate.grid.cells[0] == 8);
  CHECK(plate.grid.cells[1] == 4);
}

TEST_CASE("the resolved text reads back to the same scene") {
  const Scene s = load_scene(kGood, {"material.steel.young=70e9", "simulation.mode=ul"});
  const Scene again = parse_scene(s.text, "resolved.toml");
  CHECK(again.materials[0].young == 70e9);
  CHECK(again.simulation.mode == "ul");
  CHECK(again.grid.cells[0] == s.grid.cells[0]);
  CHECK(again.output.probes.size() == 1);
}

TEST_CASE("uGIMP gets the particle half-width h / (2 ppc)") {
  // The assembled uGIMP basis evaluates as one built by hand with l_p = h / 4
  // (2 particles per cell): same stencil, same N to round-off (the two
  // half-widths differ at most in the last bit: same arithmetic up to
  // association order).
  const Scene s = load_scene(kGood, {"basis.kind=ugimp"});
  const Engine<1> e = assemble<1>(s);
  const double h = (0.1333 - -0.0067) / 40;
  BasisOptions opt;
  opt.kind = "ugimp";
  opt.particle_half_width[0] = h / 4;
  const auto by_hand = make_basis<1>(opt, e.basis().nodes());
  for (double x : {0.0012, 0.05, 0.1201}) {
    Stencil<1> a, b;
    e.basis().evaluate({.x = Vec<1>(x)}, a);
    by_hand->evaluate({.x = Vec<1>(x)}, b);
    REQUIRE(a.node == b.node);
    for (int i = 0; i < a.size(); ++i) CHECK(a.N[i] == doctest::Approx(b.N[i]).epsilon(1e-13));
  }
}

TEST_CASE("2D scene: defaults, unnamed body and a boundary on the edge") {
  const Scene s = parse_scene(kPlate2D, "plate.toml");
  CHECK(s.simulation.dimension == 2);
  CHECK(s.bodies[0].name == "body0");
  CHECK(s.bodies[0].particles_per_cell == 2);
  CHECK_FALSE(s.boundaries[0].fix[0]);
  CHECK(s.boundaries[0].fix[1]);
  CHECK(s.output.file == "out.h5");
}

// ------------------------------------------------------------ mistakes

TEST_CASE("syntax error names file and line") {
  check_message(error_of(bad("syntax")), {"syntax.toml:21:", "syntax error"});
}

TEST_CASE("wrong type names file, line and key") {
  check_message(error_of(bad("bad_type")), {"bad_type.toml:6: key 'simulation.t_end'", "expected a number"});
}

TEST_CASE("unknown key is named, with a suggestion") {
  check_message(error_of(bad("unknown_key")),
                {"unknown_key.toml:22: key 'material.steel.yuong'", "unknown key", "did you mean 'young'"});
}

TEST_CASE("missing required key names the table's line") {
  check_message(error_of(bad("missing_required")),
                {"missing_required.toml:2: key 'simulation.t_end'", "missing"});
}

TEST_CASE("a body naming an undefined material") {
  check_message(error_of(bad("missing_material")),
                {"missing_material.toml:27: key 'body.bar.material'", "aluminium"});
}

TEST_CASE("a scene without any material") {
  check_message(error_of(bad("no_material")), {"no_material.toml:1: key 'material'", "[[material]]"});
}

TEST_CASE("negative density") {
  check_message(error_of(bad("negative_density")),
                {"negative_density.toml:21: key 'material.steel.density'", "> 0"});
}

TEST_CASE("poisson ratio 0.5 is rejected") {
  check_message(error_of(bad("poisson_half")), {"poisson_half.toml:23: key 'material.steel.poisson'", "(-1, 0.5)"});
  check_message(error_of(kGood, {"material.steel.poisson=-1"}), {"--set material.steel.poisson"});
}

TEST_CASE("gamma_lme <= 0 is rejected") {
  check_message(error_of(bad("gamma_lme_zero")), {"gamma_lme_zero.toml:11: key 'basis.gamma_lme'", "> 0"});
}

TEST_CASE("a body outside the grid names the body") {
  check_message(error_of(bad("body_outside_grid")), {"body_outside_grid.toml:25: key 'body.bar'", "not inside"});
  // The same body is fine in ul mode, where the grid is not a fixed domain.
  CHECK_NOTHROW(load_scene(bad("body_outside_grid"), {"simulation.mode=ul"}));
}

/// The message of the InputError that assembling `scene` in D dimensions throws.
template <int D> std::string assembly_error(const Scene& scene) {
  return input_error_of([&] { assemble<D>(scene); });
}

TEST_CASE("a boundary that selects no node names the boundary") {
  // The selection is made on the nodes the engine really has (B-splines:
  // their control points), so it is checked when the engine is assembled.
  check_message(assembly_error<1>(load_scene(bad("boundary_selects_nothing"))),
                {"boundary_selects_nothing.toml:37: key 'boundary.right_end'", "selects no node"});
  // A box between nodes in 2D: y in [0.1, 0.4] holds no node when h = 0.5.
  const std::string plate = kPlate2D;
  std::string moved = plate;
  moved.replace(moved.find("upper = [4.0, 0.0]"), 18, "upper = [4.0, 0.4]");
  moved.replace(moved.find("lower = [0.0, 0.0]\nupper = [4.0, 0.4]"), 18, "lower = [0.0, 0.1]");
  check_message(assembly_error<2>(parse_scene(moved, "plate.toml")), {"plate.toml:", "boundary.base", "selects no node"});
}

TEST_CASE("an unknown --set key is named as such") {
  check_message(error_of(kGood, {"simulation.modee=ul"}), {"--set simulation.modee", "did you mean 'mode'"});
  check_message(error_of(kGood, {"material.iron.young=1"}), {"--set material.iron.young", "iron"});
  check_message(error_of(kGood, {"nonsense"}), {"--set nonsense", "KEY=VALUE"});
  // Found with fuzz/fuzz_set.cpp: a bare word that is not UTF-8 used to be kept
  // as a string that the resolved scene text (written to the result file)
  // could not reproduce ("a\xffb" came back as "a\u00FFb").
  check_message(error_of(kGood, {"output.file=a\xff" "b.h5"}), {"--set output.file", "UTF-8"});
  check_message(error_of(kGood, {"output.file=\xed\xa0\x80.h5"}), {"--set output.file", "UTF-8"});  // a surrogate
  const Scene utf8 = load_scene(kGood, {"output.file=r\xc3\xa9sultat.h5"});
  CHECK(utf8.output.file == "r\xc3\xa9sultat.h5");
  CHECK(parse_scene(utf8.text, "resolved.toml").output.file == utf8.output.file);
  // A table given whole on the command line: the message names the key missing inside it.
  check_message(error_of(kGood, {"grid={}"}), {"--set grid", "missing", "'grid.lower'"});
  // ... and the key inside it whose value is wrong
  check_message(error_of(kGood, {"output={file=\"a.h5\", every=-1.0}"}),
                {"--set output: key 'output.every'", ">= 0 (got -1)"});
  check_message(error_of(kGood, {"grid={lower=[0.0], upper=[1.0], cells=[10], h=\"a\"}"}),
                {"--set grid: key 'grid.h'"});
}

TEST_CASE("otm in mpm mode is rejected") {
  check_message(error_of(bad("otm_in_mpm")), {"otm_in_mpm.toml:5: key 'simulation.integrator'", "ul"});
  CHECK_NOTHROW(load_scene(bad("otm_in_mpm"), {"simulation.mode=ul"}));
}

TEST_CASE("dimension out of range") {
  check_message(error_of(bad("dimension_four")), {"dimension_four.toml:3: key 'simulation.dimension'"});
}

TEST_CASE("array length must match the dimension") {
  check_message(error_of(bad("array_length")), {"array_length.toml:14: key 'grid.lower'", "2 components"});
}

TEST_CASE("uGIMP on a perturbed grid is rejected") {
  check_message(error_of(kGood, {"basis.kind=ugimp", "grid.kind=perturbed", "grid.perturbation=0.1"}),
                {"--set basis.kind", "Cartesian"});
}

TEST_CASE("other out-of-range values") {
  check_message(error_of(kGood, {"simulation.t_end=0"}), {"--set simulation.t_end", "> 0"});
  check_message(error_of(kGood, {"simulation.gamma=1.5"}), {"--set simulation.gamma", "must be in (0, 1] (got 1.5)"});
  check_message(error_of(kGood, {"simulation.cfl=-0.1"}), {"--set simulation.cfl"});
  check_message(error_of(kGood, {"basis.tolerance=1"}), {"--set basis.tolerance"});
  check_message(error_of(kGood, {"basis.kind=quadratic"}), {"--set basis.kind", "\"lme\""});
  check_message(error_of(kGood, {"body.bar.particles_per_cell=0"}), {"--set body.bar.particles_per_cell"});
  check_message(error_of(kGood, {"output.every=-1"}), {"--set output.every"});
  check_message(error_of(kGood, {"reference.solution=exact"}), {"--set reference.solution"});
  check_message(error_of(kGood, {"simulation.mass=diagonal"}), {"--set simulation.mass"});
  check_message(error_of(kGood, {"simulation.dimension=2.0"}), {"--set simulation.dimension", "integer"});
  check_message(error_of(kGood, {"output.fields=[\"x\", \"velocity\"]"}), {"--set output.fields", "velocity"});
}

TEST_CASE("absurd sizes are rejected before the engine allocates anything") {
  // The reader refuses what no rank count can index (cells per axis are int) ...
  check_message(error_of(kGood, {"grid.h=1e-12"}), {"--set grid.h", "cells on axis 0"});
  check_message(error_of(kGood, {"grid.cells=[2000000000]"}), {"--set grid.cells", "axis 0", "cells are allowed"});
  check_message(error_of(kGood, {"body.bar.particles_per_cell=101"}), {"--set body.bar.particles_per_cell", "[1, 100]"});
  // ul mode: the body need not lie in the grid, but it is seeded in cells of grid.h.
  check_message(error_of(kGood, {"simulation.mode=ul", "body.bar.upper=[1e7]"}),
                {"--set body.bar.upper", "cells of the grid spacing on axis 0", "are allowed"});
  check_message(error_of(kGood, {"grid.lower=[-1e308]", "grid.upper=[1e308]"}), {"--set grid.upper", "overflows"});
  // ... and a run refuses what its processes cannot hold: at most 1e8 nodes
  // and particles per process, so a bigger scene needs enough ranks.
  const Scene huge = load_scene(bad("huge_grid"));
  const auto refusal = [](const Scene& s, int processes) {
    return input_error_of([&] { validate_scene(s, s.simulation.dimension, processes); });
  };
  check_message(refusal(huge, 1), {"huge_grid.toml:18: key 'grid.cells'", "1e+09 nodes", "at most 100000000 in one process",
                                   "at least 11 ranks"});
  check_message(refusal(huge, 10), {"per rank of 10", "at least 11 ranks"});
  INFO(refusal(huge, 11));
  CHECK(refusal(huge, 11).find("particles") != std::string::npos); // 1.9e9 of them
  CHECK(refusal(huge, 20).empty());
  const Scene ul = load_scene(kGood, {"simulation.mode=ul", "body.bar.upper=[1e6]"});
  check_message(refusal(ul, 1), {"key 'grid.cells'", "nodes", "at most 100000000 in one process"});
}

TEST_CASE("scene_size counts the particles and nodes the engine creates") {
  auto check_size = [](const Scene& scene, const auto& engine) {
    const SceneSize n = scene_size(scene);
    CHECK(n.particles == engine.particles().size());
    CHECK(n.nodes == engine.basis().nodes().size());
  };
  const Scene one = load_scene(kGood), ul = load_scene(kGood, {"simulation.mode=ul", "body.bar.particles_per_cell=3"});
  const Scene two = parse_scene(kPlate2D, "plate.toml");
  check_size(one, assemble<1>(one));
  check_size(ul, assemble<1>(ul));
  check_size(two, assemble<2>(two));
}

TEST_CASE("duplicate names are rejected") {
  const std::string twice = std::string(kPlate2D) + R"(
[[material]]
name = "rubber"
model = "neo_hookean"
density = 2.0
young = 10
poisson = 0.3
)";
  check_message([&] {
    try { parse_scene(twice, "twice.toml"); } catch (const InputError& e) { return std::string(e.what()); }
    return std::string();
  }(), {"twice.toml:", "material.rubber.name", "duplicate"});
}

TEST_CASE("a missing file is an InputError naming it") {
  check_message(error_of(kScenes + "does_not_exist.toml"), {"does_not_exist.toml", "cannot open"});
}

/// The InputSource of the InputError that reading `path` (with overrides) throws.
InputSource source_of(const std::string& path, const std::vector<std::string>& overrides = {}) {
  try {
    load_scene(path, overrides);
  } catch (const InputError& e) {
    REQUIRE(e.source() != nullptr);
    return *e.source();
  }
  FAIL("no InputError");
  return {};
}

TEST_CASE("InputError carries file, line and key of the bad value (InputError::source)") {
  const InputSource key = source_of(bad("unknown_key"));
  CHECK(key.file == bad("unknown_key"));
  CHECK(key.line == 22);
  CHECK(key.key == "material.steel.yuong");
  const InputSource syntax = source_of(bad("syntax"));
  CHECK(syntax.line == 21);
  CHECK(syntax.key.empty());
  const InputSource set = source_of(kGood, {"simulation.modee=ul"});
  CHECK(set.line < 0); // from an override, not from a line of the file
  CHECK(set.key == "simulation.modee");
  CHECK(source_of(kGood, {"nonsense"}).key == "nonsense");
  CHECK(source_of("no_such_scene.toml").file == "no_such_scene.toml");
  CHECK(InputError("plain").source() == nullptr);
}

/// The message of the InputError that parsing the scene text `text` throws.
std::string text_error(const std::string& text) {
  return input_error_of([&] { parse_scene(text, "shape.toml"); });
}

TEST_CASE("a sphere or polygon whose extent rounds away names its center or vertices, with the line") {
  // center + radius rounds to the center (found by the scene fuzzer): the
  // box derived from them is empty along y; the message points at center
  const std::string head = std::string(kPlate2D).substr(0, std::string(kPlate2D).find("[[body]]"));
  const std::string sphere = head + "[[body]]\nname = \"far\"\nmaterial = \"rubber\"\nshape = \"sphere\"\n"
                                    "center = [1.0, 92233720368547758070.75]\nradius = 0.2\n";
  check_message(text_error(sphere), {"shape.toml:21: key 'body.far.center'", "extent along axis 1 is empty"});
  const std::string flat = head + "[[body]]\nname = \"flat\"\nmaterial = \"rubber\"\nshape = \"polygon\"\n"
                                  "vertices = [[1.0, 1.0], [2.0, 1.0], [3.0, 1.0]]\n";
  check_message(text_error(flat), {"shape.toml:21: key 'body.flat.vertices'", "extent along axis 1"});
}
