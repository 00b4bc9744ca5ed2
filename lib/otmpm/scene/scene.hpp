#pragma once
/// \file scene.hpp
/// A scene: everything a run needs, as plain data read from a TOML file
/// (docs/user-guide.md, "Scene file"). Vectors are stored with 3 components; only
/// the first `dimension` are meaningful. Every value remembers where it came
/// from (SourceRef) so that later consistency checks (a body outside the grid,
/// a boundary box selecting no node) can still name file, line and key.
#include "otmpm/basis/basis.hpp"
#include "otmpm/materials/material.hpp"
#include "otmpm/time_function.hpp"

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
  /// A key inside the table that `--set key=...` wrote whole (line ==
  /// kCommandLineLine; empty: `key` itself), e.g. key
  /// "simulation.initial_equilibrium", field "simulation.initial_equilibrium.damping".
  std::string field = {};
  /// "FILE:LINE: key 'KEY'" ("--set KEY" for command-line overrides, "--set
  /// KEY: key 'FIELD'" for a key inside a table it wrote, "key 'KEY'"
  /// without a file: a Scene built in code).
  std::string describe() const;
};

/// Throws InputError "FILE:LINE: key 'KEY': message".
[[noreturn]] void input_error(const SourceRef& where, const std::string& message);

using Vec3 = std::array<double, 3>;

/// The first `dim` components of `v` as an Eigen vector (the others zero).
Vec<3> first_components(const Vec3& v, int dim);

/// A gravity-loading phase before t = 0 (`simulation.initial_equilibrium`,
/// docs/theory.md sect. 15, "Initial equilibrium"): the scene's loads at
/// t = 0 step the bodies with Cundall's local non-viscous damping (eq.
/// 15.15) until the residuals (eq. 15.16) stay below `tolerance` over a
/// window (eq. 15.17) or `time`
/// has run; the run then starts from the equilibrated stresses with its own
/// initial velocities and zero displacements and energy series.
struct InitialEquilibrium {
  double time = 0.0;       ///< the longest the phase may run [s]
  double damping = 0.7;    ///< alpha of eq. 15.15, 0 <= alpha < 1
  double tolerance = 1e-3; ///< of the residual, eq. 15.16
};

struct SimulationSection {
  int dimension = 1;
  std::string mode = "mpm";        ///< mpm | ul
  std::string integrator = "npc";  ///< a name of integrator_kinds() (integrators/integrator.hpp)
  /// Integrator parameters given in the scene (gamma of npc, rho_inf of
  /// explicit_alpha, ...: IntegratorKind::parameters); the rest take their defaults.
  std::map<std::string, double> parameters;
  std::string mass = "lumped";     ///< lumped | consistent (default: consistent for otm and unified)
  /// none | fbar | fbar_nodal: the volumetric part of each particle's
  /// deformation its own, averaged over its cell (F-bar, docs/theory.md sect.
  /// 9.8), or averaged at the nodes and interpolated back (eq. 9.11); empty:
  /// the default (volumetric_treatment)
  std::string volumetric;
  /// ul: lay the nodes out anew on the grid's lattice over the particles when
  /// the nodes' smallest spacing falls below node_reset h (0: never; docs/theory.md sect.
  /// 3); unset: the default (node_reset_fraction)
  std::optional<double> node_reset;
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
  std::optional<InitialEquilibrium> initial_equilibrium; ///< none: the run starts from the seeded state
  SourceRef where;
  /// True in `ul` mode (nodes advected with the material).
  bool nodes_move() const { return mode == "ul"; }
};

struct GridSection {
  std::string kind = "cartesian"; ///< cartesian | perturbed
  Vec3 lower{0, 0, 0}, upper{1, 1, 1};
  std::array<int, 3> cells{1, 1, 1};
  double perturbation = 0.0;      ///< perturbed: fraction of h
  unsigned seed = 1;
  SourceRef where;
};

/// A [[material]]: name, model (a MaterialModel of materials/), density,
/// young, poisson and the model's own parameters (MaterialParameters::extra).
struct MaterialSection : MaterialParameters {
  SourceRef where;
};

/// A body: a region (shape) filled with particles of one material.
/// Particles are seeded on the background lattice (the node lattice),
/// particles_per_cell^D per cell at the Gauss points or cell centres, and
/// kept where they lie in the shape; a box is cut into cells of the grid
/// spacing of its own; a "file" body takes its particles from a file; an
/// "stl" body is the inside of the closed surface of an STL file (seeded on
/// the lattice like a sphere); a "mesh" body takes one particle per element
/// (or per quadrature point) of a Gmsh mesh, each carrying its volume.
/// `lower`/`upper` are the box corners, or the shape's bounding box.
struct BodySection {
  std::string name;
  std::string material;
  std::string shape = "box";           ///< box | sphere | cylinder | polygon | file | stl | mesh
  Vec3 lower{0, 0, 0}, upper{0, 0, 0}; ///< box corners; the bounds of other shapes
  Vec3 center{0, 0, 0};                ///< sphere: centre; cylinder: centre of one end
  double radius = 0.0;                 ///< sphere, cylinder
  Vec3 axis{0, 0, 1};                  ///< cylinder
  double length = 0.0;                 ///< cylinder
  std::vector<std::array<double, 2>> vertices; ///< polygon (2D)
  std::string file;                    ///< file: particle file (CSV or HDF5); stl, mesh: geometry file; resolved path
  long long file_particles = 0;        ///< file: the number of particles it holds; mesh: its material points
  std::string file_read;               ///< file, stl, mesh: the path file_particles, lower and upper were read from (else empty)
  /// file: the smallest value of its `density` column (0: none), and the
  /// largest speed of its velocity columns, read with file_particles (the
  /// first time step of scene/resources.hpp depends on them)
  double file_min_density = 0.0, file_max_speed = 0.0;
  std::string physical;                ///< mesh: the physical group of its elements (name or number; "": all)
  std::string seeding = "element";     ///< mesh: "element" (one point per element) | "quadrature"
  /// mesh, `ul` mode: "lattice" (the nodes on the lattice, as for every
  /// shape) | "mesh" (the mesh's vertices are the nodes: the classic OTM
  /// discretisation, a node cloud for the max-ent bases)
  std::string nodes = "lattice";
  long long file_vertices = 0;         ///< mesh: the vertices its elements use, read with file_particles
  /// stl, mesh: x = R (scale .* x_file) + translate, R the rotations about
  /// x, then y, then z by rotate's angles in degrees (2D: about z only)
  Vec3 scale{1, 1, 1}, rotate{0, 0, 0}, translate{0, 0, 0};
  std::string overlap = "error";       ///< "first": particles inside an earlier body are dropped
  /// "exact": the particle volumes (and masses) of a shape seeded on the
  /// lattice are scaled to sum to the shape's exact volume (area, length);
  /// "seeded": as seeded (the sum approaches it as the cells shrink).
  std::string volume = "seeded";
  int particles_per_cell = 2;           ///< per axis
  std::string placement = "gauss";      ///< gauss | cell_centres
  Vec3 velocity{0, 0, 0};
  /// "sin_x": initial velocity amplitude * sin(pi (x - lower)/(upper-lower))
  /// per component (fixed bar); "reference": the velocity of the reference
  /// solution at t = 0 (a manufactured solution's own initial state).
  std::optional<std::string> velocity_profile;
  /// A saturated body under gravity: the height (along the body force's
  /// axis, against it) of its water table. The pore pressure starts
  /// hydrostatic, rho_w |b| (water_table - z) below it and 0 above, and the
  /// effective stress geostatic (docs/theory.md eq. 15.12): the weight of
  /// the column above a particle, less its pore pressure, vertically, and
  /// `k0` times that horizontally (k0 default nu / (1 - nu)).
  std::optional<double> water_table, k0;
  SourceRef where;
};

/// Sets the initial velocity of particles inside a box.
struct InitialVelocitySection {
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};
  Vec3 velocity{0, 0, 0};
  SourceRef where;
};

/// Dirichlet node set: nodes inside the closed box [lower, upper] (within
/// kBoxTolerance h) get the fixed velocity components held at `value`. With
/// saturated bodies (docs/theory.md sect. 15) a fixed component holds the
/// pore liquid too (an impermeable support) unless `pore_pressure` is given
/// (a drained surface: the liquid passes at that pressure) or `water_level`
/// (free water standing to that height against the body force: the pressure
/// pore_pressure + rho_w |b| (water_level - z) where positive), a level
/// that rises by `water_rise` times the time function `time` (a river in
/// flood: water_level + water_rise g(t)). On a free surface the free water
/// also pushes on the body. Every other surface of a saturated body is
/// impermeable (docs/theory.md sect. 15).
struct BoundarySection {
  std::string name;
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};
  std::array<bool, 3> fix{false, false, false};
  Vec3 value{0, 0, 0};
  std::optional<double> pore_pressure, water_level, water_rise;
  TimeFunction time; ///< of water_rise
  SourceRef where{"", 0, "boundary"};
};

/// A rigid wall: the plane through `point` with `normal` pointing to the
/// material's side, moving at `velocity`, with Coulomb `friction`. It acts
/// on the nodal velocities (and, in ul mode, keeps the advected nodes from
/// crossing it); its force on the body is written as /walls/NAME/force.
struct WallSection {
  std::string name;
  Vec3 point{0, 0, 0}, normal{0, 0, 0}, velocity{0, 0, 0};
  double friction = 0.0;
  SourceRef where{"", 0, "wall"};
};

/// A rigid, frictionless, impermeable plate on saturated bodies (docs/theory.md
/// sect. 15): the nodes inside the box move together along `axis` (both
/// phases), the plate is massless and pressed by `force` times the time
/// function (N; in 2D per unit length out of plane, in 1D per unit area).
/// Its other components are free.
struct PlateSection {
  std::string name;
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};
  int axis = 0;
  double force = 0.0;
  TimeFunction time;
  SourceRef where{"", 0, "plate"};
};

/// Body-body contact on the fixed grid: each body gets its own nodal
/// velocity field, and bodies that approach each other at a node are
/// stopped along the contact normal, with Coulomb `friction` on the slip
/// (docs/theory.md sect. 6.2). Without it the bodies share one field
/// (no-slip, they stick). `mpm` mode with the lumped mass only.
struct ContactSection {
  double friction = 0.0;
  SourceRef where{"", 0, "contact"};
};

/// Plane strain in a channel: the 2D body lies between two parallel side
/// walls `width` apart (normal to the out-of-plane axis z), which press on
/// it with its out-of-plane stress and resist its in-plane motion by Coulomb
/// `friction` (docs/theory.md sect. 6.3): a laboratory flume's glass or
/// Perspex walls in a quasi-2D experiment. 2D only.
struct ChannelSection {
  double width = 0.0;
  double friction = 0.0;
  SourceRef where{"", 0, "channel"};
};

/// Body force b(t) = value * g(t) on every particle (e.g. gravity).
struct BodyForceSection {
  Vec3 value{0, 0, 0};
  TimeFunction time;
  SourceRef where;
};

/// A traction on the body surface inside a box: a force per unit area
/// `value` times the time function, on the faces normal to `axis` (default:
/// the axis of the largest component of value). The surface particles in
/// the box - the first and last particle of each column of particles along
/// the axis - carry it, each over its face area V0_p / l_p[axis], so the
/// total force is traction x loaded area whatever the particles per cell.
/// `function = "wobbes_traction_bar"` uses wobbes et al. eq. 103 instead of
/// value * g(t).
struct TractionSection {
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};
  Vec3 value{0, 0, 0};
  TimeFunction time;
  std::string function;  ///< empty or the name of a built-in traction history
  std::optional<int> axis; ///< normal of the loaded faces (default: largest component of value)
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
  /// Floating-point width of the frames' particle datasets: "double"
  /// (64-bit IEEE) or "single" (32-bit IEEE, also in the VTK files); times,
  /// attributes, histories and checkpoints are always double.
  std::string precision = "double";
  /// Symmetric tensor fields (stress, strain) stored with their independent
  /// components only: 6 in 3D (xx, xy, xz, yy, yz, zz; XDMF Tensor6), in 2D
  /// the stress 4 (xx, xy, yy and plane strain's zz) and the strain 3 (xx,
  /// xy, yy), 1 in 1D; each such dataset names its components in the
  /// attribute `components`. False: D*D components, row-major.
  bool symmetric_tensors = false;
  /// Deflate (gzip) level of the frames' particle datasets, 0..9: 0 stores
  /// them contiguous; above 0 chunked along the rows (at most 1 MiB per
  /// chunk) with HDF5's shuffle and deflate filters (ResultOptions::compression).
  int compression = 0;
  SourceRef where;
};

/// The VTK format an output section asks for: "vtp", "vtu" or "" (none).
std::string vtk_format(const OutputSection& output);

/// True when `format` is a value output.format accepts ("hdf5", "vtp", "vtu").
bool is_output_format(const std::string& format);

struct ReferenceSection {
  std::string solution; ///< "" | dyka | fixed_bar | traction_bar | mms_plate | terzaghi | mandel
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
  std::vector<WallSection> walls;
  std::vector<PlateSection> plates;
  std::optional<ContactSection> contact;
  std::optional<ChannelSection> channel;
  std::optional<BodyForceSection> body_force;
  std::vector<TractionSection> tractions;
  OutputSection output;
  ReferenceSection reference;
  /// Source locations of every key read, for consistency errors found later.
  std::map<std::string, SourceRef> where;
  /// The SourceRef of `key`: its own line when the file sets it, else (a key
  /// left to its default) the line of the nearest table around it that the
  /// file has, else {file, 0, key}.
  SourceRef locate(const std::string& key) const;
};

/// Fraction of the grid spacing h within which a node counts as inside a
/// box (boundary boxes) and a body edge as inside the grid.
inline constexpr double kBoxTolerance = 1e-6;

/// The node lattice of a scene: the grid in `mpm` mode; in `ul` mode the
/// bodies' bounding box cut into cells of the grid spacing (round(extent /
/// h), at least one per axis). Cell counts as doubles, so that absurd
/// scenes do not overflow before they are refused.
struct LatticeBox {
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};
  std::array<double, 3> cells{1, 1, 1};
};
LatticeBox node_lattice_box(const Scene& scene);

/// simulation.volumetric, or when the scene does not give it the default:
/// "fbar" in `ul` mode when a material of the scene is plastic (a model with
/// internal variables), "none" otherwise (docs/theory.md sect. 9.8).
std::string volumetric_treatment(const Scene& scene);

/// True when the run uses the consistent mass matrix: simulation.mass =
/// "consistent", or an integrator that needs it (`unified`; scenes read from
/// a file name it, scenes built in code may leave it out). The assembler, the
/// checks and the defaults that depend on it all ask here.
bool uses_consistent_mass(const Scene& scene);

/// True when a material of the scene has a pore fluid: its bodies are
/// saturated (docs/theory.md sect. 15).
bool saturated(const Scene& scene);

/// simulation.node_reset, or when the scene does not give it the default:
/// 0.7 in `ul` mode on a node lattice (not a mesh's vertices) whose
/// boundaries that fix an axis share its velocity (the reset lattice moves
/// with them), 0 otherwise (docs/theory.md sect. 3; docs/benchmarks.md, "ul
/// on the Taylor bar": 1.2x the steps of `mpm` where advected cells
/// flatten, 5 - 31x without).
double node_reset_fraction(const Scene& scene);

/// How many particles and nodes the engine of a scene has, counted the way the
/// engine counts them but in doubles, so that absurd scenes do not overflow.
/// Particles: per body, prod_k max(1, round((upper - lower) / h_k)) cells of
/// particles_per_cell^dimension particles (h = grid spacing). Nodes:
/// prod_k (cells_k + 1) over the grid (mode mpm) or over the bodies' bounding
/// box in cells of size h (mode ul). Axis cells: the most cells along one
/// axis, of the node lattice or of a body's cells.
struct SceneSize {
  double particles = 0;
  double nodes = 0;
  double axis_cells = 0;
};
SceneSize scene_size(const Scene& scene);

/// Largest particle count and node count one process (one rank of a
/// distributed run) may hold: beyond them it would not fit in a node's
/// memory (about 0.5 kB per particle) and its int indices come close to
/// overflowing. A run in one process refuses a larger scene
/// (validate_scene with processes = 1); a distributed run checks each
/// rank's share, so a scene of N particles needs at least N / 1e8 ranks.
inline constexpr double kMaxRankParticles = 1e8;
inline constexpr double kMaxRankNodes = 1e8;
/// Largest particle count and node count of a whole scene on any number of
/// ranks: global particle and lattice point ids are 64-bit integers and
/// global counts doubles, exact up to 2^53 = 9.0e15. load_scene rejects
/// larger scenes with an InputError.
inline constexpr double kMaxSceneParticles = 9.0e15;
inline constexpr double kMaxSceneNodes = 9.0e15;
/// Largest number of cells along one axis of the grid (lattice indices are
/// int; a B-spline lattice adds its degree).
inline constexpr double kMaxCellsPerAxis = 1e9;
/// Largest body.particles_per_cell (per axis): the Gauss points cost O(n^2).
inline constexpr int kMaxParticlesPerCell = 100;

/// Reads and validates a scene file. `overrides` are "KEY=VALUE" strings from
/// --set (KEY is the TOML path; an array of tables is addressed by its name:
/// material.steel.young). Throws InputError naming file, line and key for
/// syntax errors, unknown keys, missing required keys, wrong types and
/// out-of-range values (also for an empty path). Nothing partially read is
/// returned. `processes` > 0: the run's process count, so that a particle
/// file too large for it is refused as soon as its row count is read (0: the
/// whole-scene cap; the run checks its share).
Scene load_scene(const std::string& path, const std::vector<std::string>& overrides = {}, int processes = 0);
/// The same from TOML text (`name` is used as the file name in messages).
Scene parse_scene(const std::string& text, const std::string& name,
                  const std::vector<std::string>& overrides = {}, int processes = 0);

/// The scene as TOML text (scene_toml.cpp) that parse_scene() reads back to
/// the same values: every key is written, defaults included, vectors with
/// simulation.dimension components, grid.cells rather than grid.h, and
/// simulation.cfl only when simulation.dt is unset (the reader takes one of
/// the two). `file`, `where` and the derived basis.particle_half_width are not
/// written. run_scene() stores this text when Scene::text is empty (a scene
/// built in code), so its result file and checkpoints hold the scene.
std::string to_toml(const Scene& scene);

} // namespace otmpm
