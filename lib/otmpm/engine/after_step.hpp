#pragma once
/// \file after_step.hpp
/// What the engine sums over the particles after every step
/// (Engine::sum_particles): per block of reduction_block particles, added
/// in block order - the same bits for any thread count. The blocks' sums are
/// taken either by a sweep of their own after the step or, when the
/// integrator marks its last particle pass (ToParticles::last), in that pass
/// right after each block is updated, while its particles are in the cache.
#include "otmpm/core.hpp"

#include <algorithm>
#include <vector>

namespace otmpm {

/// The after-step sums of a block of particles: kinetic energy sum 1/2 m_p
/// |v_p|^2, stored (strain) and dissipated energy of the materials, the
/// squared signal speed of the CFL step max_p max(c_p^2, |v_p|^2), the
/// momentum sum m_p v_p (in particle order, as Engine::momentum() adds it),
/// whether a particle lies outside the rank's staying() box, and whether a
/// particle failed the checks' fast test in a step's last pass (`unchecked`:
/// the sweep after the step then takes every sum again and names the
/// particle).
template <int D> struct ParticleSums {
  double kinetic = 0.0, strain = 0.0, dissipated = 0.0, wave_speed2 = 0.0;
  bool outside = false, unchecked = false;
  Vec<D> momentum = Vec<D>::Zero();
  ParticleSums& operator+=(const ParticleSums& o) {
    kinetic += o.kinetic;
    strain += o.strain;
    dissipated += o.dissipated;
    wave_speed2 = std::max(wave_speed2, o.wave_speed2);
    outside |= o.outside;
    unchecked |= o.unchecked;
    momentum += o.momentum;
    return *this;
  }
};

/// The blocks' sums of the step's last particle pass (ToParticles::last):
/// `ready` from that pass until Engine::sum_particles takes them.
template <int D> struct StepSums {
  std::vector<ParticleSums<D>> partial;
  bool ready = false;
};

} // namespace otmpm
