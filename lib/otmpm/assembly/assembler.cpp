/// \file assembler.cpp
/// Scene -> engine parts (assembler.hpp). Each part has one short function.
#include "otmpm/assembly/assembler.hpp"

#include "otmpm/assembly/exact_solutions.hpp"
#include "otmpm/assembly/seeding.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/materials/pore_fluid.hpp"
#include "otmpm/reference/exact.hpp"
#include "otmpm/reference/solutions.hpp"
#include "otmpm/scene/file_bodies.hpp"
#include "otmpm/scene/validate.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>

namespace otmpm {

namespace {

template <int D> bool inside_box(const Vec<D>& x, const Vec3& lo, const Vec3& hi, double tol = 0.0) {
  for (int k = 0; k < D; ++k)
    if (x[k] < lo[k] - tol || x[k] > hi[k] + tol) return false;
  return true;
}

/// True when output.fields names `field`.
bool output_wants(const Scene& scene, const char* field) {
  const auto& f = scene.output.fields;
  return std::find(f.begin(), f.end(), field) != f.end();
}

/// The optional particle fields the materials, the mode and the output read
/// (a scene pays memory only for what it uses; the engine adds those the
/// integrator keeps, StepNeeds).
template <int D> void allocate_fields(const Scene& scene, const EngineParts<D>& parts, Particles<D>& P) {
  bool finite = false;
  for (const auto& m : parts.materials) finite = finite || m->needs_deformation_gradient();
  P.allocate_optional(output_wants(scene, "a"), finite || parts.mode.nodes_move() || output_wants(scene, "F"));
  AlignedVector<Vec<D>>().swap(P.length0); // the traction areas are taken (memory)
  for (const auto& m : parts.materials)
    for (const StateSpec& s : m->state()) P.add_state(std::string(s.name), s.width, s.initial.data());
}

/// The nodes of the scene: the node lattice, or with nodes = "mesh" the
/// mesh bodies' vertices (a cloud) and their elements (`elements`).
template <int D>
NodeSet<D> scene_nodes(const Scene& scene, const CartesianGrid<D>& grid, std::vector<ElementNodes>& elements) {
  if constexpr (D > 1)
    if (mesh_nodes(scene)) {
      MeshNodes<D> mesh = mesh_body_nodes<D>(scene.bodies);
      elements = std::move(mesh.elements);
      return NodeSet<D>::cloud(std::move(mesh.x), mesh.spacing);
    }
  return scene.grid.kind == "perturbed" ? NodeSet<D>::perturbed(grid, scene.grid.perturbation, scene.grid.seed)
                                        : NodeSet<D>::cartesian(grid);
}

/// The basis of the scene on its nodes (scene_nodes): on a mesh's vertices
/// the family on the mesh's elements when it takes them, else on the cloud.
template <int D> std::unique_ptr<Basis<D>> build_basis(const Scene& scene, const CartesianGrid<D>& grid) {
  std::vector<ElementNodes> elements;
  NodeSet<D> nodes = scene_nodes<D>(scene, grid, elements);
  try {
    if constexpr (D > 1)
      if (!elements.empty() && basis_kind(scene.basis.kind).mesh_elements)
        return make_element_basis<D>(std::move(nodes), std::move(elements));
    return make_basis<D>(basis_options<D>(scene), std::move(nodes));
  } catch (const InputError& e) {
    input_error(scene.basis_where, e.what());
  }
}

/// The nodes of `nodes` inside each boundary box (within kBoxTolerance h).
template <int D> Dirichlet<D> build_dirichlet(const Scene& scene, const NodeSet<D>& nodes, double h) {
  std::vector<long long> selected;
  Dirichlet<D> d = boundary_entries<D>(
      scene.boundaries, nodes.size(), [&nodes](int I) { return nodes.position(I); }, h, nullptr, &selected);
  require_boundary_nodes(scene, selected);
  return d;
}

/// For each particle, whether it is the first or the last of its column
/// along `axis` (the particles that carry the body's surface there).
template <int D> std::vector<char> surface_particles(const Particles<D>& P, int axis, double tol) {
  std::map<std::array<long long, 2>, std::pair<int, int>> ends; // column -> (first, last) particle
  for (int p = 0; p < P.size(); ++p) {
    auto [it, fresh] = ends.try_emplace(column_key<D>(P.X[p], axis, tol), p, p);
    if (fresh) continue;
    auto& [first, last] = it->second;
    if (P.X[p][axis] < P.X[first][axis]) first = p;
    if (P.X[p][axis] > P.X[last][axis]) last = p;
  }
  std::vector<char> surface(static_cast<std::size_t>(P.size()), 0);
  for (const auto& [column, e] : ends) surface[static_cast<std::size_t>(e.first)] = surface[static_cast<std::size_t>(e.second)] = 1;
  return surface;
}

/// The particles of traction load `i` (scene section ts) and their face
/// areas: its surface particles (surface_particles, or of a share of the
/// particles `seeded.surfaces`) in its box. InputError when it selects none.
template <int D>
void surface_loads(const TractionSection& ts, const Particles<D>& P, double h, const SeededBodies<D>& seeded,
                   std::size_t i, Traction<D>& load) {
  std::vector<char> surface;
  if (seeded.surfaces) {
    require<std::logic_error>(seeded.ids.size() == static_cast<std::size_t>(P.size()),
                              "build_tractions: a share of the particles without their global ids");
    surface.resize(static_cast<std::size_t>(P.size()));
    for (std::size_t p = 0; p < surface.size(); ++p) surface[p] = seeded.surfaces->surface(i, seeded.ids[p]);
  } else {
    surface = surface_particles<D>(P, load.axis, kBoxTolerance * h);
  }
  for (int p = 0; p < P.size(); ++p)
    if (surface[static_cast<std::size_t>(p)] && inside_box<D>(P.x[p], ts.lower, ts.upper)) {
      load.particle.push_back(p);
      load.area.push_back(P.V0[p] / P.length0[p][load.axis]);
    }
  if (seeded.surfaces ? !seeded.surfaces->selects(i) : load.particle.empty())
    input_error(ts.where, "traction box selects no surface particle (the first or last particle of a column "
                          "along axis " + std::to_string(load.axis) + ")");
}

/// Tractions on the body surface inside each traction box (TractionSection):
/// the surface particles in the box, each over its face area V0_p /
/// l_p[axis]. The built-in history of wobbes et al. eq. 103 comes from the
/// traction bar's solution (which the history keeps alive).
///
/// A share of the particles (`seeded.surfaces`: a rank of a distributed
/// run) takes its surface particles from there, found among all particles
/// while seeding; the box must select one of all particles. A restart's
/// share (`seeded.traction_area`) takes the loads as its checkpoint holds them.
template <int D>
std::vector<Traction<D>> build_tractions(const Scene& scene, const Particles<D>& P, double h,
                                         const std::shared_ptr<const ExactSolution<D>>& exact,
                                         const SeededBodies<D>& seeded) {
  std::vector<Traction<D>> out;
  for (std::size_t i = 0; i < scene.tractions.size(); ++i) {
    const TractionSection& ts = scene.tractions[i];
    Traction<D> load;
    load.value = scene_vec<D>(ts.value);
    load.time = ts.time;
    load.axis = traction_axis<D>(ts);
    if (i < seeded.traction_area.size()) { // a restart's loads, as the checkpoint holds them
      for (std::size_t p = 0; p < seeded.traction_area[i].size(); ++p)
        if (seeded.traction_area[i][p] >= 0.0) {
          load.particle.push_back(static_cast<int>(p));
          load.area.push_back(seeded.traction_area[i][p]);
        }
    } else {
      surface_loads<D>(ts, P, h, seeded, i, load);
    }
    if (ts.function == "wobbes_traction_bar") {
      const auto* bar = dynamic_cast<const TractionBar<D>*>(exact.get());
      if (!bar)
        input_error(ts.where, "traction function 'wobbes_traction_bar' needs reference.solution = \"traction_bar\"");
      load.history = [exact, bar](double t) { return bar->traction(t); };
    } else if (!ts.function.empty()) {
      input_error(ts.where, "unknown traction function '" + ts.function + "' (expected wobbes_traction_bar)");
    }
    out.push_back(std::move(load));
  }
  return out;
}

/// Body force of the scene and, for a manufactured solution, its body force
/// field b(X, t) (the engine holds the solution through the function).
template <int D>
std::optional<BodyForce<D>> build_body_force(const Scene& scene, std::shared_ptr<const ExactSolution<D>> exact) {
  const bool mms = exact && exact->has_body_force();
  if (!scene.body_force && !mms) return std::nullopt;
  BodyForce<D> b;
  if (scene.body_force) {
    b.value = scene_vec<D>(scene.body_force->value);
    b.time = scene.body_force->time;
  }
  if (mms) b.field = [exact](const Vec<D>& X, double t) { return exact->body_force(X, t); };
  return b;
}

} // namespace

std::vector<BoundarySection> boundaries_at(const Scene& scene, double t) {
  std::vector<BoundarySection> moved = scene.boundaries;
  for (BoundarySection& b : moved)
    for (std::size_t k = 0; k < 3; ++k)
      if (b.fix[k]) b.lower[k] += b.value[k] * t, b.upper[k] += b.value[k] * t;
  return moved;
}

namespace {

/// The node reset of a `ul` scene: on the scene grid's lines (translated
/// along an axis with the boundaries that fix it and move, validate_scene
/// checks that they move alike), the scene's basis and boundary boxes on the
/// new lattice, each box moved along its fixed axes with its nodes.
template <int D> NodeReset<D> node_reset(const Scene& scene) {
  NodeReset<D> r;
  r.below = node_reset_fraction(scene);
  for (int k = 0; k < D; ++k) {
    r.lines.lower[k] = scene.grid.lower[k];
    r.lines.upper[k] = scene.grid.upper[k];
    r.lines.cells[k] = scene.grid.cells[k];
    for (const BoundarySection& b : scene.boundaries)
      if (b.fix[static_cast<std::size_t>(k)]) {
        r.velocity[k] = b.value[static_cast<std::size_t>(k)];
        if (b.lower[static_cast<std::size_t>(k)] == b.upper[static_cast<std::size_t>(k)])
          r.planes.emplace_back(k, b.lower[static_cast<std::size_t>(k)]);
      }
  }
  r.lattice = [scene](const CartesianGrid<D>& grid, double t) {
    LatticePart<D> part;
    try {
      part.basis = make_basis<D>(basis_options<D>(scene), NodeSet<D>::cartesian(grid));
    } catch (const InputError& e) {
      input_error(scene.basis_where, e.what());
    }
    Scene moved = scene;
    moved.boundaries = boundaries_at(scene, t);
    part.dirichlet = build_dirichlet<D>(moved, part.basis->nodes(), grid.h().minCoeff());
    return part;
  };
  return r;
}

template <int D> StepSettings<D> build_settings(const Scene& scene, const IntegratorKind& integrator, double h) {
  const SimulationSection& sim = scene.simulation;
  StepSettings<D> s;
  s.step = integrator.step<D>();
  s.parameters = integrator.default_parameters();
  for (auto& [key, value] : s.parameters.values)
    if (const auto given = sim.parameters.find(key); given != sim.parameters.end()) value = given->second;
  s.t_end = sim.t_end;
  s.cfl = sim.cfl;
  s.dt = sim.dt;
  s.h = h;
  s.consistent_mass = uses_consistent_mass(scene);
  s.mass_tolerance = sim.mass_tolerance;
  s.energy_limit = sim.energy_limit;
  const std::string volumetric = volumetric_treatment(scene);
  s.volumetric = volumetric == "fbar"         ? Volumetric::fbar
                 : volumetric == "fbar_nodal" ? Volumetric::fbar_nodal
                                              : Volumetric::none;
  if (s.volumetric == Volumetric::fbar) s.patch_grid = node_grid<D>(scene);
  if (node_reset_fraction(scene) > 0) s.node_reset = node_reset<D>(scene);
  return s;
}

/// The liquid phase of a scene with saturated bodies (docs/theory.md sect.
/// 15), or nullopt: the pore fluid of each material; the liquid held with
/// the solid at the fixed components of the boundaries that are not drained
/// (no pore_pressure); the rigid plates (`window`: the nodes are a rank's
/// window, a plate may select none there). The particles of a saturated
/// material carry the mass of their grains, (1 - n_0) rho_s V0.
template <int D>
std::optional<TwoPhaseParts<D>> build_two_phase(const Scene& scene, const NodeSet<D>& nodes, double h,
                                                const ExactSolution<D>* exact, Particles<D>& P, bool window) {
  TwoPhaseParts<D> parts;
  for (const MaterialSection& ms : scene.materials) parts.fluid.push_back(pore_fluid(ms));
  if (std::none_of(parts.fluid.begin(), parts.fluid.end(), [](const auto& f) { return f.has_value(); }))
    return std::nullopt;
  if (exact && exact->has_body_force())
    input_error(scene.reference.where, "reference.solution = \"" + scene.reference.solution +
                                           "\" drives the bodies with a body force field, which saturated bodies "
                                           "do not take (their liquid takes the uniform body force only)");
  for (int p = 0; p < P.size(); ++p)
    if (const auto& f = parts.fluid[static_cast<std::size_t>(P.material[p])]) {
      P.m[p] *= 1.0 - f->porosity;
      P.rho[p] *= 1.0 - f->porosity;
    }
  const auto position = [&nodes](int I) { return nodes.position(I); };
  std::vector<BoundarySection> impermeable;
  const double rho_w = std::find_if(parts.fluid.begin(), parts.fluid.end(), [](const auto& f) { return f.has_value(); })
                           ->value()
                           .density; // the free water's: the saturated materials share it (validate_scene)
  for (const BoundarySection& b : scene.boundaries)
    if (b.pore_pressure || b.water_level)
      parts.drains.push_back({boundary_entries<D>({b}, nodes.size(), position, h).node, b.pore_pressure.value_or(0.0),
                              b.water_level, rho_w, b.water_rise.value_or(0.0), b.time});
    else
      impermeable.push_back(b);
  parts.held = boundary_entries<D>(impermeable, nodes.size(), position, h);
  for (const PlateSection& ps : scene.plates) { // a plate's box is a boundary's
    BoundarySection box;
    box.lower = ps.lower, box.upper = ps.upper;
    Plate plate{boundary_entries<D>({box}, nodes.size(), position, h).node, ps.axis, ps.force, ps.time};
    if (plate.node.empty() && !window) input_error(ps.where, "plate '" + ps.name + "' selects no node of the grid");
    parts.plates.push_back(std::move(plate));
  }
  return parts;
}

/// The hydrostatic pore pressure and the geostatic effective stress of the
/// particles of bodies with a water table (docs/theory.md eq. 15.12): in
/// each column of such particles along the body force's axis, from the top
/// down, the total vertical stress is the free water's pressure above the
/// column's top and the weight of the mixture above the particle; the
/// effective stress is that plus the pore pressure, times k0 across.
/// Returns each such particle with its initial effective stress (3x3, the
/// out-of-plane components k0 times the vertical one too), for
/// Material::start_from_stress.
template <int D>
std::vector<std::pair<int, Mat<3>>> set_water_table(const Scene& scene, const Vec<D>& spacing, Particles<D>& P) {
  const auto table = [&](int p) -> const BodySection& { return scene.bodies[static_cast<std::size_t>(P.body[p])]; };
  std::vector<std::pair<int, Mat<3>>> initial;
  if (std::none_of(scene.bodies.begin(), scene.bodies.end(),
                   [](const BodySection& b) { return b.water_table.has_value(); }))
    return initial;
  const Vec<D> b = scene_vec<D>(scene.body_force->value); // along one axis (validate_scene)
  int axis = 0;
  for (int k = 0; k < D; ++k)
    if (b[k] != 0.0) axis = k;
  const double g = std::abs(b[axis]), up = b[axis] < 0.0 ? 1.0 : -1.0; // height z = up x[axis]
  const double zero = 0.0;
  double* pore = P.add_state(std::string(kPorePressureField), 1, &zero).values.data();
  double* out_of_plane = D == 2 ? P.add_state(std::string(kInitialOutOfPlaneStressField), 1, &zero).values.data()
                                : nullptr; // plane strain: sigma_zz = k0 times the vertical stress too
  std::map<std::array<long long, 2>, std::vector<int>> columns;
  for (int p = 0; p < P.size(); ++p)
    if (table(p).water_table) columns[column_key<D>(P.X[p], axis, kBoxTolerance * spacing.minCoeff())].push_back(p);
  for (auto& [key, column] : columns) {
    std::sort(column.begin(), column.end(), [&](int p, int q) { return up * P.X[p][axis] > up * P.X[q][axis]; });
    const auto length = [&](int p) {
      return P.length0.size() == P.x.size() ? P.length0[p][axis] : spacing[axis] / table(p).particles_per_cell;
    };
    const int top = column.front();
    const double rho_top = pore_fluid(scene.materials[static_cast<std::size_t>(P.material[top])])->density;
    // The top of the column: the upper end of its top particle's share of the seeding lattice (a box's
    // own cells, the grid's for the other shapes seeded on it), or half its extent above it.
    const BodySection& body = table(top);
    const double z = up * P.X[top][axis];
    const double origin = up * (body.shape == "box" ? body.lower[axis] : scene.grid.lower[axis]);
    const bool lattice = body.shape != "file" && body.shape != "mesh";
    double z_up = lattice ? origin + std::ceil((z - origin) / length(top)) * length(top) : z + 0.5 * length(top);
    double sv = -rho_top * g * std::max(0.0, *body.water_table - z_up); // the total vertical stress at z_up
    for (int p : column) {
      const MaterialSection& ms = scene.materials[static_cast<std::size_t>(P.material[p])];
      const PoreFluid f = *pore_fluid(ms);
      const double rho = (1.0 - f.porosity) * ms.density + f.porosity * f.density, zp = up * P.X[p][axis];
      pore[p] = f.density * g * std::max(0.0, *table(p).water_table - zp);
      const double vertical = sv - rho * g * (z_up - zp) + pore[p];
      const double k0 = table(p).k0.value_or(ms.poisson / (1.0 - ms.poisson));
      Mat<3> sigma0 = k0 * vertical * Mat<3>::Identity();
      sigma0(axis, axis) = vertical;
      P.sigma[p] = sigma0.template topLeftCorner<D, D>();
      if (out_of_plane) out_of_plane[p] = sigma0(2, 2);
      initial.emplace_back(p, sigma0);
      sv -= rho * g * length(p), z_up -= length(p);
    }
  }
  return initial;
}

/// The initial values of material state variables given by particle files.
template <int D> void set_file_state(const Scene& scene, const SeededBodies<D>& seeded, Particles<D>& P) {
  for (const FileState& f : seeded.file_state) {
    const BodySection& body = scene.bodies[static_cast<std::size_t>(f.body)];
    StateField* field = P.find_state(f.name);
    if (!field || field->width != 1)
      input_error(scene.locate("body." + body.name + ".file"),
                  body.file + ": column '" + f.name + "' is neither x, y, z, volume, vx, vy, vz, density nor a "
                  "scalar state variable of the scene's materials (e.g. plastic_strain)");
    for (int p = 0; p < P.size(); ++p)
      if (P.body[p] == f.body) field->values[static_cast<std::size_t>(p)] = f.values[static_cast<std::size_t>(seeded.file_row[static_cast<std::size_t>(p)])];
  }
}

} // namespace

template <int D>
Dirichlet<D> boundary_entries(const std::vector<BoundarySection>& boundaries, int count,
                              const std::function<Vec<D>(int)>& position, double h,
                              const std::vector<char>* counted, std::vector<long long>* selected) {
  Dirichlet<D> d;
  const double tol = kBoxTolerance * h;
  if (selected) selected->assign(boundaries.size(), 0);
  for (std::size_t b = 0; b < boundaries.size(); ++b) {
    const BoundarySection& bs = boundaries[b];
    for (int I = 0; I < count; ++I) {
      if (!inside_box<D>(position(I), bs.lower, bs.upper, tol)) continue;
      d.node.push_back(I);
      d.fix.push_back(bs.fix);
      d.value.push_back(bs.value);
      if (selected && (!counted || (*counted)[static_cast<std::size_t>(I)])) ++(*selected)[b];
    }
  }
  return d;
}

void require_boundary_nodes(const Scene& scene, const std::vector<long long>& selected) {
  const bool ul = scene.simulation.nodes_move();
  for (std::size_t b = 0; b < scene.boundaries.size() && b < selected.size(); ++b)
    if (selected[b] == 0) {
      const BoundarySection& bs = scene.boundaries[b];
      input_error(bs.where, "boundary '" + bs.name + "' selects no node of the " +
                                std::string(ul ? "material" : "grid") + " node set");
    }
}

template <int D> Vec<D> grid_spacing(const Scene& scene) {
  Vec<D> h;
  for (int k = 0; k < D; ++k) h[k] = (scene.grid.upper[k] - scene.grid.lower[k]) / scene.grid.cells[k];
  return h;
}

template <int D> CartesianGrid<D> node_grid(const Scene& scene) {
  const LatticeBox box = node_lattice_box(scene);
  CartesianGrid<D> grid;
  for (int k = 0; k < D; ++k) {
    grid.lower[k] = box.lower[k];
    grid.upper[k] = box.upper[k];
    grid.cells[k] = static_cast<int>(box.cells[k]);
  }
  grid.validate();
  return grid;
}

template <int D> BasisOptions basis_options(const Scene& scene) {
  BasisOptions opt = scene.basis;
  if (basis_kind(opt.kind).particle_size) {
    const Vec<D> h = grid_spacing<D>(scene);
    for (int k = 0; k < D; ++k) opt.particle_half_width[k] = h[k] / (2.0 * scene.bodies.front().particles_per_cell);
  }
  return opt;
}

template <int D> Particles<D> seed_particles(const Scene& scene, const Vec<D>& h) {
  return seed_bodies<D>(scene, h, node_grid<D>(scene)).particles;
}

template <int D>
EngineParts<D> assemble_parts(const Scene& scene,
                              const std::function<SeededBodies<D>(const Vec<D>&, const CartesianGrid<D>&)>& seed) {
  return assemble_parts<D>(scene, seed, nullptr);
}

template <int D>
EngineParts<D> assemble_parts(const Scene& scene,
                              const std::function<SeededBodies<D>(const Vec<D>&, const CartesianGrid<D>&)>& seed,
                              const std::function<LatticePart<D>(const CartesianGrid<D>&)>& lattice) {
  validate_scene(scene, D, seed ? 0 : 1); // a share (seed) checks its own size
  const IntegratorKind& integrator = integrator_kind(scene.simulation.integrator);
  const bool ul = scene.simulation.nodes_move();
  EngineParts<D> parts;
  const CartesianGrid<D> grid = node_grid<D>(scene);
  parts.mode = ul ? NodeMode<D>::advected() : NodeMode<D>::fixed_grid(grid.lower, grid.upper);
  for (const MaterialSection& ms : scene.materials) {
    try {
      parts.materials.push_back(make_material<D>(ms));
    } catch (const InputError& e) {
      input_error(ms.where, e.what());
    }
  }
  SeededBodies<D> seeded = seed ? seed(grid_spacing<D>(scene), grid) : seed_bodies<D>(scene, grid_spacing<D>(scene), grid);
  parts.particles = std::move(seeded.particles);
  Particles<D>& P = parts.particles;
  std::shared_ptr<const ExactSolution<D>> exact = make_exact_solution<D>(scene);
  if (exact && exact->has_body_force())
    for (const BodySection& b : scene.bodies)
      if (b.velocity_profile.value_or("") != "reference")
        input_error(b.where, "reference.solution = \"" + scene.reference.solution +
                                 "\" drives the bodies with its manufactured body force, which assumes its own "
                                 "initial velocity: set velocity_profile = \"reference\" on body '" + b.name + "'");
  // velocity_profile = "reference": the reference solution's own initial
  // velocity (a manufactured solution: wobbes et al. sect. 8.3, u = 0 but v != 0 at t = 0).
  for (int p = 0; p < P.size(); ++p)
    if (scene.bodies[static_cast<std::size_t>(P.body[p])].velocity_profile.value_or("") == "reference")
      P.v[p] = exact->velocity(P.X[p], 0.0);
  double h = grid.h().minCoeff();
  if (lattice) {
    LatticePart<D> part = lattice(grid);
    parts.basis = std::move(part.basis);
    parts.dirichlet = std::move(part.dirichlet);
  } else {
    parts.basis = build_basis<D>(scene, grid);
    // mesh nodes: h of the time step is the shortest distance between two vertices
    if (mesh_nodes(scene)) h = parts.basis->nodes().min_spacing();
    parts.dirichlet = build_dirichlet<D>(scene, parts.basis->nodes(), h);
  }
  for (const WallSection& w : scene.walls)
    parts.walls.push_back({w.name, scene_vec<D>(w.point), scene_vec<D>(w.normal), scene_vec<D>(w.velocity), w.friction});
  if (scene.contact) parts.contact = ContactLaw{scene.contact->friction};
  if (scene.channel) parts.side_walls = SideWalls{scene.channel->width, scene.channel->friction};
  parts.loads.body_force = build_body_force<D>(scene, exact);
  require<std::logic_error>(!seed || scene.tractions.empty() || seeded.surfaces ||
                                seeded.traction_area.size() == scene.tractions.size(),
                            "assemble_parts: a share of the particles needs its traction loads' surface particles");
  parts.loads.tractions = build_tractions<D>(scene, P, h, exact, seeded);
  const auto geostatic = set_water_table<D>(scene, grid_spacing<D>(scene), P);
  allocate_fields(scene, parts, P);
  for (const auto& [p, sigma0] : geostatic)
    parts.materials[static_cast<std::size_t>(P.material[p])]->start_from_stress(P, p, sigma0);
  set_file_state<D>(scene, seeded, P);
  // a rank's window of the lattice: the ranks check the plates' nodes together (local_parts.cpp)
  parts.two_phase = build_two_phase<D>(scene, parts.basis->nodes(), h, exact.get(), P, static_cast<bool>(lattice));
  parts.settings = build_settings<D>(scene, integrator, h);
  return parts;
}

template <int D> EngineParts<D> assemble_parts(const Scene& scene) { return assemble_parts<D>(scene, nullptr); }

template <int D> Engine<D> assemble(const Scene& scene) { return Engine<D>(assemble_parts<D>(scene)); }

#define OTMPM_INSTANTIATE(D)                                                       \
  template EngineParts<D> assemble_parts<D>(const Scene&);                        \
  template EngineParts<D> assemble_parts<D>(                                      \
      const Scene&, const std::function<SeededBodies<D>(const Vec<D>&, const CartesianGrid<D>&)>&); \
  template EngineParts<D> assemble_parts<D>(                                      \
      const Scene&, const std::function<SeededBodies<D>(const Vec<D>&, const CartesianGrid<D>&)>&, \
      const std::function<LatticePart<D>(const CartesianGrid<D>&)>&);             \
  template Dirichlet<D> boundary_entries<D>(const std::vector<BoundarySection>&, int,                   \
                                            const std::function<Vec<D>(int)>&, double, const std::vector<char>*, \
                                            std::vector<long long>*);                                          \
  template Engine<D> assemble<D>(const Scene&);                                   \
  template Particles<D> seed_particles<D>(const Scene&, const Vec<D>&);   \
  template CartesianGrid<D> node_grid<D>(const Scene&);                    \
  template Vec<D> grid_spacing<D>(const Scene&);                           \
  template BasisOptions basis_options<D>(const Scene&);
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm
