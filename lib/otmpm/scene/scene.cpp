// Scene file reader: TOML text -> Scene, with errors that name file, line and
// key (docs/user-guide.md, "Scene file"). The TOML is parsed with toml++, --set
// overrides are applied to the parsed table, and only then is every value
// read and checked, so that overrides meet exactly the same checks as the file.
// The reading idiom (TableReader, Context) is in scene/toml_reader.hpp.
#include "otmpm/scene/scene.hpp"

#include "otmpm/text.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/io/particle_file.hpp"
#include "otmpm/materials/pore_fluid.hpp"
#include "otmpm/scene/file_bodies.hpp"
#include "otmpm/scene/scene_rules.hpp"
#include "otmpm/particles/output_fields.hpp"
#include "otmpm/scene/toml_reader.hpp"
#include "otmpm/scene/validate.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <set>
#include <sstream>

namespace otmpm {

namespace {

using namespace toml_input;

/// grid.h must divide (upper - lower) into an integer to this relative accuracy.
constexpr double kCellsTolerance = 1e-6;

const std::set<std::string, std::less<>> kTableArrays = {"material", "body", "initial_velocity", "boundary",
                                                         "wall", "plate", "traction", "probes"};

std::string fmt(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", x);
  return buf;
}

/// The names of a table of kinds (basis_kinds(), integrator_kinds(), ...).
template <class Table, class Name> std::vector<std::string_view> names_of(const Table& table, Name name) {
  std::vector<std::string_view> out;
  for (const auto& row : table) out.push_back(name(row));
  return out;
}

void check(bool ok, const SourceRef& r, const std::string& message) {
  if (!ok) input_error(r, message);
}

/// A shared rule (scene_rules.hpp): its message at `r` unless it passed ("").
void enforce(const std::string& broken, const SourceRef& r) {
  if (!broken.empty()) input_error(r, broken);
}

/// The value of `spec.key` in `t` - `fallback` when absent, or required
/// without one - checked against its row (ParameterSpec::check).
double number(const TableReader& t, const ParameterSpec& spec, std::optional<double> fallback = std::nullopt) {
  const double v = fallback ? t.get<double>(spec.key, *fallback) : t.require<double>(spec.key);
  const std::string why = spec.check(v);
  check(why.empty(), t.ref(spec.key), why);
  return v;
}

/// Every component of upper strictly (or not) above lower.
void check_box(const TableReader& t, const Vec3& lo, const Vec3& hi, int dim, bool strict) {
  enforce(scene_rules::box(lo, hi, dim, strict), t.ref("upper"));
}

/// The bounding box a shape derives from its key `from` (a sphere's or
/// cylinder's center and radius, a polygon's vertices): finite, with lower <
/// upper on every axis - a center so far out that adding the radius does not
/// change it, or vertices on one line along an axis, leave no extent, and
/// the message names the key the box comes from.
void check_derived_box(const TableReader& t, std::string_view from, const Vec3& lo, const Vec3& hi, int dim) {
  for (int k = 0; k < dim; ++k)
    check(std::isfinite(lo[k]) && std::isfinite(hi[k]) && lo[k] < hi[k], t.ref(from),
          "the body's extent along axis " + std::to_string(k) + " is empty or not finite (lower " + fmt(lo[k]) +
              ", upper " + fmt(hi[k]) + ")");
}

// ---------------------------------------------------------------- sections

SimulationSection read_simulation(const TableReader& t) {
  std::vector<std::string_view> keys{"dimension", "mode",          "integrator",  "mass",        "volumetric", "node_reset",
                                     "t_end",     "cfl",           "dt",          "mass_tolerance",
                                     "energy_limit", "max_steps",  "memory_limit", "initial_equilibrium"};
  for (const ParameterSpec* p : integrator_parameters()) keys.push_back(p->key);
  t.only(keys);
  SimulationSection s;
  s.where = t.self();
  s.dimension = t.require<int>("dimension");
  check(s.dimension >= 1 && s.dimension <= 3, t.ref("dimension"),
        "must be 1, 2 or 3 (got " + std::to_string(s.dimension) + ")");
  s.mode = t.choice("mode", s.mode, scene_rules::kModes);
  const auto integrators = names_of(integrator_kinds(), [](const IntegratorKind& k) { return k.name; });
  s.integrator = t.choice("integrator", s.integrator, integrators);
  for (const ParameterSpec* p : integrator_parameters()) {
    const auto value = t.get<double>(p->key);
    if (!value) continue;
    const std::string why = p->check(*value);
    check(why.empty(), t.ref(p->key), why);
    s.parameters[std::string(p->key)] = *value;
  }
  // Default: the mass matrix of each algorithm's listing (IntegratorKind).
  const bool consistent_default = integrator_kind(s.integrator).consistent_by_default;
  s.mass = t.choice("mass", consistent_default ? "consistent" : "lumped", scene_rules::kMasses);
  if (t.has("volumetric")) s.volumetric = t.choice("volumetric", "none", scene_rules::kVolumetric);
  using namespace scene_keys;
  if (t.has("node_reset")) s.node_reset = number(t, kNodeReset);
  enforce(scene_rules::node_reset(s.node_reset.value_or(0.0), s.nodes_move()), t.ref("node_reset"));
  s.t_end = number(t, kTEnd);
  check(!(t.has("cfl") && t.has("dt")), t.ref("dt"), "give either simulation.cfl or simulation.dt, not both");
  s.cfl = number(t, kCfl, s.cfl);
  if (t.has("dt")) s.dt = number(t, kDt);
  s.mass_tolerance = number(t, kMassTolerance, s.mass_tolerance);
  s.energy_limit = number(t, kEnergyLimit, s.energy_limit);
  s.max_steps = number(t, kMaxSteps, s.max_steps);
  s.memory_limit = number(t, kMemoryLimit, s.memory_limit);
  if (auto q = t.table("initial_equilibrium")) {
    q->only({"time", "damping", "tolerance"});
    InitialEquilibrium e;
    e.time = number(*q, kEquilibriumTime);
    e.damping = number(*q, kEquilibriumDamping, e.damping);
    e.tolerance = number(*q, kEquilibriumTolerance, e.tolerance);
    s.initial_equilibrium = e;
  }
  return s;
}

/// [basis]: the family, the metric and the parameters of every family
/// (BasisKind::parameters; each accepted whatever the family, so that
/// switching families with --set works), each checked against its row.
BasisOptions read_basis(const TableReader& t) {
  std::vector<std::string_view> keys{"kind", "metric"};
  for (const ParameterSpec* p : basis_parameters()) keys.push_back(p->key);
  t.only(keys);
  BasisOptions b;
  if (!t.has("kind")) t.missing("kind");
  b.kind = t.choice("kind", b.kind, names_of(basis_kinds(), [](const BasisKind& k) { return k.name; }));
  for (const ParameterSpec* p : basis_parameters())
    if (t.has(p->key)) b.values[std::string(p->key)] = number(t, *p, p->fallback);
  b.metric = t.choice("metric", b.metric, basis_metrics());
  return b;
}

/// grid.cells, or grid.h converted to cells (must divide the box evenly).
std::array<int, 3> read_cells(const TableReader& t, const GridSection& g, int dim) {
  std::array<int, 3> cells{1, 1, 1};
  check(!(t.has("cells") && t.has("h")), t.ref("h"), "give either grid.cells or grid.h, not both");
  if (t.has("h")) {
    const Vec3 h = *t.vec("h", dim, true);
    for (int k = 0; k < dim; ++k) {
      check(h[k] > 0, t.ref("h"), "must be > 0 (got " + fmt(h[k]) + ")");
      const double n = (g.upper[k] - g.lower[k]) / h[k];
      check(n <= kMaxCellsPerAxis, t.ref("h"),
            "gives " + fmt(n) + " cells on axis " + std::to_string(k) + "; at most " + fmt(kMaxCellsPerAxis) +
                " are allowed");
      cells[k] = static_cast<int>(std::lround(n));
      check(cells[k] >= 1 && std::abs(n - cells[k]) <= kCellsTolerance * n, t.ref("h"),
            "does not divide the grid box into whole cells on axis " + std::to_string(k) + " ((upper - lower) / h = " +
                fmt(n) + ")");
    }
    return cells;
  }
  const toml::node* n = t.node("cells");
  if (!n) t.missing("cells", "required key is missing (give grid.cells or grid.h)");
  const SourceRef r = t.ref("cells");
  if (n->is_array()) {
    const toml::array& a = *n->as_array();
    check(static_cast<int>(a.size()) == dim, r,
          "has " + std::to_string(a.size()) + " components but simulation.dimension = " + std::to_string(dim));
    for (int k = 0; k < dim; ++k) cells[k] = convert<int>(a[static_cast<std::size_t>(k)], r);
  } else {
    const int c = convert<int>(*n, r);
    for (int k = 0; k < dim; ++k) cells[k] = c;
  }
  enforce(scene_rules::cells(cells, dim), r);
  for (int k = 0; k < dim; ++k) {
    check(cells[k] <= kMaxCellsPerAxis, r,
          "axis " + std::to_string(k) + ": at most " + fmt(kMaxCellsPerAxis) + " cells are allowed (got " +
              std::to_string(cells[k]) + ")");
  }
  return cells;
}

GridSection read_grid(const TableReader& t, int dim) {
  t.only({"kind", "lower", "upper", "cells", "h", "perturbation", "seed"});
  GridSection g;
  g.where = t.self();
  g.kind = t.choice("kind", g.kind, scene_rules::kGridKinds);
  g.lower = t.require_vec("lower", dim);
  g.upper = t.require_vec("upper", dim);
  check_box(t, g.lower, g.upper, dim, true);
  enforce(scene_rules::extent(g.lower, g.upper, dim), t.ref("upper"));
  g.cells = read_cells(t, g, dim);
  g.perturbation = number(t, scene_keys::kPerturbation, g.perturbation);
  const std::int64_t seed = t.get<std::int64_t>("seed", g.seed);
  check(seed >= 0 && seed <= std::numeric_limits<unsigned>::max(), t.ref("seed"), "must be a non-negative 32-bit integer");
  g.seed = static_cast<unsigned>(seed);
  return g;
}

double spacing(const GridSection& g, int k) { return (g.upper[k] - g.lower[k]) / g.cells[k]; }

/// Cells of size h over an extent, rounded as the engine rounds them (at least one).
double cells_over(double extent, double h) { return std::max(1.0, std::round(extent / h)); }

/// The cells seed_particles fills in body `b` (see SceneSize).
double body_cells(const BodySection& b, const GridSection& g, int dim) {
  double n = 1;
  for (int k = 0; k < dim; ++k) n *= cells_over(b.upper[k] - b.lower[k], spacing(g, k));
  return n;
}

/// The particles seed_particles puts into body `b` (see SceneSize).
double body_particles(const BodySection& b, const GridSection& g, int dim) {
  if (b.shape == "file" || b.shape == "mesh") return b.file_particles;
  return body_cells(b, g, dim) * std::pow(b.particles_per_cell, dim);
}

/// The nodes of the engine's node set (see SceneSize).
double node_count(const Scene& s) {
  if (mesh_nodes(s)) { // the bodies' vertices (those two bodies share counted twice)
    double n = 0;
    for (const BodySection& b : s.bodies) n += static_cast<double>(b.file_vertices);
    return n;
  }
  const LatticeBox box = node_lattice_box(s);
  double n = 1;
  for (int k = 0; k < s.simulation.dimension; ++k) n *= box.cells[k] + 1;
  return n;
}

/// Reads a required non-empty `name` of a `what` ("body", "probe", ...) (or
/// returns the default) and checks that it can name a group of the result
/// file and a --set key (invalid_name_reason: no '/', '.', control
/// character or surrounding space) and is unique.
std::string read_name(const TableReader& t, bool required, const std::string& fallback, std::set<std::string>& seen,
                      std::string_view what) {
  std::string name = required ? t.require<std::string>("name") : t.get<std::string>("name", fallback);
  check(!name.empty(), t.ref("name"), "must not be empty");
  const std::string why = name_error(name, what);
  check(why.empty(), t.ref("name"), why);
  check(seen.insert(name).second, t.has("name") ? t.ref("name") : t.self(),
        "duplicate name \"" + shortened(name) + "\"");
  return name;
}

/// The part of a parameter key before the dot ("johnson_cook" of
/// "johnson_cook.B"), "" for a key of the material table itself.
std::string_view sub_table(std::string_view key) {
  const auto dot = key.find('.');
  return dot == std::string_view::npos ? std::string_view() : key.substr(0, dot);
}

/// Reads the parameter `spec` of a model from `t` (the material table, or
/// the sub-table the key names) into m.extra, with its range check.
void read_parameter(const TableReader& t, std::string_view key, const ParameterSpec& spec, MaterialSection& m) {
  const auto value = t.get<double>(key);
  if (!value) {
    if (!spec.fallback) t.missing(key);
    return;
  }
  const std::string why = spec.check(*value);
  check(why.empty(), t.ref(key), why);
  m.extra[std::string(spec.key)] = *value;
}

/// The keys of a model in the material table: the common ones, its
/// top-level parameters and the names of its sub-tables.
std::vector<std::string_view> material_keys(const MaterialModel& model) {
  std::vector<std::string_view> keys{"name", "model", "density", "young", "poisson"};
  for (const ParameterSpec& p : pore_fluid_parameters()) keys.push_back(p.key);
  for (const ParameterSpec& p : model.parameters) {
    const std::string_view table = sub_table(p.key);
    const std::string_view key = table.empty() ? p.key : table;
    if (std::find(keys.begin(), keys.end(), key) == keys.end()) keys.push_back(key);
  }
  return keys;
}

/// The model's parameters: top-level keys, and the keys of each sub-table
/// the scene gives (an absent sub-table is an absent option).
void read_model_parameters(const TableReader& t, const MaterialModel& model, MaterialSection& m) {
  for (const ParameterSpec& p : model.parameters)
    if (sub_table(p.key).empty()) read_parameter(t, p.key, p, m);
  for (const std::string_view key : material_keys(model)) {
    std::vector<std::string_view> inner;
    for (const ParameterSpec& p : model.parameters)
      if (sub_table(p.key) == key) inner.push_back(p.key.substr(key.size() + 1));
    if (inner.empty()) continue;
    const auto sub = t.table(key);
    if (!sub) continue;
    sub->only(inner);
    for (const ParameterSpec& p : model.parameters)
      if (sub_table(p.key) == key) read_parameter(*sub, p.key.substr(key.size() + 1), p, m);
  }
}

MaterialSection read_material(const TableReader& t, std::set<std::string>& names) {
  MaterialSection m;
  m.where = t.self();
  if (!t.has("model")) t.missing("model");
  const auto models = names_of(material_models(), [](const MaterialModel* k) { return k->name; });
  m.model = t.choice("model", m.model, models);
  const MaterialModel& model = *find_material_model(m.model);
  t.only(material_keys(model));
  m.name = read_name(t, true, "", names, "material");
  for (auto [spec, value] : {std::pair{&kDensity, &m.density}, {&kYoung, &m.young}, {&kPoisson, &m.poisson}})
    *value = number(t, *spec);
  read_model_parameters(t, model, m);
  for (const ParameterSpec& p : pore_fluid_parameters()) // a saturated material: all five (validate_material)
    if (t.has(p.key)) read_parameter(t, p.key, p, m);
  try {
    validate_material(m); // the model's own cross-checks
  } catch (const InputError& e) {
    input_error(t.self(), e.what());
  }
  return m;
}

std::vector<MaterialSection> read_materials(const TableReader& root) {
  auto tables = root.tables("material");
  if (tables.empty()) root.missing("material", scene_rules::kNoMaterial);
  std::vector<MaterialSection> out;
  std::set<std::string> names;
  for (const TableReader& t : tables) out.push_back(read_material(t, names));
  return out;
}

/// The SourceRef of a box: the --set that changed it, else the table's line.
SourceRef box_ref(const TableReader& t) {
  for (const char* key : {"lower", "upper"}) {
    SourceRef r = t.ref(key);
    if (r.line == kCommandLineLine) return r;
  }
  return t.self();
}

/// The keys of each body shape (scene_rules::kShapes) beyond the common ones.
const std::map<std::string, std::vector<std::string_view>, std::less<>> kShapeKeys = {
    {"box", {"lower", "upper"}},
    {"sphere", {"center", "radius"}},
    {"cylinder", {"center", "axis", "radius", "length"}},
    {"polygon", {"vertices"}},
    {"file", {"file"}},
    {"stl", {"file", "scale", "rotate", "translate"}},
    {"mesh", {"file", "physical", "seeding", "nodes", "scale", "rotate", "translate"}}};

/// A size the shape needs (finite, > 0).
double positive_required(const TableReader& t, std::string_view key) {
  const double v = t.require<double>(key);
  enforce(scene_rules::size(v), t.ref(key));
  return v;
}

/// polygon: vertices = [[x, y], ...] (2D, at least 3).
std::vector<std::array<double, 2>> read_vertices(const TableReader& t, int dim) {
  enforce(scene_rules::polygon_dimension(dim), t.ref("shape"));
  const toml::node* n = t.node("vertices");
  if (!n) t.missing("vertices");
  const SourceRef r = t.ref("vertices");
  const toml::array* a = n->as_array();
  check(a, r, "expected an array of at least 3 vertices [[x, y], ...]");
  enforce(scene_rules::vertex_count(a->size()), r);
  std::vector<std::array<double, 2>> out;
  for (const toml::node& v : *a) {
    const toml::array* xy = v.as_array();
    check(xy && xy->size() == 2, r, "every vertex is an array of 2 numbers [x, y]");
    out.push_back({convert<double>((*xy)[0], r), convert<double>((*xy)[1], r)});
  }
  return out;
}

/// The bounding box of a cylinder body (center of one end, axis, radius, length).
void cylinder_bounds(BodySection& b) {
  const Vec<3> axis = first_components(b.axis, 3).stableNormalized();
  for (int k = 0; k < 3; ++k) {
    const double a = axis[k], top = b.center[k] + b.length * a;
    const double e = b.radius * std::sqrt(std::max(0.0, 1.0 - a * a));
    b.lower[k] = std::min(b.center[k], top) - e;
    b.upper[k] = std::max(b.center[k], top) + e;
  }
}

/// The path of the body's `file` (relative to the scene file's folder).
std::string scene_relative_file(const TableReader& t, const Scene& s) {
  const std::string name = t.require<std::string>("file");
  enforce(scene_rules::file_name(name), t.ref("file"));
  namespace fs = std::filesystem;
  const fs::path given(name);
  return (given.is_absolute() || s.file.empty() ? given : fs::path(s.file).parent_path() / given).string();
}

/// The keys that place a geometry file: scale (a number or one per axis,
/// > 0), rotate (degrees about x, y, z; 2D: one angle about z), translate.
void read_placement(const TableReader& t, int dim, Vec3& scale, Vec3& rotate, Vec3& translate) {
  const Vec3 given = t.vec("scale", dim, true).value_or(Vec3{1, 1, 1});
  for (int k = 0; k < dim; ++k) {
    check(given[k] > 0, t.ref("scale"), "must be > 0 (got " + fmt(given[k]) + ")");
    scale[k] = given[k];
  }
  if (dim == 3) rotate = t.vec("rotate", 3).value_or(rotate);
  else rotate[2] = t.get<double>("rotate", 0.0); // about z
  translate = t.vec("translate", dim).value_or(translate);
}

/// stl, mesh: the geometry file (relative to the scene file) and its
/// placement, read now for its bounds, checks and (mesh) particle count, so
/// that a bad file is reported with the scene's line.
void read_geometry_file_body(const TableReader& t, BodySection& b, const Scene& s) {
  const int dim = s.simulation.dimension;
  b.file = scene_relative_file(t, s);
  if (b.shape == "mesh") {
    b.physical = t.get<std::string>("physical", "");
    b.seeding = t.choice("seeding", b.seeding, scene_rules::kSeedings);
    b.nodes = t.choice("nodes", b.nodes, scene_rules::kNodeSources);
  }
  read_placement(t, dim, b.scale, b.rotate, b.translate);
  try {
    read_geometry_file(b, dim);
  } catch (const InputError& e) {
    input_error(t.ref("file"), e.what());
  }
  check_derived_box(t, "file", b.lower, b.upper, dim);
}

/// file: the path (relative to the scene file), read now for its bounds,
/// particle count and the extremes of its density and velocity columns
/// (the first time step), so that a bad file is reported with the scene's
/// line. Its rows meet the checks of the scene keys of the same quantities
/// (particle_file_rules). The file is streamed (stream_particle_file: a
/// block of rows at a time), so that every rank of a distributed run holds
/// one block, not the file.
void read_particle_file_body(const TableReader& t, BodySection& b, const Scene& s) {
  b.file = scene_relative_file(t, s);
  const int D = s.simulation.dimension;
  long long count = 0;
  const auto bounds = [&b, &count, D](const ParticleColumns& columns, const ParticleRows& rows) {
    const auto density = std::find(columns.fields.begin(), columns.fields.end(), kDensity.key);
    for (int p = 0; p < rows.size(); ++p, ++count) {
      const std::size_t i = static_cast<std::size_t>(p);
      for (int k = 0; k < D; ++k) {
        const double x = rows.x[i * D + k];
        const double half = 0.5 * std::pow(rows.volume[i], 1.0 / D);
        if (count == 0) b.lower[k] = b.upper[k] = x; // the first position, then min/max as one pass over the file
        b.lower[k] = std::min(b.lower[k], x - half);
        b.upper[k] = std::max(b.upper[k], x + half);
      }
      if (density != columns.fields.end()) {
        const double rho = rows.fields[static_cast<std::size_t>(density - columns.fields.begin())][i];
        b.file_min_density = count == 0 ? rho : std::min(b.file_min_density, rho);
      }
      if (!rows.v.empty())
        b.file_max_speed = std::max(b.file_max_speed, Eigen::Map<const Eigen::VectorXd>(&rows.v[i * D], D).norm());
    }
  };
  const ParticleFileRules rules = particle_file_rules(s, b, t.context().processes);
  try {
    stream_particle_file(b.file, D, bounds, kParticleChunk, &rules);
  } catch (const InputError& e) {
    input_error(t.ref("file"), e.what());
  }
  b.file_particles = count;
  b.file_read = b.file;
}

/// The shape's own keys, and lower/upper = its bounding box.
void read_shape(const TableReader& t, BodySection& b, const Scene& s) {
  const int dim = s.simulation.dimension;
  if (b.shape == "box") {
    b.lower = t.require_vec("lower", dim);
    b.upper = t.require_vec("upper", dim);
    check_box(t, b.lower, b.upper, dim, true);
  } else if (b.shape == "sphere") {
    b.center = t.require_vec("center", dim);
    b.radius = positive_required(t, "radius");
    for (int k = 0; k < dim; ++k) b.lower[k] = b.center[k] - b.radius, b.upper[k] = b.center[k] + b.radius;
    check_derived_box(t, "center", b.lower, b.upper, dim);
  } else if (b.shape == "cylinder") {
    enforce(scene_rules::cylinder_dimension(dim), t.ref("shape"));
    b.center = t.require_vec("center", dim);
    b.axis = t.require_vec("axis", dim);
    enforce(scene_rules::cylinder_axis(b.axis, dim), t.ref("axis"));
    b.radius = positive_required(t, "radius");
    b.length = positive_required(t, "length");
    cylinder_bounds(b);
    check_derived_box(t, "center", b.lower, b.upper, dim);
  } else if (b.shape == "polygon") {
    b.vertices = read_vertices(t, dim);
    b.lower = {b.vertices[0][0], b.vertices[0][1], 0};
    b.upper = b.lower;
    for (const auto& v : b.vertices)
      for (int k = 0; k < 2; ++k) b.lower[k] = std::min(b.lower[k], v[k]), b.upper[k] = std::max(b.upper[k], v[k]);
    check_derived_box(t, "vertices", b.lower, b.upper, 2);
  } else if (geometry_file_body(b)) {
    read_geometry_file_body(t, b, s);
  } else {
    read_particle_file_body(t, b, s);
  }
}

std::vector<BodySection> read_bodies(const TableReader& root, const Scene& s) {
  auto tables = root.tables("body");
  if (tables.empty()) root.missing("body", scene_rules::kNoBody);
  const int dim = s.simulation.dimension;
  std::vector<BodySection> out;
  std::set<std::string> names;
  double particles = 0;
  for (const TableReader& t : tables) {
    BodySection b;
    b.where = t.self();
    b.shape = t.choice("shape", b.shape, scene_rules::kShapes);
    std::vector<std::string_view> allowed{"name", "material", "shape", "particles_per_cell", "placement", "velocity",
                                          "velocity_profile", "overlap", "volume", "water_table", "k0"};
    const auto& own = kShapeKeys.find(b.shape)->second;
    allowed.insert(allowed.end(), own.begin(), own.end());
    t.only(allowed);
    b.name = read_name(t, false, default_name("body", out.size()), names, "body");
    b.material = t.require<std::string>("material");
    enforce(scene_rules::material(s.materials, b.material), t.ref("material"));
    read_shape(t, b, s);
    b.particles_per_cell = t.get<int>("particles_per_cell", b.particles_per_cell);
    enforce(scene_rules::particles_per_cell(b.particles_per_cell), t.ref("particles_per_cell"));
    b.placement = t.choice("placement", b.placement, scene_rules::kPlacements);
    b.velocity = t.vec("velocity", dim).value_or(b.velocity);
    if (t.has("velocity_profile"))
      b.velocity_profile = t.choice("velocity_profile", "", scene_rules::kVelocityProfiles);
    b.overlap = t.choice("overlap", b.overlap, scene_rules::kOverlaps);
    b.volume = t.choice("volume", b.volume, scene_rules::kVolumes);
    if (t.has("water_table")) b.water_table = number(t, scene_keys::kWaterTable);
    if (t.has("k0")) b.k0 = number(t, scene_keys::kK0);
    particles += body_particles(b, s.grid, dim);
    for (int k = 0; k < dim && b.shape != "file" && b.shape != "mesh"; ++k) {
      const double cells = cells_over(b.upper[k] - b.lower[k], spacing(s.grid, k));
      check(cells <= kMaxCellsPerAxis, box_ref(t),
            "body \"" + b.name + "\" spans " + fmt(cells) + " cells of the grid spacing on axis " +
                std::to_string(k) + "; at most " + fmt(kMaxCellsPerAxis) + " are allowed");
    }
    check(particles <= kMaxSceneParticles, box_ref(t),
          "body \"" + b.name + "\" brings the particle count to " + fmt(particles) + " (" +
              fmt(body_cells(b, s.grid, dim)) + " cells of the grid spacing, " +
              fmt(std::pow(b.particles_per_cell, dim)) + " particles each); at most " + fmt(kMaxSceneParticles) +
              " are allowed");
    out.push_back(std::move(b));
  }
  return out;
}

std::vector<InitialVelocitySection> read_initial_velocities(const TableReader& root, int dim) {
  std::vector<InitialVelocitySection> out;
  for (const TableReader& t : root.tables("initial_velocity")) {
    t.only({"lower", "upper", "velocity"});
    InitialVelocitySection iv;
    iv.where = t.self();
    iv.lower = t.require_vec("lower", dim);
    iv.upper = t.require_vec("upper", dim);
    check_box(t, iv.lower, iv.upper, dim, false);
    iv.velocity = t.require_vec("velocity", dim);
    out.push_back(iv);
  }
  return out;
}

/// A boundary's box from a physical group of a mesh file (`file`,
/// `physical`): the box of the group's nodes, which must be flat along an
/// axis (a boundary holds the nodes in a box: a slanted group would give more).
void read_boundary_group(const TableReader& t, BoundarySection& b, const Scene& s) {
  const int dim = s.simulation.dimension;
  check(dim >= 2, t.ref("file"), "a boundary from a mesh's physical group needs dimension 2 or 3");
  const std::string file = scene_relative_file(t, s), group = t.require<std::string>("physical");
  BodySection placed; // the placement keys, as a mesh body's
  read_placement(t, dim, placed.scale, placed.rotate, placed.translate);
  try {
    Vec<3> lo = Vec<3>::Zero(), hi = Vec<3>::Zero();
    if (dim == 2) {
      const auto [lo2, hi2] = mesh_group_box<2>(file, group, body_placement(placed));
      lo.head<2>() = lo2, hi.head<2>() = hi2;
    } else {
      std::tie(lo, hi) = mesh_group_box<3>(file, group, body_placement(placed));
    }
    double widest = 0;
    for (int k = 0; k < dim; ++k) widest = std::max(widest, hi[k] - lo[k]);
    bool flat = false;
    for (int k = 0; k < dim; ++k) flat |= hi[k] - lo[k] <= 1e-9 * widest;
    require(flat, file, ": physical group \"", group, "\" spans the box ", format_point<3>(lo), " - ",
            format_point<3>(hi), ", flat along no axis (a boundary is the nodes of a box)");
    for (int k = 0; k < dim; ++k) b.lower[k] = lo[k], b.upper[k] = hi[k];
  } catch (const InputError& e) {
    input_error(t.ref("physical"), e.what());
  }
}

TimeFunction read_time(const TableReader& parent);

std::vector<BoundarySection> read_boundaries(const TableReader& root, const Scene& s) {
  const int dim = s.simulation.dimension;
  std::vector<BoundarySection> out;
  std::set<std::string> names;
  for (const TableReader& t : root.tables("boundary")) {
    const bool group = t.has("physical") || t.has("file");
    if (group) t.only({"name", "file", "physical", "scale", "rotate", "translate", "fix", "value", "pore_pressure",
                     "water_level", "water_rise", "time"});
    else t.only({"name", "lower", "upper", "fix", "value", "pore_pressure", "water_level", "water_rise", "time"});
    BoundarySection b;
    b.where = t.self();
    b.name = read_name(t, false, default_name("boundary", out.size()), names, "boundary");
    if (group) {
      read_boundary_group(t, b, s);
    } else {
      b.lower = t.require_vec("lower", dim);
      b.upper = t.require_vec("upper", dim);
    }
    check_box(t, b.lower, b.upper, dim, false);
    auto fix = t.bools("fix", dim);
    if (!fix && !t.has("pore_pressure") && !t.has("water_level")) t.missing("fix");
    b.fix = fix.value_or(b.fix);
    b.value = t.vec("value", dim).value_or(b.value);
    if (t.has("pore_pressure")) b.pore_pressure = number(t, scene_keys::kPorePressure);
    if (t.has("water_level")) b.water_level = number(t, scene_keys::kWaterLevel);
    if (t.has("water_rise")) b.water_rise = number(t, scene_keys::kWaterRise);
    check(!t.has("time") || t.has("water_rise"), t.ref("time"), "is the time function of water_rise, which is not set");
    b.time = read_time(t);
    out.push_back(std::move(b));
  }
  return out;
}

std::vector<WallSection> read_walls(const TableReader& root, int dim) {
  std::vector<WallSection> out;
  std::set<std::string> names;
  for (const TableReader& t : root.tables("wall")) {
    t.only({"name", "point", "normal", "velocity", "friction"});
    WallSection w;
    w.where = t.self();
    w.name = read_name(t, false, default_name("wall", out.size()), names, "wall");
    w.point = t.require_vec("point", dim);
    w.normal = t.require_vec("normal", dim);
    enforce(scene_rules::wall_normal(w.normal, dim), t.ref("normal"));
    w.velocity = t.vec("velocity", dim).value_or(w.velocity);
    w.friction = number(t, scene_keys::kFriction, w.friction);
    out.push_back(std::move(w));
  }
  return out;
}

std::vector<PlateSection> read_plates(const TableReader& root, int dim) {
  std::vector<PlateSection> out;
  std::set<std::string> names;
  for (const TableReader& t : root.tables("plate")) {
    t.only({"name", "lower", "upper", "axis", "force", "time"});
    PlateSection p;
    p.where = t.self();
    p.name = read_name(t, false, default_name("plate", out.size()), names, "plate");
    p.lower = t.require_vec("lower", dim);
    p.upper = t.require_vec("upper", dim);
    check_box(t, p.lower, p.upper, dim, false);
    p.axis = t.get<int>("axis", dim - 1);
    enforce(scene_rules::axis_index(p.axis, dim), t.ref("axis"));
    p.force = number(t, scene_keys::kPlateForce, 0.0);
    p.time = read_time(t);
    out.push_back(std::move(p));
  }
  return out;
}

std::optional<ContactSection> read_contact(const TableReader& root) {
  auto t = root.table("contact");
  if (!t) return std::nullopt;
  t->only({"friction"});
  ContactSection c;
  c.where = t->self();
  c.friction = number(*t, scene_keys::kFriction, c.friction);
  return c;
}

std::optional<ChannelSection> read_channel(const TableReader& root) {
  auto t = root.table("channel");
  if (!t) return std::nullopt;
  t->only({"width", "friction"});
  ChannelSection c;
  c.where = t->self();
  c.width = number(*t, scene_keys::kChannelWidth);
  c.friction = number(*t, scene_keys::kFriction);
  return c;
}

TimeFunction read_time(const TableReader& parent) {
  TimeFunction f;
  auto t = parent.table("time");
  if (!t) return f;
  t->only({"kind", "period"});
  f.kind = t->choice("kind", f.kind, scene_rules::kTimeKinds);
  if (f.kind == "ramp" && !t->has("period")) t->missing("period", "required key is missing (kind = \"ramp\")");
  f.period = t->has("period") ? number(*t, scene_keys::kPeriod) : 0.0;
  return f;
}

std::optional<BodyForceSection> read_body_force(const TableReader& root, int dim) {
  auto t = root.table("body_force");
  if (!t) return std::nullopt;
  t->only({"value", "time"});
  BodyForceSection b;
  b.where = t->self();
  b.value = t->require_vec("value", dim);
  b.time = read_time(*t);
  return b;
}

std::vector<TractionSection> read_tractions(const TableReader& root, int dim) {
  std::vector<TractionSection> out;
  for (const TableReader& t : root.tables("traction")) {
    t.only({"lower", "upper", "value", "time", "function", "axis"});
    TractionSection tr;
    tr.where = t.self();
    tr.lower = t.require_vec("lower", dim);
    tr.upper = t.require_vec("upper", dim);
    check_box(t, tr.lower, tr.upper, dim, false);
    if (t.has("function")) tr.function = t.choice("function", "", scene_rules::kTractionFunctions);
    if (tr.function.empty()) tr.value = t.require_vec("value", dim);
    else tr.value = t.vec("value", dim).value_or(tr.value);
    tr.time = read_time(t);
    if (t.has("axis")) {
      tr.axis = t.get<int>("axis", 0);
      enforce(scene_rules::axis_index(*tr.axis, dim), t.ref("axis"));
    }
    out.push_back(tr);
  }
  return out;
}

std::vector<ProbeSection> read_probes(const TableReader& out_table, int dim) {
  std::vector<ProbeSection> out;
  std::set<std::string> names;
  for (const TableReader& t : out_table.tables("probes")) {
    t.only({"name", "particle", "at"});
    ProbeSection p;
    p.where = t.self();
    p.name = read_name(t, true, "", names, "probe");
    p.particle = t.choice("particle", p.particle, scene_rules::kProbeParticles);
    if (p.particle == "nearest" && !t.has("at")) t.missing("at", "required key is missing (particle = \"nearest\")");
    p.at = t.vec("at", dim).value_or(p.at);
    out.push_back(std::move(p));
  }
  return out;
}

/// output.fields: known, distinct particle field names - the built-in
/// fields (output_fields()) and the state of the scene's material models.
std::vector<std::string> read_fields(const TableReader& t, std::string_view key, std::vector<std::string> fallback,
                                     const Scene& s) {
  const toml::node* n = t.node(key);
  if (!n) return fallback;
  const SourceRef r = t.ref(key);
  const toml::array* a = n->as_array();
  if (!a) input_error(r, "expected an array of strings, got " + type_name(*n));
  const std::vector<std::string_view> known = output_field_names(s);
  std::vector<std::string> out;
  for (const toml::node& el : *a) {
    out.push_back(convert<std::string>(el, r));
    enforce(scene_rules::field(out, out.size() - 1, known, s.simulation.dimension), r);
  }
  return out;
}

/// output.format: "hdf5" (required) and at most one of "vtp", "vtu"; a
/// string is a list of one.
std::vector<std::string> read_formats(const TableReader& t) {
  const toml::node* n = t.node("format");
  if (!n) return {"hdf5"};
  const SourceRef r = t.ref("format");
  std::vector<std::string> out;
  if (n->is_string()) out.push_back(convert<std::string>(*n, r));
  else if (const toml::array* a = n->as_array())
    for (const toml::node& el : *a) out.push_back(convert<std::string>(el, r));
  else input_error(r, "expected an array of strings, got " + type_name(*n));
  enforce(scene_rules::formats(out), r);
  return out;
}

/// output.checkpoint_every (steps, >= 0) and output.checkpoint_file.
void read_checkpoint_keys(const TableReader& t, OutputSection& o) {
  const std::int64_t every = t.get<std::int64_t>("checkpoint_every", 0);
  enforce(scene_rules::checkpoint_every(every), t.ref("checkpoint_every"));
  o.checkpoint_every = static_cast<long>(every);
  o.checkpoint_file = t.get<std::string>("checkpoint_file", "");
  if (t.has("checkpoint_file")) enforce(scene_rules::file_name(o.checkpoint_file), t.ref("checkpoint_file"));
  enforce(scene_rules::checkpoint_file(o.checkpoint_file, o.file), t.ref("checkpoint_file"));
}

OutputSection read_output(const TableReader& root, const Scene& s) {
  const int dim = s.simulation.dimension;
  OutputSection o;
  auto t = root.table("output");
  if (!t) return o;
  t->only({"file", "every", "fields", "probes", "checkpoint_every", "checkpoint_file", "format", "precision",
            "symmetric_tensors", "compression"});
  o.where = t->self();
  o.file = t->get<std::string>("file", o.file);
  enforce(scene_rules::file_name(o.file), t->ref("file"));
  o.every = t->get<double>("every", o.every);
  check(o.every >= 0, t->ref("every"), "must be >= 0 (got " + fmt(o.every) + ")");
  o.fields = read_fields(*t, "fields", o.fields, s);
  o.probes = read_probes(*t, dim);
  read_checkpoint_keys(*t, o);
  o.formats = read_formats(*t);
  o.precision = t->choice("precision", o.precision, scene_rules::kPrecisions);
  o.symmetric_tensors = t->get<bool>("symmetric_tensors", o.symmetric_tensors);
  const std::int64_t level = t->get<std::int64_t>("compression", o.compression);
  enforce(scene_rules::compression(level), t->ref("compression"));
  o.compression = static_cast<int>(level);
  return o;
}

ReferenceSection read_reference(const TableReader& root) {
  ReferenceSection r;
  auto t = root.table("reference");
  if (!t) return r;
  t->only({"solution"});
  r.where = t->self();
  r.solution = t->choice("solution", "", {"", "dyka", "fixed_bar", "traction_bar", "mms_plate", "terzaghi", "mandel"});
  return r;
}

/// The node set must stay within kMaxSceneNodes: the grid in mpm mode, the
/// bodies' bounding box in ul mode (both in cells of grid.h).
void check_node_count(const TableReader& grid, const Scene& s) {
  const LatticeBox box = node_lattice_box(s);
  for (int k = 0; k < s.simulation.dimension; ++k)
    check(box.cells[k] <= kMaxCellsPerAxis, grid.ref(grid.has("h") ? "h" : "cells"),
          "the node set would have " + fmt(box.cells[k]) + " cells on axis " + std::to_string(k) +
              " (the bodies' bounding box in cells of the grid spacing); at most " + fmt(kMaxCellsPerAxis) +
              " are allowed");
  const double n = node_count(s);
  check(n <= kMaxSceneNodes, grid.ref(grid.has("h") ? "h" : "cells"),
        "the node set would have " + fmt(n) + " nodes" +
            (s.simulation.mode == "ul" ? " (the bodies' bounding box in cells of the grid spacing)" : "") +
            "; at most " + fmt(kMaxSceneNodes) + " are allowed");
}

Scene read_scene(const toml::table& root, Context& ctx) {
  TableReader r(ctx, &root, "", SourceRef{ctx.file, 1, ""});
  r.only({"simulation", "basis", "grid", "material", "body", "initial_velocity", "boundary", "wall", "plate",
          "contact", "channel", "body_force", "traction", "output", "reference"});
  Scene s;
  s.file = ctx.file;
  s.simulation = read_simulation(r.require_table("simulation"));
  const int dim = s.simulation.dimension;
  const TableReader basis = r.require_table("basis");
  s.basis = read_basis(basis);
  s.basis_where = basis.self();
  const TableReader grid = r.require_table("grid");
  s.grid = read_grid(grid, dim);
  // The node count before the bodies (their particle count assumes a sane
  // grid) - except in ul mode, where the bodies make the node lattice.
  if (!s.simulation.nodes_move()) check_node_count(grid, s);
  s.materials = read_materials(r);
  s.bodies = read_bodies(r, s);
  if (s.simulation.nodes_move()) check_node_count(grid, s);
  s.initial_velocities = read_initial_velocities(r, dim);
  s.boundaries = read_boundaries(r, s);
  s.walls = read_walls(r, dim);
  s.plates = read_plates(r, dim);
  s.contact = read_contact(r);
  s.channel = read_channel(r);
  s.body_force = read_body_force(r, dim);
  s.tractions = read_tractions(r, dim);
  s.output = read_output(r, s);
  s.reference = read_reference(r);
  return s;
}

// ---------------------------------------------------------------- --set

/// Keys that exclude each other: setting one on the command line drops the other.
const std::map<std::string, std::string> kExclusive = {
    {"grid.h", "grid.cells"}, {"grid.cells", "grid.h"}, {"simulation.dt", "simulation.cfl"},
    {"simulation.cfl", "simulation.dt"}};

/// Throws InputError "--set KEY: message" (source: the override's key).
[[noreturn]] void override_error(const std::string& key, const std::string& message) {
  throw InputError("--set " + shortened(key) + ": " + message, {"", kCommandLineLine, key});
}

std::vector<std::string> split_key(const std::string& key, const std::string& what) {
  std::vector<std::string> segs;
  std::size_t start = 0;
  for (;;) {
    const std::size_t dot = key.find('.', start);
    segs.push_back(key.substr(start, dot - start));
    if (segs.back().empty()) override_error(what, "empty key segment");
    if (dot == std::string::npos) return segs;
    start = dot + 1;
  }
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

/// VALUE as a TOML value; a bare word that is not valid TOML is a string
/// (if it is valid UTF-8: otherwise the resolved scene text would not read back).
toml::table parse_value(const std::string& key, const std::string& value) {
  // A line break would let the value end early and the rest of it become
  // more keys of its own ("1e-5\nsimulation.cfl=5"), silently dropped.
  if (value.find_first_of("\n\r") != std::string::npos)
    override_error(key, "cannot read '" + shortened(TableReader::printable(value)) +
                            "' as a TOML value: it contains a line break (one --set takes one value on one line)");
  try {
    const std::string doc = "v = " + value + "\n";
    return toml::parse(std::string_view(doc), std::string_view("--set"));
  } catch (const toml::parse_error& e) {
    const bool bare = !value.empty() && std::string("[{\"'").find(value.front()) == std::string::npos;
    if (!bare)
      override_error(key, "cannot read '" + shortened(value) + "' as a TOML value: " + std::string(e.description()));
    if (!text::valid_utf8(value)) override_error(key, "the value is not valid UTF-8 text");
    toml::table t;
    t.insert("v", value);
    return t;
  }
}

/// Finds the element of an array of tables named `seg` (or with index `seg`).
toml::table* find_element(toml::array& a, const std::string& seg, std::string& canonical) {
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!a[i].is_table()) continue;
    const std::string name = TableReader::element_name(a[i], i);
    if (name == seg || std::to_string(i) == seg) {
      canonical = name;
      return a[i].as_table();
    }
  }
  return nullptr;
}

void apply_override(toml::table& root, const std::string& text, Context& ctx) {
  const std::size_t eq = text.find('=');
  if (eq == std::string::npos) override_error(text, "expected KEY=VALUE");
  const std::string key = trim(text.substr(0, eq));
  const std::vector<std::string> segs = split_key(key, text);
  toml::table parsed = parse_value(key, trim(text.substr(eq + 1)));
  toml::table* cur = &root;
  std::string path;
  for (std::size_t i = 0; i + 1 < segs.size(); ++i) {
    toml::node* n = cur->get(segs[i]);
    path = join_path(path, segs[i]);
    if (!n) {
      if (kTableArrays.count(segs[i])) override_error(key, "the scene has no [[" + path + "]]");
      n = &cur->insert(segs[i], toml::table{}).first->second;
      ctx.overridden.emplace(path, key);
    }
    if (toml::array* a = n->as_array(); a && i + 2 < segs.size()) {
      std::string name;
      cur = find_element(*a, segs[++i], name);
      if (!cur) override_error(key, "no element '" + segs[i] + "' in [[" + path + "]]");
      path += "." + name;
    } else if (!(cur = n->as_table())) {
      override_error(key, "'" + path + "' is not a table");
    }
  }
  path = join_path(path, segs.back());
  cur->insert_or_assign(segs.back(), *parsed.get("v"));
  ctx.overridden[path] = key;
  if (auto ex = kExclusive.find(path); ex != kExclusive.end())
    cur->erase(ex->second.substr(ex->second.find('.') + 1));
}

} // namespace

// ---------------------------------------------------------------- public

std::string SourceRef::describe() const {
  const std::string k = shortened(key);
  if (line == kCommandLineLine) return "--set " + k + (field.empty() ? "" : ": key '" + shortened(field) + "'");
  if (file.empty() && line <= 0) return "key '" + k + "'"; // a Scene built in code
  std::string s = shortened(file);
  if (line > 0) s += ":" + std::to_string(line);
  return s + ": key '" + k + "'";
}

void input_error(const SourceRef& where, const std::string& message) {
  throw InputError(where.describe() + ": " + message, {where.file, where.line, where.key});
}

Vec<3> first_components(const Vec3& v, int dim) {
  Vec<3> out = Vec<3>::Zero();
  for (int k = 0; k < dim; ++k) out[k] = v[static_cast<std::size_t>(k)];
  return out;
}

namespace {

/// `key` with an unnamed table's element as the reader records it: the
/// name the reader gives it (default_name: the section's name and its
/// index, "body.body0.lower") replaced by its index ("body.0.lower"); ""
/// when `key` has no such element.
std::string unnamed_element_key(const std::string& key) {
  const std::size_t dot = key.find('.');
  if (dot == std::string::npos) return "";
  const std::string section = key.substr(0, dot);
  const std::size_t end = std::min(key.find('.', dot + 1), key.size());
  const std::string element = key.substr(dot + 1, end - dot - 1);
  if (element.size() <= section.size() || element.compare(0, section.size(), section) != 0) return "";
  const std::string index = element.substr(section.size());
  if (index.find_first_not_of("0123456789") != std::string::npos) return "";
  return section + "." + index + key.substr(end);
}

} // namespace

SourceRef Scene::locate(const std::string& key) const {
  const auto found = [&](const std::string& k) -> const SourceRef* {
    auto it = where.find(k);
    if (it == where.end()) {
      const std::string unnamed = unnamed_element_key(k);
      if (!unnamed.empty()) it = where.find(unnamed);
    }
    return it == where.end() ? nullptr : &it->second;
  };
  if (const SourceRef* r = found(key)) return *r;
  // A key the file leaves to its default: the line of the nearest table
  // around it that the file has (its [simulation], its [[body]] element).
  // A section's own line is taken only for its direct keys ("simulation.mass"),
  // not for an element it does not have ("body.sand.k0" is not at [[body]]).
  const std::size_t section_end = key.find('.');
  const bool direct = section_end != std::string::npos && key.find('.', section_end + 1) == std::string::npos;
  for (std::size_t dot = key.rfind('.');
       dot != std::string::npos && (dot > section_end || (dot > 0 && direct));
       dot = key.rfind('.', dot - 1)) {
    const SourceRef* table = found(key.substr(0, dot));
    if (!table || table->line == 0) continue;
    if (table->line == kCommandLineLine) return SourceRef{table->file, table->line, table->key, key};
    return SourceRef{table->file, table->line, key};
  }
  return SourceRef{file, 0, key};
}

Scene parse_scene(const std::string& text, const std::string& name, const std::vector<std::string>& overrides,
                  int processes) {
  toml::table root = parse_toml_text(text, name);
  Context ctx;
  ctx.file = name;
  ctx.processes = processes;
  for (const std::string& o : overrides) apply_override(root, o, ctx);
  Scene s = read_scene(root, ctx);
  s.where = std::move(ctx.where);
  // checks across sections, with the lines recorded above; the size per
  // process is for the run to check, which knows its rank count
  validate_scene(s, s.simulation.dimension, 0);
  std::ostringstream os;
  os << root << "\n";
  s.text = os.str();
  return s;
}

bool is_output_format(const std::string& format) {
  return std::find(scene_rules::kOutputFormats.begin(), scene_rules::kOutputFormats.end(), format) !=
         scene_rules::kOutputFormats.end();
}

std::string vtk_format(const OutputSection& output) {
  for (const std::string& f : output.formats)
    if (f == "vtp" || f == "vtu") return f;
  return "";
}

namespace {
/// The default node reset fraction (node_reset_fraction): measured on the
/// quarter Taylor bar (docs/benchmarks.md), the fewest steps whose runs
/// dissipate (0.8 created 1.4 % of E0 at h = R/3).
constexpr double kDefaultNodeReset = 0.7;
} // namespace

bool uses_consistent_mass(const Scene& scene) {
  const IntegratorKind* integrator = find_integrator(scene.simulation.integrator);
  return scene.simulation.mass == "consistent" || (integrator && integrator->needs_consistent_mass);
}

bool saturated(const Scene& scene) {
  return std::any_of(scene.materials.begin(), scene.materials.end(),
                     [](const MaterialSection& m) { return pore_fluid(m).has_value(); });
}

double node_reset_fraction(const Scene& scene) {
  if (scene.simulation.node_reset) return *scene.simulation.node_reset;
  if (!scene.simulation.nodes_move()) return 0.0;
  for (const BodySection& b : scene.bodies)
    if (b.nodes == "mesh") return 0.0;
  // The consistent mass on a reset lattice: its lines cut the body's cells
  // (a cell holding one layer of particles), where M extrapolates the nodal
  // values from one side and the run fails within steps; the advected nodes
  // keep their cells filled. B-splines keep the reset: it also keeps their
  // particles inside the knot vectors (docs/theory.md sect. 3).
  if (const BasisKind* kind = find_basis_kind(scene.basis.kind);
      uses_consistent_mass(scene) && kind && !kind->bspline)
    return 0.0;
  for (const BoundarySection& a : scene.boundaries)
    for (const BoundarySection& b : scene.boundaries)
      for (std::size_t k = 0; k < 3; ++k)
        if (a.fix[k] && b.fix[k] && a.value[k] != b.value[k]) return 0.0;
  return kDefaultNodeReset;
}

std::string volumetric_treatment(const Scene& scene) {
  if (!scene.simulation.volumetric.empty()) return scene.simulation.volumetric;
  // ul: the lattice cells move with the material and keep their particles,
  // whose own volume changes lock isochoric plastic flow; an elastic body
  // does not lock, and with a hyperelastic law (whose mean stress depends on
  // the isochoric part) the average lowers the stable step; a frictional
  // model's cone does not fit the patch's mean stress (a granular column's
  // top sinks); mpm: particles change cells, and a cell's average does not
  // follow them (docs/benchmarks.md, "ul on large deformation", "Granular
  // column collapse").
  if (!scene.simulation.nodes_move()) return "none";
  for (const MaterialSection& m : scene.materials)
    if (const MaterialModel* model = find_material_model(m.model); model && !model->state.empty() && !model->frictional)
      return "fbar";
  return "none";
}

namespace {

/// The extent along axis k that body `b` gives the `ul` node lattice: a shape
/// seeded by otmpm is seeded in the lattice's own cells, so its bounds are
/// the lattice's; a particle file's particles were placed by the user, so the
/// bounds of their extents are rounded out to the scene grid's lines (origin
/// `g0`, spacing h): every particle is then inside the nodes' hull by at
/// least half its size, as in `mpm` mode (docs/theory.md sect. 3).
std::pair<double, double> lattice_bounds(const BodySection& b, double g0, double h, int k) {
  if (b.shape != "file") return {b.lower[k], b.upper[k]};
  constexpr double on_line = 1e-6; // of h: a bound this close to a grid line lies on it
  return {g0 + std::floor((b.lower[k] - g0) / h + on_line) * h, g0 + std::ceil((b.upper[k] - g0) / h - on_line) * h};
}

} // namespace

LatticeBox node_lattice_box(const Scene& s) {
  LatticeBox box;
  box.lower = s.grid.lower;
  box.upper = s.grid.upper;
  for (int k = 0; k < s.simulation.dimension; ++k) {
    box.cells[k] = s.grid.cells[k];
    if (!s.simulation.nodes_move() || s.bodies.empty()) continue;
    // ul: the nodes discretise only the material, in cells of the grid spacing
    const double h = (s.grid.upper[k] - s.grid.lower[k]) / s.grid.cells[k];
    box.lower[k] = std::numeric_limits<double>::infinity();
    box.upper[k] = -box.lower[k];
    for (const BodySection& b : s.bodies) {
      const auto [lo, hi] = lattice_bounds(b, s.grid.lower[k], h, k);
      box.lower[k] = std::min(box.lower[k], lo);
      box.upper[k] = std::max(box.upper[k], hi);
    }
    box.cells[k] = cells_over(box.upper[k] - box.lower[k], h);
  }
  return box;
}

SceneSize scene_size(const Scene& scene) {
  SceneSize n;
  const int dim = scene.simulation.dimension;
  const LatticeBox box = node_lattice_box(scene);
  for (int k = 0; k < dim; ++k) n.axis_cells = std::max(n.axis_cells, box.cells[k]);
  for (const BodySection& b : scene.bodies) {
    n.particles += body_particles(b, scene.grid, dim);
    for (int k = 0; k < dim && b.shape != "file" && b.shape != "mesh"; ++k)
      n.axis_cells = std::max(n.axis_cells, cells_over(b.upper[k] - b.lower[k], spacing(scene.grid, k)));
  }
  n.nodes = node_count(scene);
  return n;
}

Scene load_scene(const std::string& path, const std::vector<std::string>& overrides, int processes) {
  if (path.empty()) throw InputError("load_scene: the scene file path is empty");
  return parse_scene(read_text_file(path, "scene file"), path, overrides, processes);
}

} // namespace otmpm
