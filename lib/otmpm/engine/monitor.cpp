/// \file monitor.cpp
/// What the engine watches after every step (engine.hpp): the particle
/// checks (finite state, on the fixed grid inside it and not about to leave
/// it), the energies of the balance and of the runaway monitor, the wave
/// speed of the next CFL step and the momentum - one pass over the particles.
#include "otmpm/engine/engine.hpp"

#include "otmpm/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>

namespace otmpm {

namespace {

/// Floor of the energy reference of the runaway monitor (J), so that a body
/// at rest with no load never trips it.
constexpr double energy_floor = 1e-300;

/// Particles per sub-block of the after-step pass: the kinematic sums and
/// checks, then the materials' energies over the same particles while they
/// are in the L1 cache (a second sweep over a whole reduction block of
/// stresses and strains missed it: about 4% of a linear block step).
constexpr int monitor_sub_block = 64;

/// The sum of d_i - d_i over the n doubles d: 0 exactly when every one is
/// finite (inf - inf and NaN - NaN are NaN, which the later sums keep), in
/// eight lanes that the compiler turns into vector adds.
double finite_residue(const double* d, long long n) {
  constexpr int lanes = 8;
  double lane[lanes] = {};
  long long i = 0;
  for (; i + lanes <= n; i += lanes)
    for (int k = 0; k < lanes; ++k) lane[k] += d[i + k] - d[i + k];
  for (; i < n; ++i) lane[0] += d[i] - d[i];
  double z = 0.0;
  for (const double l : lane) z += l;
  return z;
}

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
  Vec<D> m = blocked_reduce<VecSum<D>>(P_.size(), [&](long long p, VecSum<D>& s) { s.v += P_.m[p] * P_.v[p]; }).v;
  if (settings_.two_phase) m += settings_.two_phase->momentum(P_);
  if (dist_) dist_->sum({m.data(), D});
  return m;
}

template <int D> void Engine<D>::update_energy() { sum_particles(false); }

template <int D> bool Engine<D>::particle_ok(int p) const { return particles_ok(p, p + 1); }

template <int D> bool Engine<D>::particles_ok(int p0, int p1) const {
  if (p1 <= p0) return true;
  // 0 when every value of every particle is finite: the arrays of x, v and
  // sigma over [p0, p1) read as plain doubles.
  const auto residue = [&](const auto& a) {
    constexpr int width = static_cast<int>(sizeof(a[0]) / sizeof(double));
    return finite_residue(a[static_cast<std::size_t>(p0)].data(), static_cast<long long>(p1 - p0) * width);
  };
  bool ok = residue(P_.x) + residue(P_.v) + residue(P_.sigma) == 0.0;
  ok &= mode_.keep_inside(P_.x.data(), P_.v.data(), p0, p1, dt_);
  return ok;
}

template <int D> bool Engine<D>::kinematic_sums(int p0, int p1, bool check, ParticleSums<D>& acc) const {
  if (const PositionBox<D>* stay = dist_ ? dist_->staying() : nullptr)
    for (int p = p0; p < p1; ++p) acc.outside |= !stay->contains(P_.x[p]);
  const bool ok = !check || particles_ok(p0, p1);
  // The sums in locals (acc is memory the particle arrays might alias, as
  // far as the compiler knows), in particle order.
  const Vec<D>* v = P_.v.data();
  const double* m = P_.m.data();
  double kinetic = acc.kinetic, wave_speed2 = acc.wave_speed2;
  Vec<D> momentum = acc.momentum;
  for (int p = p0; p < p1; ++p) {
    const double v2 = v[p].squaredNorm();
    kinetic += 0.5 * m[p] * v2;
    momentum += m[p] * v[p];
    wave_speed2 = std::max(wave_speed2, v2);
  }
  acc.kinetic = kinetic, acc.wave_speed2 = wave_speed2, acc.momentum = momentum;
  return ok;
}

template <int D> void Engine<D>::material_sums(int p0, int p1, ParticleSums<D>& acc) const {
  for (int r0 = p0; r0 < p1;) { // runs of one material
    const int id = P_.material[r0];
    int r1 = r0 + 1;
    while (r1 < p1 && P_.material[r1] == id) ++r1;
    const Material<D>& material = *materials_[static_cast<std::size_t>(id)];
    material.add_energies(P_, r0, r1, acc.strain, acc.dissipated);
    material.max_wave_speed2(P_, r0, r1, acc.wave_speed2); // the model's own c_p
    r0 = r1;
  }
}

template <int D> void Engine<D>::to_particles_and_sum(const ToParticles<D>& what, const Gradient<D>& g) {
  std::vector<ParticleSums<D>>& partial = step_sums_.partial;
  partial.assign(static_cast<std::size_t>(reduction_blocks(P_.size())), {});
  parallel_blocks(P_.size(), [&](long long b, long long b0, long long b1) {
    ParticleSums<D>& acc = partial[static_cast<std::size_t>(b)];
    // The sums' sub-blocks of sum_particles, each right after its update.
    for (int s0 = static_cast<int>(b0); s0 < b1; s0 += monitor_sub_block) {
      const int s1 = static_cast<int>(std::min<long long>(b1, s0 + monitor_sub_block));
      to_particles_on(what, g, s0, s1);
      if (acc.unchecked) continue; // the sweep after the step takes this step's sums
      try {
        acc.unchecked = !kinematic_sums(s0, s1, true, acc);
        if (!acc.unchecked) material_sums(s0, s1, acc);
      } catch (const InstabilityError&) { // a model that cannot price a failed particle: the sweep names it
        acc.unchecked = true;
      }
    }
  });
  step_sums_.ready = true;
}

template <int D> void Engine<D>::sum_particles(bool check) {
  // Checks in particle order within each block: the lowest failing particle
  // is reported, as a serial loop would. A rank of a distributed run notes
  // a failure and looks for its lowest global id afterwards (agree_checks).
  std::atomic<bool> failed{false};
  const auto sums = [&](long long b0, long long b1, ParticleSums<D>& acc) {
    // Sub-blocks small enough that the material's energy pass finds the
    // particles still in the L1 cache; the sums keep particle order.
    for (int s0 = static_cast<int>(b0); s0 < b1; s0 += monitor_sub_block) {
      const int s1 = static_cast<int>(std::min<long long>(b1, s0 + monitor_sub_block));
      const bool ok = kinematic_sums(s0, s1, check, acc);
      for (int p = s0; !ok && p < s1; ++p) {
        if (particle_ok(p)) continue;
        if (!dist_)
          check_particle(p);
        else
          try {
            check_particle(p);
          } catch (const InstabilityError&) {
            failed.store(true, std::memory_order_relaxed);
          }
      }
      material_sums(s0, s1, acc);
    }
  };
  // The step's last pass took the blocks' sums (ToParticles::last) unless a particle failed there.
  const bool taken = check && step_sums_.ready;
  step_sums_.ready = false;
  ParticleSums<D> s = taken ? total_in_order(step_sums_.partial) : ParticleSums<D>{};
  if (!taken || s.unchecked) try {
      s = {};
      s = blocked_reduce_ranges<ParticleSums<D>>(P_.size(), sums);
    } catch (const InstabilityError& e) {
      // A model that cannot price a failed particle (det F <= 0): a rank of a
      // distributed run defers it and meets the others in the reduction below,
      // where every rank stops on the lowest failure.
      if (!dist_) throw;
      LocalFailure failure;
      failure.deferred = true;
      failure.message = e.what();
      dist_->defer(failure);
    }
  TwoPhase<D>* phase = settings_.two_phase.get(); // the liquid of saturated bodies
  LiquidTotals<D> liquid;
  if (phase) {
    liquid = phase->totals(*this);
    if (check && liquid.bad >= 0) {
      if (!dist_) unstable(liquid.bad, "pore pressure or liquid velocity is not finite");
      LocalFailure failure; // every rank stops on the lowest failure in the reduction below
      failure.key = particle_id(liquid.bad);
      try {
        unstable(liquid.bad, "pore pressure or liquid velocity is not finite");
      } catch (const InstabilityError& e) {
        failure.message = e.what();
      }
      dist_->defer(failure);
    }
    s.kinetic += liquid.kinetic, s.strain += liquid.stored, s.momentum += liquid.momentum;
    // (a distributed run: the bound of the serial run's groups of particles, reduced below)
    if (!dist_) s.wave_speed2 = std::max(s.wave_speed2, liquid.wave_speed2);
  }
  if (dist_) {
    // One reduction per step: energies, momentum, this step's reaction
    // impulse and work and the friction loss, the prescribed kinetic energy; the wave speed,
    // whether any rank's checks failed (a deferred failure throws in it) and
    // whether any particle may leave its rank before the next step.
    // The walls' impulses of this step follow.
    AlignedVector<Vec<D>>& wall = constraints_.rank_wall_impulse();
    constexpr std::size_t W0 = 7 + 2 * D; // the walls' impulses start here
    std::vector<double> sums(W0 + wall.size() * D + 2); // last: the liquid's W_a of the step, before it W_v
    sums[0] = s.kinetic, sums[1] = s.strain, sums[2] = s.dissipated, sums[3] = rank_reaction_.work;
    sums[4] = constraints_.prescribed_kinetic_energy(nodal_.m);
    sums[5] = rank_reaction_.friction, sums[6] = rank_reaction_.impact;
    for (int k = 0; k < D; ++k) sums[7 + k] = s.momentum[k], sums[7 + D + k] = rank_reaction_.impulse[k];
    for (std::size_t w = 0; w < wall.size(); ++w)
      for (int k = 0; k < D; ++k) sums[W0 + w * D + static_cast<std::size_t>(k)] = wall[w][k];
    std::vector<double> maxima{s.wave_speed2, failed.load() ? 1.0 : 0.0, s.outside ? 1.0 : 0.0};
    if (phase) { // the liquid's fast-wave bound (eq. 15.7) follows
      const std::vector<double> wave = phase->wave_maxima(*this);
      maxima.insert(maxima.end(), wave.begin(), wave.end());
    }
    sums[sums.size() - 2] = rank_reaction_.relaxation;
    sums.back() = liquid.averaged;
    dist_->reduce(sums, maxima);
    if (phase) {
      phase->add_pressure_average(sums.back());
      maxima[0] = std::max(maxima[0], phase->wave_speed2(std::span<const double>(maxima).subspan(3)));
    }
    if (maxima[1] > 0.0) agree_checks(failed.load());
    dist_->departures(maxima[2] > 0.0);
    s.kinetic = sums[0], s.strain = sums[1], s.dissipated = sums[2], s.wave_speed2 = maxima[0];
    energy_.reaction_work += sums[3];
    boundary_kinetic_ = sums[4];
    energy_.friction += sums[5];
    energy_.impact += sums[6];
    energy_.relaxation += sums[sums.size() - 2];
    for (int k = 0; k < D; ++k) s.momentum[k] = sums[7 + k], reaction_impulse_[k] += sums[7 + D + k];
    for (std::size_t w = 0; w < wall.size(); ++w) {
      for (int k = 0; k < D; ++k) constraints_.wall_impulse()[w][k] += sums[W0 + w * D + static_cast<std::size_t>(k)];
      wall[w] = Vec<D>::Zero();
    }
    rank_reaction_ = {};
  }
  if (phase) energy_.darcy = phase->darcy(), energy_.pressure_average = phase->pressure_average();
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

template <int D> void Engine<D>::agree_checks(bool failed) const {
  LocalFailure first;
  for (int p = 0; failed && p < P_.size(); ++p) {
    try {
      check_particle(p);
    } catch (const InstabilityError& e) {
      if (particle_id(p) < first.key) first = {particle_id(p), e.what(), true};
    }
  }
  dist_->agree(failed ? &first : nullptr);
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
  const double boundary_kinetic = dist_ ? boundary_kinetic_ : constraints_.prescribed_kinetic_energy(nodal_.m);
  // The tractions' work over motions below the positions' rounding is not booked (Loads::unresolved_work).
  const double reference = std::max(energy_.initial + std::abs(energy_.external_work) +
                                        std::abs(energy_.reaction_work) + boundary_kinetic + unresolved_work_,
                                    energy_floor);
  // The energy the materials, friction and impacts took counts: E + W_s
  // cannot exceed what the body was given, so a spurious jump shows in a
  // plastic run too.
  const double total = energy_.total() + energy_.spent();
  if (total > settings_.energy_limit * reference)
    unstable(std::string("runaway energy: kinetic + strain") + (energy_.spent() > 0 ? " + dissipated" : "") +
             " = " + format_number(total) + " J exceeds " +
             format_number(settings_.energy_limit) +
             " x (initial energy + |external work| + |reaction work| + boundary kinetic energy) = " +
             format_number(reference) + " J");
}

#define OTMPM_INSTANTIATE(D)                                                                                 \
  template Vec<D> Engine<D>::momentum() const;                                                               \
  template void Engine<D>::update_energy();                                                                  \
  template void Engine<D>::sum_particles(bool);                                                              \
  template void Engine<D>::to_particles_and_sum(const ToParticles<D>&, const Gradient<D>&);                  \
  template bool Engine<D>::kinematic_sums(int, int, bool, ParticleSums<D>&) const;                           \
  template void Engine<D>::material_sums(int, int, ParticleSums<D>&) const;                                  \
  template bool Engine<D>::particle_ok(int) const;                                                           \
  template bool Engine<D>::particles_ok(int, int) const;                                                     \
  template void Engine<D>::check_particle(int) const;                                                        \
  template void Engine<D>::check_particles_inside() const;                                                   \
  template void Engine<D>::agree_checks(bool) const;                                                         \
  template void Engine<D>::check_energy() const;
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm
