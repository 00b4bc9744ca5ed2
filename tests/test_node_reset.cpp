// `ul` mode's node reset (simulation.node_reset, docs/theory.md sect. 3):
// the nodes laid out anew on the grid's lattice over the particles when the
// CFL spacing has fallen below a fraction of h.
#include <doctest/doctest.h>

#include "otmpm/assembly/assembler.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/scene/resources.hpp"
#include "otmpm/scene/validate.hpp"
#include "otmpm/state.hpp"
#include "temp_dir.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

using namespace otmpm;

namespace {

/// A j2 block (0.4 x 0.2 m, 2 x 2 particles per cell of 0.05 m) at 60 m/s
/// onto a rigid wall: its bottom cells flatten within a few hundred steps.
Scene impact(const std::vector<std::string>& sets) {
  const std::string text = R"(
[simulation]
dimension = 2
mode = "ul"
integrator = "npc"
t_end = 4.0e-3
cfl = 0.3
node_reset = 0.5
[basis]
kind = "linear"
[grid]
lower = [-0.2, 0.0]
upper = [0.6, 0.3]
cells = [16, 6]
[[material]]
name = "m"
model = "j2"
density = 1000.0
young = 1.0e7
poisson = 0.3
yield_stress = 1.0e5
hardening_modulus = 1.0e5
[[body]]
name = "b"
material = "m"
lower = [0.0, 0.05]
upper = [0.4, 0.25]
velocity = [0.0, -60.0]
[[wall]]
name = "floor"
point = [0.0, 0.05]
normal = [0.0, 1.0]
[[boundary]]
name = "symmetry"
lower = [0.0, 0.0]
upper = [0.0, 0.3]
fix = [true, false]
[output]
every = 0.0
)";
  return parse_scene(text, "impact.toml", sets);
}

/// Same bits in every particle field that a step changes.
template <int D> bool same_particles(const Particles<D>& a, const Particles<D>& b) {
  if (a.size() != b.size()) return false;
  for (int p = 0; p < a.size(); ++p)
    if (a.x[p] != b.x[p] || a.v[p] != b.v[p] || a.sigma[p] != b.sigma[p] || a.F[p] != b.F[p] || a.V[p] != b.V[p])
      return false;
  return true;
}

/// Runs scene `s` to its first node reset and 5 steps on (a few steps on the
/// new lattice), restores its checkpoint into a second engine, steps both
/// up to `steps` more steps (at most to t_end), and checks that they made as
/// many resets and hold the same particle bits; returns both.
std::pair<Engine<2>, Engine<2>> restarted_after_reset(const Scene& s, int steps) {
  Engine<2> a = assemble<2>(s);
  while (a.node_resets() == 0 && a.time() < s.simulation.t_end) a.step();
  REQUIRE(a.node_resets() > 0);
  for (int k = 0; k < 5; ++k) a.step();
  Checkpoint ck;
  a.save_state(ck);
  Engine<2> b = assemble<2>(s);
  b.restore_state(ck);
  CHECK(b.node_resets() == a.node_resets());
  CHECK(b.basis().nodes().size() == a.basis().nodes().size());
  for (int k = 0; k < steps && a.time() < s.simulation.t_end; ++k) {
    a.step();
    b.step();
  }
  CHECK(a.node_resets() == b.node_resets());
  CHECK(same_particles(a.particles(), b.particles()));
  return {std::move(a), std::move(b)};
}

} // namespace

TEST_CASE("node reset: the nodes are laid out anew when their spacing falls below the fraction") {
  for (const char* basis : {"linear", "lme"}) {
    CAPTURE(basis);
    Engine<2> e = assemble<2>(impact({std::string("basis.kind=\"") + basis + "\""}));
    const int nodes0 = e.basis().nodes().size();
    while (e.time() < 4.0e-3) e.step();
    CHECK(e.node_resets() > 0);
    CHECK(e.basis().nodes().on_lattice() == false); // they moved on after the last reset
    // the lattice spans the flattened, widened block now (more nodes along x)
    CHECK(e.basis().nodes().size() != nodes0);
    // without resets the same run takes more steps (its step keeps shrinking)
    Engine<2> plain = assemble<2>(impact({std::string("basis.kind=\"") + basis + "\"", "simulation.node_reset=0"}));
    while (plain.time() < 4.0e-3) plain.step();
    CHECK(plain.node_resets() == 0);
    CHECK(plain.steps() > e.steps());
  }
}

TEST_CASE("node reset with B-splines: the nodes are laid out anew before a particle leaves the knot vectors") {
  // The block spreads on the wall faster than the knot vectors, which
  // follow the nodes' mean motion per axis: without the domain rule its
  // edge particles leave them within a few steps (a run stopped there).
  for (const char* basis : {"bspline2", "bspline3"}) {
    CAPTURE(basis);
    const Scene s = impact({std::string("basis.kind=\"") + basis + "\""});
    Engine<2> e = assemble<2>(s); // the symmetry plane x = 0: the reset lattices end on it
    while (e.time() < s.simulation.t_end) {
      e.step();
      const auto domain = e.basis().domain();
      REQUIRE(domain.has_value());
      for (int p = 0; p < e.particles().size(); ++p)
        for (int k = 0; k < 2; ++k) {
          REQUIRE(e.particles().x[p][k] >= domain->first[k]);
          REQUIRE(e.particles().x[p][k] <= domain->second[k]);
        }
    }
    CHECK(e.node_resets() > 0);
  }
}

TEST_CASE("node reset: a lattice the boundaries cannot be laid out on stops the run as unstable, with the reason") {
  // The reset builds the boundary sets on the new lattice as the setup did;
  // a box that selects none of its nodes there (a body that left its plane)
  // is the state the run reached, not bad input: exit 1, not 2.
  const Scene s = impact({});
  EngineParts<2> parts = assemble_parts<2>(s);
  auto lattice = parts.settings.node_reset.lattice;
  int calls = 0;
  parts.settings.node_reset.lattice = [&](const CartesianGrid<2>& grid, double t) {
    ++calls;
    LatticePart<2> part = lattice(grid, t);
    if (part.basis) throw InputError("impact.toml:43: key 'boundary.symmetry': boundary 'symmetry' selects no node");
    return part;
  };
  Engine<2> e(std::move(parts));
  try {
    while (e.time() < s.simulation.t_end) e.step();
    FAIL("the run went on past a reset that failed");
  } catch (const InstabilityError& f) {
    const std::string what = f.what();
    CHECK(what.find("step ") == 0);
    CHECK(what.find("laid out anew") != std::string::npos);
    CHECK(what.find("boundary 'symmetry' selects no node") != std::string::npos);
  }
  CHECK(calls == 1);
  CHECK(e.node_resets() == 0);
}

TEST_CASE("node reset with the consistent mass: the reset lattice's cut cells fail the run, the advected nodes do not") {
  // Why the default is no reset with the consistent mass (linear, LME): the
  // lattice laid out anew on the grid's lines leaves cells that hold one
  // layer of particles, where M extrapolates the nodal velocities from one
  // side (the impact block: det F < 0 within steps of the first reset);
  // without resets the same run reaches t_end.
  for (const char* integrator : {"otm", "npc"}) {
    CAPTURE(integrator);
    const std::vector<std::string> sets = {std::string("simulation.integrator=\"") + integrator + "\"",
                                           "simulation.mass=\"consistent\""};
    Scene s = impact(sets);
    s.simulation.node_reset.reset(); // the default
    Engine<2> e = assemble<2>(s);
    while (e.time() < s.simulation.t_end) e.step();
    CHECK(e.node_resets() == 0);
    CHECK(e.energy().balance_error() < 0.01 * e.energy().initial); // creates no energy
    Engine<2> reset = assemble<2>(impact(sets)); // the scene's node_reset = 0.5
    CHECK_THROWS_AS(
        [&] {
          while (reset.time() < s.simulation.t_end) reset.step();
        }(),
        InstabilityError);
    CHECK(reset.node_resets() > 0);
  }
}

TEST_CASE("node reset: a run reports how many resets it made, in its summary and its result file") {
  const Scene s = impact({});
  Engine<2> e = assemble<2>(s);
  while (e.time() < s.simulation.t_end) e.step();
  REQUIRE(e.node_resets() > 1);
  test::TempDir dir("node_reset_count");
  RunOptions opt;
  opt.out_file = dir.file("impact.h5");
  const RunSummary r = run_scene(s, opt);
  REQUIRE(r.exit_code == 0);
  CHECK(r.steps == e.steps());
  REQUIRE(r.diagnostics.count("node_resets") == 1);
  CHECK(r.diagnostics.at("node_resets") == static_cast<double>(e.node_resets()));
  CHECK(summary_line(r).find("node_resets = " + std::to_string(e.node_resets())) != std::string::npos);
  CHECK(read_double_attribute(opt.out_file, "node_resets") == static_cast<double>(e.node_resets()));
  // mpm mode has no node set to reset: no count is reported.
  RunOptions none;
  none.write_results = false;
  const RunSummary m = run_scene(impact({"simulation.mode=mpm", "simulation.node_reset=0"}), none);
  CHECK(m.diagnostics.count("node_resets") == 0);
}

TEST_CASE("node reset: a run restarted from a checkpoint after a reset goes on bit for bit") {
  for (const char* volumetric : {"fbar", "none"}) {
    CAPTURE(volumetric);
    // 0.6: the locked block ("none") flattens its cells less
    const Scene s = impact({std::string("simulation.volumetric=\"") + volumetric + "\"", "simulation.node_reset=0.6"});
    const auto [a, b] = restarted_after_reset(s, 200);
    CHECK(a.energy().kinetic == b.energy().kinetic);
  }
}

TEST_CASE("node reset with a B-spline basis: a run restarted after a reset goes on bit for bit") {
  // The block at 5 m/s without the symmetry plane (at 60 m/s a corner
  // particle leaves the knot vectors within 7 steps, with or without resets).
  Scene s = impact({"basis.kind=\"bspline2\"", "body.b.velocity=[0.0, -5.0]", "simulation.node_reset=0.95",
                    "simulation.t_end=2.0e-2"});
  s.boundaries.clear();
  restarted_after_reset(s, 200); // the control points are all present: the restore removes none
}

namespace {

/// The impact block at rest, squeezed between the floor wall moving up at
/// 5 m/s and a platen (a boundary box holding the top node plane's y
/// velocity) moving down at 5 m/s: 40 % shorter at t_end.
Scene squeeze(const std::vector<std::string>& sets) {
  Scene s = impact(sets);
  s.simulation.t_end = 8.0e-3;
  s.bodies.at(0).velocity = {0.0, 0.0, 0.0};
  s.walls.at(0).velocity = {0.0, 5.0, 0.0};
  BoundarySection platen;
  platen.name = "platen";
  platen.lower = {-0.2, 0.25, 0.0};
  platen.upper = {0.6, 0.25, 0.0};
  platen.fix = {false, true, false};
  platen.value = {0.0, -5.0, 0.0};
  s.boundaries.push_back(platen);
  return s;
}

/// The largest particle y: the block's top, which the platen carries.
double top(const Particles<2>& P) {
  double y = -1.0;
  for (int p = 0; p < P.size(); ++p) y = std::max(y, P.x[p][1]);
  return y;
}

} // namespace

TEST_CASE(
    "node reset with a moving wall and a moving boundary: the lattice lines and the box follow the platen") {
  const double h = 0.05;
  Engine<2> reset = assemble<2>(squeeze({"simulation.node_reset=0.7"}));
  Engine<2> plain = assemble<2>(squeeze({"simulation.node_reset=0"}));
  while (reset.time() < 8.0e-3) reset.step();
  while (plain.time() < 8.0e-3) plain.step();
  REQUIRE(reset.node_resets() > 0);
  CHECK(plain.steps() > reset.steps());
  // The platen plane is at 0.25 - 5 t: the top particles (a quarter cell
  // below the top node plane at the start) stay under it and within a
  // quarter cell of where the run without resets has them.
  const double platen = 0.25 - 5.0 * reset.time();
  CHECK(top(reset.particles()) < platen);
  // The nodes the platen holds after the reset are the lattice's top plane,
  // carried with it: all at y = 0.25 - 5 t (the lines moved with it).
  const Dirichlet<2>& held = reset.dirichlet();
  int on_platen = 0;
  for (std::size_t i = 0; i < held.node.size(); ++i)
    if (held.fix[i][1]) {
      ++on_platen;
      CHECK(std::abs(reset.basis().nodes().position(held.node[i])[1] - platen) < 1e-9);
    }
  CHECK(on_platen > 0);
  CHECK(std::abs(top(reset.particles()) - top(plain.particles())) < 0.25 * h);
  // The platen's and the wall's impulses and the work agree with the run
  // without resets within 10 % (measured 7 %: the fresh lattice is less stiff
  // than the flattened one, as on the Taylor bar), and the energy balance
  // closes within 5 % of the work (npc dissipates: measured 1.2 %).
  const double J = plain.reaction_impulse()[1];
  CHECK(std::abs(reset.reaction_impulse()[1] - J) < 0.1 * std::abs(J));
  const double Jw = plain.wall_impulse()[0][1];
  CHECK(std::abs(reset.wall_impulse()[0][1] - Jw) < 0.1 * std::abs(Jw));
  const EnergyBalance a = reset.energy(), b = plain.energy();
  CHECK(std::abs(a.work() - b.work()) < 0.1 * std::abs(b.work()));
  CHECK(std::abs(a.balance_error()) < 0.05 * std::abs(a.work()));
}

TEST_CASE("node reset with a moving boundary: a run restarted after a reset goes on bit for bit") {
  const auto [a, b] = restarted_after_reset(squeeze({"simulation.node_reset=0.7"}), 300);
  CHECK(a.reaction_impulse() == b.reaction_impulse());
}

TEST_CASE("node reset: refused in mpm mode, out of its range (0 to 1) and with boundaries fixing an axis at "
          "different "
          "velocities") {
  CHECK_THROWS_WITH_AS(impact({"simulation.mode=\"mpm\""}), doctest::Contains("node_reset"), InputError);
  CHECK_THROWS_WITH_AS(impact({"simulation.node_reset=1.0"}), doctest::Contains("node_reset"), InputError);
  // one moving boundary per axis is followed; two that part are not
  CHECK_NOTHROW(assemble<2>(impact({"boundary.symmetry.value=[0.1, 0.0]"})));
  Scene s = squeeze({"simulation.node_reset=0.7"});
  s.boundaries.push_back(s.boundaries.back());
  s.boundaries.back().name = "base";
  s.boundaries.back().value = {0.0, 0.0, 0.0};
  CHECK_THROWS_WITH_AS(assemble<2>(s), doctest::Contains("different velocities"), InputError);
}

TEST_CASE("node reset by default: 0.7 in ul on a node lattice, none where the lattice cannot follow the "
          "boundaries") {
  Scene s = impact({});
  s.simulation.node_reset.reset(); // the scene gives none
  CHECK(node_reset_fraction(s) == 0.7);
  CHECK(assemble_parts<2>(s).settings.node_reset.below == 0.7);
  // the default as a file says it: read back, the same fraction given
  const Scene back = parse_scene(to_toml(s), "back.toml");
  REQUIRE(back.simulation.node_reset.has_value());
  CHECK(*back.simulation.node_reset == 0.7);
  Scene given = s;
  given.simulation.node_reset = 0.3;
  CHECK(node_reset_fraction(given) == 0.3);
  Scene fixed_grid = s;
  fixed_grid.simulation.mode = "mpm";
  CHECK(node_reset_fraction(fixed_grid) == 0.0);
  Scene mesh = s;
  mesh.bodies.at(0).nodes = "mesh";
  CHECK(node_reset_fraction(mesh) == 0.0);
  for (const char* integrator : {"otm", "npc"}) { // the consistent mass: none (the test below); B-splines keep it
    Scene consistent = s;
    consistent.simulation.integrator = integrator;
    consistent.simulation.mass = "consistent";
    CHECK(node_reset_fraction(consistent) == 0.0);
    consistent.basis.kind = "lme";
    CHECK(node_reset_fraction(consistent) == 0.0);
    consistent.basis.kind = "bspline2";
    CHECK(node_reset_fraction(consistent) == 0.7);
  }
  // two boundaries fixing x at different velocities: no lattice line follows both
  Scene moving = s;
  BoundarySection pusher = moving.boundaries.at(0);
  pusher.name = "pusher";
  pusher.lower[0] = pusher.upper[0] = 0.4;
  pusher.value[0] = -1.0;
  moving.boundaries.push_back(pusher);
  CHECK(node_reset_fraction(moving) == 0.0);
  CHECK_NOTHROW(validate_scene(moving, 2)); // the default gives way; a given fraction is refused
  moving.simulation.node_reset = 0.5;
  CHECK_THROWS_WITH_AS(validate_scene(moving, 2), doctest::Contains("different velocities"), InputError);
}

TEST_CASE("the consistent mass: the scene's mass or an integrator that needs it, the same answer for the "
          "assembler, the node reset and the memory estimate") {
  // A scene built in code may leave simulation.mass "lumped" under an
  // integrator that needs the consistent mass (the assembler refuses it);
  // every reader asks the one question.
  for (const IntegratorKind& integrator : integrator_kinds()) {
    for (const char* mass : {"lumped", "consistent"}) {
      CAPTURE(integrator.name);
      CAPTURE(mass);
      Scene s = impact({"basis.kind=bspline2"});
      s.simulation.integrator = std::string(integrator.name);
      s.simulation.mass = mass;
      s.simulation.node_reset.reset();
      const bool consistent = std::string(mass) == "consistent" || integrator.needs_consistent_mass;
      CHECK(uses_consistent_mass(s) == consistent);
      if (integrator.needs_consistent_mass && std::string(mass) == "lumped") // a scene must say it
        CHECK_THROWS_WITH_AS(assemble_parts<2>(s), doctest::Contains("set mass = \"consistent\""), InputError);
      else
        CHECK(assemble_parts<2>(s).settings.consistent_mass == consistent);
      Scene lumped = s; // the memory estimate counts the mass matrix's factor
      lumped.simulation.mass = "lumped";
      lumped.simulation.integrator = "npc";
      CHECK((estimate_resources(s).bytes_per_node > estimate_resources(lumped).bytes_per_node) == consistent);
      s.basis.kind = "linear"; // the consistent mass on a reset lattice's cut cells: no reset
      CHECK(node_reset_fraction(s) == (consistent ? 0.0 : 0.7));
    }
  }
}
