// check_scene() (run.hpp): what `otmpm run --check` prints about a scene
// without running it, after the checks a run makes, in the run's order.
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
  for (std::size_t b = 0; b < scene.bodies.size(); ++b)
    if (const BodySection& body = scene.bodies[b]; geometry_file_body(body)) {
      const Particles<D>& P = e.particles();
      double seeded = 0.0;
      for (int p = 0; p < P.size(); ++p) seeded += P.body[p] == static_cast<int>(b) ? P.V0[p] : 0.0;
      double exact = 0.0;
      if constexpr (D == 3)
        exact = body.shape == "stl" ? stl_body_surface(body)->measure() : mesh_body_shape<3>(body)->measure();
      if constexpr (D == 2) exact = mesh_body_shape<2>(body)->measure();
      c.volumes.push_back({body.name, body.shape, seeded, exact});
    }
  return c;
}

} // namespace

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
