/// \file monitor.cpp
/// What the engine watches after every step (engine.hpp): the particle
/// checks (finite state, on the fixed grid inside it and not about to leave
/// it), the energies of the balance and of the runaway monitor, the wave
/// speed of the next CFL step and the momentum - one pass over the particles.
#include "otmpm/engine/engine.hpp"

#include "otmpm/parallel.hpp"

#include <algorithm>
#include <cmath>

namespace otmpm {

namespace {

/// Floor of the energy reference of the runaway monitor (J), so that a body
/// at rest with no load never trips it.
constexpr double energy_floor = 1e-300;

/// Per-block sums of the after-step pass (added block by block; the
/// momentum as momentum() adds it, so it has its bits).
template <int D> struct ParticleSums {
  double kinetic = 0.0, strain = 0.0, dissipated = 0.0, wave_speed2 = 0.0;
  Vec<D> momentum = Vec<D>::Zero();
  ParticleSums& operator+=(const ParticleSums& o) {
    kinetic += o.kinetic;
    strain += o.strain;
    dissipated += o.dissipated;
    wave_speed2 = std::max(wave_speed2, o.wave_speed2);
    momentum += o.momentum;
    return *this;
  }
};

/// A D-vector summed over particles with blocked_reduce.
template <int D> struct VecSum {
  Vec<D> v = Vec<D>::Zero();
  VecSum& operator+=(const VecSum& o) {
    v += o.v;
    return *this;
  }
};

} // namespace

template <int D> Vec<D> Engine<D>::momentum() const {
  return blocked_reduce<VecSum<D>>(P_.size(), [&](long long p, VecSum<D>& s) { s.v += P_.m[p] * P_.v[p]; }).v;
}

template <int D> void Engine<D>::update_energy() { sum_particles(false); }

template <int D> void Engine<D>::sum_particles(bool check) {
  // Checks in particle order within each block: the lowest failing particle
  // is reported, as a serial loop would.
  const auto s = blocked_reduce_ranges<ParticleSums<D>>(P_.size(), [&](long long b0, long long b1, ParticleSums<D>& acc) {
    for (int p = static_cast<int>(b0); p < b1; ++p) {
      if (check) check_particle(p);
      const double v2 = P_.v[p].squaredNorm();
      acc.kinetic += 0.5 * P_.m[p] * v2;
      acc.momentum += P_.m[p] * P_.v[p];
      const double c2 = p_modulus_[static_cast<std::size_t>(P_.material[p])] / P_.rho[p];
      acc.wave_speed2 = std::max({acc.wave_speed2, c2, v2});
    }
    for (int r0 = static_cast<int>(b0); r0 < b1;) { // runs of one material
      const int id = P_.material[r0];
      int r1 = r0 + 1;
      while (r1 < b1 && P_.material[r1] == id) ++r1;
      materials_[static_cast<std::size_t>(id)]->add_energies(P_, r0, r1, acc.strain, acc.dissipated);
      r0 = r1;
    }
  });
  energy_.kinetic = s.kinetic;
  energy_.strain = s.strain;
  energy_.dissipated = s.dissipated;
  wave_speed_ = std::sqrt(s.wave_speed2);
  momentum_ = s.momentum;
}

template <int D> void Engine<D>::check_particle(int p) const {
  if (!P_.x[p].allFinite() || !P_.v[p].allFinite()) unstable(p, "position or velocity is not finite");
  if (!P_.sigma[p].allFinite()) unstable(p, "stress is not finite");
  if (!mode_.keeps_inside(P_.x[p], P_.v[p], dt_)) unstable(p, mode_.leaving(P_.x[p], P_.v[p]));
}

template <int D> void Engine<D>::check_particles_inside() const {
  for (int p = 0; p < P_.size(); ++p) check_particle(p);
}

template <int D> void Engine<D>::check_energy() const {
  // A boundary moving at a prescribed velocity puts energy into a body at rest
  // in the first step, before its reaction (computed from the forces at the
  // start of the step in fe/musl/otm/unified) has done any work: the kinetic
  // energy of the prescribed nodal motion, sum 1/2 m_I v_Ik^2, covers that
  // (zero for fixed supports).
  const double boundary_kinetic = constraints_.prescribed_kinetic_energy(nodal_.m);
  const double reference =
      std::max(energy_.initial + std::abs(energy_.external_work) + std::abs(energy_.reaction_work) + boundary_kinetic,
               energy_floor);
  const double total = energy_.total();
  if (total > settings_.energy_limit * reference)
    unstable("runaway energy: kinetic + strain = " + format_number(total) + " J exceeds " +
             format_number(settings_.energy_limit) +
             " x (initial energy + |external work| + |reaction work| + boundary kinetic energy) = " +
             format_number(reference) + " J");
}

#define OTMPM_INSTANTIATE(D)                                  \
  template Vec<D> Engine<D>::momentum() const;               \
  template void Engine<D>::update_energy();                  \
  template void Engine<D>::sum_particles(bool);              \
  template void Engine<D>::check_particle(int) const;        \
  template void Engine<D>::check_particles_inside() const;   \
  template void Engine<D>::check_energy() const;
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm
