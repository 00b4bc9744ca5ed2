/// \file engine.cpp
/// The engine's construction, its step and the stages the integrators drive
/// (engine.hpp); the after-step checks and energies are in monitor.cpp, the
/// checkpoint state in engine_state.cpp.
#include "otmpm/engine/engine.hpp"
#include "otmpm/engine/scatter.hpp"

#include "otmpm/parallel.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>

namespace otmpm {

namespace {

/// Particles whose velocity gradient is gathered before their materials
/// update them (a batch on the stack, one virtual call per run of a material).
constexpr int kStressBatch = 64;

/// The Dirichlet set repeated on every one of `fields` copies of `nodes` nodes.
template <int D> Dirichlet<D> repeat_per_field(const Dirichlet<D>& d, int nodes, int fields) {
  Dirichlet<D> out;
  for (int b = 0; b < fields; ++b) {
    for (int I : d.node) out.node.push_back(I + b * nodes);
    out.fix.insert(out.fix.end(), d.fix.begin(), d.fix.end());
    out.value.insert(out.value.end(), d.value.begin(), d.value.end());
  }
  return out;
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
      materials_(std::move(parts.materials)), loads_(std::move(parts.loads)), settings_(parts.settings),
      dist_(std::move(parts.distribution)) {
  scatter_ = std::make_unique<ParticleToNodes<D>>();
  check_parts();
  const int nodes = basis_->nodes().size();
  const int bodies = P_.body.empty() ? 1 : 1 + *std::max_element(P_.body.begin(), P_.body.end());
  require<InputError>(!(parts.contact && dist_), "[contact]: body-body contact is not available in distributed "
                                                 "runs (MPI); run the scene on one process");
  if (parts.contact && bodies > 1) {
    using E = std::invalid_argument;
    require<E>(!mode_.nodes_move(), "Engine: body contact needs the fixed grid (mode mpm): in ul mode each body "
                                    "would need its own advected nodes");
    require<E>(!settings_.consistent_mass, "Engine: body contact needs the lumped mass");
    contact_ = std::make_unique<BodyContact<D>>(nodes, bodies, *parts.contact);
    parts.dirichlet = repeat_per_field(parts.dirichlet, nodes, bodies);
    for (int b = 0; b < bodies; ++b)
      field_positions_.insert(field_positions_.end(), basis_->nodes().positions().begin(),
                              basis_->nodes().positions().end());
  }
  const int field_nodes = contact_ ? nodes * contact_->fields() : nodes;
  constraints_ = Constraints<D>(std::move(parts.dirichlet), std::move(parts.walls), field_nodes);
  if (dist_) constraints_.count_only(dist_->owned_nodes());
  bool needs_F = false;
  for (const auto& m : materials_) needs_F = needs_F || m->needs_deformation_gradient();
  needs_F = needs_F || basis_->point_state_use(mode_.nodes_move()).deformation; // basis.metric = "deformation"
  if (needs_F && P_.F.empty()) P_.F.assign(static_cast<std::size_t>(P_.size()), Mat<D>::Identity());
  for (const auto& m : materials_) m->bind(P_);
  basis_->bind_points(P_.size(), mode_.nodes_move());
  nodal_.resize(field_nodes);
  node_spacing0_ = basis_->nodes().min_spacing();
  if (dist_) dist_->min({&node_spacing0_, 1});
  if (settings_.consistent_mass && !dist_) // the band path for the fixed stencils (mass_matrix.hpp)
    mass_matrix_ = std::make_unique<MassMatrix<D>>(basis_->fixed_stencil() > 0);
  sum_particles(true); // initial checks, energy and wave speed
  energy_.initial = energy_.total();
  external_power_ = global_power(0.0, momentum_);
}

template <int D> Engine<D>::Engine(Engine&&) noexcept = default;
template <int D> Engine<D>::~Engine() = default;

template <int D> bool Engine<D>::scatter_blocked() const { return scatter_->blocked(); }

template <int D> void Engine<D>::repartition(std::unique_ptr<Basis<D>> basis, Dirichlet<D> dirichlet) {
  require<std::invalid_argument>(basis && dist_, "Engine::repartition: needs a basis and a distributed run");
  PointState<D> state = std::move(basis_->point_state());
  basis_ = std::move(basis);
  basis_->bind_points(P_.size(), mode_.nodes_move());
  PointState<D>& fresh = basis_->point_state();
  if (fresh.lambda.size() == state.lambda.size()) fresh.lambda = std::move(state.lambda);
  if (fresh.slope.size() == state.slope.size()) fresh.slope = std::move(state.slope);
  if (fresh.history.size() == state.history.size()) fresh.history = std::move(state.history);
  if (fresh.cell_hint.size() == state.cell_hint.size()) fresh.cell_hint = std::move(state.cell_hint);
  const int nodes = basis_->nodes().size();
  // The walls' impulses carry over; their held nodes do not (a run with
  // walls is not rebalanced: distributed/local_parts.cpp).
  const AlignedVector<Vec<D>> wall_impulse = constraints_.wall_impulse();
  constraints_ = Constraints<D>(std::move(dirichlet), constraints_.walls(), nodes);
  constraints_.wall_impulse() = wall_impulse;
  constraints_.count_only(dist_->owned_nodes());
  nodal_.resize(nodes);
  scatter_->invalidate(0); // the table is evaluated anew before it is used
}

template <int D> void Engine<D>::check_parts() const {
  using E = std::invalid_argument;
  require<E>(basis_ != nullptr, "Engine: no basis");
  require<E>(settings_.step != nullptr, "Engine: no step function (StepSettings::step)");
  require<E>(finite_positive(settings_.t_end), "Engine: t_end = ", settings_.t_end, " must be finite and > 0");
  require<E>(finite_positive(settings_.h), "Engine: h = ", settings_.h, " must be finite and > 0");
  require<E>(settings_.dt ? finite_positive(*settings_.dt) : finite_positive(settings_.cfl), "Engine: the time step (",
             settings_.dt ? "dt" : "cfl", ") must be finite and > 0");
  require<E>(P_.size() > 0 || dist_, "Engine: no particles");
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
  for (int p = 0; p < P_.size(); ++p)
    require<E>(P_.body[p] >= 0, "Engine: particle ", p, " has body ", P_.body[p], " (must be >= 0)");
  loads_.check(P_.size());
}

template <int D> double Engine<D>::stable_dt() const {
  double dt;
  if (settings_.dt) {
    dt = *settings_.dt;
  } else {
    const double c = wave_speed_; // max_p max(c_p, |v_p|), from the last sum_particles()
    double h = mode_.cfl_spacing(*basis_, settings_.h, node_spacing0_);
    if (dist_ && mode_.nodes_move()) dist_->min({&h, 1}); // the ranks' smallest (monotone in the spacing)
    dt = settings_.cfl * h / c;
  }
  return std::min(dt, settings_.t_end - t_);
}

template <int D> void Engine<D>::step() {
  if (dist_) dist_->before_step(*this);
  dt_ = stable_dt();
  if (!(dt_ > 0.0) || !std::isfinite(dt_))
    unstable("time step " + format_number(dt_) + " is not positive and finite");
  if (dt_prev_ == 0.0) dt_prev_ = dt_;
  try {
    settings_.step(*this, {t_, dt_, dt_prev_, step_, settings_.parameters, P_, nodal_});
  } catch (const ParticleFailure& f) {
    unstable(f.particle, f.what);
  }
  const double t0 = t_, dt_prev0 = dt_prev_;
  t_ += dt_;
  ++step_;
  dt_prev_ = dt_;
  try {
    sum_particles(true); // checks, energies, wave speed
  } catch (const DeferredInstability&) { // a rank failed inside the step: stop there, as a serial run does
    t_ = t0, dt_prev_ = dt_prev0, --step_;
    throw;
  }
  // Trapezoidal rule: exact for a constant load on a uniformly accelerating
  // body, where the one-sided rule would leave an O(dt) error in the balance.
  const double power = global_power(t_, momentum_);
  energy_.external_work += 0.5 * dt_ * (external_power_ + power);
  external_power_ = power;
  check_energy();
}

template <int D> void Engine<D>::evaluate_basis() {
  ScopedPhase timer(timers_, Phase::basis);
  fallible([&] {
    try {
      basis_->evaluate_points(P_.x, table_, P_.F.empty() ? nullptr : &P_.F);
      if (contact_) contact_->remap(table_, P_.body);
      row_width_ = linear_row_width(table_);
      scatter_->invalidate(row_width_);
      if (dist_) dist_->check_support(table_);
    } catch (const BasisError& e) {
      if (!dist_) unstable(std::string("basis evaluation failed: ") + e.what());
      // Every particle gets an empty row until the ranks stop on the failure
      // (fallible() names the particle by its global id).
      table_ = BasisTable<D>{};
      table_.offset.assign(static_cast<std::size_t>(P_.size()) + 1, 0);
      row_width_ = 0;
      scatter_->invalidate(row_width_);
      throw;
    }
  });
}

template <int D> void Engine<D>::to_nodes(const ToNodes<D>& what) {
  ScopedPhase timer(timers_, Phase::to_nodes);
  if (what.forces && !loads_.uniform() && loads_.any()) loads_.particle_forces(what.t, P_, fext_);
  to_nodes_with(what, [](int, int) {});
  exchange_sums(what.mass, what.w != nullptr, what.forces);
  if (what.mass) finish_mass();
}

template <int D>
template <class Update>
void Engine<D>::to_nodes_with(const ToNodes<D>& what, Update&& update) {
  const bool q = what.w != nullptr;
  if (what.mass && q && what.forces) to_nodes_impl<true, true, true>(what, update);
  else if (what.mass && q) to_nodes_impl<true, true, false>(what, update);
  else if (what.mass && what.forces) to_nodes_impl<true, false, true>(what, update);
  else if (what.mass) to_nodes_impl<true, false, false>(what, update);
  else if (q && what.forces) to_nodes_impl<false, true, true>(what, update);
  else if (q) to_nodes_impl<false, true, false>(what, update);
  else if (what.forces) to_nodes_impl<false, false, true>(what, update);
}

template <int D> void Engine<D>::update_stress_and_to_nodes(const Gradient<D>& g, const ToNodes<D>& what) {
  // Its time counts in the to_nodes phase, as the fe update counts in to_particles.
  ScopedPhase timer(timers_, Phase::to_nodes);
  require<std::invalid_argument>(what.forces && !what.mass && !what.w,
                                 "Engine::update_stress_and_to_nodes: only the forces follow a stress update");
  if (!loads_.uniform() && loads_.any()) loads_.particle_forces(what.t, P_, fext_);
  fallible([&] { to_nodes_impl<false, false, true>(what, [&](int p0, int p1) { update_stress_range(g, p0, p1); }); });
  exchange_sums(false, false, true);
}

template <int D> void Engine<D>::to_particles_then_to_nodes(const ToParticles<D>& move, const ToNodes<D>& what) {
  // Its time counts in the to_nodes phase.
  ScopedPhase timer(timers_, Phase::to_nodes);
  require<std::invalid_argument>(!what.mass, "Engine::to_particles_then_to_nodes: the mass does not follow a move");
  if (what.forces && !loads_.uniform() && loads_.any()) loads_.particle_forces(what.t, P_, fext_);
  to_nodes_with(what, [&](int p0, int p1) { to_particles_on(move, {}, p0, p1); });
  exchange_sums(false, what.w != nullptr, what.forces);
}

template <int D> void Engine<D>::exchange_sums(bool mass, bool momentum, bool forces) {
  if (!dist_) return;
  std::vector<NodalArray> fields;
  if (mass) fields.push_back({nodal_.m.data(), 1});
  if (momentum) fields.push_back({nodal_.q.data()->data(), D});
  if (forces) fields.push_back({nodal_.f.data()->data(), D});
  dist_->sum_nodal(fields);
}

template <int D>
template <bool Mass, bool Momentum, bool Forces, class Update>
void Engine<D>::to_nodes_impl(const ToNodes<D>& what, Update&& update) {
  const Vec<D> b = loads_.uniform() ? loads_.body_force_at(what.t) : Vec<D>::Zero();
  const bool field = !fext_.empty() && loads_.any() && !loads_.uniform(), uniform = loads_.uniform();
  struct Payload { // what particle p carries to each of its nodes
    double m;
    Vec<D> mw, fext;
    Mat<D> Vs;
  };
  // The arrays by value in the lambdas: the sums' stores cannot alias them.
  const double* m = P_.m.data();
  const double* V = P_.V.data();
  const Mat<D>* sigma = P_.sigma.data();
  const Vec<D>* vw = Momentum ? what.w->data() : nullptr;
  const Vec<D>* va = Momentum && what.a ? what.a->data() : nullptr;
  const Vec<D>* fext = field ? fext_.data() : nullptr;
  const double c = what.c;
  auto prep = [=](int p) {
    Payload w;
    w.m = m[p];
    if (Momentum) {
      w.mw = m[p] * vw[p];
      if (va) w.mw += (m[p] * c) * va[p];
    }
    if (Forces) {
      w.Vs = V[p] * sigma[p];
      w.fext = uniform ? Vec<D>(m[p] * b) : fext ? fext[p] : Vec<D>::Zero();
    }
    return w;
  };
  const double* Ne = table_.N.data(); // by value in the lambda: the sums' stores cannot alias it
  const Vec<D>* dNe = table_.dN.data();
  auto add = [Ne, dNe](NodeSums<D>& acc, int e, const Payload& w) {
    const double N = Ne[e];
    if (Mass) acc.m += N * w.m;
    if (Momentum) acc.q += N * w.mw;
    if (Forces) {
      acc.f -= w.Vs * dNe[e];
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
  scatter_->run(table_, static_cast<int>(nodal_.m.size()), update, prep, add, merge, clear);
}

template <int D> void Engine<D>::finish_mass() {
  const int nodes = static_cast<int>(nodal_.m.size());
  // The largest nodal mass: a maximum, exact in any grouping.
  double m_max = blocked_reduce<MaxOf>(nodes, [&](long long I, MaxOf& acc) {
    acc.value = std::max(acc.value, nodal_.m[I]);
  }).value;
  if (dist_) dist_->max({&m_max, 1});
  const double m_min = settings_.mass_tolerance * m_max;
  parallel_for(nodes, [&](long long I) { nodal_.active[I] = nodal_.m[I] > m_min; });
  if (mass_matrix_) mass_matrix_->assemble(table_, P_.m, nodal_.active, constraints_.constrained(), nodes);
  if (contact_) contact_mass_gradient();
}

template <int D> void Engine<D>::contact_mass_gradient() {
  AlignedVector<Vec<D>>& g = contact_->mass_gradient();
  auto update = [](int, int) {};
  auto prep = [&](int p) { return P_.m[p]; };
  auto add = [&](NodeSums<D>& acc, int e, double m) { acc.q += m * table_.dN[e]; };
  auto merge = [&](int I, const NodeSums<D>& acc) { g[I] += acc.q; };
  auto clear = [&](int I0, int I1) { std::fill(g.begin() + I0, g.begin() + I1, Vec<D>::Zero()); };
  scatter_->run(table_, static_cast<int>(g.size()), update, prep, add, merge, clear);
}

template <int D> const AlignedVector<Vec<D>>& Engine<D>::field_positions() const {
  return contact_ ? field_positions_ : basis_->nodes().positions();
}

template <int D>
void Engine<D>::solve_mass(const AlignedVector<Vec<D>>& r, AlignedVector<Vec<D>>& y) {
  ScopedPhase timer(timers_, Phase::nodal_update);
  const int n = static_cast<int>(r.size());
  y.resize(n);
  const bool lumped = !settings_.consistent_mass;
  parallel_for(n, [&](long long I) { y[I] = lumped && nodal_.active[I] ? Vec<D>(r[I] / nodal_.m[I]) : Vec<D>::Zero(); });
  if (lumped) return;
  if (dist_) dist_->solve_consistent_mass(table_, P_.m, nodal_.m, nodal_.active, constraints_.constrained(), r, y);
  else mass_matrix_->solve(r, y);
}

template <int D> void Engine<D>::constrain_velocity(AlignedVector<Vec<D>>& v, const WallEffect<D>& effect) {
  constraints_.apply_velocity(v);
  if (contact_) contact_->apply(v, {nodal_.m, nodal_.active, constraints_.constrained()}, effect);
  if (constraints_.walls().empty()) return;
  // A distributed run: the work of this rank's owned nodes, summed over the ranks after the step.
  constraints_.apply_walls(v, {field_positions(), nodal_.m, nodal_.active}, t_, dt_, effect,
                           dist_ ? rank_reaction_.work : energy_.reaction_work);
}

template <int D> void Engine<D>::constrain_increment(AlignedVector<Vec<D>>& dx) const {
  if (contact_) contact_->apply_to_increment(dx, {nodal_.m, nodal_.active, constraints_.constrained()});
  if (constraints_.walls().empty()) return;
  constraints_.apply_walls_to_increment(dx, {field_positions(), nodal_.m, nodal_.active}, t_, dt_);
}

template <int D> void Engine<D>::apply_dirichlet_force(AlignedVector<Vec<D>>& f) {
  // A distributed run: this rank's owned nodes, summed over the ranks after the step (sum_particles).
  if (!dist_) constraints_.apply_force(f, nodal_.reaction, dt_, reaction_impulse_, energy_.reaction_work);
  else constraints_.apply_force(f, nodal_.reaction, dt_, rank_reaction_.impulse, rank_reaction_.work);
}

template <int D> void Engine<D>::to_particles(const ToParticles<D>& what) {
  to_particles_and_update_stress(what, {});
}

template <int D>
void Engine<D>::to_particles_and_update_stress(const ToParticles<D>& what, const Gradient<D>& g) {
  ScopedPhase timer(timers_, Phase::to_particles);
  fallible([&] {
    parallel_chunks(P_.size(), [&](long long begin, long long end) {
      to_particles_on(what, g, static_cast<int>(begin), static_cast<int>(end));
    });
  });
}

template <int D>
void Engine<D>::to_particles_on(const ToParticles<D>& what, const Gradient<D>& g, int begin, int end) {
  const bool rate = what.rate != nullptr, move = what.move != nullptr, field = g.field != nullptr;
  if (rate && move && field) to_particles_range<true, true, true>(what, g, begin, end);
  else if (rate && move) to_particles_range<true, true, false>(what, g, begin, end);
  else if (rate && field) to_particles_range<true, false, true>(what, g, begin, end);
  else if (rate) to_particles_range<true, false, false>(what, g, begin, end);
  else if (move && field) to_particles_range<false, true, true>(what, g, begin, end);
  else if (move) to_particles_range<false, true, false>(what, g, begin, end);
  else if (field) to_particles_range<false, false, true>(what, g, begin, end);
}

template <int D>
template <bool Rate, bool Move, bool Field>
void Engine<D>::to_particles_range(const ToParticles<D>& what, const Gradient<D>& g, int begin, int end) {
  if (row_width_ == (1 << D)) to_particles_rows<Rate, Move, Field, (1 << D)>(what, g, begin, end);
  else to_particles_rows<Rate, Move, Field, 0>(what, g, begin, end);
}

template <int D>
template <bool Rate, bool Move, bool Field, int W>
void Engine<D>::to_particles_rows(const ToParticles<D>& what, const Gradient<D>& g, int begin, int end) {
  // Plain pointers and factors in locals: the stores to the particles below
  // cannot alias them, so the loops keep them in registers.
  const Vec<D>* rate = Rate ? what.rate->data() : nullptr;
  const Vec<D>* move = Move ? what.move->data() : nullptr;
  const Vec<D>* field = Field ? g.field->data() : nullptr;
  Vec<D>* rate_out = what.rate_out ? what.rate_out->data() : nullptr;
  const double c_rate = what.c_rate, c_move = what.c_move, c = g.c;
  const int* offset = table_.offset.data();
  const int* node = table_.node.data();
  const double* N = table_.N.data();
  const Vec<D>* dN = table_.dN.data();
  Vec<D>* v = P_.v.data();
  Vec<D>* x = P_.x.data();
  Mat<D> H[kStressBatch];
  for (int p0 = begin; p0 < end; p0 += kStressBatch) {
    const int p1 = std::min(end, p0 + kStressBatch);
    for (int p = p0; p < p1; ++p) {
      Vec<D> r = Vec<D>::Zero(), u = Vec<D>::Zero();
      Mat<D> G = Mat<D>::Zero();
      const auto [e0, e1] = row_entries<W>(offset, p);
      for (int e = e0; e < e1; ++e) {
        const int I = node[e];
        if constexpr (Rate) r += N[e] * rate[I];
        if constexpr (Move) u += N[e] * move[I];
        if constexpr (Field) G.noalias() += field[I] * dN[e].transpose();
      }
      if constexpr (Rate) {
        if (rate_out) rate_out[p] = r;
        v[p] += c_rate * r;
      }
      if constexpr (Move) x[p] += c_move * u;
      if constexpr (Field) H[p - p0] = c * G;
    }
    if constexpr (Field) update_materials(p0, p1, H);
  }
}

template <int D> void Engine<D>::update_stress(const Gradient<D>& g) {
  ScopedPhase timer(timers_, Phase::constitutive);
  fallible([&] {
    parallel_chunks(P_.size(), [&](long long begin, long long end) {
      update_stress_range(g, static_cast<int>(begin), static_cast<int>(end));
    });
  });
}

template <int D> void Engine<D>::update_stress_range(const Gradient<D>& g, int p0, int p1) {
  to_particles_range<false, false, true>({}, g, p0, p1);
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
  // Ranks agree on the increments first: a family may meet the other ranks
  // while it advects (the B-spline knots are global).
  if (dist_) {
    LocalFailure bad;
    const auto it = std::find_if(dx.begin(), dx.end(), [](const Vec<D>& d) { return !d.allFinite(); });
    if (it != dx.end())
      bad.message = "step " + std::to_string(step_) + ", t = " + format_number(t_) + " s: the increment of node " +
                    std::to_string(it - dx.begin()) + " is not finite";
    dist_->agree(it != dx.end() ? &bad : nullptr);
  }
  mode_.advect(*basis_, dx);
}

template <int D> double Engine<D>::global_power(double t, const Vec<D>& momentum) const {
  double power = loads_.power(t, P_, momentum); // uniform: b . momentum, already global
  if (dist_ && !loads_.uniform()) dist_->sum({&power, 1});
  return power;
}

template <int D> double Engine<D>::external_power(double t) const { return global_power(t, momentum()); }

/// A leading "particle P at " of a basis error: P, and where the rest starts.
static bool leading_particle(const std::string& what, int& p, std::size_t& rest) {
  const std::string prefix = "particle ";
  if (what.rfind(prefix, 0) != 0) return false;
  std::size_t i = prefix.size(), j = i;
  while (j < what.size() && std::isdigit(static_cast<unsigned char>(what[j]))) ++j;
  if (j == i || j > i + 9 || what.compare(j, 4, " at ") != 0) return false;
  p = std::stoi(what.substr(i, j - i));
  rest = j;
  return true;
}

template <int D> template <class Stage> void Engine<D>::fallible(Stage&& stage) {
  if (!dist_) return stage();
  LocalFailure failure;
  failure.deferred = true;
  bool failed = true;
  const std::string when = "step " + std::to_string(step_) + ", t = " + format_number(t_) + " s: ";
  try {
    stage();
    failed = false;
  } catch (const ParticleFailure& f) {
    failure.key = particle_id(f.particle);
    failure.message = when + "particle " + std::to_string(failure.key) + " at " + format_point<D>(P_.x[f.particle]) +
                      ": " + f.what;
  } catch (const BasisError& e) {
    const std::string what = e.what();
    int p = -1;
    std::size_t rest = 0;
    const bool named = leading_particle(what, p, rest) && p >= 0 && p < P_.size();
    if (named) failure.key = particle_id(p);
    failure.message = when + "basis evaluation failed: " +
                      (named ? "particle " + std::to_string(failure.key) + what.substr(rest) : what);
  } catch (const InstabilityError& e) {
    failure.message = e.what();
  }
  if (failed) dist_->defer(failure); // every rank stops on it at the next reduction
}

template <int D> void Engine<D>::unstable(int p, const std::string& what) const {
  unstable("particle " + std::to_string(particle_id(p)) + " at " + format_point<D>(P_.x[p]) + ": " + what);
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
