// The gravity-loading phase of simulation.initial_equilibrium
// (run/initial_equilibrium.hpp, docs/theory.md sect. 15, "Initial equilibrium"): a confined
// elastic column reaches the geostatic stress, a slope brought into
// equilibrium stays still where one started stress-free moves, the run
// starts with zero displacements and energy series, and the key is
// checked like every scene key.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/run/initial_equilibrium.hpp"
#include "otmpm/scene/resources.hpp"
#include "otmpm/run/simulation.hpp"
#include "otmpm/scene/validate.hpp"

#include "run_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <regex>
#include <string>
#include <vector>

using namespace otmpm;

namespace {

constexpr double kRho = 2000.0, kG = 9.81, kNu = 0.3;

/// A linear elastic column 0.5 m wide and 4 m high (h = 0.25 m), fixed at
/// its base and held laterally at its sides, under gravity; stress-free at
/// the start.
std::string column(const std::string& phase) {
  return "[simulation]\ndimension = 2\nmode = \"mpm\"\nintegrator = \"musl\"\nt_end = 0.5\ncfl = 0.4\n" +
         phase +
         "\n[basis]\nkind = \"linear\"\n"
         "[grid]\nlower = [0.0, 0.0]\nupper = [0.5, 5.0]\ncells = [2, 20]\n"
         "[[material]]\nname = \"soil\"\nmodel = \"linear_elastic\"\ndensity = 2000.0\nyoung = "
         "1.0e7\npoisson = 0.3\n"
         "[[body]]\nname = \"column\"\nmaterial = \"soil\"\nlower = [0.0, 0.0]\nupper = [0.5, 4.0]\n"
         "particles_per_cell = 2\n"
         "[body_force]\nvalue = [0.0, -9.81]\n"
         "[[boundary]]\nname = \"base\"\nlower = [0.0, 0.0]\nupper = [0.5, 0.0]\nfix = [true, true]\n"
         "[[boundary]]\nname = \"left\"\nlower = [0.0, 0.0]\nupper = [0.0, 5.0]\nfix = [true, false]\n"
         "[[boundary]]\nname = \"right\"\nlower = [0.5, 0.0]\nupper = [0.5, 5.0]\nfix = [true, false]\n"
         "[output]\nfile = \"column.h5\"\n";
}

/// A dry elastic slope (1:1.5, 2 m high) on a fixed base, stress-free at the start.
std::string slope(const std::string& phase) {
  return "[simulation]\ndimension = 2\nmode = \"mpm\"\nintegrator = \"musl\"\nt_end = 2.0\ncfl = 0.4\n" +
         phase +
         "\n[basis]\nkind = \"linear\"\n"
         "[grid]\nlower = [-0.5, 0.0]\nupper = [6.5, 3.0]\ncells = [28, 12]\n"
         "[[material]]\nname = \"soil\"\nmodel = \"linear_elastic\"\ndensity = 2000.0\nyoung = "
         "1.0e7\npoisson = 0.3\n"
         "[[body]]\nname = \"slope\"\nmaterial = \"soil\"\nshape = \"polygon\"\n"
         "vertices = [[0.0, 0.0], [6.0, 0.0], [6.0, 2.0], [3.0, 2.0]]\nparticles_per_cell = 2\n"
         "[body_force]\nvalue = [0.0, -9.81]\n"
         "[[boundary]]\nname = \"base\"\nlower = [-0.5, 0.0]\nupper = [6.5, 0.0]\nfix = [true, true]\n"
         "[[boundary]]\nname = \"back\"\nlower = [6.0, 0.0]\nupper = [6.0, 3.0]\nfix = [true, false]\n"
         "[output]\nfile = \"slope.h5\"\n";
}

/// A saturated elastic column 1 m high (h = 1/64 m, 1D) under its weight,
/// drained at its top, without a water table: its pore water carries the
/// weight at first and drains through the top over about 1 s (c_v = 1 m^2/s).
std::string consolidating(const std::string& phase) {
  return "[simulation]\ndimension = 1\nmode = \"mpm\"\nintegrator = \"fe\"\nt_end = 0.001\ncfl = 0.5\n" + phase +
         "\n[basis]\nkind = \"linear\"\n[grid]\nlower = [0.0]\nupper = [1.0]\ncells = [64]\n"
         "[[material]]\nname = \"sand\"\nmodel = \"linear_elastic\"\ndensity = 2650.0\nyoung = 1.0e7\n"
         "poisson = 0.0\nporosity = 0.4\npermeability = 1.0e-10\nfluid_density = 1000.0\n"
         "fluid_bulk_modulus = 2.2e9\nfluid_viscosity = 1.0e-3\n"
         "[[body]]\nname = \"column\"\nmaterial = \"sand\"\nlower = [0.0]\nupper = [1.0]\nparticles_per_cell = 2\n"
         "[body_force]\nvalue = [-9.81]\n"
         "[[boundary]]\nname = \"base\"\nlower = [0.0]\nupper = [0.0]\nfix = [true]\n"
         "[[boundary]]\nname = \"top\"\nlower = [1.0]\nupper = [1.0]\npore_pressure = 0.0\n"
         "[output]\nfile = \"consolidating.h5\"\n";
}

RunOptions no_files() {
  RunOptions o;
  o.write_results = false;
  return o;
}

double largest_displacement(const Particles<2>& P) {
  double d = 0.0;
  for (int p = 0; p < P.size(); ++p) d = std::max(d, (P.x[p] - P.X[p]).norm());
  return d;
}

double largest_speed(const Particles<2>& P) {
  double v = 0.0;
  for (int p = 0; p < P.size(); ++p) v = std::max(v, P.v[p].norm());
  return v;
}

} // namespace

TEST_CASE("a confined elastic column ends at sigma_yy = -rho g (H - y) and sigma_xx = K0 sigma_yy") {
  const Scene scene = parse_scene(
      column("initial_equilibrium = { time = 10.0, damping = 0.7, tolerance = 1e-4 }"), "column.toml");
  Simulation sim(scene, no_files());
  const Engine<2>& e = sim.engine<2>();
  const Particles<2>& P = e.particles();
  MESSAGE(sim.finish().initial_equilibrium);
  // the exact stress at each particle's height as seeded (the phase moved it down)
  Simulation seeded(parse_scene(column(""), "column.toml"), no_files());
  const AlignedVector<Vec<2>> Y = seeded.engine<2>().particles().X;
  REQUIRE(Y.size() == P.X.size());
  const double H = 4.0, h = 0.25, K0 = kNu / (1.0 - kNu);
  double mean = 0.0, exact_mean = 0.0, worst = 0.0;
  for (int p = 0; p < P.size(); ++p) {
    CAPTURE(P.x[p][1]);
    const double exact = -kRho * kG * (H - Y[p][1]);
    // a linear basis gives each cell one strain: the particle's stress is
    // its cell's, within half a cell's weight of the exact one at the particle
    CHECK(std::abs(P.sigma[p](1, 1) - exact) <= 0.5 * kRho * kG * h);
    // the sides hold every node laterally: eps_xx = 0 exactly
    CHECK(P.sigma[p](0, 0) == doctest::Approx(K0 * P.sigma[p](1, 1)).epsilon(1e-6));
    mean += P.sigma[p](1, 1), exact_mean += exact;
    worst = std::max(worst, std::abs(P.sigma[p](1, 1) - exact) / (kRho * kG * h));
  }
  MESSAGE("largest sigma_yy error: " << worst << " rho g h; mean " << mean / exact_mean - 1.0);
  // the column's weight is carried: the mean vertical stress within ten
  // times the phase's tolerance on the unbalanced force (measured: 1e-4)
  CHECK(mean == doctest::Approx(exact_mean).epsilon(1e-3));
}

TEST_CASE(
    "a slope brought into equilibrium stays still, one started stress-free moves, its series start at zero") {
  const std::string phase = "initial_equilibrium = { time = 20.0, tolerance = 1e-4 }";
  Simulation still(parse_scene(slope(phase), "slope.toml"), no_files());
  const Engine<2>& e = still.engine<2>();
  // at t = 0: no displacement, at rest, every work and loss zero, E(0) the stored energy
  CHECK(e.time() == 0.0);
  CHECK(e.steps() == 0);
  CHECK(largest_displacement(e.particles()) == 0.0);
  CHECK(largest_speed(e.particles()) == 0.0);
  CHECK(e.energy().kinetic == 0.0);
  CHECK(e.energy().external_work == 0.0);
  CHECK(e.energy().reaction_work == 0.0);
  CHECK(e.energy().dissipated == 0.0);
  CHECK(e.energy().strain > 0.0);
  CHECK(e.energy().initial == e.energy().strain);
  Simulation moving(parse_scene(slope(""), "slope.toml"), no_files());
  double still_u = 0.0, still_v = 0.0, moving_u = 0.0;
  while (!still.finished()) {
    still.step();
    still_u = std::max(still_u, largest_displacement(e.particles()));
    still_v = std::max(still_v, largest_speed(e.particles()));
  }
  while (!moving.finished()) {
    moving.step();
    moving_u = std::max(moving_u, largest_displacement(moving.engine<2>().particles()));
  }
  const RunSummary summary = still.finish();
  MESSAGE(summary.initial_equilibrium);
  MESSAGE("largest displacement over 2 s: " << still_u << " m with the phase, " << moving_u << " m without");
  CHECK(summary.initial_equilibrium.starts_with("converged"));
  CHECK(moving_u > 1e-3);
  CHECK(still_u < 0.02 * moving_u);
  CHECK(still_v < 1e-3);
  (void)moving.finish();
}

TEST_CASE("the result file says how the phase ended") {
  test::TempDir tmp("initial_equilibrium");
  RunOptions o;
  o.out_file = tmp.file("slope.h5");
  const RunSummary s = run_scene(
      parse_scene(slope("initial_equilibrium = { time = 0.05 }"), "slope.toml", {"simulation.t_end=0.01"}),
      o);
  REQUIRE(s.exit_code == 0);
  CHECK(s.initial_equilibrium.starts_with("not converged in")); // 0.05 s is a sixth of what it needs
  CHECK(read_string_attribute(o.out_file, "initial_equilibrium") == s.initial_equilibrium);
}

TEST_CASE("a restart's result file says how the interrupted run's phase ended") {
  test::TempDir tmp("initial_equilibrium_restart");
  RunOptions o;
  o.out_file = tmp.file("slope.h5");
  const RunSummary first = run_scene(parse_scene(slope("initial_equilibrium = { time = 20.0, tolerance = 1e-4 }"),
                                                 "slope.toml", {"simulation.t_end=0.05", "output.checkpoint_every=20"}),
                                     o);
  REQUIRE(first.exit_code == 0);
  REQUIRE(first.initial_equilibrium.starts_with("converged after"));
  RunOptions again;
  again.out_file = tmp.file("again.h5");
  const RunSummary restarted = restart_run(read_checkpoint(tmp.file("slope.checkpoint.h5")), again);
  REQUIRE(restarted.exit_code == 0);
  CHECK(restarted.steps == first.steps);
  CHECK(restarted.initial_equilibrium == first.initial_equilibrium);
  CHECK(read_string_attribute(again.out_file, "initial_equilibrium") == first.initial_equilibrium);
}

TEST_CASE("a dip of the residuals below the tolerance during the transient does not end the phase") {
  // The column's damped oscillation passes through its equilibrium every
  // half period (2 H / c): both residuals fall below 1e-2 there for up to
  // 0.023 s (steps 361 to 380), then rise above it again (measured).
  const double tolerance = 1e-2;
  const auto below = [&](const EquilibriumReport& s) {
    return std::max(s.force_residual, s.velocity_residual) < tolerance;
  };
  // the residuals step by step, from a phase that cannot converge (its
  // steps are those of any tolerance: the tolerance only ends the phase)
  const Scene endless =
      parse_scene(column("initial_equilibrium = { time = 1.0, tolerance = 1e-12 }"), "column.toml");
  Engine<2> e0(assemble_parts<2>(endless));
  std::vector<EquilibriumReport> steps;
  (void)settle<2>(endless, e0, [&](const EquilibriumReport& s) { steps.push_back(s); });
  REQUIRE(steps.size() > 2);
  CHECK(steps.back().steps == static_cast<long>(steps.size()));
  // the transient has a dip: a step below the tolerance, a later one above it
  const auto dip = std::find_if(steps.begin(), steps.end(), below);
  REQUIRE(dip != steps.end());
  const auto above_again = std::find_if_not(dip, steps.end(), below);
  REQUIRE(above_again != steps.end());
  MESSAGE("below the tolerance at step " << dip->steps << ", above it again at step " << above_again->steps);
  // the phase with that tolerance does not end in the dip
  const Scene scene =
      parse_scene(column("initial_equilibrium = { time = 10.0, tolerance = 1e-2 }"), "column.toml");
  Engine<2> e(assemble_parts<2>(scene));
  const EquilibriumReport r = settle<2>(scene, e);
  MESSAGE(r.describe(tolerance));
  REQUIRE(r.converged);
  CHECK(r.steps > above_again->steps);
  REQUIRE(r.steps < static_cast<long>(steps.size()));
  const EquilibriumReport& last = steps[static_cast<std::size_t>(r.steps - 1)];
  CHECK(last.time == r.time);
  // W of eq. 15.17: twice the particles' extent (H less half a particle spacing) over c_p
  const double M = 1.0e7 * (1.0 - kNu) / ((1.0 + kNu) * (1.0 - 2.0 * kNu));
  CHECK(r.window == doctest::Approx(2.0 * (4.0 - 0.125) / std::sqrt(M / kRho)).epsilon(0.01));
  // it ended at the first step that closed W below the tolerance: the run
  // of steps below it began W before its end, one step later than that
  auto k = static_cast<std::size_t>(r.steps - 1); // the run's first step: steps[k]
  while (k > 0 && below(steps[k - 1])) --k;
  REQUIRE(k > 0);
  const double began = steps[k - 1].time; // the start of that step
  CHECK(r.time - began >= r.window * (1.0 - 1e-9));
  CHECK(steps[static_cast<std::size_t>(r.steps - 2)].time - began < r.window);
  CHECK(r.held == doctest::Approx(r.time - began));
  // out of time before the window has passed: not converged, and the message says how long they held
  const Scene short_phase = parse_scene(
      column("initial_equilibrium = { time = " + std::to_string(r.time - 0.5 * r.window) + ", tolerance = 1e-2 }"),
      "column.toml");
  Engine<2> again(assemble_parts<2>(short_phase));
  const EquilibriumReport cut = settle<2>(short_phase, again);
  const std::string why = cut.describe(tolerance);
  MESSAGE(why);
  CHECK(!cut.converged);
  CHECK(cut.held > 0.0);
  CHECK(cut.held < cut.window);
  CHECK(why.find("both below the tolerance for the last") != std::string::npos);
  CHECK(why.find("give a longer time") != std::string::npos);
}

TEST_CASE("a phase that ends with the bodies creeping says so, and names the fastest particle") {
  // consolidation under its weight: the drag balances the weight (R_f small)
  // while the column settles for about 1 s, longer than the phase's 0.2 s
  const Scene scene = parse_scene(consolidating("initial_equilibrium = { time = 0.2 }"), "consolidating.toml");
  Engine<1> e(assemble_parts<1>(scene));
  const EquilibriumReport r = settle<1>(scene, e);
  const std::string why = r.describe(1e-3);
  MESSAGE(why);
  REQUIRE(!r.converged);
  CHECK(why.starts_with("not converged in"));
  CHECK(r.force_residual < 1e-3);
  CHECK(r.velocity_residual > 1e-3);
  CHECK(why.find("R_v above the tolerance with no unbalanced force to damp: the bodies creep") !=
        std::string::npos);
  CHECK(why.find("give a longer time") != std::string::npos);
  // the fastest particle, where the run starts it: at the drained top, which settles fastest
  std::smatch m;
  REQUIRE(std::regex_search(why, m, std::regex("particle ([0-9]+) \\(body 'column'\\) at (\\([^)]*\\)): \\|v\\| = ")));
  const int p = std::stoi(m[1].str());
  REQUIRE(p < e.particles().size());
  CHECK(m[2].str() == format_point<1>(e.particles().x[p]));
  CHECK(e.particles().x[p][0] > 0.9);
}

TEST_CASE("every integrator of the fixed grid brings the slope into equilibrium") {
  for (const IntegratorKind& k : integrator_kinds()) {
    if (k.needs_ul || k.needs_bspline) continue;
    CAPTURE(k.name);
    std::vector<std::string> sets{"simulation.integrator=\"" + std::string(k.name) + "\"",
                                  "simulation.t_end=0.5"};
    if (k.needs_consistent_mass) sets.push_back("simulation.mass=\"consistent\"");
    Simulation sim(
        parse_scene(slope("initial_equilibrium = { time = 20.0, tolerance = 1e-4 }"), "slope.toml", sets),
        no_files());
    double moved = 0.0;
    while (!sim.finished()) {
      sim.step();
      moved = std::max(moved, largest_displacement(sim.engine<2>().particles()));
    }
    const RunSummary s = sim.finish();
    MESSAGE(k.name << ": " << s.initial_equilibrium << "; largest displacement over 0.5 s " << moved << " m");
    CHECK(s.initial_equilibrium.starts_with("converged"));
    CHECK(moved < 1e-4); // started stress-free it moves 8.3 mm
  }
}

TEST_CASE("simulation.initial_equilibrium is checked with the file's line, and needs the fixed grid and a "
          "constant weight") {
  using test::input_error_of;
  std::string why = input_error_of(
      [] { parse_scene(column("initial_equilibrium = { time = 1.0, damping = 1.0 }"), "c.toml"); });
  CHECK(why.find("c.toml:7") != std::string::npos);
  CHECK(why.find("damping") != std::string::npos);
  why = input_error_of([] { parse_scene(column("initial_equilibrium = { damping = 0.5 }"), "c.toml"); });
  CHECK(why.find("time") != std::string::npos);
  why = input_error_of(
      [] { parse_scene(column("initial_equilibrium = { time = 1.0, alpha = 0.5 }"), "c.toml"); });
  CHECK(why.find("alpha") != std::string::npos);
  // the table given whole by --set: the message names the key inside it
  for (const char* set : {"simulation.initial_equilibrium={time=1.0, damping=2}",
                          "simulation.initial_equilibrium.damping=2"}) {
    CAPTURE(set);
    why = input_error_of([&] { parse_scene(column("initial_equilibrium = { time = 1.0 }"), "c.toml", {set}); });
    CHECK(why.starts_with("--set simulation.initial_equilibrium"));
    CHECK(why.find("simulation.initial_equilibrium.damping") != std::string::npos);
    CHECK(why.ends_with(scene_keys::kEquilibriumDamping.check(2.0)));
  }
  Scene s = parse_scene(column("initial_equilibrium = { time = 1.0 }"), "c.toml");
  s.simulation.initial_equilibrium->damping = 1.0; // a Scene built in code meets the same row
  why = input_error_of([&] { validate_scene(s, 2); });
  CHECK(why.find("key 'simulation.initial_equilibrium.damping'") != std::string::npos);
  CHECK(why.ends_with(scene_keys::kEquilibriumDamping.check(1.0)));
  s.simulation.initial_equilibrium->damping = 0.7;
  s.body_force->time = {"ramp", 1.0};
  why = input_error_of([&] { validate_scene(s, 2); });
  CHECK(why.find("body_force.time must be constant") != std::string::npos);
  CHECK(why.find("simulation.initial_equilibrium") != std::string::npos);
  s = parse_scene(column("initial_equilibrium = { time = 1.0 }"), "c.toml");
  s.body_force.reset();
  why = input_error_of([&] { validate_scene(s, 2); });
  CHECK(why.find("[body_force]") != std::string::npos);
  s = parse_scene(column("initial_equilibrium = { time = 1.0 }"), "c.toml");
  s.body_force->value = {0.0, 0.0, -9.81}; // the third component is not the 2D run's
  why = input_error_of([&] { validate_scene(s, 2); });
  CHECK(why.find("body_force.value is zero") != std::string::npos);
  s = parse_scene(column("initial_equilibrium = { time = 1.0 }"), "c.toml");
  s.simulation.mode = "ul";
  why = input_error_of([&] { validate_scene(s, 2); });
  CHECK(why.find("needs mode = \"mpm\"") != std::string::npos);
  // written back as TOML it reads back the same
  const Scene again = parse_scene(
      to_toml(parse_scene(column("initial_equilibrium = { time = 2.5, damping = 0.8, tolerance = 1e-5 }"),
                          "c.toml")),
      "again.toml");
  REQUIRE(again.simulation.initial_equilibrium);
  CHECK(again.simulation.initial_equilibrium->time == 2.5);
  CHECK(again.simulation.initial_equilibrium->damping == 0.8);
  CHECK(again.simulation.initial_equilibrium->tolerance == 1e-5);
}

TEST_CASE("run --check counts the phase's steps and its engine beside the run's in the memory") {
  const Scene with = parse_scene(column("initial_equilibrium = { time = 3.0 }"), "column.toml");
  const Scene without = parse_scene(column(""), "column.toml");
  const SceneCheck a = check_scene(with), b = check_scene(without);
  CHECK(b.phase_steps == 0.0);
  CHECK(a.phase_steps == std::ceil(3.0 / a.dt * (1.0 - 1e-9)));
  CHECK(a.phase_steps > 5.0 * a.estimated_steps); // 3 s of settling against a 0.5 s run
  CHECK(a.estimated_steps == b.estimated_steps);
  // The phase's engine holds the particles and nodes a second time while it runs.
  const ResourceEstimate e = estimate_resources(without);
  CHECK(a.memory_bytes == doctest::Approx(b.memory_bytes + e.particles * e.bytes_per_particle +
                                          e.nodes * e.bytes_per_node).epsilon(1e-12));
}

TEST_CASE("the phase's scene holds the loads at their values at t = 0") {
  Scene s = parse_scene(slope("initial_equilibrium = { time = 3.0 }"), "slope.toml");
  TractionSection ramped;
  ramped.time.kind = "ramp";
  ramped.time.period = 2.0;
  s.tractions.push_back(ramped);
  s.boundaries[0].water_rise = 1.0;
  s.boundaries[0].time = {"ramp", 2.0};
  s.boundaries[1].value = {0.1, 0.0, 0.0};
  s.bodies[0].velocity = {1.0, 0.0, 0.0};
  const Scene q = equilibrium_scene(s);
  CHECK(q.simulation.t_end == 3.0);
  CHECK(!q.simulation.initial_equilibrium);
  CHECK(q.tractions.empty());
  CHECK(!q.boundaries[0].water_rise);
  CHECK(q.boundaries[1].value == Vec3{0, 0, 0});
  CHECK(q.bodies[0].velocity == Vec3{0, 0, 0});
}

TEST_CASE("a saturated dike brought into equilibrium stands still under its slopes until the river rises") {
  // examples/dike_rising.toml to t = 3 s: without the phase its crest's
  // landward edge moves 12.8 cm landward in these 3 s (docs/gallery.md)
  const std::string dike = OTMPM_SOURCE_DIR "/examples/dike_rising.toml";
  Simulation sim(load_scene(dike, {"simulation.t_end=3.0"}), no_files());
  const Engine<2>& e = sim.engine<2>();
  CHECK(e.energy().darcy == 0.0);
  CHECK(e.energy().pressure_average == 0.0);
  CHECK(e.energy().kinetic == 0.0);
  const Particles<2>& P = e.particles();
  const StateField* w = P.find_state("liquid_velocity");
  REQUIRE(w != nullptr);
  CHECK(std::all_of(w->values.begin(), w->values.end(), [](double v) { return v == 0.0; }));
  double moved = 0.0;
  while (!sim.finished()) {
    sim.step();
    moved = std::max(moved, largest_displacement(P));
  }
  const RunSummary s = sim.finish();
  MESSAGE(s.initial_equilibrium << "; largest displacement over 3 s: " << moved << " m");
  CHECK(s.initial_equilibrium.starts_with("converged"));
  CHECK(moved <
        0.01); // the phase leaves the residual of its tolerance: 2.2 mm at the crest in the first second
}
