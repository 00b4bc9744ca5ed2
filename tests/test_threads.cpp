// Results do not depend on the number of OpenMP threads (issue 7): the same
// scene stepped with 1 and with 2 threads gives bitwise identical particles.
#include <doctest/doctest.h>

#include "otmpm/engine/engine.hpp"

#include <algorithm>
#include <numeric>
#include <random>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

using namespace otmpm;

namespace {

/// Steps the andersen block (10 x 10 m at h = 0.125 m: 25600
/// particles, enough for fill_basis_table to split the work) with `threads`.
struct Result {
  Particles<2> particles;
  EnergyBalance energy;
  Vec<2> momentum;
};

/// Reorders every particle field by a fixed random permutation, so that the
/// particle order is no longer spatial (the scatter then gathers by columns).
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
  apply(P.F), apply(P.eps), apply(P.sigma), apply(P.lambda), apply(P.cell_hint), apply(P.length0);
  apply(P.material), apply(P.body);
}

Result run_with_threads(int threads, const std::vector<std::string>& sets, bool shuffled = false) {
#ifdef OTMPM_HAVE_OPENMP
  const int saved = omp_get_max_threads();
  omp_set_num_threads(threads);
#else
  (void)threads;
#endif
  std::vector<std::string> all{"grid.cells=[144, 96]", "output.every=0"};
  all.insert(all.end(), sets.begin(), sets.end());
  const Scene scene = load_scene(OTMPM_SOURCE_DIR "/examples/andersen_block.toml", all);
  Engine<2> e(scene);
  if (shuffled) shuffle_particles(e.particles());
  for (int s = 0; s < 5; ++s) e.step();
  CHECK(e.scatter_blocked() == !shuffled);
#ifdef OTMPM_HAVE_OPENMP
  omp_set_num_threads(saved);
#endif
  return {e.particles(), e.energy(), e.momentum()};
}

} // namespace

// Every stage runs threaded: the basis table, the gather over node columns
// (mass, momentum, forces), the particle updates, and the blocked sums of
// energy and momentum. Each variant exercises another path.
TEST_CASE("engine results are bitwise identical with 1 and 2 threads") {
  const std::vector<std::vector<std::string>> variants{
      {"basis.kind=\"lme\""},
      {"basis.kind=\"linear\"", "simulation.integrator=\"fe\""},
      {"basis.kind=\"linear\"", "simulation.integrator=\"musl\""},
      {"basis.kind=\"bspline2\"", "simulation.mode=\"ul\"", "simulation.integrator=\"unified\""},
      {"basis.kind=\"linear\"", "simulation.mode=\"ul\"", "simulation.integrator=\"otm\""},
  };
  for (const auto& sets : variants) {
    CAPTURE(sets.front());
    CAPTURE(sets.back());
    const Result one = run_with_threads(1, sets);
    const Result two = run_with_threads(2, sets);
    const Particles<2>& a = one.particles;
    const Particles<2>& b = two.particles;
    REQUIRE(a.size() == 25600); // several scatter blocks (scatter_block = 8192)
    REQUIRE(a.size() == b.size());
    bool same = true;
    for (int p = 0; p < a.size(); ++p)
      same = same && a.x[p] == b.x[p] && a.v[p] == b.v[p] && a.sigma[p] == b.sigma[p] && a.V[p] == b.V[p];
    CHECK(same);
    CHECK(one.energy.kinetic == two.energy.kinetic);
    CHECK(one.energy.strain == two.energy.strain);
    CHECK(one.energy.external_work == two.energy.external_work);
    CHECK(one.momentum == two.momentum);
  }
}

TEST_CASE("engine results are bitwise identical with 1 and 2 threads when particles are not spatially ordered") {
  const std::vector<std::string> sets{"basis.kind=\"linear\"", "simulation.integrator=\"fe\""};
  const Result one = run_with_threads(1, sets, true);
  const Result two = run_with_threads(2, sets, true);
  bool same = true;
  for (int p = 0; p < one.particles.size(); ++p)
    same = same && one.particles.x[p] == two.particles.x[p] && one.particles.sigma[p] == two.particles.sigma[p];
  CHECK(same);
  CHECK(one.energy.kinetic == two.energy.kinetic);
}
