#pragma once
/// \file scene.hpp
/// A scene: everything a run needs, as plain data read from a TOML file
/// (interfaces.md "Scene file"). Vectors are stored with 3 components; only
/// the first `dimension` are meaningful. Every value remembers where it came
/// from (SourceRef) so that later consistency checks (a body outside the grid,
/// a boundary box selecting no node) can still name file, line and key.
#include "otmpm/basis/basis.hpp"

#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace otmpm {

/// Where a scene value came from: "dyka.toml:12: key 'grid.cells'".
struct SourceRef {
  std::string file;
  int line = 0;
  std::string key;
  /// "FILE:LINE: key 'KEY'" ("--set KEY" for command-line overrides, "key 'KEY'"
  /// without a file: a Scene built in code).
  std::string describe() const;
};

/// Throws InputError "FILE:LINE: key 'KEY': message".
[[noreturn]] void input_error(const SourceRef& where, const std::string& message);

using Vec3 = std::array<double, 3>;

/// A time function multiplying a load: constant 1, or the ramp of molinos
/// eq. 45, g(t) = 0.5 (sin(2 pi t / T - pi/2) + 1), rising to 1 at T/2 and constant after.
struct TimeFunction {
  std::string kind = "constant"; ///< constant | ramp
  double period = 0.0;           ///< T of molinos eq. 45
};

struct SimulationSection {
  int dimension = 1;
  std::string mode = "mpm";        ///< mpm | ul
  std::string integrator = "npc";  ///< fe | musl | npc | otm | unified
  double gamma = 0.5;              ///< Newmark parameter of NPC
  std::string mass = "lumped";     ///< lumped | consistent (default: consistent for otm and unified)
  double t_end = 0.0;
  double cfl = 0.1;
  std::optional<double> dt;        ///< fixed step instead of cfl
  double mass_tolerance = 1e-12;   ///< nodes with m_I < tol * max m are inactive
  double energy_limit = 10.0;      ///< runaway: kinetic + strain energy > limit * (initial energy + |external work| + |reaction work|) stops the run
  /// Largest estimated number of steps (t_end / first dt) a run may take
  /// (scene/resources.hpp); a larger estimate is refused before the run.
  double max_steps = 1e8;
  /// Largest estimated memory of a run in bytes; 0: the memory this process
  /// may use (scene/resources.hpp available_memory()).
  double memory_limit = 0.0;
  SourceRef where;
};

struct GridSection {
  std::string kind = "cartesian"; ///< cartesian | perturbed
  Vec3 lower{0, 0, 0}, upper{1, 1, 1};
  std::array<int, 3> cells{1, 1, 1};
  double perturbation = 0.0;      ///< perturbed: fraction of h
  unsigned seed = 1;
  SourceRef where;
};

struct MaterialSection {
  std::string name;
  std::string model = "linear_elastic"; ///< linear_elastic | linear_elastic_finite | neo_hookean
  double density = 0, young = 0, poisson = 0;
  SourceRef where;
};

struct BodySection {
  std::string name;
  std::string material;
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};
  int particles_per_cell = 2;           ///< per axis
  std::string placement = "gauss";      ///< gauss | cell_centres
  Vec3 velocity{0, 0, 0};
  /// "sin_x": initial velocity amplitude * sin(pi (x - lower)/(upper-lower)) per component (fixed bar)
  std::optional<std::string> velocity_profile;
  SourceRef where;
};

/// Sets the initial velocity of particles inside a box.
struct InitialVelocitySection {
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};
  Vec3 velocity{0, 0, 0};
  SourceRef where;
};

/// Dirichlet node set: nodes inside the closed box [lower, upper] (with a
/// tolerance of 1e-9 h) get the fixed velocity components held at `value`.
struct BoundarySection {
  std::string name;
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};
  std::array<bool, 3> fix{false, false, false};
  Vec3 value{0, 0, 0};
  SourceRef where{"", 0, "boundary"};
};

/// Body force b(t) = value * g(t) on every particle (e.g. gravity).
struct BodyForceSection {
  Vec3 value{0, 0, 0};
  TimeFunction time;
  SourceRef where;
};

/// Traction on the particles inside a box: a force per unit area `value` times
/// the time function, applied as f_I += N_Ip t A_p with A_p = V_p / h_p along
/// `normal_axis` (the particle's face area). `function = "wobbes_traction_bar"`
/// uses wobbes eq. 103 instead of value * g(t).
struct TractionSection {
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};
  Vec3 value{0, 0, 0};
  TimeFunction time;
  std::string function;  ///< empty or the name of a built-in traction history
  SourceRef where{"", 0, "traction"};
};

struct ProbeSection {
  std::string name;
  std::string particle = "leftmost"; ///< leftmost | rightmost | nearest
  Vec3 at{0, 0, 0};                  ///< for "nearest"
  SourceRef where;
};

struct OutputSection {
  std::string file = "out.h5";
  double every = 0.0;                 ///< seconds between frames (0: first and last only)
  std::vector<std::string> fields{"x", "v", "stress"};
  std::vector<ProbeSection> probes;
  long checkpoint_every = 0;          ///< steps between checkpoints (0: none)
  std::string checkpoint_file;        ///< "" : the result file with .h5 -> .checkpoint.h5
  /// What is written: "hdf5" (always: the result file and its XDMF sidecar)
  /// and at most one of "vtp", "vtu" (VTK frame files and a .pvd, io/vtk.hpp).
  std::vector<std::string> formats{"hdf5"};
  SourceRef where;
};

/// The VTK format an output section asks for: "vtp", "vtu" or "" (none).
std::string vtk_format(const OutputSection& output);

/// True when `name` is a particle field a frame can hold (output.fields).
bool is_output_field(const std::string& name);
/// True when `format` is a value output.format accepts ("hdf5", "vtp", "vtu").
bool is_output_format(const std::string& format);

struct ReferenceSection {
  std::string solution; ///< "" | dyka | fixed_bar | traction_bar | mms_plate
  SourceRef where;
};

/// The whole scene. `text` is the resolved scene as TOML (after --set), stored
/// in the result file.
struct Scene {
  std::string file;
  std::string text;
  SimulationSection simulation;
  BasisOptions basis;
  SourceRef basis_where{"", 0, "basis"}; ///< the [basis] table (key "basis" when built in code)
  GridSection grid;
  std::vector<MaterialSection> materials;
  std::vector<BodySection> bodies;
  std::vector<InitialVelocitySection> initial_velocities;
  std::vector<BoundarySection> boundaries;
  std::optional<BodyForceSection> body_force;
  std::vector<TractionSection> tractions;
  OutputSection output;
  ReferenceSection reference;
  /// Source locations of every key read, for consistency errors found later.
  std::map<std::string, SourceRef> where;
  /// The SourceRef of `key` if known, else {file, 0, key}.
  SourceRef locate(const std::string& key) const;
};

/// How many particles and nodes Engine<D>(scene) creates, counted the way the
/// engine counts them but in doubles, so that absurd scenes do not overflow.
/// Particles: per body, prod_k max(1, round((upper - lower) / h_k)) cells of
/// particles_per_cell^dimension particles (h = grid spacing). Nodes:
/// prod_k (cells_k + 1) over the grid (mode mpm) or over the bodies' bounding
/// box in cells of size h (mode ul).
struct SceneSize {
  double particles = 0;
  double nodes = 0;
};
SceneSize scene_size(const Scene& scene);

/// Largest particle count and node count a scene may ask for: beyond them a
/// run would not fit in memory (about 0.5 kB per particle) and int indices
/// come close to overflowing. load_scene rejects larger scenes with an InputError.
inline constexpr double kMaxSceneParticles = 1e8;
inline constexpr double kMaxSceneNodes = 1e8;
/// Largest body.particles_per_cell (per axis): the Gauss points cost O(n^2).
inline constexpr int kMaxParticlesPerCell = 100;

/// Reads and validates a scene file. `overrides` are "KEY=VALUE" strings from
/// --set (KEY is the TOML path; an array of tables is addressed by its name:
/// material.steel.young). Throws InputError naming file, line and key for
/// syntax errors, unknown keys, missing required keys, wrong types and
/// out-of-range values (also for an empty path). Nothing partially read is returned.
Scene load_scene(const std::string& path, const std::vector<std::string>& overrides = {});
/// The same from TOML text (`name` is used as the file name in messages).
Scene parse_scene(const std::string& text, const std::string& name,
                  const std::vector<std::string>& overrides = {});

} // namespace otmpm
