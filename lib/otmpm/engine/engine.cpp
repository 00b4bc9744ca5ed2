/// \file engine.cpp
/// The engine's construction, its step and the stages the integrators drive
/// (engine.hpp); the after-step checks and energies are in monitor.cpp, the
/// checkpoint state in engine_state.cpp.
#include "otmpm/engine/engine.hpp"

#include "otmpm/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace otmpm {

namespace {

/// Particles whose velocity gradient is gathered before their materials
/// update them (a batch on the stack, one virtual call per run of a material).
constexpr int kStressBatch = 64;

/// Gradient of a nodal field at particle p: sum_I y_I (x) grad N_Ip.
template <int D>
Mat<D> nodal_gradient(const BasisTable<D>& table, int p, const AlignedVector<Vec<D>>& y) {
  Mat<D> G = Mat<D>::Zero();
  for (int e = table.begin(p); e < table.end(p); ++e) G.noalias() += y[table.node[e]] * table.dN[e].transpose();
  return G;
}

/// The maximum of a blocked_reduce (exact, so any grouping gives its bits).
struct MaxOf {
  double value = -std::numeric_limits<double>::infinity();
  MaxOf& operator+=(const MaxOf& o) {
    value = std::max(value, o.value);
    return *this;
  }
};

} // namespace

template <int D> void NodalFields<D>::resize(int n) {
  m.assign(n, 0.0);
  q.assign(n, Vec<D>::Zero());
  v = f = a = dx = reaction = q;
  active.assign(n, 0);
}

template <int D>
Engine<D>::Engine(EngineParts<D> parts)
    : basis_(std::move(parts.basis)), mode_(parts.mode), P_(std::move(parts.particles)),
      materials_(std::move(parts.materials)), loads_(std::move(parts.loads)), settings_(parts.settings) {
  check_parts();
  const int nodes = basis_->nodes().size();
  constraints_ = Constraints<D>(std::move(parts.dirichlet), std::move(parts.walls), nodes);
  bool needs_F = false;
  for (const auto& m : materials_) {
    needs_F = needs_F || m->needs_deformation_gradient();
    p_modulus_.push_back(m->p_modulus());
  }
  if (needs_F && P_.F.empty()) P_.F.assign(static_cast<std::size_t>(P_.size()), Mat<D>::Identity());
  for (const auto& m : materials_) m->bind(P_);
  basis_->bind_points(P_.size(), mode_.nodes_move());
  nodal_.resize(nodes);
  node_spacing0_ = basis_->nodes().min_spacing();
  if (settings_.consistent_mass) mass_matrix_ = std::make_unique<MassMatrix<D>>();
  sum_particles(true); // initial checks, energy and wave speed
  energy_.initial = energy_.total();
  external_power_ = loads_.power(0.0, P_, momentum_);
}

template <int D> Engine<D>::Engine(Engine&&) noexcept = default;
template <int D> Engine<D>::~Engine() = default;

template <int D> void Engine<D>::check_parts() const {
  using E = std::invalid_argument;
  require<E>(basis_ != nullptr, "Engine: no basis");
  require<E>(settings_.step != nullptr, "Engine: no step function (StepSettings::step)");
  require<E>(finite_positive(settings_.t_end), "Engine: t_end = ", settings_.t_end, " must be finite and > 0");
  require<E>(finite_positive(settings_.h), "Engine: h = ", settings_.h, " must be finite and > 0");
  require<E>(settings_.dt ? finite_positive(*settings_.dt) : finite_positive(settings_.cfl), "Engine: the time step (",
             settings_.dt ? "dt" : "cfl", ") must be finite and > 0");
  require<E>(P_.size() > 0, "Engine: no particles");
  const std::size_t n = static_cast<std::size_t>(P_.size());
  const bool sized = P_.X.size() == n && P_.v.size() == n && P_.m.size() == n && P_.V.size() == n &&
                     P_.V0.size() == n && P_.rho.size() == n && P_.eps.size() == n && P_.sigma.size() == n &&
                     P_.material.size() == n && P_.body.size() == n;
  require<E>(sized, "Engine: the particle fields do not all have ", n, " entries (Particles::resize)");
  for (int p = 0; p < P_.size(); ++p)
    require<E>(P_.material[p] >= 0 && P_.material[p] < static_cast<int>(materials_.size()) &&
                   materials_[static_cast<std::size_t>(P_.material[p])],
               "Engine: particle ", p, " has material ", P_.material[p], " but there are ", materials_.size(),
               " materials");
  loads_.check(P_.size());
}

template <int D> double Engine<D>::stable_dt() const {
  double dt;
  if (settings_.dt) {
    dt = *settings_.dt;
  } else {
    const double c = wave_speed_; // max_p max(c_p, |v_p|), from the last sum_particles()
    dt = settings_.cfl * mode_.cfl_spacing(*basis_, settings_.h, node_spacing0_) / c;
  }
  return std::min(dt, settings_.t_end - t_);
}

template <int D> void Engine<D>::step() {
  dt_ = stable_dt();
  if (!(dt_ > 0.0) || !std::isfinite(dt_))
    unstable("time step " + format_number(dt_) + " is not positive and finite");
  if (dt_prev_ == 0.0) dt_prev_ = dt_;
  try {
    settings_.step(*this, {t_, dt_, dt_prev_, step_, settings_.parameters, P_, nodal_});
  } catch (const ParticleFailure& f) {
    unstable(f.particle, f.what);
  }
  t_ += dt_;
  ++step_;
  dt_prev_ = dt_;
  sum_particles(true); // checks, energies, wave speed
  // Trapezoidal rule: exact for a constant load on a uniformly accelerating
  // body, where the one-sided rule would leave an O(dt) error in the balance.
  const double power = loads_.power(t_, P_, momentum_);
  energy_.external_work += 0.5 * dt_ * (external_power_ + power);
  external_power_ = power;
  check_energy();
}

template <int D> void Engine<D>::evaluate_basis() {
  ScopedPhase timer(timers_, Phase::basis);
  try {
    basis_->evaluate_points(P_.x, table_);
    scatter_.invalidate();
  } catch (const BasisError& e) {
    unstable(std::string("basis evaluation failed: ") + e.what());
  }
}

template <int D> void Engine<D>::to_nodes(const ToNodes<D>& what) {
  ScopedPhase timer(timers_, Phase::to_nodes);
  if (what.forces && !loads_.uniform() && loads_.any()) loads_.particle_forces(what.t, P_, fext_);
  const bool q = what.w != nullptr;
  if (what.mass && q && what.forces) to_nodes_impl<true, true, true>(what, nullptr);
  else if (what.mass && q) to_nodes_impl<true, true, false>(what, nullptr);
  else if (what.mass && what.forces) to_nodes_impl<true, false, true>(what, nullptr);
  else if (what.mass) to_nodes_impl<true, false, false>(what, nullptr);
  else if (q && what.forces) to_nodes_impl<false, true, true>(what, nullptr);
  else if (q) to_nodes_impl<false, true, false>(what, nullptr);
  else if (what.forces) to_nodes_impl<false, false, true>(what, nullptr);
  if (what.mass) finish_mass();
}

template <int D> void Engine<D>::update_stress_and_to_nodes(const Gradient<D>& g, const ToNodes<D>& what) {
  // Its time counts in the to_nodes phase, as the fe update counts in to_particles.
  ScopedPhase timer(timers_, Phase::to_nodes);
  require<std::invalid_argument>(what.forces && !what.mass && !what.w,
                                 "Engine::update_stress_and_to_nodes: only the forces follow a stress update");
  if (!loads_.uniform() && loads_.any()) loads_.particle_forces(what.t, P_, fext_);
  to_nodes_impl<false, false, true>(what, &g);
}

template <int D>
template <bool Mass, bool Momentum, bool Forces>
void Engine<D>::to_nodes_impl(const ToNodes<D>& what, const Gradient<D>* g) {
  const Vec<D> b = loads_.uniform() ? loads_.body_force_at(what.t) : Vec<D>::Zero();
  const bool field = !fext_.empty() && loads_.any() && !loads_.uniform(), uniform = loads_.uniform();
  struct Payload { // what particle p carries to each of its nodes
    double m;
    Vec<D> mw, fext;
    Mat<D> Vs;
  };
  auto update = [&](int p0, int p1) {
    if (g) update_stress_range(*g, p0, p1);
  };
  auto prep = [&](int p) {
    Payload w{};
    w.m = P_.m[p];
    if (Momentum) {
      w.mw = P_.m[p] * (*what.w)[p];
      if (what.a) w.mw += (P_.m[p] * what.c) * (*what.a)[p];
    }
    if (Forces) {
      w.Vs = P_.V[p] * P_.sigma[p];
      w.fext = uniform ? Vec<D>(P_.m[p] * b) : field ? fext_[p] : Vec<D>::Zero();
    }
    return w;
  };
  auto add = [&](NodeSums<D>& acc, int e, const Payload& w) {
    const double N = table_.N[e];
    if (Mass) acc.m += N * w.m;
    if (Momentum) acc.q += N * w.mw;
    if (Forces) {
      acc.f -= w.Vs * table_.dN[e];
      acc.f += N * w.fext;
    }
  };
  auto merge = [&](int I, const NodeSums<D>& acc) {
    if (Mass) nodal_.m[I] += acc.m;
    if (Momentum) nodal_.q[I] += acc.q;
    if (Forces) nodal_.f[I] += acc.f;
  };
  auto clear = [&](int I0, int I1) {
    if (Mass) std::fill(nodal_.m.begin() + I0, nodal_.m.begin() + I1, 0.0);
    if (Momentum) std::fill(nodal_.q.begin() + I0, nodal_.q.begin() + I1, Vec<D>::Zero());
    if (Forces) std::fill(nodal_.f.begin() + I0, nodal_.f.begin() + I1, Vec<D>::Zero());
  };
  scatter_.run(table_, static_cast<int>(nodal_.m.size()), update, prep, add, merge, clear);
}

template <int D> void Engine<D>::finish_mass() {
  const int nodes = static_cast<int>(nodal_.m.size());
  // The largest nodal mass: a maximum, exact in any grouping.
  const double m_max = blocked_reduce<MaxOf>(nodes, [&](long long I, MaxOf& acc) {
    acc.value = std::max(acc.value, nodal_.m[I]);
  }).value;
  const double m_min = settings_.mass_tolerance * m_max;
  parallel_for(nodes, [&](long long I) { nodal_.active[I] = nodal_.m[I] > m_min; });
  if (mass_matrix_) mass_matrix_->assemble(table_, P_.m, nodal_.active, constraints_.constrained(), nodes);
}

template <int D>
void Engine<D>::solve_mass(const AlignedVector<Vec<D>>& r, AlignedVector<Vec<D>>& y) {
  ScopedPhase timer(timers_, Phase::nodal_update);
  const int n = static_cast<int>(r.size());
  y.resize(n);
  const bool lumped = !mass_matrix_;
  parallel_for(n, [&](long long I) { y[I] = lumped && nodal_.active[I] ? Vec<D>(r[I] / nodal_.m[I]) : Vec<D>::Zero(); });
  if (!lumped) mass_matrix_->solve(r, y);
}

template <int D> void Engine<D>::constrain_velocity(AlignedVector<Vec<D>>& v, const WallEffect<D>& effect) {
  constraints_.apply_velocity(v);
  if (constraints_.walls().empty()) return;
  constraints_.apply_walls(v, {basis_->nodes().positions(), nodal_.m, nodal_.active}, t_, dt_, effect,
                           energy_.reaction_work);
}

template <int D> void Engine<D>::constrain_increment(AlignedVector<Vec<D>>& dx) const {
  if (constraints_.walls().empty()) return;
  constraints_.apply_walls_to_increment(dx, {basis_->nodes().positions(), nodal_.m, nodal_.active}, t_, dt_);
}

template <int D> void Engine<D>::apply_dirichlet_force(AlignedVector<Vec<D>>& f) {
  constraints_.apply_force(f, nodal_.reaction, dt_, reaction_impulse_, energy_.reaction_work);
}

template <int D> void Engine<D>::to_particles(const ToParticles<D>& what) {
  to_particles_and_update_stress(what, {});
}

template <int D>
void Engine<D>::to_particles_and_update_stress(const ToParticles<D>& what, const Gradient<D>& g) {
  ScopedPhase timer(timers_, Phase::to_particles);
  parallel_chunks(P_.size(), [&](long long begin, long long end) {
    Mat<D> H[kStressBatch];
    for (int p0 = static_cast<int>(begin); p0 < end; p0 += kStressBatch) {
      const int p1 = std::min(static_cast<int>(end), p0 + kStressBatch);
      for (int p = p0; p < p1; ++p) {
        Vec<D> r = Vec<D>::Zero(), u = Vec<D>::Zero();
        Mat<D> G = Mat<D>::Zero();
        for (int e = table_.begin(p); e < table_.end(p); ++e) {
          const int I = table_.node[e];
          if (what.rate) r += table_.N[e] * (*what.rate)[I];
          if (what.move) u += table_.N[e] * (*what.move)[I];
          if (g.field) G.noalias() += (*g.field)[I] * table_.dN[e].transpose();
        }
        if (what.rate) {
          if (what.rate_out) (*what.rate_out)[p] = r;
          P_.v[p] += what.c_rate * r;
        }
        if (what.move) P_.x[p] += what.c_move * u;
        if (g.field) H[p - p0] = g.c * G;
      }
      if (g.field) update_materials(p0, p1, H);
    }
  });
}

template <int D> void Engine<D>::update_stress(const Gradient<D>& g) {
  ScopedPhase timer(timers_, Phase::constitutive);
  parallel_chunks(P_.size(), [&](long long begin, long long end) {
    update_stress_range(g, static_cast<int>(begin), static_cast<int>(end));
  });
}

template <int D> void Engine<D>::update_stress_range(const Gradient<D>& g, int p0, int p1) {
  Mat<D> H[kStressBatch];
  for (int b0 = p0; b0 < p1; b0 += kStressBatch) {
    const int b1 = std::min(p1, b0 + kStressBatch);
    for (int p = b0; p < b1; ++p) H[p - b0] = g.c * nodal_gradient(table_, p, *g.field);
    update_materials(b0, b1, H);
  }
}

template <int D> void Engine<D>::update_materials(int p0, int p1, const Mat<D>* H) {
  for (int r0 = p0; r0 < p1;) {
    const int id = P_.material[r0];
    int r1 = r0 + 1;
    while (r1 < p1 && P_.material[r1] == id) ++r1;
    materials_[static_cast<std::size_t>(id)]->update(P_, r0, r1, H + (r0 - p0), dt_);
    r0 = r1;
  }
}

template <int D> void Engine<D>::advect_nodes(const AlignedVector<Vec<D>>& dx) {
  if (!mode_.nodes_move()) return;
  ScopedPhase timer(timers_, Phase::nodal_update);
  mode_.advect(*basis_, dx);
}

template <int D> void Engine<D>::unstable(int p, const std::string& what) const {
  unstable("particle " + std::to_string(p) + " at " + format_point<D>(P_.x[p]) + ": " + what);
}

template <int D> void Engine<D>::unstable(const std::string& what) const {
  throw InstabilityError("step " + std::to_string(step_) + ", t = " + format_number(t_) + " s: " + what);
}

template class Engine<1>;
template class Engine<2>;
template class Engine<3>;
template struct NodalFields<1>;
template struct NodalFields<2>;
template struct NodalFields<3>;

} // namespace otmpm
