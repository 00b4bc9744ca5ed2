// Energy balance tests: E(t) - E(0) - W_ext(t) - W_R(t) on small 1D
// bars, E = kinetic + strain energy, W_ext the work of a body force, W_R the
// work of the Dirichlet reactions. Units: E = rho = 1, so c = 1; the bar is
// [0, 1] with h = 1/8 and two particles per cell. Each run takes well under a
// second.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/run/run.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <string>
#include <vector>

using namespace otmpm;

namespace {

/// A linear elastic bar [0, 1], E = rho = 1, h = 1/8, 2 particles per cell, on
/// a grid [-0.25, 1.25] (mpm) or on its own nodes (ul), plus `extra` TOML
/// (boundaries, loads, initial velocities).
std::string bar_scene(const std::string& mode, const std::string& integrator, const std::string& basis,
                      double cfl, double t_end, const std::string& extra) {
  return "[simulation]\ndimension = 1\nmode = \"" + mode + "\"\nintegrator = \"" + integrator +
         "\"\nt_end = " + std::to_string(t_end) + "\ncfl = " + std::to_string(cfl) + "\n" +
         "[basis]\nkind = \"" + basis + "\"\n[grid]\nlower = [-0.25]\nupper = [1.25]\ncells = [12]\n" +
         "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1.0\nyoung = 1.0\npoisson = "
         "0.0\n" +
         "[[body]]\nname = \"bar\"\nmaterial = \"m\"\nlower = [0.0]\nupper = [1.0]\nparticles_per_cell = "
         "2\n" +
         extra;
}

/// Both ends held fixed (the nodes at x = 0 and x = 1).
const std::string kFixedEnds = "[[boundary]]\nname = \"left\"\nlower = [0.0]\nupper = [0.0]\nfix = [true]\n"
                               "[[boundary]]\nname = \"right\"\nlower = [1.0]\nupper = [1.0]\nfix = [true]\n";
/// The first mode of the fixed-end bar, v = 0.01 c sin(pi x) (continues the [[body]] table).
const std::string kMode = "velocity = [0.01]\nvelocity_profile = \"sin_x\"\n";

/// Steps the engine to t_end; returns the largest |balance error| / E(0) + max|W| seen, and
/// leaves the engine at t_end.
double run_balance(Engine<1>& e) {
  double max_error = 0.0, max_work = 0.0;
  while (e.time() < e.settings().t_end * (1.0 - 1e-12)) {
    e.step();
    max_error = std::max(max_error, std::abs(e.energy().balance_error()));
    max_work = std::max(max_work, std::abs(e.energy().work()));
  }
  return max_error / (e.energy().initial + max_work);
}

struct Combination {
  const char* mode;
  const char* integrator;
  const char* basis;
};

} // namespace

TEST_CASE("energy balance: a bar with fixed ends and no load loses energy at O(dt) and never gains it") {
  // The first mode v = 0.01 c sin(pi x) for two periods (t_end = 4 L/c). No
  // load and fixed supports: W = 0 and the balance error is E(t) - E(0), the
  // scheme's energy error. Measured drift at cfl 0.1 / 0.05: mpm fe linear
  // 0.030 / 0.015, mpm npc linear 0.208 / 0.110, mpm npc lme 0.206 / 0.109,
  // ul npc linear 0.207 / 0.109, ul otm linear 0.020 / 0.010. It halves with dt
  // (a first-order time error, for NPC from v_p += dt a_p^{n+1} of molinos
  // Algorithm 1), so the balance closes as dt -> 0: asserted as a ratio below
  // 0.6 (first order gives 0.5). No energy may appear beyond the scheme's
  // oscillation: E(t_end) <= 1.01 E(0) (largest measured: otm, 1.0032).
  for (const Combination& c : {Combination{"mpm", "fe", "linear"}, Combination{"mpm", "npc", "linear"},
                               Combination{"mpm", "npc", "lme"}, Combination{"ul", "npc", "linear"},
                               Combination{"ul", "otm", "linear"}}) {
    double drift[2] = {0, 0};
    const double cfls[2] = {0.1, 0.05};
    for (int k = 0; k < 2; ++k) {
      Engine<1> e = assemble<1>(parse_scene(bar_scene(c.mode, c.integrator, c.basis, cfls[k], 4.0, kMode + kFixedEnds),
                              "bar.toml"));
      REQUIRE(e.energy().initial > 0.0);
      drift[k] = run_balance(e);
      CHECK(e.energy().reaction_work == 0.0); // fixed supports do no work, exactly
      CHECK(e.energy().external_work == 0.0);
      CHECK(e.energy().total() <= 1.01 * e.energy().initial);
    }
    MESSAGE(std::string(c.mode) << " " << std::string(c.integrator) << " " << std::string(c.basis)
                                << ": energy drift " << drift[0] << " at cfl 0.1, " << drift[1]
                                << " at cfl 0.05");
    CHECK(drift[0] < 0.25);
    CHECK(drift[1] < 0.6 * drift[0]);
  }
}

TEST_CASE("energy balance: the work of a constant body force equals the change of E") {
  SUBCASE("free bar, rigid acceleration: exact for the trapezoidal work") {
    // No boundary: every particle gets b dt per step and the bar accelerates
    // rigidly, E(t) = M (b t)^2 / 2; the trapezoidal rule integrates the
    // linear power M b^2 t exactly, so the balance holds to round-off.
    for (const char* integrator : {"fe", "npc"}) {
      Engine<1> e = assemble<1>(parse_scene(
          bar_scene("mpm", integrator, "linear", 0.1, 0.5, "[body_force]\nvalue = [-0.01]\n"), "fall.toml"));
      const double drift = run_balance(e);
      INFO(std::string(integrator) << ": W_ext = " << e.energy().external_work
                                   << ", E = " << e.energy().total());
      CHECK(e.energy().external_work == doctest::Approx(0.5 * 1.0 * 0.005 * 0.005).epsilon(1e-9));
      CHECK(drift < 1e-9);
    }
  }
  SUBCASE("bar hanging from a fixed end: elastic waves, W_ext = E to the scheme's error") {
    // The bar is held at x = 1 and pulled by b = -0.01 from rest: E(0) = 0 and
    // E(t) = W_ext(t) + the scheme's energy error. Measured drift (relative
    // to max W_ext, over two periods of the hanging oscillation): fe 0.0096,
    // npc 0.017; 0.05 bounds them and fails for a lost factor of 1/2.
    const std::string extra = "[body_force]\nvalue = [-0.01]\n[[boundary]]\nname = \"top\"\nlower = "
                              "[1.0]\nupper = [1.0]\nfix = [true]\n";
    for (const char* integrator : {"fe", "npc"}) {
      Engine<1> e = assemble<1>(parse_scene(bar_scene("mpm", integrator, "linear", 0.1, 4.0, extra), "hang.toml"));
      const double drift = run_balance(e);
      MESSAGE("hanging bar, " << std::string(integrator) << ": W_ext = " << e.energy().external_work
                              << ", E = " << e.energy().total() << ", drift " << drift);
      CHECK(e.energy().external_work > 0.0);
      CHECK(e.energy().reaction_work == 0.0);
      CHECK(drift < 0.05);
    }
  }
}

TEST_CASE("energy balance: a moving boundary does the work rho c v0^2 t of a piston") {
  // ul mode: the node at x = 0 is driven at v0 = 0.01 c into the bar at rest.
  // Until the wave reaches x = 1 (t = L/c = 1) the exact reaction is the
  // impedance force rho c v0, so W_R(t) = rho c v0^2 t (per unit area) and
  // E(t) = W_R(t). Measured at t = 0.5, cfl 0.1: W_R / exact = 0.947 (fe),
  // 0.962 (npc), 0.950 (musl): the reaction lags by about one step (2.5% of
  // t), the front is smeared at h = 1/8, and W_R counts the kinetic energy
  // the impulsive start takes (the particles at rest jump to v0 at the
  // driven node); 10% allows that. The balance E - W_R closes to 0.022
  // (fe), 0.044 (npc), 0.021 (musl). otm (consistent mass) closes to 0.17
  // (before its driven node's change was booked: 5.14): its free rows do not
  // see the moving value (docs/theory.md sect. 6), and E ends 16% above W_R.
  const double v0 = 0.01, t_end = 0.5;
  const std::string extra =
      "[[boundary]]\nname = \"piston\"\nlower = [0.0]\nupper = [0.0]\nfix = [true]\nvalue = [" +
      std::to_string(v0) + "]\n";
  for (const char* integrator : {"fe", "npc", "musl"}) {
    Engine<1> e = assemble<1>(parse_scene(bar_scene("ul", integrator, "linear", 0.1, t_end, extra), "piston.toml"));
    const double drift = run_balance(e);
    const double exact = v0 * v0 * t_end;
    MESSAGE("piston, " << std::string(integrator) << ": W_R = " << e.energy().reaction_work << " (exact "
                       << exact << "), E = " << e.energy().total() << ", drift " << drift);
    CHECK(e.energy().initial == 0.0);
    CHECK(e.energy().reaction_work == doctest::Approx(exact).epsilon(0.1));
    CHECK(drift < 0.06);
  }
  Engine<1> otm = assemble<1>(parse_scene(bar_scene("ul", "otm", "linear", 0.1, t_end, extra), "piston.toml"));
  CHECK(run_balance(otm) < 0.2);
}

TEST_CASE("energy summary: max_energy_ratio and energy_drift of a run") {
  // The fixed-end bar of the first test (mpm fe linear, measured drift 0.030)
  // through run_scene. The ratio is at least 1 (t = 0 is a sample); FE's
  // energy oscillates above E(0) by up to 1.9% (measured 1.0193) on this
  // 8-cell bar: below the stability band of 0.05 used by the studies.
  RunOptions opt;
  opt.write_results = false;
  const RunSummary s =
      run_scene(parse_scene(bar_scene("mpm", "fe", "linear", 0.1, 4.0, kMode + kFixedEnds), "bar.toml"), opt);
  REQUIRE(s.exit_code == 0);
  CHECK(s.energy.initial > 0.0);
  CHECK(s.energy.max_work == 0.0);
  CHECK(s.energy.max_energy_ratio() == doctest::Approx(s.energy.max_energy / s.energy.initial));
  CHECK(s.energy.max_energy_ratio() >= 1.0); // the maximum includes t = 0
  CHECK(s.energy.max_energy_ratio() < 1.05);
  CHECK(s.energy.energy_drift() > 0.0);
  CHECK(s.energy.energy_drift() < 0.05);
  EnergySummary rest; // a body at rest with no load: 0, not 0/0
  rest.sample(0.0, 0.0, 0.0);
  CHECK(rest.max_energy_ratio() == 0.0);
  CHECK(rest.energy_drift() == 0.0);
}
