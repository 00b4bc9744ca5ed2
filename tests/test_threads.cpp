// Results do not depend on the number of OpenMP threads (issue 7): the same
// scene stepped with 1 and with 2 threads gives bitwise identical particles.
#include <doctest/doctest.h>

#include "otmpm/engine/engine.hpp"

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

using namespace otmpm;

namespace {

/// Steps the andersen block (LME, NPC; 10 x 10 m at h = 0.25 m: 6400
/// particles, enough for fill_basis_table to split the work) with `threads`.
Particles<2> run_with_threads(int threads, const std::string& basis) {
#ifdef OTMPM_HAVE_OPENMP
  const int saved = omp_get_max_threads();
  omp_set_num_threads(threads);
#else
  (void)threads;
#endif
  const Scene scene = load_scene(OTMPM_SOURCE_DIR "/examples/andersen_block.toml",
                                 {"grid.cells=[72, 48]", "output.every=0", "basis.kind=" + basis});
  Engine<2> e(scene);
  for (int s = 0; s < 5; ++s) e.step();
#ifdef OTMPM_HAVE_OPENMP
  omp_set_num_threads(saved);
#endif
  return e.particles();
}

} // namespace

TEST_CASE("engine results are bitwise identical with 1 and 2 threads") {
  for (const char* basis : {"lme", "linear"}) {
    CAPTURE(basis);
    const Particles<2> one = run_with_threads(1, basis);
    const Particles<2> two = run_with_threads(2, basis);
    REQUIRE(one.size() == 6400);
    REQUIRE(one.size() == two.size());
    bool same = true;
    for (int p = 0; p < one.size(); ++p)
      same = same && one.x[p] == two.x[p] && one.v[p] == two.v[p] && one.sigma[p] == two.sigma[p];
    CHECK(same);
  }
}
