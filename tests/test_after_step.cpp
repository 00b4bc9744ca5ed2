// The after-step sums (kinetic, stored and dissipated energy, momentum, the
// CFL signal speed) and checks, which an integrator that marks its last
// particle pass takes there, block by block right after each block's update
// (ToParticles::last): they must have the bits of the sweep after the step
// (Engine::update_energy sums that way), for every integrator of the table
// (those that do not mark one included), in each node mode it runs in, with elastic
// and plastic materials side by side in one block and a PIC relaxation
// (which moves the particles after the pass, so that the sweep takes the
// sums); and a particle that fails the checks in that pass must be the one
// the full check names; and a NaN or an infinity in any value the checks
// read is caught and named, wherever the particle sits in their sub-blocks.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/scene/scene.hpp"

#include <doctest/doctest.h>

#include <limits>
#include <string>

using namespace otmpm;

namespace {

/// Three bodies of 9 particles per cell (3888 particles: four blocks of
/// sums, the second and the third holding two materials): an elastic one moving at 1 m/s
/// into a j2 one at rest, a Drucker-Prager one beside them, under gravity on a
/// floor wall with friction; linear elements, quadratic B-splines for an
/// integrator that needs them.
std::string three_blocks(const std::string& mode, const IntegratorKind& integrator,
                         const std::string& extra) {
  const std::string basis = integrator.needs_bspline ? "bspline2" : "linear";
  return "[simulation]\ndimension = 2\nmode = \"" + mode + "\"\nintegrator = \"" +
         std::string(integrator.name) + "\"\nt_end = 1.0\ncfl = 0.2\n" + extra + "[basis]\nkind = \"" +
         basis +
         "\"\n[grid]\nlower = [-0.25, -0.25]\nupper = [3.0, 1.5]\ncells = [52, 28]\n"
         "[[material]]\nname = \"rubber\"\nmodel = \"linear_elastic\"\ndensity = 1000.0\nyoung = 1.0e6\n"
         "poisson = 0.3\n"
         "[[material]]\nname = \"metal\"\nmodel = \"j2\"\ndensity = 1000.0\nyoung = 1.0e6\npoisson = 0.3\n"
         "yield_stress = 2.0e3\nhardening_modulus = 1.0e4\n"
         "[[material]]\nname = \"sand\"\nmodel = \"drucker_prager\"\ndensity = 1000.0\nyoung = 1.0e6\n"
         "poisson = 0.3\nfriction_angle = 30.0\n"
         "[[body]]\nname = \"a\"\nmaterial = \"rubber\"\nlower = [0.0, 0.0]\nupper = [0.75, 0.75]\n"
         "particles_per_cell = 3\nvelocity = [1.0, 0.0]\n"
         "[[body]]\nname = \"b\"\nmaterial = \"metal\"\nlower = [0.75, 0.0]\nupper = [1.5, 0.75]\n"
         "particles_per_cell = 3\n"
         "[[body]]\nname = \"c\"\nmaterial = \"sand\"\nlower = [1.75, 0.0]\nupper = [2.5, 0.75]\n"
         "particles_per_cell = 3\n"
         "[[wall]]\nname = \"floor\"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\nfriction = 0.3\n"
         "[body_force]\nvalue = [0.0, -9.81]\n";
}

/// What the after-step sums give, as the engine keeps them.
struct Sums {
  double kinetic, strain, dissipated, wave_speed;
  Vec<2> momentum;
};

Sums sums_of(const Engine<2>& e) {
  return {e.energy().kinetic, e.energy().strain, e.energy().dissipated, e.wave_speed(), e.momentum()};
}

} // namespace

TEST_CASE("the after-step sums taken in the last particle pass have the bits of the sweep after the step") {
  for (const char* mode : {"mpm", "ul"})
    for (const IntegratorKind& integrator : integrator_kinds())
      for (const char* extra : {"", "pic_relaxation_time = 1e-3\n"}) {
        if (integrator.needs_ul && std::string(mode) == "mpm") continue;
        if (*extra && !integrator.takes("pic_relaxation_time")) continue;
        const std::string run = std::string(mode) + " " + std::string(integrator.name) + " " + extra;
        INFO(run);
        Engine<2> e = assemble<2>(parse_scene(three_blocks(mode, integrator, extra), "three_blocks.toml"));
        REQUIRE(e.particles().size() == 3888);
        // unified 30 steps: its knots, advected with the bodies, are laid out
        // anew at step 39, and the new lattice's top row of cells holds only a
        // sliver of body b (lifted by the impact): its consistent mass is
        // singular there
        const int steps = integrator.needs_bspline ? 30 : 40;
        for (int s = 0; s < steps; ++s) {
          e.step();
          const Sums pass = sums_of(e);
          e.update_energy(); // the sweep
          const Sums sweep = sums_of(e);
          REQUIRE(pass.kinetic == sweep.kinetic);
          REQUIRE(pass.strain == sweep.strain);
          REQUIRE(pass.dissipated == sweep.dissipated);
          REQUIRE(pass.wave_speed == sweep.wave_speed);
          REQUIRE(pass.momentum == sweep.momentum);
        }
        // the sums are not trivially equal: the bodies move, deform and yield
        CHECK(e.energy().kinetic > 0.0);
        CHECK(e.energy().strain > 0.0);
        CHECK(e.energy().dissipated > 0.0);
      }
}

TEST_CASE("a particle about to leave the grid in the last particle pass is the one the full check names") {
  // 1536 particles (two blocks of sums) at 1 m/s towards the grid's right
  // end: the step that brings the front within a step of it fails, and its
  // message names the particle check_particles_inside() finds first.
  const std::string block =
      "[simulation]\ndimension = 2\nmode = \"mpm\"\nintegrator = \"INTEGRATOR\"\nt_end = 10.0\ncfl = 0.5\n"
      "[basis]\nkind = \"linear\"\n[grid]\nlower = [0.0, 0.0]\nupper = [4.0, 1.0]\ncells = [64, 16]\n"
      "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1.0\nyoung = 1.0\npoisson = 0.0\n"
      "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.5, 0.25]\nupper = [3.5, 0.75]\n"
      "particles_per_cell = 2\nvelocity = [1.0, 0.0]\n";
  for (const IntegratorKind& integrator : integrator_kinds()) {
    if (integrator.needs_ul) continue; // nodes that move with the body: no fixed grid to leave
    const std::string run(integrator.name);
    INFO(run);
    std::string text = block;
    text.replace(text.find("INTEGRATOR"), 10, run);
    Engine<2> e = assemble<2>(parse_scene(text, "escaping.toml"));
    REQUIRE(e.particles().size() == 1536);
    std::string message;
    try {
      for (int s = 0; s < 10000; ++s) e.step();
    } catch (const InstabilityError& err) {
      message = err.what();
    }
    REQUIRE(message.find("would leave the grid in the next step") != std::string::npos);
    std::string full;
    try {
      e.check_particles_inside();
    } catch (const InstabilityError& err) {
      full = err.what();
    }
    CHECK(message == full);
  }
}

namespace {

/// A block of 21 x 5 cells, 3 particles per cell and axis, linear elastic,
/// at rest: 945 particles in 2D (fifteen sub-blocks of the checks, the
/// last one short), 2835 in 3D (the block one cell deep).
template <int D> EngineParts<D> resting_block() {
  const std::string axes = D == 2 ? "" : ", 0.0";
  const std::string top = D == 2 ? "" : ", 0.1";
  const std::string text = "[simulation]\ndimension = " + std::to_string(D) +
                           "\nmode = \"mpm\"\nintegrator = \"npc\"\nt_end = 1.0\ncfl = 0.2\n"
                           "[basis]\nkind = \"linear\"\n[grid]\nlower = [-0.2, -0.2" +
                           axes + "]\nupper = [2.3, 0.7" + (D == 2 ? std::string() : ", 0.3") +
                           "]\ncells = [25, 9" + (D == 2 ? std::string() : ", 3") +
                           "]\n[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1.0\n"
                           "young = 1.0\npoisson = 0.0\n[[body]]\nname = \"b\"\nmaterial = \"m\"\n"
                           "lower = [0.0, 0.0" +
                           axes + "]\nupper = [2.1, 0.5" + top + "]\nparticles_per_cell = 3\n";
  return assemble_parts<D>(parse_scene(text, "block.toml"));
}

/// Puts `bad` into component k of one of particle p's position, velocity
/// or stress (`which` 0, 1, 2); the engine's first checks must name p.
template <int D> void expect_named(int which, int k, int p, double bad) {
  EngineParts<D> parts = resting_block<D>();
  Particles<D>& P = parts.particles;
  if (which == 0) P.x[p](k) = bad;
  if (which == 1) P.v[p](k) = bad;
  if (which == 2) P.sigma[p](k % D, k / D) = bad;
  std::string message;
  try {
    Engine<D> e(std::move(parts));
  } catch (const InstabilityError& err) {
    message = err.what();
  }
  const std::string named = "particle " + std::to_string(p) + " ";
  CHECK_MESSAGE(message.find(named) != std::string::npos, "'" << message << "' does not name " << named);
  CHECK(message.find("not finite") != std::string::npos);
}

template <int D> void every_value_is_checked() {
  const int n = resting_block<D>().particles.size();
  const double inf = std::numeric_limits<double>::infinity();
  const double bad[3] = {std::numeric_limits<double>::quiet_NaN(), inf, -inf};
  int case_no = 0;
  for (int which = 0; which < 3; ++which)
    for (int k = 0; k < (which == 2 ? D * D : D); ++k)
      for (const int p : {0, 1, 63, 64, 65, 511, 512, n - 2, n - 1}) {
        INFO(D << "D: array " << which << " component " << k << " particle " << p);
        expect_named<D>(which, k, p, bad[case_no++ % 3]);
      }
}

} // namespace

TEST_CASE("a NaN or an infinity in any value of any particle's position, velocity or stress fails the checks "
          "and names it") {
  // The after-step checks test the arrays as plain doubles, a sub-block of
  // particles at a time: every component and every place in a sub-block
  // (first, last, in the short one at the end) must count.
  REQUIRE(resting_block<2>().particles.size() == 945);
  REQUIRE(resting_block<3>().particles.size() == 2835);
  every_value_is_checked<2>();
  every_value_is_checked<3>();
}
