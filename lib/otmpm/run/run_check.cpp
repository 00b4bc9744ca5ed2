// check_scene() (run.hpp): what `otmpm run --check` prints about a scene
// without running it, after the checks a run makes, in the run's order.
#include "otmpm/assembly/seeding.hpp"
#include "otmpm/distributed/global_view.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/scene/file_bodies.hpp"
#include "otmpm/scene/resources.hpp"

#include <cmath>

namespace otmpm {

namespace {

/// The set-up of this rank's engine (the whole scene in one process), as
/// the run sets it up, and the step-count check on its first step.
template <int D> SceneCheck check_dim(const Scene& scene, SceneCheck c) {
  const Engine<D> e(distributed::rank_parts<D>(scene, distributed::Comm::world()));
  const distributed::GlobalView<D> view(e);
  c.dt = e.stable_dt();
  check_first_step(scene, c.dt, e.wave_speed());
  c.particles = view.particles();
  c.nodes = view.nodes();
  c.estimated_steps = std::ceil(c.t_end / c.dt * (1.0 - 1e-9));
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
    out.push_back({scene.bodies[b].name, scene.bodies[b].shape, seeded[b], body_measure<D>(scene.bodies[b])});
  return out;
}

template std::vector<BodyVolume> body_volumes<1>(const Scene&, const Engine<1>&);
template std::vector<BodyVolume> body_volumes<2>(const Scene&, const Engine<2>&);
template std::vector<BodyVolume> body_volumes<3>(const Scene&, const Engine<3>&);

SceneCheck check_scene(const Scene& scene) {
  const int D = scene.simulation.dimension;
  if (D < 1 || D > 3)
    input_error(scene.locate("simulation.dimension"), "dimension must be 1, 2 or 3, got " + std::to_string(D));
  // the run's checks, before anything is allocated (the ranks agree, as in the run)
  distributed::agree_on(distributed::Comm::world(), [&] { check_before_allocating(scene, D); });
  SceneCheck c;
  c.dimension = D;
  c.mode = scene.simulation.mode;
  c.integrator = scene.simulation.integrator;
  c.basis = scene.basis.kind;
  c.t_end = scene.simulation.t_end;
  c.memory_bytes = estimate_resources(scene).bytes;
  c.memory_limit = memory_limit(scene);
  c.out_file = scene.output.file;
  switch (D) {
  case 1: return check_dim<1>(scene, c);
  case 2: return check_dim<2>(scene, c);
  default: return check_dim<3>(scene, c);
  }
}

} // namespace otmpm
