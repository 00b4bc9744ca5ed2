// to_toml(const Scene&): the scene as TOML text that parse_scene() reads back
// to the same values, for a Scene built in code (run_scene() stores it in the
// result file and in checkpoints, so such a run can be restarted and its
// result file says what was run).
#include "otmpm/scene/scene.hpp"
#include "otmpm/basis/kinds.hpp"

#include <toml++/toml.h>

#include <cstdint>
#include <filesystem>
#include <sstream>

namespace otmpm {

namespace {

/// The first `dim` components of v as a TOML array.
template <class T, std::size_t N> toml::array first(const std::array<T, N>& v, int dim) {
  toml::array a;
  for (int k = 0; k < dim; ++k) a.push_back(v[static_cast<std::size_t>(k)]);
  return a;
}

toml::table time_function(const TimeFunction& f) {
  toml::table t{{"kind", f.kind}};
  if (f.kind != "constant") t.insert("period", f.period);
  return t;
}

toml::table simulation(const SimulationSection& s, const Scene& scene) {
  toml::table t{{"dimension", s.dimension}, {"mode", s.mode},          {"integrator", s.integrator},
                {"mass", s.mass},           {"t_end", s.t_end},        {"mass_tolerance", s.mass_tolerance},
                {"energy_limit", s.energy_limit}, {"max_steps", s.max_steps}, {"memory_limit", s.memory_limit}};
  t.insert("volumetric", volumetric_treatment(scene)); // the default resolved: the file says what ran
  if (s.nodes_move()) t.insert("node_reset", node_reset_fraction(scene)); // the default resolved
  for (const auto& [key, value] : s.parameters) t.insert(key, value); // the integrator's own (gamma, rho_inf)
  // The reader takes one of cfl and dt: a fixed dt makes cfl irrelevant.
  if (s.dt) t.insert("dt", *s.dt);
  else t.insert("cfl", s.cfl);
  if (const auto& q = s.initial_equilibrium)
    t.insert("initial_equilibrium",
             toml::table{{"time", q->time}, {"damping", q->damping}, {"tolerance", q->tolerance}});
  return t;
}

toml::table basis(const BasisOptions& b) {
  // particle_half_width is derived by the assembler from the grid and the first body.
  toml::table t{{"kind", b.kind}, {"metric", b.metric}};
  for (const ParameterSpec* p : basis_parameters()) {
    const double v = b.value(*p);
    if (p->integer) t.insert(p->key, static_cast<std::int64_t>(v));
    else t.insert(p->key, v);
  }
  return t;
}

toml::table grid(const GridSection& g, int dim) {
  return toml::table{{"kind", g.kind},
                     {"lower", first(g.lower, dim)},
                     {"upper", first(g.upper, dim)},
                     {"cells", first(g.cells, dim)},
                     {"perturbation", g.perturbation},
                     {"seed", static_cast<std::int64_t>(g.seed)}};
}

/// A material: the common keys, then the model's parameters; a key
/// "table.key" (johnson_cook.B) goes into the sub-table [material.table].
toml::table material(const MaterialSection& m) {
  toml::table t{{"name", m.name}, {"model", m.model}, {"density", m.density}, {"young", m.young}, {"poisson", m.poisson}};
  for (const auto& [key, value] : m.extra) {
    const auto dot = key.find('.');
    if (dot == std::string::npos) {
      t.insert(key, value);
      continue;
    }
    const std::string table = key.substr(0, dot);
    if (!t.contains(table)) t.insert(table, toml::table{});
    t[table].as_table()->insert(key.substr(dot + 1), value);
  }
  return t;
}

toml::array materials(const std::vector<MaterialSection>& ms) {
  toml::array a;
  for (const MaterialSection& m : ms) a.push_back(material(m));
  return a;
}

/// The keys of the body's shape (the reader derives lower/upper of the
/// other shapes from them).
void insert_shape(toml::table& t, const BodySection& b, int dim) {
  t.insert("shape", b.shape);
  if (b.shape == "box") {
    t.insert("lower", first(b.lower, dim));
    t.insert("upper", first(b.upper, dim));
  } else if (b.shape == "sphere" || b.shape == "cylinder") {
    t.insert("center", first(b.center, dim));
    t.insert("radius", b.radius);
    if (b.shape == "cylinder") {
      t.insert("axis", first(b.axis, dim));
      t.insert("length", b.length);
    }
  } else if (b.shape == "polygon") {
    toml::array vertices;
    for (const auto& v : b.vertices) vertices.push_back(toml::array{v[0], v[1]});
    t.insert("vertices", std::move(vertices));
  } else {
    t.insert("file", std::filesystem::absolute(b.file).string()); // readable from any directory
  }
  if (b.shape == "stl" || b.shape == "mesh") {
    t.insert("scale", first(b.scale, dim));
    if (dim == 3) t.insert("rotate", first(b.rotate, 3));
    else t.insert("rotate", b.rotate[2]);
    t.insert("translate", first(b.translate, dim));
  }
  if (b.shape == "mesh") {
    if (!b.physical.empty()) t.insert("physical", b.physical);
    t.insert("seeding", b.seeding);
    t.insert("nodes", b.nodes);
  }
}

toml::array bodies(const std::vector<BodySection>& bs, int dim) {
  toml::array a;
  for (const BodySection& b : bs) {
    toml::table t{{"material", b.material},
                  {"particles_per_cell", b.particles_per_cell},
                  {"placement", b.placement},
                  {"velocity", first(b.velocity, dim)},
                  {"overlap", b.overlap},
                  {"volume", b.volume}};
    if (!b.name.empty()) t.insert("name", b.name); // else the reader's name, "body<index>"
    insert_shape(t, b, dim);
    if (b.velocity_profile) t.insert("velocity_profile", *b.velocity_profile);
    if (b.water_table) t.insert("water_table", *b.water_table);
    if (b.k0) t.insert("k0", *b.k0);
    a.push_back(std::move(t));
  }
  return a;
}

toml::array initial_velocities(const std::vector<InitialVelocitySection>& ivs, int dim) {
  toml::array a;
  for (const InitialVelocitySection& iv : ivs)
    a.push_back(toml::table{
        {"lower", first(iv.lower, dim)}, {"upper", first(iv.upper, dim)}, {"velocity", first(iv.velocity, dim)}});
  return a;
}

toml::array boundaries(const std::vector<BoundarySection>& bs, int dim) {
  toml::array a;
  for (const BoundarySection& b : bs) {
    toml::table t{{"lower", first(b.lower, dim)},
                  {"upper", first(b.upper, dim)},
                  {"fix", first(b.fix, dim)},
                  {"value", first(b.value, dim)}};
    if (!b.name.empty()) t.insert("name", b.name); // else the reader's name, "boundary<index>"
    if (b.pore_pressure) t.insert("pore_pressure", *b.pore_pressure);
    if (b.water_level) t.insert("water_level", *b.water_level);
    if (b.water_rise) t.insert("water_rise", *b.water_rise), t.insert("time", time_function(b.time));
    a.push_back(std::move(t));
  }
  return a;
}

toml::array plates(const std::vector<PlateSection>& ps, int dim) {
  toml::array a;
  for (const PlateSection& p : ps) {
    toml::table t{{"lower", first(p.lower, dim)}, {"upper", first(p.upper, dim)}, {"axis", p.axis},
                  {"force", p.force},         {"time", time_function(p.time)}};
    if (!p.name.empty()) t.insert("name", p.name); // else the reader's name, "plate<index>"
    a.push_back(std::move(t));
  }
  return a;
}

toml::array tractions(const std::vector<TractionSection>& ts, int dim) {
  toml::array a;
  for (const TractionSection& tr : ts) {
    toml::table t{{"lower", first(tr.lower, dim)},
                  {"upper", first(tr.upper, dim)},
                  {"value", first(tr.value, dim)},
                  {"time", time_function(tr.time)}};
    if (!tr.function.empty()) t.insert("function", tr.function);
    if (tr.axis) t.insert("axis", *tr.axis);
    a.push_back(std::move(t));
  }
  return a;
}

toml::array walls(const std::vector<WallSection>& ws, int dim) {
  toml::array a;
  for (const WallSection& w : ws)
    a.push_back(toml::table{{"name", w.name},
                            {"point", first(w.point, dim)},
                            {"normal", first(w.normal, dim)},
                            {"velocity", first(w.velocity, dim)},
                            {"friction", w.friction}});
  return a;
}

toml::table output(const OutputSection& o, int dim) {
  toml::array fields;
  for (const std::string& f : o.fields) fields.push_back(f);
  toml::table t{{"file", o.file},
                {"every", o.every},
                {"fields", std::move(fields)},
                {"checkpoint_every", static_cast<std::int64_t>(o.checkpoint_every)}};
  if (!o.checkpoint_file.empty()) t.insert("checkpoint_file", o.checkpoint_file);
  toml::array formats;
  for (const std::string& f : o.formats) formats.push_back(f);
  t.insert("format", std::move(formats));
  // Only when not the default: the scene text of a default run stays as it was.
  if (o.precision != "double") t.insert("precision", o.precision);
  if (o.symmetric_tensors) t.insert("symmetric_tensors", true);
  if (o.compression != 0) t.insert("compression", static_cast<std::int64_t>(o.compression));
  if (!o.probes.empty()) {
    toml::array probes;
    for (const ProbeSection& p : o.probes) {
      toml::table pt{{"name", p.name}, {"particle", p.particle}};
      if (p.particle == "nearest") pt.insert("at", first(p.at, dim));
      probes.push_back(std::move(pt));
    }
    t.insert("probes", std::move(probes));
  }
  return t;
}

} // namespace

std::string to_toml(const Scene& scene) {
  const int dim = scene.simulation.dimension;
  toml::table root{{"simulation", simulation(scene.simulation, scene)},
                   {"basis", basis(scene.basis)},
                   {"grid", grid(scene.grid, dim)},
                   {"material", materials(scene.materials)},
                   {"body", bodies(scene.bodies, dim)},
                   {"output", output(scene.output, dim)}};
  if (!scene.initial_velocities.empty()) root.insert("initial_velocity", initial_velocities(scene.initial_velocities, dim));
  if (!scene.boundaries.empty()) root.insert("boundary", boundaries(scene.boundaries, dim));
  if (!scene.walls.empty()) root.insert("wall", walls(scene.walls, dim));
  if (!scene.plates.empty()) root.insert("plate", plates(scene.plates, dim));
  if (scene.contact) root.insert("contact", toml::table{{"friction", scene.contact->friction}});
  if (scene.channel)
    root.insert("channel",
                toml::table{{"width", scene.channel->width}, {"friction", scene.channel->friction}});
  if (scene.body_force)
    root.insert("body_force",
                toml::table{{"value", first(scene.body_force->value, dim)}, {"time", time_function(scene.body_force->time)}});
  if (!scene.tractions.empty()) root.insert("traction", tractions(scene.tractions, dim));
  if (!scene.reference.solution.empty()) root.insert("reference", toml::table{{"solution", scene.reference.solution}});
  std::ostringstream os;
  os << root << "\n";
  return os.str();
}

} // namespace otmpm
