// A plane-strain body between a channel's side walls ([channel],
// engine/side_walls.hpp, docs/theory.md sect. 6.3): the force of eq. 6.7 on
// one particle; an elastic block sliding on a frictionless floor between
// the walls decelerates at mu_w nu g H / W with every integrator, and the
// energy it loses is booked as friction (eq. 6.8); the same bits with 1
// and 2 threads; bad [channel] input is refused with its key.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/scene/scene.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <string>
#include <vector>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

using namespace otmpm;

namespace {

constexpr double kG = 9.81, kNu = 0.3, kH = 0.1, kWidth = 0.1, kMu = 0.5;

/// An elastic block 0.5 m x H (rho 1000, E 2e7, nu 0.3) at 1 m/s on a
/// frictionless floor under gravity, between side walls W apart with
/// friction mu_w, run with integrator k (ul and B-splines where it needs
/// them) on a grid of spacing h. Laterally free, the block carries sigma_xx
/// = 0 and sigma_yy = -rho g (H - y), so plane strain's sigma_zz = nu
/// sigma_yy: the walls take 2 mu_w nu rho g H / 2 per unit area of the
/// block, a deceleration mu_w nu g H / W.
std::string sliding_block(const IntegratorKind& k, double h, double length = 0.5, std::string basis = "") {
  const std::string mode = k.needs_ul ? "ul" : "mpm";
  if (basis.empty()) basis = k.needs_bspline ? "bspline2" : "linear";
  return "[simulation]\ndimension = 2\nmode = \"" + mode + "\"\nintegrator = \"" + std::string(k.name) +
         "\"\nt_end = 0.3\ncfl = 0.2\n[basis]\nkind = \"" + basis + "\"\n[grid]\nlower = [-0.1, -0.1]\n" +
         "upper = [" + std::to_string(length + 0.6) + ", 0.3]\nh = " + std::to_string(h) + "\n" +
         "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1000.0\nyoung = 2.0e7\npoisson = "
         "0.3\n"
         "[[body]]\nname = \"block\"\nmaterial = \"m\"\nlower = [0.0, 0.0]\nupper = [" +
         std::to_string(length) +
         ", 0.1]\nvelocity = [1.0, 0.0]\n"
         "[[wall]]\nname = \"floor\"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\n"
         "[body_force]\nvalue = [0.0, -9.81]\n[channel]\nwidth = 0.1\nfriction = 0.5\n";
}

const IntegratorKind& kind(const std::string& name) {
  for (const IntegratorKind& k : integrator_kinds())
    if (k.name == name) return k;
  throw std::logic_error("no integrator " + name);
}

/// The block's mean horizontal velocity.
double mean_vx(const Particles<2>& P) {
  double q = 0.0, m = 0.0;
  for (int p = 0; p < P.size(); ++p) q += P.m[p] * P.v[p][0], m += P.m[p];
  return q / m;
}

} // namespace

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
  Engine<2> e = assemble<2>(parse_scene(sliding_block(kind("npc"), 0.025), "channel.toml"));
  while (e.time() < 0.2 - 1e-12) e.step();
  const double v = mean_vx(e.particles());
  CHECK((1.0 - v) / e.time() == doctest::Approx(expected).epsilon(0.05));
}

TEST_CASE("channel: the energy the side walls take is booked as friction, every integrator") {
  // Every integrator on a quadratic B-spline basis (the forward-Euler
  // family is unstable on this scene with the linear basis, walls or not):
  // the block's horizontal motion lost M (1 - v^2) / 2 (its vertical
  // settling keeps < 1e-3 of that); the balance closes as without walls.
  for (const IntegratorKind& k : integrator_kinds()) {
    const std::string name(k.name);
    INFO(name);
    Engine<2> e = assemble<2>(parse_scene(sliding_block(k, 0.025, 0.5, "bspline2"), "channel.toml"));
    CHECK(e.has_friction()); // the result file writes /energy/friction
    const double E0 = e.energy().initial;
    while (e.time() < 0.2 - 1e-12) e.step();
    const double v = mean_vx(e.particles()), M = 1000.0 * 0.5 * kH;
    MESSAGE(name << ": friction / lost kinetic energy " << e.energy().friction / (0.5 * M * (1.0 - v * v))
                 << ", balance error / E0 " << e.energy().balance_error() / E0);
    CHECK(v < 0.9);
    CHECK(e.energy().friction == doctest::Approx(0.5 * M * (1.0 - v * v)).epsilon(0.03));
    CHECK(std::abs(e.energy().balance_error()) <= 2e-3 * E0);
  }
}

TEST_CASE("channel: on a granular column the side walls shorten the run-out alike with musl and npc") {
  // examples/column_collapse_mu_i.toml, a = 1 at h = L0/10 between walls
  // W = 0.2 m apart with mu_w = 0.4. Measured (scripts/column_collapse.py,
  // t = 1.2 s): (L_f - L0)/L0 = 0.935 musl, 0.925 npc; 1.090 and 1.084
  // without the walls. Here the front max x_p at t = 0.8 s (the flow has
  // stopped at t_c = 0.475 s), measured 0.382 m musl, 0.380 npc, 0.413 and
  // 0.412 without: the walls shorten it by 4% or more, and the two
  // integrators agree within 2% with the walls as without.
  auto front = [](const std::string& integrator, bool walls) {
    std::vector<std::string> sets{"grid.h=0.02", "simulation.t_end=0.8", "output.every=0",
                                  "simulation.integrator=\"" + integrator + "\""};
    if (walls) sets.insert(sets.end(), {"channel.width=0.2", "channel.friction=0.4"});
    Engine<2> e = assemble<2>(load_scene(OTMPM_SOURCE_DIR "/examples/column_collapse_mu_i.toml", sets));
    while (e.time() < 0.8 - 1e-12) e.step();
    const auto& P = e.particles();
    double x = 0.0;
    for (int p = 0; p < P.size(); ++p) x = std::max(x, P.x[p][0]);
    return x;
  };
  const double musl = front("musl", true), npc = front("npc", true);
  const double musl0 = front("musl", false), npc0 = front("npc", false);
  MESSAGE("front with walls: musl " << musl << ", npc " << npc << "; without: " << musl0 << ", " << npc0);
  CHECK(musl < 0.96 * musl0);
  CHECK(npc < 0.96 * npc0);
  CHECK(musl == doctest::Approx(npc).epsilon(0.02));
  CHECK(musl0 == doctest::Approx(npc0).epsilon(0.02));
}

TEST_CASE("channel: without friction the side walls change nothing") {
  const std::string with = sliding_block(kind("musl"), 0.025);
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
    Engine<2> e = assemble<2>(parse_scene(sliding_block(kind("musl"), 0.01, 4.0), "channel.toml"));
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
  const std::string text = sliding_block(kind("musl"), 0.025);
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
}
