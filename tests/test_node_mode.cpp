// The fixed grid's containment test over a range of particles
// (NodeMode::keep_inside, the after-step pass's fast form) against the
// particle-by-particle test (keeps_inside), in 1D, 2D and 3D.
#include "otmpm/engine/node_mode.hpp"

#include <doctest/doctest.h>

#include <random>

using namespace otmpm;

namespace {

/// 64 particles inside the box [0, 1]^D moving at most 0.1 per step (all
/// keep inside); then, one case per particle index and face, the same with
/// that particle's x on or beyond a face, or its x + dt v beyond it. keep_inside over the
/// range must be true exactly when every particle's keeps_inside is.
template <int D> void check_keep_inside() {
  const NodeMode<D> mode = NodeMode<D>::fixed_grid(Vec<D>::Zero(), Vec<D>::Ones());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> inside(0.2, 0.8), speed(-1.0, 1.0);
  const int n = 64;
  const double dt = 0.1;
  AlignedVector<Vec<D>> x(n), v(n);
  for (int p = 0; p < n; ++p)
    for (int k = 0; k < D; ++k) x[p][k] = inside(rng), v[p][k] = speed(rng);
  const auto all_keep = [&] {
    bool in = true;
    for (int p = 0; p < n; ++p) in &= mode.keeps_inside(x[p], v[p], dt);
    return in;
  };
  REQUIRE(all_keep());
  CHECK(mode.keep_inside(x.data(), v.data(), 0, n, dt));
  CHECK(mode.keep_inside(x.data(), v.data(), 3, 3, dt)); // an empty range
  for (int p = 0; p < n; p += 9)
    for (int k = 0; k < D; ++k)
      for (const double at : {0.0, 1.0, -0.5, 1.5}) {
        CAPTURE(p);
        CAPTURE(k);
        CAPTURE(at);
        const Vec<D> x0 = x[p], v0 = v[p];
        x[p][k] = at; // on a face (outside the open box) or beyond it
        CHECK_FALSE(all_keep());
        CHECK_FALSE(mode.keep_inside(x.data(), v.data(), 0, n, dt));
        CHECK(mode.keep_inside(x.data(), v.data(), p + 1, n, dt)); // the others alone
        x[p] = x0;
        // inside now, beyond the face after dt (by 1e-9: the rounding of x + dt v cannot bring it back)
        v[p][k] = (at + (at < 0.5 ? -1e-9 : 1e-9) - x0[k]) / dt;
        CHECK_FALSE(mode.keeps_inside(x[p], v[p], dt));
        CHECK_FALSE(mode.keep_inside(x.data(), v.data(), 0, n, dt));
        v[p] = v0;
      }
  CHECK(all_keep());
}

} // namespace

TEST_CASE("keep_inside over a range of particles answers as keeps_inside one particle at a time (1D, 2D, 3D)") {
  check_keep_inside<1>();
  check_keep_inside<2>();
  check_keep_inside<3>();
}
