// A plane-strain body between a channel's side walls ([channel],
// engine/side_walls.hpp, docs/theory.md sect. 6.3): the force of eq. 6.7 on
// one particle; an elastic block sliding on a frictionless floor between
// the walls decelerates at mu_w nu g H / W (npc); walls without friction
// change nothing; the same bits with 1 and 2 threads; bad [channel] input is
// refused with its key. The whole-scene checks (every integrator, the
// granular column) are in test_scenes_channel.cpp.
#include "channel_support.hpp"
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/scene/scene.hpp"
#include "otmpm/scene/validate.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <string>
#include <vector>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

using namespace otmpm;
using namespace otmpm::test;

TEST_CASE(
    "channel: the side walls' force is 2 mu_w |sigma_zz| V / W against the motion, never reversing it") {
  const SideWalls walls{0.2, 0.4};
  const Vec<2> v(0.6, -0.8); // |v| = 1
  // 2 (0.4) (1e3 Pa) (1e-4 m^2) / 0.2 m = 0.4 N/m, along -v
  const Vec<2> f = walls.force<2>(1.0, 1e-4, v, -1e3, 1e-3);
  CHECK(f[0] == doctest::Approx(-0.4 * 0.6).epsilon(1e-14));
  CHECK(f[1] == doctest::Approx(0.4 * 0.8).epsilon(1e-14));
  // A wall in tension takes nothing; nor does a particle at rest.
  CHECK(walls.force<2>(1.0, 1e-4, v, 1e3, 1e-3) == Vec<2>::Zero());
  CHECK(walls.force<2>(1.0, 1e-4, Vec<2>::Zero(), -1e3, 1e-3) == Vec<2>::Zero());
  // Capped at m |v| / dt: within the step it stops the particle, not more.
  const Vec<2> capped = walls.force<2>(1e-4, 1e-4, v, -1e3, 1e-3);
  CHECK(capped.norm() == doctest::Approx(1e-4 * 1.0 / 1e-3).epsilon(1e-14));
  CHECK(capped.dot(v) < 0.0);
}

TEST_CASE("channel: a block sliding between side walls decelerates at mu_w nu g H / W (npc, linear)") {
  // Measured (1 - v) / t / (mu_w nu g H / W) = 1.014 at t = 0.2 s, h = 0.025
  // (4 cells through the block): the block's
  // settling under the suddenly applied gravity and its cells' crossings
  // make sigma_zz oscillate about the static value, and the walls take
  // only its compressive part (eq. 6.7's max), which raises the mean.
  const double expected = kMu * kNu * kG * kH / kWidth;
  Engine<2> e = assemble<2>(parse_scene(sliding_block(integrator_kind("npc"), 0.025), "channel.toml"));
  while (e.time() < 0.2 - 1e-12) e.step();
  const double v = mean_vx(e.particles());
  CHECK((1.0 - v) / e.time() == doctest::Approx(expected).epsilon(0.05));
}

TEST_CASE("channel: without friction the side walls change nothing") {
  const std::string with = sliding_block(integrator_kind("musl"), 0.025);
  std::string without = with;
  without.replace(without.find("friction = 0.5"), 14, "friction = 0.0");
  Engine<2> a = assemble<2>(parse_scene(with, "a.toml")), b = assemble<2>(parse_scene(without, "b.toml"));
  while (b.time() < 0.3 - 1e-12) a.step(), b.step();
  CHECK(mean_vx(b.particles()) == doctest::Approx(1.0).epsilon(1e-3));
  CHECK(b.energy().friction == 0.0);
  CHECK(mean_vx(a.particles()) < 0.6);
}

#ifdef OTMPM_HAVE_OPENMP
TEST_CASE("channel: the same bits with 1 and 2 threads") {
  // A longer block on a finer grid: 4 m x 0.1 m at h = 0.01, 16 000 particles.
  auto run = [](int threads) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    Engine<2> e = assemble<2>(parse_scene(sliding_block(integrator_kind("musl"), 0.01, 4.0), "channel.toml"));
    for (int s = 0; s < 5; ++s) e.step();
    omp_set_num_threads(saved);
    return std::pair{e.particles(), e.energy().friction};
  };
  const auto [one, f1] = run(1);
  const auto [two, f2] = run(2);
  REQUIRE(one.size() == two.size());
  CHECK(f1 > 0.0);
  CHECK(f1 == f2);
  int differ = 0;
  for (int p = 0; p < one.size(); ++p) differ += one.x[p] != two.x[p] || one.v[p] != two.v[p];
  CHECK(differ == 0);
}
#endif

TEST_CASE("bad [channel] input is refused with its key") {
  const std::string text = sliding_block(integrator_kind("musl"), 0.025);
  auto with = [&](const std::string& from, const std::string& to) {
    std::string s = text;
    return s.replace(s.find(from), from.size(), to);
  };
  CHECK_THROWS_WITH_AS(parse_scene(with("width = 0.1", "width = 0.0"), "c.toml"),
                       doctest::Contains("channel.width"), InputError);
  CHECK_THROWS_WITH_AS(parse_scene(with("friction = 0.5", "friction = -1.0"), "c.toml"),
                       doctest::Contains("channel.friction"), InputError);
  CHECK_THROWS_WITH_AS(parse_scene(with("friction = 0.5\n", ""), "c.toml"), doctest::Contains("friction"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse_scene(with("width = 0.1", "wide = 0.1"), "c.toml"), doctest::Contains("c.toml:"),
                       InputError);
  // Not a plane-strain run: the side walls have nothing to bound.
  const std::string bar =
      "[simulation]\ndimension = 1\nintegrator = \"musl\"\nt_end = 0.1\n[basis]\n"
      "kind = \"linear\"\n[grid]\nlower = [0.0]\nupper = [1.0]\nh = 0.1\n"
      "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1.0\nyoung = 1.0\n"
      "poisson = 0.0\n[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.2]\nupper = [0.8]\n"
      "[channel]\nwidth = 0.1\nfriction = 0.5\n";
  CHECK_THROWS_WITH_AS(parse_scene(bar, "c.toml"), doctest::Contains("dimension = 2"), InputError);
  // Saturated bodies: the liquid's share of the wall pressure is not modelled.
  CHECK_THROWS_WITH_AS(assemble<2>(load_scene(OTMPM_SOURCE_DIR "/examples/mandel.toml",
                                              {"channel.width=0.2", "channel.friction=0.4"})),
                       doctest::Contains("[channel]: side walls are not available with saturated bodies"),
                       InputError);
  // Planned for several ranks (run --check --ranks N, or mpirun): accepted,
  // the nodal mean is summed over the ranks (test_mpi.cpp runs it).
  const Scene scene = parse_scene(text, "c.toml");
  CHECK_NOTHROW(validate_scene(scene, 2, 1));
  CHECK_NOTHROW(validate_scene(scene, 2, 4));
}
