/// \file validate.cpp
/// Checks of a Scene as plain data (see validate.hpp). Each section has one
/// short function; every failure is an InputError at the scene key.
#include "otmpm/scene/validate.hpp"

#include "otmpm/basis/kinds.hpp"
#include "otmpm/engine/side_walls.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/io/particle_file.hpp"
#include "otmpm/materials/material.hpp"
#include "otmpm/materials/models.hpp"
#include "otmpm/materials/pore_fluid.hpp"
#include "otmpm/particles/output_fields.hpp"
#include "otmpm/scene/file_bodies.hpp"
#include "otmpm/scene/scene_rules.hpp"
#include "otmpm/scene/toml_reader.hpp"
#include "otmpm/text.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <span>
#include <stdexcept>
#include <string_view>

namespace otmpm {

namespace {

/// Throws InputError "<where key>: <parts>" unless `ok`.
template <class... Parts> void check(const Scene& s, bool ok, const std::string& key, const Parts&... parts) {
  if (!ok) [[unlikely]]
    input_error(s.locate(key), error_message(parts...));
}

/// A shared rule (scene_rules.hpp) at `key`: its message unless it passed ("").
void enforce(const Scene& s, const std::string& broken, const std::string& key) {
  if (!broken.empty()) [[unlikely]]
    input_error(s.locate(key), broken);
}

/// `value` of `key` one of the words of its rule.
void check_choice(const Scene& s, const std::string& key, std::span<const std::string_view> allowed,
                  const std::string& value) {
  enforce(s, scene_rules::choice(allowed, value), key);
}

/// The key of element `index` of an array of tables: "section.NAME", or
/// "section.INDEX" when it has no name (as parse_scene records them); a
/// control character of the name shown as \\xHH (toml_input::TableReader::printable).
std::string element_key(const std::string& section, const std::string& name, std::size_t index) {
  return section + "." + (name.empty() ? std::to_string(index) : toml_input::TableReader::printable(name));
}

/// The name of a `what` at key.name as the reader takes it (read_name in
/// scene.cpp): one a result-file group and a --set key can hold
/// (invalid_name_reason), and unique in its kind (`seen`). A name left
/// empty is an error when `required`, else it stands for `fallback`, the
/// name the reader gives an unnamed table (default_name; to_toml leaves the
/// name out, so a scene built in code reads back with the same names).
void check_name(const Scene& s, const std::string& key, const std::string& name, const char* what, bool required,
                const std::string& fallback, std::set<std::string>& seen) {
  check(s, !required || !name.empty(), key + ".name", "must not be empty");
  if (!name.empty()) {
    const std::string why = name_error(name, what);
    check(s, why.empty(), key + ".name", why);
  }
  const std::string& effective = name.empty() ? fallback : name;
  check(s, seen.insert(effective).second, key + ".name", "duplicate name \"", shortened(effective), "\"",
        name.empty() ? " (the name of an unnamed " + std::string(what) + " at this place)" : std::string());
}

/// The first `dim` components of every vector are finite.
void check_finite(const Scene& s, const std::string& key, const Vec3& v, int dim) {
  for (int k = 0; k < dim; ++k) check(s, std::isfinite(v[k]), key, "component ", k, " is not finite (", v[k], ")");
}

/// key.lower and key.upper finite, upper > lower (strict) or >= lower.
void check_box(const Scene& s, const std::string& key, const Vec3& lo, const Vec3& hi, int dim, bool strict) {
  check_finite(s, key + ".lower", lo, dim);
  check_finite(s, key + ".upper", hi, dim);
  enforce(s, scene_rules::box(lo, hi, dim, strict), key + ".upper");
}

/// `value` of `key` in the range of its row (scene_keys).
void check_number(const Scene& s, const std::string& key, double value, const ParameterSpec& spec) {
  const std::string why = spec.check(value);
  check(s, why.empty(), key, why);
}

/// kind "constant" or "ramp"; a ramp needs a finite period > 0 (it divides by it).
void check_time(const Scene& s, const std::string& key, const TimeFunction& g) {
  check_choice(s, key + ".kind", scene_rules::kTimeKinds, g.kind);
  if (g.kind == "ramp") check_number(s, key + ".period", g.period, scene_keys::kPeriod);
}

/// simulation.initial_equilibrium: its numbers, and a scene whose loads at
/// t = 0 it can bring into equilibrium: the fixed grid and a constant body force.
void check_initial_equilibrium(const Scene& s) {
  const auto& q = s.simulation.initial_equilibrium;
  if (!q) return;
  const std::string key = "simulation.initial_equilibrium";
  using namespace scene_keys;
  for (const auto& [spec, value] : {std::pair{&kEquilibriumTime, q->time}, {&kEquilibriumDamping, q->damping},
                                   {&kEquilibriumTolerance, q->tolerance}})
    check_number(s, key + "." + std::string(spec->key), value, *spec);
  check(s, s.simulation.mode == "mpm", key, "needs mode = \"mpm\" (the fixed grid), got \"", s.simulation.mode, "\"");
  check(s, s.body_force.has_value(), key,
        "brings the bodies into equilibrium under their weight: it needs a [body_force]");
  check(s, first_components(s.body_force->value, s.simulation.dimension).norm() != 0.0, key,
        "brings the bodies into equilibrium under their weight: body_force.value is zero");
  check(s, s.body_force->time.kind == "constant", key,
        "brings the bodies into equilibrium under their weight at t = 0: body_force.time must be constant");
}

void check_simulation(const Scene& s, int dim) {
  const SimulationSection& m = s.simulation;
  check(s, m.dimension == dim, "simulation.dimension", "the scene is ", m.dimension, "D but the run is ", dim, "D");
  check_choice(s, "simulation.mode", scene_rules::kModes, m.mode);
  const IntegratorKind* integrator = find_integrator(m.integrator);
  check(s, integrator != nullptr, "simulation.integrator", "must be one of ", integrator_list(), " (got \"",
        m.integrator, "\")");
  check_choice(s, "simulation.mass", scene_rules::kMasses, m.mass);
  if (!m.volumetric.empty()) check_choice(s, "simulation.volumetric", scene_rules::kVolumetric, m.volumetric);
  if (m.node_reset) check_number(s, "simulation.node_reset", *m.node_reset, scene_keys::kNodeReset);
  enforce(s, scene_rules::node_reset(m.node_reset.value_or(0.0), m.nodes_move()), "simulation.node_reset");
  // A node reset moves the lattice lines along an axis with the boundaries that fix it: one velocity per axis.
  for (std::size_t k = 0; k < static_cast<std::size_t>(m.dimension) && node_reset_fraction(s) > 0; ++k)
    for (const BoundarySection& a : s.boundaries)
      for (const BoundarySection& b : s.boundaries)
        check(s, !(a.fix[k] && b.fix[k] && a.value[k] != b.value[k]), "simulation.node_reset", "boundaries '",
              a.name, "' and '", b.name, "' fix axis ", k, " at different velocities (", a.value[k], ", ",
              b.value[k],
              "): a node reset moves the lattice lines with the boundaries, one velocity per axis");
  check(s, !integrator->needs_ul || m.nodes_move(), "simulation.integrator", "integrator \"", m.integrator,
        "\" needs advected nodes: use simulation.mode = \"ul\"");
  check(s, !integrator->needs_consistent_mass || m.mass == "consistent", "simulation.mass", "integrator \"",
        m.integrator, "\" uses the consistent mass matrix (wobbes et al. Algorithm 3): set mass = \"consistent\"");
  const auto known = integrator_parameters();
  for (const auto& entry : m.parameters) {
    const std::string& key = entry.first; // named, not a structured binding: the lambda captures it (clang)
    const auto spec = std::find_if(known.begin(), known.end(), [&](const ParameterSpec* p) { return p->key == key; });
    check(s, spec != known.end(), "simulation." + key, "is not a parameter of any integrator");
    const std::string why = (*spec)->check(entry.second);
    check(s, why.empty(), "simulation." + key, why);
  }
  // The one parameter an integrator must not ignore: a run without the relaxation it asks for is not the run.
  check(s, !m.parameters.count("pic_relaxation_time") || integrator->takes("pic_relaxation_time"),
        "simulation.pic_relaxation_time", "integrator \"", m.integrator,
        "\" does not relax the particle velocities toward the grid's (use ", integrator_list("pic_relaxation_time"),
        ")");
  using namespace scene_keys;
  check_number(s, "simulation.t_end", m.t_end, kTEnd);
  if (m.dt) check_number(s, "simulation.dt", *m.dt, kDt);
  else check_number(s, "simulation.cfl", m.cfl, kCfl);
  for (const auto& [spec, value] : {std::pair{&kMassTolerance, m.mass_tolerance}, {&kEnergyLimit, m.energy_limit},
                                   {&kMaxSteps, m.max_steps}, {&kMemoryLimit, m.memory_limit}})
    check_number(s, "simulation." + std::string(spec->key), value, *spec);
  check_initial_equilibrium(s);
}

void check_grid(const Scene& s, int dim) {
  const GridSection& g = s.grid;
  check_choice(s, "grid.kind", scene_rules::kGridKinds, g.kind);
  check_box(s, "grid", g.lower, g.upper, dim, true);
  enforce(s, scene_rules::extent(g.lower, g.upper, dim), "grid.upper");
  enforce(s, scene_rules::cells(g.cells, dim), "grid.cells");
  if (g.kind == "perturbed") check_number(s, "grid.perturbation", g.perturbation, scene_keys::kPerturbation);
}

void check_basis(const Scene& s) {
  const BasisKind* kind = find_basis_kind(s.basis.kind);
  if (!kind) input_error(s.basis_where, "kind must be one of " + basis_kind_list() + " (got \"" + s.basis.kind + "\")");
  const IntegratorKind* integrator = find_integrator(s.simulation.integrator);
  check(s, !integrator->needs_bspline || kind->bspline, "basis.kind", "integrator \"", s.simulation.integrator,
        "\" needs a B-spline basis (bspline2 or bspline3), got \"", s.basis.kind, "\"");
  check(s, !kind->cartesian_only || s.grid.kind == "cartesian", "basis.kind", s.basis.kind,
        " needs an unperturbed Cartesian grid; this scene has grid.kind = \"", s.grid.kind, "\"");
  check(s, !kind->cartesian_only || !s.simulation.nodes_move(), "basis.kind", s.basis.kind,
        " needs a fixed Cartesian grid: its nodes cannot move (use simulation.mode = \"mpm\")");
  const auto metrics = basis_metrics();
  check(s, std::find(metrics.begin(), metrics.end(), s.basis.metric) != metrics.end(), "basis.metric",
        "must be one of ", basis_metric_list(), " (got \"", s.basis.metric, "\")");
  check(s, s.basis.metric == metrics.front() || kind->adapts_metric, "basis.metric", "\"", s.basis.metric,
        "\" needs a basis that adapts its locality; basis.kind = \"", s.basis.kind, "\" has only \"",
        metrics.front(), "\"");
  for (const auto& [key, value] : s.basis.values) {
    const ParameterSpec* p = find_basis_parameter(key);
    check(s, p != nullptr, "basis." + key, "unknown key (not a parameter of any basis family)");
    check_number(s, "basis." + key, value, *p);
  }
}

void check_materials(const Scene& s) {
  check(s, !s.materials.empty(), "material", scene_rules::kNoMaterial);
  std::set<std::string> names;
  for (std::size_t i = 0; i < s.materials.size(); ++i) {
    const MaterialSection& ms = s.materials[i];
    const std::string key = element_key("material", ms.name, i);
    check_name(s, key, ms.name, "material", true, "", names);
    try {
      validate_material(ms);
    } catch (const InputError& e) {
      input_error(s.locate(key), e.what());
    }
  }
}

/// The shape of a body: known, with the values it needs (its bounds are
/// lower/upper for every shape).
void check_shape(const Scene& s, const BodySection& b, const std::string& key, int dim) {
  check_choice(s, key + ".shape", scene_rules::kShapes, b.shape);
  check_box(s, key, b.lower, b.upper, dim, true);
  if (b.shape == "sphere" || b.shape == "cylinder") {
    check_finite(s, key + ".center", b.center, dim);
    enforce(s, scene_rules::size(b.radius), key + ".radius");
  }
  if (b.shape == "cylinder") {
    enforce(s, scene_rules::cylinder_dimension(dim), key + ".shape");
    check_finite(s, key + ".axis", b.axis, dim);
    enforce(s, scene_rules::cylinder_axis(b.axis, dim), key + ".axis");
    enforce(s, scene_rules::size(b.length), key + ".length");
  }
  if (b.shape == "polygon") {
    enforce(s, scene_rules::polygon_dimension(dim), key + ".shape");
    enforce(s, scene_rules::vertex_count(b.vertices.size()), key + ".vertices");
  }
  if (b.shape == "file") {
    enforce(s, scene_rules::file_name(b.file), key + ".file");
    check(s, b.file.find('\0') == std::string::npos, key + ".file", "must not contain NUL (code 0)");
  }
  if (b.shape == "stl" || b.shape == "mesh") {
    enforce(s, scene_rules::file_name(b.file), key + ".file");
    check(s, b.file.find('\0') == std::string::npos, key + ".file", "must not contain NUL (code 0)");
    check(s, b.shape == "mesh" ? dim >= 2 : dim == 3, key + ".shape", "\"", b.shape, "\" needs dimension ",
          b.shape == "mesh" ? "2 or 3" : "3");
    check_choice(s, key + ".seeding", scene_rules::kSeedings, b.seeding);
    check_choice(s, key + ".nodes", scene_rules::kNodeSources, b.nodes);
    for (int k = 0; k < 3; ++k)
      check(s, finite_positive(b.scale[static_cast<std::size_t>(k)]) && std::isfinite(b.rotate[static_cast<std::size_t>(k)]) &&
                   std::isfinite(b.translate[static_cast<std::size_t>(k)]),
            key + ".scale", "scale must be finite and > 0, rotate and translate finite");
  }
}

/// nodes = "mesh": a mesh body in `ul` mode, every body alike (one node
/// set), a basis that takes a node cloud (the max-ent families).
void check_mesh_nodes(const Scene& s) {
  if (!mesh_nodes(s)) return;
  const auto first = std::find_if(s.bodies.begin(), s.bodies.end(), [](const BodySection& b) { return b.nodes == "mesh"; });
  for (std::size_t i = 0; i < s.bodies.size(); ++i) {
    const BodySection& b = s.bodies[i];
    const std::string key = element_key("body", b.name, i) + ".nodes";
    check(s, b.nodes != "mesh" || b.shape == "mesh", key, "\"mesh\" takes the vertices of a mesh body's elements "
          "as nodes: it needs shape = \"mesh\" (got \"", b.shape, "\")");
    check(s, b.nodes == "mesh", key, "body '", first->name, "' takes its mesh's vertices as the nodes, body '",
          b.name, "' its nodes from the lattice: a scene has one node set (give every body shape = \"mesh\" and "
          "nodes = \"mesh\")");
  }
  const std::string key = element_key("body", first->name, static_cast<std::size_t>(first - s.bodies.begin())) + ".nodes";
  check(s, s.simulation.nodes_move(), key, "the mesh's vertices as nodes move with the material: nodes = \"mesh\" "
        "needs simulation.mode = \"ul\" (mpm's nodes are the fixed grid)");
  const BasisKind* kind = find_basis_kind(s.basis.kind);
  std::string takes; // the families that take a mesh's vertices: on its elements, or as a cloud
  for (const BasisKind& k : basis_kinds())
    if (k.mesh_elements || !k.needs_lattice) takes += (takes.empty() ? "" : ", ") + std::string(k.name);
  check(s, kind && (kind->mesh_elements || !kind->needs_lattice), "basis.kind", "basis \"", s.basis.kind,
        "\" needs the nodes of a lattice, and body '", first->name, "' gives the mesh's vertices as nodes (nodes = "
        "\"mesh\"): use ", takes, ", or nodes = \"lattice\"");
}

/// Where a box of `key` came from: the --set that changed its lower or
/// upper corner, else the table itself.
SourceRef box_where(const Scene& s, const std::string& key) {
  for (const char* corner : {".lower", ".upper"}) {
    const SourceRef r = s.locate(key + corner);
    if (r.line < 0) return r;
  }
  return s.locate(key);
}

/// In `mpm` mode the particles must start on the grid.
void check_body_in_grid(const Scene& s, const BodySection& b, const std::string& key, int dim) {
  const GridSection& g = s.grid;
  for (int k = 0; k < dim; ++k) {
    const double tol = kBoxTolerance * (g.upper[k] - g.lower[k]) / g.cells[k];
    if (b.lower[k] >= g.lower[k] - tol && b.upper[k] <= g.upper[k] + tol) continue;
    input_error(box_where(s, key), error_message("body '", b.name, "' [", b.lower[k], ", ", b.upper[k], "] on axis ", k,
                                                 " is not inside the grid [", g.lower[k], ", ", g.upper[k],
                                                 "] (mpm mode)"));
  }
}

/// [contact]: friction >= 0; the fixed grid with the lumped mass (each body
/// is given its own copy of the grid's nodal fields).
void check_contact(const Scene& s) {
  if (!s.contact) return;
  const ContactSection& c = *s.contact;
  check_number(s, "contact.friction", c.friction, scene_keys::kFriction);
  if (s.simulation.nodes_move())
    input_error(c.where, "body-body contact needs simulation.mode = \"mpm\": it gives each body its own copy of "
                         "the fixed grid's nodal fields, and in \"ul\" mode, where the nodes move with the "
                         "material, contact between bodies is not implemented (remove [contact] or use mode = "
                         "\"mpm\"; rigid [[wall]]s work in both modes)");
  if (uses_consistent_mass(s))
    input_error(c.where, "body-body contact needs the lumped mass (simulation.mass = \"lumped\"): the "
                         "correction acts node by node on each body's velocity field");
}

/// [channel]: width > 0, friction >= 0, finite; plane strain (2D) only, dry
/// bodies.
void check_channel(const Scene& s) {
  if (!s.channel) return;
  const ChannelSection& c = *s.channel;
  check_number(s, "channel.width", c.width, scene_keys::kChannelWidth);
  check_number(s, "channel.friction", c.friction, scene_keys::kFriction);
  if (s.simulation.dimension != 2)
    input_error(c.where,
                "[channel] needs simulation.dimension = 2: its side walls bound a plane-strain body in the "
                "out-of-plane direction (in 3D model the walls as [[wall]]s)");
  if (saturated(s)) input_error(c.where, SideWalls::refusal_saturated());
}

/// The integrators that step saturated bodies (IntegratorKind::two_phase), for messages.
std::string two_phase_integrators() {
  std::string list;
  for (const IntegratorKind& k : integrator_kinds())
    if (k.two_phase) list += std::string(list.empty() ? "" : " or ") + "\"" + std::string(k.name) + "\"";
  return list;
}

/// The axis of the scene's body force when it acts along one axis of the
/// run (gravity), else -1.
int gravity_axis(const Scene& s, int dim) {
  if (!s.body_force) return -1;
  int axis = -1;
  for (int k = 0; k < dim; ++k)
    if (s.body_force->value[k] != 0.0) axis = axis < 0 ? k : dim;
  return axis < dim ? axis : -1;
}

/// The fluid density the saturated materials share, or 0 when they differ.
double shared_fluid_density(const Scene& s) {
  double rho = -1.0;
  for (const MaterialSection& m : s.materials)
    if (const auto f = pore_fluid(m)) rho = rho < 0.0 || rho == f->density ? f->density : 0.0;
  return std::max(rho, 0.0);
}

/// A boundary's saturated keys: pore_pressure (any value) and water_level
/// (free water under the body force, of the pore fluid's density), in a
/// scene with saturated bodies.
void check_saturated_boundary(const Scene& s, const BoundarySection& b, const std::string& key) {
  if (b.pore_pressure) check_number(s, key + ".pore_pressure", *b.pore_pressure, scene_keys::kPorePressure);
  if (b.water_level) {
    check_number(s, key + ".water_level", *b.water_level, scene_keys::kWaterLevel);
    check(s, gravity_axis(s, s.simulation.dimension) >= 0, key + ".water_level",
          "is a height against the body force, but the scene has no [body_force] along one axis");
    check(s, !saturated(s) || shared_fluid_density(s) > 0.0, key + ".water_level",
          "takes the free water's density from the pore fluid, but the saturated materials' fluid_density differ");
  }
  if (b.water_rise) {
    check_number(s, key + ".water_rise", *b.water_rise, scene_keys::kWaterRise);
    check(s, b.water_level.has_value(), key + ".water_rise", "raises a water level, which needs water_level");
    check_time(s, key + ".time", b.time);
  }
  if (b.pore_pressure || b.water_level)
    check(s, saturated(s), key + (b.pore_pressure ? ".pore_pressure" : ".water_level"),
          "marks a drained surface of a saturated body, but no material has a pore fluid (porosity, "
          "permeability, fluid_density, fluid_bulk_modulus, fluid_viscosity)");
}

/// A body's water table and k0: a saturated material whose model takes an
/// initial stress, under a body force along one axis.
void check_water_table(const Scene& s, const BodySection& b, const std::string& key) {
  check(s, !b.k0 || b.water_table, key + ".k0", "sets the geostatic stress, which needs water_table");
  if (b.k0) check_number(s, key + ".k0", *b.k0, scene_keys::kK0);
  if (!b.water_table) return;
  check_number(s, key + ".water_table", *b.water_table, scene_keys::kWaterTable);
  check(s, gravity_axis(s, s.simulation.dimension) >= 0, key + ".water_table",
        "is a height against the body force, but the scene has no [body_force] along one axis");
  const auto m = std::find_if(s.materials.begin(), s.materials.end(),
                              [&](const MaterialSection& ms) { return ms.name == b.material; });
  if (m == s.materials.end()) return;
  check(s, pore_fluid(*m).has_value(), key + ".water_table", "needs a saturated material; \"", m->name,
        "\" has no pore fluid");
  const MaterialModel* model = find_material_model(m->model);
  std::string takers;
  for (const MaterialModel* t : material_models())
    if (t->takes_initial_stress) takers += std::string(takers.empty() ? "" : ", ") + std::string(t->name);
  check(s, !model || model->takes_initial_stress, key + ".water_table", "sets the initial effective stress, which "
        "model \"", m->model, "\" does not take (its stress follows its elastic strain); use one of ", takers);
}

/// The rigid plates: named, boxes, an axis of the run, a finite force and its
/// time function, in a scene with saturated bodies.
void check_plates(const Scene& s, int dim) {
  std::set<std::string> names;
  for (std::size_t i = 0; i < s.plates.size(); ++i) {
    const PlateSection& p = s.plates[i];
    const std::string key = element_key("plate", p.name, i);
    check_name(s, key, p.name, "plate", false, default_name("plate", i), names);
    check_box(s, key, p.lower, p.upper, dim, false);
    enforce(s, scene_rules::axis_index(p.axis, dim), key + ".axis");
    check_number(s, key + ".force", p.force, scene_keys::kPlateForce);
    check_time(s, key + ".time", p.time);
    check(s, saturated(s), key, "a rigid plate is available with saturated bodies only (a material with "
          "porosity, permeability, fluid_density, fluid_bulk_modulus and fluid_viscosity)");
  }
}

/// Saturated bodies run with an integrator that steps them, on the fixed
/// grid, with the lumped mass, without walls or body contact.
void check_saturated(const Scene& s) {
  if (!saturated(s)) return;
  const std::string why = "saturated bodies (materials with a pore fluid) ";
  check(s, find_integrator(s.simulation.integrator)->two_phase, "simulation.integrator", why,
        "are stepped by ", two_phase_integrators(), " (got \"", s.simulation.integrator, "\"",
        s.where.count("simulation.integrator") ? "" : ", the default", ")");
  check(s, !s.simulation.nodes_move(), "simulation.mode", why, "need simulation.mode = \"mpm\"");
  check(s, s.simulation.mass == "lumped", "simulation.mass", why, "need the lumped mass");
  check(s, s.walls.empty(), element_key("wall", s.walls.empty() ? "" : s.walls[0].name, 0), why,
        "cannot meet rigid walls (use a [[boundary]])");
  if (s.contact) input_error(s.contact->where, why + "cannot have body contact");
}

void check_loads(const Scene& s, int dim) {
  std::set<std::string> boundary_names, wall_names;
  for (std::size_t i = 0; i < s.initial_velocities.size(); ++i) {
    const InitialVelocitySection& iv = s.initial_velocities[i];
    const std::string key = element_key("initial_velocity", "", i);
    check_box(s, key, iv.lower, iv.upper, dim, false);
    check_finite(s, key + ".velocity", iv.velocity, dim);
  }
  for (std::size_t i = 0; i < s.boundaries.size(); ++i) {
    const BoundarySection& b = s.boundaries[i];
    const std::string key = element_key("boundary", b.name, i);
    check_name(s, key, b.name, "boundary", false, default_name("boundary", i), boundary_names);
    check_box(s, key, b.lower, b.upper, dim, false);
    check_finite(s, key + ".value", b.value, dim);
    check_saturated_boundary(s, b, key);
  }
  for (std::size_t i = 0; i < s.walls.size(); ++i) {
    const WallSection& w = s.walls[i];
    const std::string key = element_key("wall", w.name, i);
    check_name(s, key, w.name, "wall", true, "", wall_names); // it names the wall's history in the result file
    check_finite(s, key + ".point", w.point, dim);
    check_finite(s, key + ".normal", w.normal, dim);
    check_finite(s, key + ".velocity", w.velocity, dim);
    enforce(s, scene_rules::wall_normal(w.normal, dim), key + ".normal");
    check_number(s, key + ".friction", w.friction, scene_keys::kFriction);
  }
  if (s.body_force) {
    check_finite(s, "body_force.value", s.body_force->value, dim);
    check_time(s, "body_force.time", s.body_force->time);
  }
  for (std::size_t i = 0; i < s.tractions.size(); ++i) {
    const TractionSection& t = s.tractions[i];
    const std::string key = element_key("traction", "", i);
    check_box(s, key, t.lower, t.upper, dim, false);
    check_finite(s, key + ".value", t.value, dim);
    check_time(s, key + ".time", t.time);
    if (!t.function.empty()) check_choice(s, key + ".function", scene_rules::kTractionFunctions, t.function);
    if (t.axis) enforce(s, scene_rules::axis_index(*t.axis, dim), key + ".axis");
  }
}

/// output.every: 0 (first and last frame only) or a finite interval that asks
/// for at most kMaxOutputTimes output times (a tiny interval never advances).
void check_output_every(const Scene& s) {
  constexpr double kMaxOutputTimes = 1e9;
  const double every = s.output.every;
  check(s, every == 0.0 || (finite_positive(every) && s.simulation.t_end / every <= kMaxOutputTimes), "output.every",
        "must be 0 or finite and > 0 with at most ", kMaxOutputTimes, " output times up to t_end (got ", every, ")");
  const std::vector<std::string_view> known = output_field_names(s);
  for (std::size_t i = 0; i < s.output.fields.size(); ++i)
    enforce(s, scene_rules::field(s.output.fields, i, known, s.simulation.dimension), "output.fields");
}

/// Each probe: a unique name the result file can hold (invalid_name_reason),
/// a known particle choice, a finite point for "nearest".
void check_probes(const Scene& s, int dim) {
  std::set<std::string> names;
  for (std::size_t i = 0; i < s.output.probes.size(); ++i) {
    const ProbeSection& p = s.output.probes[i];
    const std::string key = element_key("output.probes", p.name, i);
    check_name(s, key, p.name, "probe", true, "", names);
    check_choice(s, key + ".particle", scene_rules::kProbeParticles, p.particle);
    if (p.particle == "nearest") check_finite(s, key + ".at", p.at, dim);
  }
}

/// output.file, fields, format and the checkpoint keys, as parse_scene reads them.
void check_output(const Scene& s, int dim) {
  const OutputSection& o = s.output;
  enforce(s, scene_rules::file_name(o.file), "output.file");
  check_output_every(s);
  check_probes(s, dim);
  enforce(s, scene_rules::checkpoint_every(o.checkpoint_every), "output.checkpoint_every");
  enforce(s, scene_rules::checkpoint_file(o.checkpoint_file, o.file), "output.checkpoint_file");
  enforce(s, scene_rules::formats(o.formats), "output.format");
  check_choice(s, "output.precision", scene_rules::kPrecisions, o.precision);
  enforce(s, scene_rules::compression(o.compression), "output.compression");
  // Frames a viewer can show: the XDMF sidecar and the VTK files place the particles at x.
  const bool x = std::count(o.fields.begin(), o.fields.end(), "x") > 0;
  check(s, x || o.fields.empty(), "output.fields",
        "must include \"x\": the XDMF sidecar and the VTK files place the particles at x, without which a viewer "
        "shows none of the other fields ([] writes frames without fields, for the histories only)");
  check(s, x || vtk_format(o).empty(), "output.format",
        "\"vtp\" and \"vtu\" need \"x\" in output.fields (a VTK file places the particles at x)");
  for (const auto& [key, path] :
       {std::pair{"output.file", &o.file}, std::pair{"output.checkpoint_file", &o.checkpoint_file}}) {
    const std::string c = text::control_character(*path);
    check(s, c.empty(), key, "must not contain ", c, " (a file name otmpm writes, also into XML files)");
  }
}

/// The caps of parse_scene (kMaxSceneParticles, kMaxSceneNodes,
/// kMaxCellsPerAxis) and, for a scene split over `processes` processes
/// (0: a share that checks its own size), the per-process caps
/// (kMaxRankParticles, kMaxRankNodes) on an even share.
void check_size(const Scene& s, int processes) {
  const SceneSize n = scene_size(s);
  check(s, n.axis_cells <= kMaxCellsPerAxis, "grid.cells", "the node lattice or a body would have ", n.axis_cells,
        " cells along one axis; at most ", kMaxCellsPerAxis, " are allowed");
  check(s, n.nodes <= kMaxSceneNodes, "grid.cells", "the node set would have ", n.nodes, " nodes; at most ",
        kMaxSceneNodes, " are allowed");
  check(s, n.particles <= kMaxSceneParticles, "body", "the bodies would have ", n.particles,
        " particles; at most ", kMaxSceneParticles, " are allowed");
  if (processes <= 0) return;
  const std::string ranks = processes == 1 ? " in one process" : " per rank of " + std::to_string(processes);
  auto needed = [](double count, double cap) { return static_cast<long long>(std::ceil(count / cap)); };
  check(s, n.nodes <= kMaxRankNodes * processes, "grid.cells", "the node set would have ", n.nodes,
        " nodes; at most ", kMaxRankNodes, ranks, " are allowed (run on at least ", needed(n.nodes, kMaxRankNodes),
        " ranks: mpirun -np N otmpm run)");
  check(s, n.particles <= kMaxRankParticles * processes, "body", "the bodies would have ", n.particles,
        " particles; at most ", kMaxRankParticles, ranks, " are allowed (run on at least ",
        needed(n.particles, kMaxRankParticles), " ranks: mpirun -np N otmpm run)");
}

} // namespace

void validate_bodies(const Scene& s, int dim) {
  check(s, !s.bodies.empty(), "body", scene_rules::kNoBody);
  check_mesh_nodes(s);
  std::set<std::string> names;
  for (std::size_t i = 0; i < s.bodies.size(); ++i) {
    const BodySection& b = s.bodies[i];
    const std::string key = element_key("body", b.name, i);
    check_name(s, key, b.name, "body", false, default_name("body", i), names);
    enforce(s, scene_rules::material(s.materials, b.material), key + ".material");
    check_shape(s, b, key, dim);
    enforce(s, scene_rules::particles_per_cell(b.particles_per_cell), key + ".particles_per_cell");
    check_choice(s, key + ".overlap", scene_rules::kOverlaps, b.overlap);
    check_choice(s, key + ".volume", scene_rules::kVolumes, b.volume);
    check_choice(s, key + ".placement", scene_rules::kPlacements, b.placement);
    check_finite(s, key + ".velocity", b.velocity, dim);
    if (b.velocity_profile)
      check_choice(s, key + ".velocity_profile", scene_rules::kVelocityProfiles, *b.velocity_profile);
    check(s, b.velocity_profile.value_or("") != "reference" || !s.reference.solution.empty(), key + ".velocity_profile",
          "\"reference\" takes the initial velocity of the reference solution, but the scene has no reference.solution");
    if (!s.simulation.nodes_move()) check_body_in_grid(s, b, key, dim);
    check_water_table(s, b, key);
  }
}

std::string default_name(std::string_view kind, std::size_t index) {
  return std::string(kind) + std::to_string(index);
}

std::string name_error(const std::string& name, std::string_view what) {
  const std::string why = invalid_name_reason(name);
  if (why.empty()) return why;
  return "\"" + shortened(toml_input::TableReader::printable(name)) + "\" cannot name a " +
         std::string(what) + ": " + why;
}

void validate_scene(const Scene& s, int dimension, int processes) {
  require<std::invalid_argument>(dimension >= 1 && dimension <= 3, "validate_scene: dimension must be 1, 2 or 3, got ",
                                 dimension);
  check_simulation(s, dimension);
  check_grid(s, dimension);
  check_basis(s);
  check_materials(s);
  validate_bodies(s, dimension);
  check_size(s, processes);
  check_loads(s, dimension);
  check_contact(s);
  check_channel(s);
  check_plates(s, dimension);
  check_saturated(s);
  check_output(s, dimension);
}

std::vector<std::string_view> output_field_names(const Scene& s) {
  std::vector<std::string_view> names;
  for (const OutputField& f : output_fields()) names.push_back(f.name);
  names.push_back(kStressZzField); // 2D only (read_fields, check_output_every say so)
  for (const MaterialSection& m : s.materials)
    if (const MaterialModel* model = find_material_model(m.model))
      for (const StateSpec& st : model->state)
        if (std::find(names.begin(), names.end(), st.name) == names.end()) names.push_back(st.name);
  if (saturated(s)) names.insert(names.end(), {kPorePressureField, kLiquidVelocityField});
  return names;
}

ParticleFileRules particle_file_rules(const Scene& s, const BodySection& body, int processes) {
  ParticleFileRules rules;
  rules.max_rows = static_cast<long long>(processes > 0 ? kMaxRankParticles * processes : kMaxSceneParticles);
  const int dim = std::clamp(s.simulation.dimension, 1, 3);
  const char* axes[] = {"x", "y", "z"};
  for (const char* prefix : {"", "v"})
    for (int k = 0; k < dim; ++k) rules.known += prefix + std::string(axes[k]) + ", ";
  rules.known += "volume, density";
  rules.columns.emplace(kDensity.key, kDensity);
  const auto material = std::find_if(s.materials.begin(), s.materials.end(),
                                     [&](const MaterialSection& m) { return m.name == body.material; });
  const MaterialModel* model = material == s.materials.end() ? nullptr : find_material_model(material->model);
  std::string states;
  for (const StateSpec& st : model ? model->state : std::span<const StateSpec>{})
    if (st.width == 1) {
      rules.columns.emplace(st.name, st.range());
      states += std::string(states.empty() ? "" : ", ") + std::string(st.name);
    }
  rules.known += states.empty() ? "; the model of material '" + body.material + "' has no state variable"
                                : ", or a state variable of model '" + material->model + "': " + states;
  return rules;
}

template <int D> void validate_seeding(const Scene& s, const Vec<D>& h, bool whole) {
  for (int k = 0; k < D; ++k)
    require(finite_positive(h[k]), "seed_particles: grid spacing h[", k, "] = ", h[k], " must be finite and > 0");
  validate_bodies(s, D);
  if (!whole) return;
  double total = 0.0;
  for (std::size_t i = 0; i < s.bodies.size(); ++i) {
    const BodySection& b = s.bodies[i];
    double count = 1.0;
    for (int k = 0; k < D; ++k)
      count *= std::max(1.0, std::round((b.upper[k] - b.lower[k]) / h[k])) * b.particles_per_cell;
    total += count;
    check(s, total <= std::numeric_limits<int>::max(), element_key("body", b.name, i), "body '", b.name,
          "' brings the particle count to ", total, " at h = ", h, ", more than an int can count");
  }
}

template void validate_seeding<1>(const Scene&, const Vec<1>&, bool);
template void validate_seeding<2>(const Scene&, const Vec<2>&, bool);
template void validate_seeding<3>(const Scene&, const Vec<3>&, bool);

} // namespace otmpm
