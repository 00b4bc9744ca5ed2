#pragma once
/// \file particles_box.hpp
/// The axis-aligned box of a set of particles' positions (node resets, the
/// extent L of the initial-equilibrium phase's tolerance).
#include "otmpm/particles/particles.hpp"

#include <limits>
#include <utility>

namespace otmpm {

/// The box [lo, hi] of the particles' positions x_p, each widened by
/// half(p) (a Vec<D>) either way; lo = +inf and hi = -inf without particles.
template <int D, class Half> std::pair<Vec<D>, Vec<D>> particles_box(const Particles<D>& P, Half half) {
  Vec<D> lo = Vec<D>::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (int p = 0; p < P.size(); ++p) {
    const Vec<D> w = half(p);
    lo = lo.cwiseMin(P.x[p] - w), hi = hi.cwiseMax(P.x[p] + w);
  }
  return {lo, hi};
}

/// The box of the particles' positions alone (particles_box, not widened).
template <int D> std::pair<Vec<D>, Vec<D>> particles_box(const Particles<D>& P) {
  return particles_box(P, [](int) { return Vec<D>::Zero().eval(); });
}

} // namespace otmpm
