// A channel's side walls on whole scenes ([channel], docs/theory.md sect.
// 6.3): with every integrator the energy an elastic block sliding between
// the walls loses is booked as friction (eq. 6.8) and the balance closes;
// on the granular column collapse the walls shorten the run-out alike with
// musl and npc.
#include "channel_support.hpp"
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/scene/scene.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

using namespace otmpm;
using namespace otmpm::test;

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
