// Results do not depend on the number of OpenMP threads: the same
// scene stepped with 1 and with 2 threads gives bitwise identical particles.
// Nor on fusing stages into one pass: the NPC stress update inside the force
// scatter gives the bits of the two separate stages.
#include <doctest/doctest.h>

#include "otmpm/assembly/assembler.hpp"
#include "otmpm/engine/scatter.hpp"
#include "support.hpp"

#include <algorithm>
#include <numeric>
#include <random>
#include <string>


using namespace otmpm;
using otmpm::test::ScopedThreads;

namespace {

/// Steps the andersen block (10 x 10 m at h = 0.125 m: 25600
/// particles, enough for fill_basis_table to split the work) with `threads`.
struct Result {
  Particles<2> particles;
  EnergyBalance energy;
  Vec<2> momentum;
  Vec<2> reaction_impulse;
  NodalFields<2> nodal;
};

/// Reorders every particle field by a fixed random permutation, so that the
/// particle order is no longer spatial (the scatter then takes a blocked
/// path over overlapping node ranges - the sparse one for the linear basis -
/// or on a wide grid the gather by columns).
void shuffle_particles(Particles<2>& P) {
  std::vector<int> perm(static_cast<std::size_t>(P.size()));
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), std::mt19937(42));
  auto apply = [&](auto& field) {
    if (field.empty()) return;
    auto copy = field;
    for (std::size_t i = 0; i < perm.size(); ++i) field[i] = copy[static_cast<std::size_t>(perm[i])];
  };
  apply(P.x), apply(P.X), apply(P.v), apply(P.a), apply(P.m), apply(P.V), apply(P.V0), apply(P.rho);
  apply(P.F), apply(P.eps), apply(P.sigma), apply(P.length0);
  apply(P.material), apply(P.body);
}

/// The andersen block at h = 0.125 m (25600 particles) with overrides.
Scene andersen_block(const std::vector<std::string>& sets) {
  std::vector<std::string> all{"grid.cells=[144, 96]", "output.every=0"};
  all.insert(all.end(), sets.begin(), sets.end());
  return load_scene(OTMPM_SOURCE_DIR "/examples/andersen_block.toml", all);
}

/// Overrides that widen the andersen grid to 800 x 96 cells (same h, the
/// block where it was): shuffled, its scatter blocks' node ranges then add up
/// to more than max_sparse_ranges times the linear table's entries, and the
/// scatter gathers by columns.
const std::vector<std::string> wide_grid{"grid.upper=[96.0, 12.0]", "grid.cells=[800, 96]"};

Result run_with_threads(int threads, const std::vector<std::string>& sets, bool shuffled = false,
                        bool blocked = true) {
  const ScopedThreads scope(threads);
  Engine<2> e = assemble<2>(andersen_block(sets));
  if (shuffled) shuffle_particles(e.particles());
  for (int s = 0; s < 5; ++s) e.step();
  CHECK(e.scatter_blocked() == blocked);
  return {e.particles(), e.energy(), e.momentum(), e.reaction_impulse(), e.nodal()};
}

/// The positions, velocities, stresses and volumes of a and b have the same bits.
void check_same_particles(const Particles<2>& a, const Particles<2>& b) {
  REQUIRE(a.size() == b.size());
  bool same = true;
  for (int p = 0; p < a.size(); ++p)
    same = same && a.x[p] == b.x[p] && a.v[p] == b.v[p] && a.sigma[p] == b.sigma[p] && a.V[p] == b.V[p];
  CHECK(same);
}

/// Every particle and nodal field, the energies, the momentum and the
/// reaction impulse have the same bits in a and b.
void check_same(const Result& one, const Result& two) {
  check_same_particles(one.particles, two.particles);
  CHECK(one.energy.kinetic == two.energy.kinetic);
  CHECK(one.energy.strain == two.energy.strain);
  CHECK(one.energy.external_work == two.energy.external_work);
  CHECK(one.energy.reaction_work == two.energy.reaction_work);
  CHECK(one.momentum == two.momentum);
  CHECK(one.reaction_impulse == two.reaction_impulse);
  CHECK(one.nodal.m == two.nodal.m);
  CHECK(one.nodal.active == two.nodal.active);
  CHECK(one.nodal.f == two.nodal.f);
  CHECK(one.nodal.v == two.nodal.v);
  CHECK(one.nodal.dx == two.nodal.dx);
  CHECK(one.nodal.reaction == two.nodal.reaction);
}

} // namespace

// Every stage runs threaded: the basis table, the gather over node columns
// (mass, momentum, forces), the particle updates, and the blocked sums of
// energy and momentum. Each variant exercises another path.
TEST_CASE("engine results are bitwise identical with 1 and 2 threads") {
  // npc (the scene's integrator) runs its stress update inside the force
  // scatter, in ul mode on moving nodes; unified runs the consistent mass.
  const std::vector<std::vector<std::string>> variants{
      {"basis.kind=\"lme\""},
      {"basis.kind=\"lme\"", "simulation.mode=\"ul\""},
      {"basis.kind=\"linear\"", "simulation.integrator=\"fe\""},
      {"basis.kind=\"linear\"", "simulation.integrator=\"musl\""},
      {"basis.kind=\"bspline2\"", "simulation.mode=\"ul\"", "simulation.integrator=\"unified\""},
      {"basis.kind=\"linear\"", "simulation.mode=\"ul\"", "simulation.integrator=\"otm\""},
      {"basis.kind=\"bspline2\"", "simulation.integrator=\"central_difference\""},
      {"basis.kind=\"lme\"", "simulation.integrator=\"explicit_alpha\""},
  };
  for (const auto& sets : variants) {
    CAPTURE(sets.front());
    CAPTURE(sets.back());
    const Result one = run_with_threads(1, sets);
    const Result two = run_with_threads(2, sets);
    REQUIRE(one.particles.size() == 25600); // several scatter blocks (scatter_block = 8192)
    check_same(one, two);
  }
}

TEST_CASE("engine results are bitwise identical with 1 and 2 threads when particles are not spatially ordered") {
  // fe, and npc, whose stress update runs inside the sparse blocked scatter
  // and, on the wide grid, before the column gather
  for (const char* integrator : {"\"fe\"", "\"npc\""})
    for (const bool wide : {false, true}) {
      CAPTURE(integrator);
      CAPTURE(wide);
      std::vector<std::string> sets{"basis.kind=\"linear\"", std::string("simulation.integrator=") + integrator};
      if (wide) sets.insert(sets.end(), wide_grid.begin(), wide_grid.end());
      check_same(run_with_threads(1, sets, true, !wide), run_with_threads(2, sets, true, !wide));
    }
}

// The plane-strain j2 update runs two particles per vector register; a
// particle must get the same bits whichever thread's chunk it falls in.
TEST_CASE("j2 plastic flow: bitwise identical with 1 and 2 threads, plastic state included") {
  const std::vector<std::string> sets{"basis.kind=\"linear\"", "simulation.integrator=\"fe\"",
                                      "material.soil.model=\"j2\"", "material.soil.poisson=0.3",
                                      "material.soil.yield_stress=1e3", "material.soil.hardening_modulus=1e4",
                                      "body.block.velocity=[0.5, -1.0]"};
  const Result one = run_with_threads(1, sets);
  const Result two = run_with_threads(2, sets);
  check_same(one, two);
  const StateField* a = one.particles.find_state("plastic_strain");
  const StateField* b = two.particles.find_state("plastic_strain");
  REQUIRE(a != nullptr);
  REQUIRE(b != nullptr);
  CHECK(a->values == b->values);
  const long yielded = std::count_if(a->values.begin(), a->values.end(), [](double v) { return v > 0.0; });
  CHECK(yielded > 300); // the block moving onto its fixed base yields in the rows next to it (640 particles)
  const StateField* be1 = one.particles.find_state("elastic_left_cauchy_green");
  const StateField* be2 = two.particles.find_state("elastic_left_cauchy_green");
  CHECK(be1->values == be2->values);
}

// mu_i: the flowing state (I, mu) and the stress-free grains below the
// critical packing are per particle; the block, cohesionless, collapses.
TEST_CASE("mu_i granular flow: bitwise identical with 1 and 2 threads, flowing state included") {
  const std::vector<std::string> sets{"basis.kind=\"linear\"", "material.soil.model=\"mu_i\"",
                                      "material.soil.poisson=0.3", "material.soil.mu_s=0.6",
                                      "material.soil.mu_2=0.86", "material.soil.I_0=0.28",
                                      "material.soil.grain_diameter=5e-4", "material.soil.grain_density=10000.0",
                                      "material.soil.critical_packing=0.55", "body.block.velocity=[0.5, -1.0]"};
  const Result one = run_with_threads(1, sets);
  const Result two = run_with_threads(2, sets);
  check_same(one, two);
  for (const char* name : {"inertial_number", "friction", "elastic_left_cauchy_green", "plastic_work"}) {
    CAPTURE(name);
    CHECK(one.particles.find_state(name)->values == two.particles.find_state(name)->values);
  }
  const std::vector<double>& I = one.particles.find_state("inertial_number")->values;
  // In flow after 5 steps: the rows the block's velocity drives into its
  // fixed base (64 particles measured).
  CHECK(std::count_if(I.begin(), I.end(), [](double v) { return v > 0.0; }) > 30);
}

// The PIC relaxation sums the kinetic energy it removes in fixed blocks.
TEST_CASE("PIC relaxation: bitwise identical with 1 and 2 threads, its booked energy included") {
  const std::vector<std::string> sets{"simulation.pic_relaxation_time=0.01", "body.block.velocity=[0.5, -1.0]"};
  const Result one = run_with_threads(1, sets);
  const Result two = run_with_threads(2, sets);
  check_same(one, two);
  CHECK(one.energy.relaxation == two.energy.relaxation);
  CHECK(one.energy.relaxation > 0.0);
}

// molinos Algorithm 1 stages 4-5 in one pass (update_stress_and_to_nodes, what
// step_npc runs) against update_stress followed by compute_forces, from the
// same state: with the dense and the sparse blocked scatter (spatial and
// shuffled order) and with the column gather (linear, shuffled, wide grid).
// On one thread each scatter block updates its particles before it sums
// them; on two, the block's 4 scatter blocks are too few for two threads
// (few_scatter_blocks) and the updates run first, in shared chunks.
TEST_CASE("npc: the stress update inside the force scatter gives the bits of the two separate stages") {
  for (const int threads : {1, 2}) {
    for (const char* basis : {"\"linear\"", "\"lme\""})
      for (const int order : {0, 1, 2}) { // spatial, shuffled, shuffled on the wide grid
        const bool shuffled = order > 0, wide = order == 2;
        if (wide && std::string(basis) != "\"linear\"") continue;
        CAPTURE(threads);
        CAPTURE(basis);
        CAPTURE(order);
        const ScopedThreads scope(threads);
        CHECK(few_scatter_blocks(25600) == (threads == 2));
        std::vector<std::string> sets{std::string("basis.kind=") + basis};
        if (wide) sets.insert(sets.end(), wide_grid.begin(), wide_grid.end());
        const Scene scene = andersen_block(sets);
        Engine<2> fused = assemble<2>(scene), separate = assemble<2>(scene);
        if (shuffled) shuffle_particles(fused.particles()), shuffle_particles(separate.particles());
        fused.step(); // a stressed state, the same in both
        separate.step();
        const AlignedVector<Vec<2>> v = fused.nodal().v;
        const double dt = fused.last_dt(), t = fused.time();
        fused.update_stress_and_to_nodes({&v, dt}, {.forces = true, .t = t});
        separate.update_stress({&v, dt});
        separate.to_nodes({.forces = true, .t = t});
        CHECK(fused.scatter_blocked() == !wide);
        const Particles<2>& a = fused.particles();
        const Particles<2>& b = separate.particles();
        bool same = true;
        for (int p = 0; p < a.size(); ++p)
          same = same && a.sigma[p] == b.sigma[p] && a.eps[p] == b.eps[p] && a.V[p] == b.V[p] && a.rho[p] == b.rho[p];
        CHECK(same);
        CHECK(fused.nodal().f == separate.nodal().f);
      }
  }
}

// The 3D block in the seeded particle order with 3 x 3 x 3 particles per cell
// (20^3 cells, 216 000 particles): a scatter block of 8 192 particles is
// three quarters of a cell layer, and the blocks' node ranges overlap (more
// than max_block_overlap times the nodes: the column gather before the
// sparse path and the relaxed dense limit); the particle-to-node pass takes
// the dense blocked path (tests/test_scatter.cpp checks both blocked paths
// on such tables). The step gives the same bits on 1 and 2 threads.
TEST_CASE("3D block with overlapping scatter blocks: bitwise identical with 1 and 2 threads") {
  const std::string toml = R"(
[simulation]
dimension = 3
integrator = "fe"
t_end = 1.0
cfl = 0.3
[basis]
kind = "linear"
[grid]
lower = [-0.1, -0.1, 0.0]
upper = [1.1, 1.1, 1.05]
cells = [24, 24, 21]
[[material]]
name = "m"
model = "linear_elastic"
density = 1000.0
young = 1.0e7
poisson = 0.3
[[body]]
name = "block"
material = "m"
lower = [0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0]
particles_per_cell = 3
[[boundary]]
name = "base"
lower = [-0.1, -0.1, 0.0]
upper = [1.1, 1.1, 0.0]
fix = [true, true, true]
[body_force]
value = [0.0, 0.0, -9.81]
)";
  const Scene scene = parse_scene(toml, "block3d.toml");
  auto run = [&](int threads) {
    const ScopedThreads scope(threads);
    Engine<3> e = assemble<3>(scene);
    for (int s = 0; s < 2; ++s) e.step();
    return e;
  };
  const Engine<3> one = run(1), two = run(2);
  REQUIRE(one.particles().size() == 216000);
  CHECK(one.scatter_blocked());
  const BasisTable<3>& table = one.table();
  const int nodes = static_cast<int>(one.nodal().m.size());
  long long ranges = 0; // the blocks' node ranges overlap
  for (int p0 = 0; p0 < table.rows(); p0 += scatter_block) {
    const int e0 = table.begin(p0), e1 = table.end(std::min(table.rows(), p0 + scatter_block) - 1);
    const auto [lo, hi] = std::minmax_element(table.node.begin() + e0, table.node.begin() + e1);
    ranges += *hi - *lo + 1;
  }
  CHECK(ranges > static_cast<long long>(max_block_overlap) * nodes);
  ParticleToNodes<3> probe; // the plan the engine made on this table
  probe.run(
      table, nodes, [](int, int) {}, [](int) { return 0; }, [](NodeSums<3>&, double, const Vec<3>&, int) {},
      [](int, const NodeSums<3>&) {}, [](int, int) {});
  CHECK(probe.path() == ScatterPath::dense);
  const Particles<3>& a = one.particles();
  const Particles<3>& b = two.particles();
  bool same = true;
  for (int p = 0; p < a.size(); ++p)
    same = same && a.x[p] == b.x[p] && a.v[p] == b.v[p] && a.sigma[p] == b.sigma[p] && a.V[p] == b.V[p];
  CHECK(same);
  CHECK(one.nodal().m == two.nodal().m);
  CHECK(one.nodal().f == two.nodal().f);
  CHECK(one.nodal().v == two.nodal().v);
  CHECK(one.energy().strain == two.energy().strain);
  CHECK(one.energy().kinetic == two.energy().kinetic);
}

// On a fixed grid the nodal loops visit only the nodes of the basis table's
// rows (and the constrained ones) while fewer than half the nodes are active;
// every other node keeps zero fields. A block sliding across cells (nodes
// leave and join the list every step) gives the same bits on a tight grid,
// where its nodes are most of the grid and the loops visit every node, and
// on a wide grid of the same lines, where they visit the list.
TEST_CASE("a body on a wide grid gives the bits of a tight grid: the nodal loops visit only its nodes") {
  auto run = [](const std::vector<std::string>& grid) {
    std::vector<std::string> sets{"body.block.velocity=[100.0, 0.0]"};
    sets.insert(sets.end(), grid.begin(), grid.end());
    Engine<2> e = assemble<2>(andersen_block(sets));
    for (int s = 0; s < 10; ++s) e.step();
    return e;
  };
  const Engine<2> tight = run({"grid.lower=[-1.0, 0.0]", "grid.upper=[12.0, 11.0]", "grid.cells=[104, 88]"});
  const Engine<2> wide = run(wide_grid);
  const NodalFields<2>& n = wide.nodal();
  const auto nodes = n.m.size();
  CHECK(tight.nodal().visited.size() == tight.nodal().m.size()); // every node
  REQUIRE(2 * n.visited.size() < nodes);                           // a list
  CHECK(wide.particles().x[0][0] - wide.particles().X[0][0] > 0.1); // about a cell (h = 0.125 m)
  // the list holds every node of the table's rows; the others hold zero
  std::vector<char> listed(nodes, 0);
  for (const int I : n.visited) listed[static_cast<std::size_t>(I)] = 1;
  CHECK(std::all_of(wide.table().node.begin(), wide.table().node.end(),
                    [&](int I) { return listed[static_cast<std::size_t>(I)] == 1; }));
  bool zero = true;
  for (std::size_t I = 0; I < nodes; ++I)
    if (!listed[I])
      zero = zero && n.m[I] == 0.0 && n.q[I].isZero(0) && n.v[I].isZero(0) && n.f[I].isZero(0) &&
             n.a[I].isZero(0) && n.dx[I].isZero(0) && !n.active[I];
  CHECK(zero);
  // the particles and the energies have the same bits
  check_same_particles(tight.particles(), wide.particles());
  CHECK(tight.energy().kinetic == wide.energy().kinetic);
  CHECK(tight.energy().strain == wide.energy().strain);
  CHECK(tight.energy().external_work == wide.energy().external_work);
  CHECK(tight.momentum() == wide.momentum());
}
