// The scene rules the reader and the validator share (scene/scene_rules.hpp):
// a value a rule refuses gives the same message whether it comes from a
// scene file (parse_scene, here through --set) or from a Scene built in code
// or from a Python dict (validate_scene), at the same key.
#include "input_error.hpp"

#include "otmpm/scene/scene.hpp"
#include "otmpm/scene/validate.hpp"

#include <doctest/doctest.h>

#include <functional>
#include <string>
#include <vector>

using namespace otmpm;

namespace {

/// A 2D scene with one of each table the rules below break.
const char* kScene = R"(
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
name = "block"
material = "rubber"
lower = [1.0, 0.5]
upper = [3.0, 1.5]
[[body]]
name = "ball"
material = "rubber"
shape = "sphere"
center = [3.5, 1.0]
radius = 0.25
[[body]]
name = "tri"
material = "rubber"
shape = "polygon"
vertices = [[0.2, 0.2], [0.8, 0.2], [0.5, 0.8]]
[[wall]]
name = "floor"
point = [0.0, 0.25]
normal = [0.0, 1.0]
[[traction]]
lower = [2.9, 0.5]
upper = [3.0, 1.5]
value = [1.0, 0.0]
[traction.time]
kind = "constant"
[output]
file = "rules.h5"
fields = ["x", "v"]
[[output.probes]]
name = "tip"
particle = "rightmost"
)";

/// A rule broken two ways: `overrides` of the scene file, and `change` of the Scene in code; `key` the key both name.
struct BrokenRule {
  const char* rule;
  const char* key;
  std::vector<std::string> overrides;
  std::function<void(Scene&)> change;
};

const std::vector<BrokenRule>& broken_rules() {
  static const std::vector<BrokenRule> rules = {
      {"choice", "simulation.mode", {"simulation.mode=\"warp\""}, [](Scene& s) { s.simulation.mode = "warp"; }},
      {"choice", "simulation.mass", {"simulation.mass=\"heavy\""}, [](Scene& s) { s.simulation.mass = "heavy"; }},
      {"choice", "simulation.volumetric", {"simulation.volumetric=\"bbar\""},
       [](Scene& s) { s.simulation.volumetric = "bbar"; }},
      {"node_reset", "simulation.node_reset", {"simulation.node_reset=0.3"},
       [](Scene& s) { s.simulation.node_reset = 0.3; }},
      {"choice", "grid.kind", {"grid.kind=\"hex\""}, [](Scene& s) { s.grid.kind = "hex"; }},
      {"box", "grid.upper", {"grid.upper=[0.0, 2.0]"}, [](Scene& s) { s.grid.upper[0] = 0.0; }},
      {"extent", "grid.upper", {"grid.lower=[-1e308, 0.0]", "grid.upper=[1e308, 2.0]"},
       [](Scene& s) { s.grid.lower[0] = -1e308, s.grid.upper[0] = 1e308; }},
      {"cells", "grid.cells", {"grid.cells=[8, 0]"}, [](Scene& s) { s.grid.cells = {8, 0, 1}; }},
      {"choice", "body.block.shape", {"body.block.shape=\"cube\""}, [](Scene& s) { s.bodies[0].shape = "cube"; }},
      {"material", "body.block.material", {"body.block.material=\"wood\""},
       [](Scene& s) { s.bodies[0].material = "wood"; }},
      {"particles_per_cell", "body.block.particles_per_cell", {"body.block.particles_per_cell=0"},
       [](Scene& s) { s.bodies[0].particles_per_cell = 0; }},
      {"choice", "body.block.overlap", {"body.block.overlap=\"merge\""},
       [](Scene& s) { s.bodies[0].overlap = "merge"; }},
      {"choice", "body.block.volume", {"body.block.volume=\"guessed\""},
       [](Scene& s) { s.bodies[0].volume = "guessed"; }},
      {"choice", "body.block.placement", {"body.block.placement=\"random\""},
       [](Scene& s) { s.bodies[0].placement = "random"; }},
      {"choice", "body.block.velocity_profile", {"body.block.velocity_profile=\"cos_x\""},
       [](Scene& s) { s.bodies[0].velocity_profile = "cos_x"; }},
      {"size", "body.ball.radius", {"body.ball.radius=-1.0"}, [](Scene& s) { s.bodies[1].radius = -1.0; }},
      {"cylinder_dimension", "body.ball.shape", {"body.ball.shape=\"cylinder\""},
       [](Scene& s) { s.bodies[1].shape = "cylinder"; }},
      {"vertex_count", "body.tri.vertices", {"body.tri.vertices=[[0.2, 0.2], [0.8, 0.2]]"},
       [](Scene& s) { s.bodies[2].vertices.resize(2); }},
      {"wall_normal", "wall.floor.normal", {"wall.floor.normal=[0.0, 0.0]"},
       [](Scene& s) { s.walls[0].normal = {0, 0, 0}; }},
      {"axis_index", "traction.0.axis", {"traction.0.axis=2"}, [](Scene& s) { s.tractions[0].axis = 2; }},
      {"choice", "traction.0.time.kind", {"traction.0.time.kind=\"sine\""},
       [](Scene& s) { s.tractions[0].time.kind = "sine"; }},
      {"choice", "traction.0.function", {"traction.0.function=\"wobbes\""},
       [](Scene& s) { s.tractions[0].function = "wobbes"; }},
      {"choice", "output.probes.tip.particle", {"output.probes.tip.particle=\"middle\""},
       [](Scene& s) { s.output.probes[0].particle = "middle"; }},
      {"file_name", "output.file", {"output.file=\"\""}, [](Scene& s) { s.output.file = ""; }},
      {"field", "output.fields", {"output.fields=[\"x\", \"speed\"]"},
       [](Scene& s) { s.output.fields = {"x", "speed"}; }},
      {"field", "output.fields", {"output.fields=[\"x\", \"x\"]"}, [](Scene& s) { s.output.fields = {"x", "x"}; }},
      {"formats", "output.format", {"output.format=[\"hdf5\", \"vtk\"]"},
       [](Scene& s) { s.output.formats = {"hdf5", "vtk"}; }},
      {"formats", "output.format", {"output.format=[\"hdf5\", \"hdf5\"]"},
       [](Scene& s) { s.output.formats = {"hdf5", "hdf5"}; }},
      {"formats", "output.format", {"output.format=[\"vtp\"]"}, [](Scene& s) { s.output.formats = {"vtp"}; }},
      {"formats", "output.format", {"output.format=[\"hdf5\", \"vtp\", \"vtu\"]"},
       [](Scene& s) { s.output.formats = {"hdf5", "vtp", "vtu"}; }},
      {"checkpoint_every", "output.checkpoint_every", {"output.checkpoint_every=-2"},
       [](Scene& s) { s.output.checkpoint_every = -2; }},
      {"checkpoint_file", "output.checkpoint_file", {"output.checkpoint_file=\"rules.h5\""},
       [](Scene& s) { s.output.checkpoint_file = "rules.h5"; }},
      {"choice", "output.precision", {"output.precision=\"half\""}, [](Scene& s) { s.output.precision = "half"; }},
      {"compression", "output.compression", {"output.compression=12"}, [](Scene& s) { s.output.compression = 12; }},
  };
  return rules;
}

/// The message after "key 'KEY': " (a Scene built in code) or "--set KEY: " (the file read with --set).
std::string rule_message(const std::string& message, const std::string& key) {
  for (const std::string& head : {"key '" + key + "': ", "--set " + key + ": "}) {
    const auto at = message.find(head);
    if (at != std::string::npos) return message.substr(at + head.size());
  }
  return "";
}

} // namespace

TEST_CASE("scene rules: the scene file and a Scene built in code get the same message at the same key") {
  const Scene good = parse_scene(kScene, "rules.toml");
  CHECK_NOTHROW(validate_scene(good, 2, 0));
  for (const BrokenRule& r : broken_rules()) {
    INFO("rule " << r.rule << " at " << r.key);
    const std::string from_file = test::input_error_of([&] { parse_scene(kScene, "rules.toml", r.overrides); });
    Scene coded = good;
    coded.where.clear(); // a Scene built in code (or from a Python dict) has no lines
    coded.file.clear();
    r.change(coded);
    const std::string from_code = test::input_error_of([&] { validate_scene(coded, 2, 0); });
    INFO("file: " << from_file);
    INFO("code: " << from_code);
    const std::string message = rule_message(from_file, r.key);
    REQUIRE_FALSE(message.empty());
    CHECK(from_code == "key '" + std::string(r.key) + "': " + message);
  }
}
