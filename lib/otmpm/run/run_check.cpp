// check_scene() and estimate_memory_bytes() (run.hpp): what `otmpm run
// --check` prints about a scene without running it.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/assembly/seeding.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/materials/models.hpp"
#include "otmpm/run/run.hpp"

#include <algorithm>
#include <cmath>

namespace otmpm {

namespace {

template <int D> SceneCheck check_dim(const Scene& scene) {
  const Engine<D> e = assemble<D>(scene);
  SceneCheck c;
  c.dimension = D;
  c.mode = scene.simulation.mode;
  c.integrator = scene.simulation.integrator;
  c.basis = scene.basis.kind;
  c.particles = e.particles().size();
  c.nodes = e.basis().nodes().size();
  c.dt = e.stable_dt();
  c.t_end = scene.simulation.t_end;
  c.estimated_steps = c.dt > 0 ? std::ceil(c.t_end / c.dt * (1.0 - 1e-9)) : 0.0;
  c.memory_bytes = estimate_memory_bytes(scene);
  c.out_file = scene.output.file;
  c.volumes = body_volumes<D>(scene, e);
  return c;
}

} // namespace

template <int D> std::vector<BodyVolume> body_volumes(const Scene& scene, const Engine<D>& e) {
  std::vector<double> seeded(scene.bodies.size(), 0.0);
  const Particles<D>& P = e.particles();
  for (int p = 0; p < P.size(); ++p) seeded[static_cast<std::size_t>(P.body[p])] += P.V0[p];
  if (Distribution<D>* d = e.distribution()) d->sum(seeded);
  std::vector<BodyVolume> out;
  for (std::size_t b = 0; b < scene.bodies.size(); ++b)
    out.push_back({scene.bodies[b].name, seeded[b], body_measure<D>(scene.bodies[b])});
  return out;
}

template std::vector<BodyVolume> body_volumes<1>(const Scene&, const Engine<1>&);
template std::vector<BodyVolume> body_volumes<2>(const Scene&, const Engine<2>&);
template std::vector<BodyVolume> body_volumes<3>(const Scene&, const Engine<3>&);

double estimate_memory_bytes(const Scene& scene) {
  const int D = scene.simulation.dimension;
  const SceneSize size = scene_size(scene);
  const IntegratorKind& integrator = integrator_kind(scene.simulation.integrator);
  const BasisKind& basis = basis_kind(scene.basis.kind);
  const bool maxent = basis.searches_nodes;
  constexpr double real = sizeof(double), index = sizeof(int);
  // Particles<D>: x, X, v (+ a for npc and explicit_alpha, x_prev for otm,
  // lambda for max-ent, length0 with tractions) vectors; m, V, V0, rho; eps,
  // sigma (+ F) tensors; material and body; a cell hint.
  const double vectors = 3 + integrator.needs_acceleration + integrator.needs_previous_position + maxent +
                         !scene.tractions.empty();
  const double tensors = 3;
  // The materials' internal variables (state columns; the widest model counts for all).
  double state = 0.0;
  for (const MaterialSection& m : scene.materials)
    if (const MaterialModel* model = find_material_model(m.model)) {
      double width = 0.0;
      for (const StateSpec& st : model->state) width += st.width;
      state = std::max(state, width);
    }
  // The max-ent multiplier's slope while the nodes stay fixed (MultiplierSlope: x0, e, G, G_prev),
  // its history while they move (MultiplierHistory: two multipliers and a count, with its padding).
  const std::size_t history_bytes = D == 1   ? sizeof(MultiplierHistory<1>)
                                    : D == 2 ? sizeof(MultiplierHistory<2>)
                                             : sizeof(MultiplierHistory<3>);
  const double history = static_cast<double>(history_bytes) / real;
  const double slope = !maxent ? 0.0 : scene.simulation.nodes_move() ? history : 2.0 * (D + D * D);
  const double per_particle_fields = real * (vectors * D + 4 + tensors * D * D + state + slope) + index * (2 + D);
  // Basis table row, its transpose (NodeColumns) and, for the families that
  // search nodes, the Verlet list (candidates within R + h/4).
  const double S = basis.stencil_nodes(scene.basis, D);
  const double per_entry = index + real * (1 + D) + 2 * index + (maxent ? index * std::pow(1.25, D) : 0.0);
  const double per_particle = per_particle_fields + S * per_entry;
  // NodalFields<D>: m, active and six vectors; node positions; the scatter
  // blocks' per-node sums (counted as one more set of nodal vectors).
  const double per_node = real * (1 + 8 * D) + 1 + real * D;
  double bytes = size.particles * per_particle + size.nodes * per_node;
  // Consistent mass (mass_matrix.cpp): the assembly's S^2 triplets per
  // particle (16 bytes each) and the uncompressed matrix setFromTriplets
  // builds from them (12 bytes each), then M, its constrained copies and
  // their LDL^T factors, about (2 S^(1/D) - 1)^D entries per node each.
  if (scene.simulation.mass == "consistent" || integrator.needs_consistent_mass) {
    const double neighbours = std::pow(2.0 * std::pow(S, 1.0 / D) - 1.0, D);
    bytes += size.particles * S * S * (16.0 + 12.0) + 4.0 * size.nodes * neighbours * (real + index);
  }
  return bytes;
}

SceneCheck check_scene(const Scene& scene) {
  switch (scene.simulation.dimension) {
  case 1: return check_dim<1>(scene);
  case 2: return check_dim<2>(scene);
  case 3: return check_dim<3>(scene);
  default:
    input_error(scene.locate("simulation.dimension"),
                "dimension must be 1, 2 or 3, got " + std::to_string(scene.simulation.dimension));
  }
}

} // namespace otmpm
