//                    otmpm example: a run stepped by hand, with a per-step hook
//
// Compile:  part of the otmpm build (target example_stepping_loop), or in your
//           own CMake project with find_package(otmpm) and otmpm::otmpm.
//
// Sample runs:  build/bin/example_stepping_loop examples/dyka.toml
//               build/bin/example_stepping_loop examples/plate_impact.toml /tmp/plate.h5
//
// Description:  Loads a scene file and runs it one step at a time through
//               otmpm::Simulation - the loop `otmpm run` makes - with code of
//               our own between the steps:
//
//               1. the scene, read from its TOML file (errors name file, line
//                  and key),
//               2. the simulation: the engine, the result file and the frame
//                  at t = 0,
//               3. the loop: one step, then a hook that follows the largest
//                  particle speed and the kinetic energy (any diagnostic can
//                  go here: the engine's particle and nodal arrays are
//                  public),
//               4. an extra frame in the result file whenever the kinetic
//                  energy has fallen by half since the last one (frames at
//                  our own times, beside the scene's output.every),
//               5. finish(): final errors, status and the summary.
//
//               The result file is an ordinary otmpm result: `otmpm render`,
//               ParaView (the .xdmf beside it) and otmpm.results read it.
#include "otmpm/core.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/run/simulation.hpp"
#include "otmpm/scene/scene.hpp"

#include <cstdio>
#include <exception>
#include <string>

using namespace otmpm;

namespace {

/// What the hook follows: the largest particle speed and the kinetic energy.
template <int D> void hook(const Engine<D>& engine, double& max_speed, double& kinetic) {
  const Particles<D>& P = engine.particles();
  max_speed = 0.0;
  for (int p = 0; p < P.size(); ++p) max_speed = std::max(max_speed, P.v[p].norm());
  kinetic = engine.energy().kinetic;
}

/// Steps `sim` to its end, calling the hook after every step (steps 3 and 4).
template <int D> void loop(Simulation& sim) {
  double max_speed = 0.0, kinetic = 0.0, kinetic_at_frame = -1.0;
  int extra_frames = 0;
  while (!sim.finished()) {
    sim.step();
    hook<D>(sim.engine<D>(), max_speed, kinetic);
    if (kinetic_at_frame < 0) kinetic_at_frame = kinetic;
    if (kinetic < 0.5 * kinetic_at_frame) {
      sim.write_frame();
      kinetic_at_frame = kinetic;
      ++extra_frames;
    }
    if (sim.steps() % 500 == 0)
      std::printf("step %6ld  t = %.4e s  max |v| = %.4g m/s  kinetic = %.4g J\n", sim.steps(), sim.time(),
                  max_speed, kinetic);
  }
  std::printf("%d extra frames written when the kinetic energy halved\n", extra_frames);
}

} // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s SCENE.toml [RESULT.h5]\n", argv[0]);
    return 2;
  }
  try {
    // 1. The scene.
    const Scene scene = load_scene(argv[1]);

    // 2. The simulation (result file per output.file, or the one given).
    RunOptions options;
    if (argc > 2) options.out_file = argv[2];
    options.force = true; // an example: replace the result of the previous run
    Simulation sim(scene, options);

    // 3-4. The loop with the hook, in the scene's dimension.
    try {
      switch (sim.dimension()) {
      case 1: loop<1>(sim); break;
      case 2: loop<2>(sim); break;
      default: loop<3>(sim); break;
      }
    } catch (const InstabilityError& e) {
      std::fprintf(stderr, "unstable: %s\n", e.what()); // the result file says so too
    }

    // 5. The summary.
    const RunSummary s = sim.finish();
    std::printf("%s\n", summary_line(s).c_str());
    return s.exit_code;
  } catch (const InputError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
}
