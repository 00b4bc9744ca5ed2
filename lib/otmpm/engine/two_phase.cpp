/// \file two_phase.cpp
/// The liquid phase of saturated bodies (two_phase.hpp; docs/theory.md
/// sect. 15): its particle-to-node sums, the coupled nodal solve with the
/// implicit Darcy drag, rigid plates, and the liquid's particle update.
#include "otmpm/engine/two_phase.hpp"

#include "otmpm/engine/engine.hpp"
#include "otmpm/engine/two_phase_scatter.hpp"
#include "otmpm/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace otmpm {

namespace {

/// The liquid velocity w_p of particle p in the state array (D values per particle).
template <int D> Eigen::Map<Vec<D>> liquid_at(StateField& w, int p) { return Eigen::Map<Vec<D>>(w.row(p)); }
template <int D> Eigen::Map<const Vec<D>> liquid_at(const StateField& w, int p) {
  return Eigen::Map<const Vec<D>>(w.row(p));
}

/// The largest squared speed of the two compressional waves of the mixture
/// (eq. 15.7): the largest eigenvalue of K v = c^2 R v with the stiffness
/// K = [M + (1-n)^2 K_w/n, (1-n) K_w; (1-n) K_w, n K_w] and the partial
/// densities R = diag(rho_s', n rho_w); M = c2 rho_s' the skeleton's P-wave
/// modulus. With a = K_11 / rho_s' and d = K_22 / (n rho_w) = K_w / rho_w the
/// eigenvalues are (a + d) / 2 +- sqrt(((a + d) / 2)^2 - det), det = det K /
/// det R = c2 K_w / rho_w.
double fast_wave_speed2(double c2, double n, double rho_solid, double Kw, double Kw_over_rho_w) {
  const double half = 0.5 * (c2 + (1.0 - n) * (1.0 - n) * Kw / (n * rho_solid) + Kw_over_rho_w);
  return half + std::sqrt(std::max(0.0, half * half - c2 * Kw_over_rho_w));
}

/// One component of the nodal solve (eq. 15.5): the liquid's acceleration
/// and the drag's dissipation (eq. 15.6).
struct Relative {
  double aw = 0.0, darcy = 0.0;
};

/// Component k of eq. 15.5 at a node of solid mass ms, liquid mass mw and
/// drag Q, the mixture's force Fm, the liquid's Fw and the start relative
/// velocity r0; `drained`: a drained support (the solid held, no F term).
[[gnu::always_inline]] inline Relative relative(double Q, double ms, double mw, double dt, double Fm, double Fw, double r0,
                                                bool drained) {
  const double both = drained ? 1.0 : 1.0 + mw / ms, push = drained ? 0.0 : dt * Fm / ms;
  // eq. 15.5 and the end relative velocity r'; where the drag dominates, divided by Q and r' from
  // the drag force Q r' = f_w - m_w a_w, so that no permeability makes them overflow or cancel
  const bool stiff = Q * dt > mw;
  Relative r;
  r.aw = stiff ? (Fw / Q - r0 + push) / (mw / Q + dt * both) : (Fw - Q * r0 + Q * push) / (mw + Q * dt * both);
  const double solid = drained ? 0.0 : (Fm - mw * r.aw) / ms; // a_v
  const double r1 = stiff ? (Fw - mw * r.aw) / Q : r0 + dt * (r.aw - solid);
  r.darcy = dt * Q * r1 * 0.5 * (r0 + r1);
  return r;
}

/// The free water's pressure at x and time t (Drain, eq. 15.11) under the body force b.
template <int D> double water_pressure(const Drain& s, const Vec<D>& x, const Vec<D>& b, double t) {
  if (!s.level) return s.pressure;
  const double level = *s.level + (s.rise != 0.0 ? s.rise * time_function(s.time, t) : 0.0);
  return s.pressure + s.density * std::max(0.0, b.norm() * level + b.dot(x));
}

/// The lower of two particle indices, -1 meaning none.
int lowest(int a, int b) { return a < 0 ? b : b < 0 ? a : std::min(a, b); }

/// Per local node: 1 where this rank counts it in a sum over the nodes (its
/// own nodes in a distributed run), or null (a serial run: every node).
template <int D> const char* counted_nodes(const Engine<D>& e) {
  return e.distribution() ? e.distribution()->owned_nodes().data() : nullptr;
}

} // namespace

template <int D>
TwoPhase<D>::TwoPhase(TwoPhaseParts<D> parts, Particles<D>& P, const Dirichlet<D>& dirichlet, int nodes)
    : parts_(std::move(parts)), scatter_(std::make_unique<BlockedScatter<D, LiquidSums<D>>>()),
      mixture_(std::make_unique<BlockedScatter<D, MixtureSums<D>>>()) {
  using E = std::invalid_argument;
  for (int p = 0; p < P.size(); ++p)
    require<E>(P.material[p] >= 0 && P.material[p] < static_cast<int>(parts_.fluid.size()), "TwoPhase: particle ", p,
               " has material ", P.material[p], " but the pore fluids are given for ", parts_.fluid.size());
  const auto n = static_cast<std::size_t>(nodes) * D;
  fixed_.assign(n, 0), held_.assign(n, 0), rigid_.assign(n, 0), value_.assign(n, 0.0);
  for (std::size_t i = 0; i < dirichlet.node.size(); ++i)
    for (int k = 0; k < D; ++k)
      if (dirichlet.fix[i][k]) {
        const std::size_t c = static_cast<std::size_t>(dirichlet.node[i]) * D + k;
        if (!fixed_[c]) fixed_list_.push_back(c);
        fixed_[c] = 1, value_[c] = dirichlet.value[i][k];
      }
  std::sort(fixed_list_.begin(), fixed_list_.end());
  for (std::size_t i = 0; i < parts_.held.node.size(); ++i)
    for (int k = 0; k < D; ++k) {
      const int I = parts_.held.node[i];
      require<E>(I >= 0 && I < nodes, "TwoPhase: held node ", I, " out of range [0, ", nodes, ")");
      const std::size_t c = static_cast<std::size_t>(I) * D + k;
      require<E>(!parts_.held.fix[i][k] || fixed_[c], "TwoPhase: the liquid is held at node ", I, " component ", k,
                 ", which the Dirichlet sets do not fix");
      if (parts_.held.fix[i][k]) held_[c] = 1;
    }
  for (const Plate& r : parts_.plates) {
    require<E>(r.axis >= 0 && r.axis < D && std::isfinite(r.force), "TwoPhase: a plate along axis ", r.axis, " in ",
               D, "D with the force ", r.force);
    for (int I : r.node) {
      require<E>(I >= 0 && I < nodes, "TwoPhase: plate node ", I, " out of range [0, ", nodes, ")");
      rigid_[static_cast<std::size_t>(I) * D + r.axis] = 1;
    }
  }
  for (std::size_t m = 0; m < parts_.fluid.size(); ++m) fluids_.push_back(parts_.fluid[m] ? &*parts_.fluid[m] : nullptr);
  const bool fresh = P.find_state(kLiquidVelocityField) == nullptr;
  const double zero[9] = {};
  P.add_state(std::string(kPorePressureField), 1, zero);
  StateField& w = P.add_state(std::string(kLiquidVelocityField), D, zero);
  if (fresh) // the liquid starts with the solid's velocity
    for (int p = 0; p < P.size(); ++p) liquid_at<D>(w, p) = P.v[p];
  mw_.assign(static_cast<std::size_t>(nodes), 0.0);
  drag_ = mw_;
  wet_.assign(static_cast<std::size_t>(nodes), 0);
  qw_.assign(static_cast<std::size_t>(nodes), Vec<D>::Zero());
  fw_ = fp_ = fm_ = vw_ = aw_ = g_ = gn_ = normal_ = qw_;
  drain_.assign(static_cast<std::size_t>(nodes), -1);
  pbar_.assign(static_cast<std::size_t>(nodes), 0.0);
  for (std::size_t d = 0; d < parts_.drains.size(); ++d) {
    const Drain& s = parts_.drains[d];
    require<E>(std::isfinite(s.pressure) && std::isfinite(s.level.value_or(0.0)) && std::isfinite(s.density) &&
                   s.density >= 0.0 && std::isfinite(s.rise),
               "TwoPhase: a drain with the pressure ", s.pressure, ", the level ", s.level.value_or(0.0),
               ", the rise ", s.rise, " and the density ", s.density);
    for (int I : s.node) {
      require<E>(I >= 0 && I < nodes, "TwoPhase: drained node ", I, " out of range [0, ", nodes, ")");
      drain_[static_cast<std::size_t>(I)] = static_cast<int>(d);
    }
  }
}

template <int D> TwoPhase<D>::~TwoPhase() = default;

template <int D> void TwoPhase<D>::to_nodes(Engine<D>& e, double t, double dt) {
  ScopedPhase timer(e.timers(), Phase::to_nodes);
  totals_ready_ = false;
  if (!std::exchange(summed_, false)) scatter<false>(e, [](int, int) {}); // else in the engine's pass
  count_occupied(e);
  exchange(e, false);
  const double held = dt * held_power(e, e.loads().body_force_at(t));
  find_surface(e);
  const double darcy = solve(e, t, dt);
  std::vector<double> plates = plate_sums(e, t, true);
  if (Distribution<D>* dist = e.distribution()) { // one reduction: the ranks' own nodes' parts
    plates.insert(plates.end(), {held, darcy});
    dist->sum(plates);
    boundary_work_ -= plates.end()[-2], darcy_ += plates.end()[-1];
    plates.resize(plates.size() - 2);
  } else {
    boundary_work_ -= held, darcy_ += darcy;
  }
  tie(e, t, dt, plates);
}

template <int D> void TwoPhase<D>::exchange(Engine<D>& e, bool momentum_only) {
  Distribution<D>* dist = e.distribution();
  if (!dist) return;
  std::vector<NodalArray> fields{{qw_.data()->data(), D}};
  if (!momentum_only)
    fields.insert(fields.end(), {{mw_.data(), 1},
                                 {drag_.data(), 1},
                                 {fw_.data()->data(), D},
                                 {fp_.data()->data(), D},
                                 {g_.data()->data(), D},
                                 {gn_.data()->data(), D},
                                 {around_.data(), 1}});
  dist->sum_nodal(fields);
}

template <int D> double TwoPhase<D>::held_power(const Engine<D>& e, const Vec<D>& b) const {
  // eq. 15.14: per fixed component, b_k (q_Ik - m_I vbar_Ik), and the liquid's where it is held
  const NodalFields<D>& n = e.nodal();
  const char* counted = counted_nodes(e);
  double power = 0.0;
  for (const std::size_t c : fixed_list_) {
    const std::size_t I = c / D;
    const int k = static_cast<int>(c % D);
    if (!n.active[I] || (counted && !counted[I])) continue;
    power += b[k] * (n.q[I][k] - n.m[I] * value_[c]);
    if (held_[c]) power += b[k] * (qw_[I][k] - mw_[I] * value_[c]);
  }
  return power;
}

template <int D> double TwoPhase<D>::solve(Engine<D>& e, double t, double dt) {
  NodalFields<D>& n = e.nodal();
  const Vec<D> b = e.loads().body_force_at(t); // the uniform body force (a field is refused with saturated bodies)
  double mw_max = mw_.empty() ? 0.0 : *std::max_element(mw_.begin(), mw_.end());
  if (e.distribution()) e.distribution()->max({&mw_max, 1});
  const char* counted = counted_nodes(e); // the ranks' own nodes' dissipation
  const double mw_min = e.settings().mass_tolerance * mw_max;
  const NodeSet<D>& nodes = e.basis().nodes();
  return blocked_reduce<double>(static_cast<long long>(mw_.size()), [&](long long i, double& darcy) {
    const auto I = static_cast<std::size_t>(i);
    Vec<D> Fm = n.f[I] + fp_[I] + mw_[I] * b, Fw = fw_[I] + mw_[I] * b;
    if (drain_[I] >= 0) { // the free water's push (eq. 15.11)
      const Drain& drain = parts_.drains[static_cast<std::size_t>(drain_[I])];
      const double pbar = water_pressure(drain, nodes.position(static_cast<int>(I)), b, t);
      Fm -= pbar * g_[I], Fw -= pbar * gn_[I];
      pbar_[I] = pbar;
    }
    fm_[I] = Fm;
    aw_[I].setZero();
    wet_[I] = n.active[I] && mw_[I] > mw_min;
    n.f[I] = Fm;
    if (!wet_[I]) return;
    const bool count = !counted || counted[I];
    if (!normal_[I].isZero()) {
      const double d = solve_impermeable(n, I, Fm, Fw, normal_[I], dt);
      if (count) darcy += d;
      return;
    }
    const double ms = n.m[I], mw = mw_[I];
    const Vec<D> vs0 = n.q[I] / ms, vw0 = qw_[I] / mw;
    for (int k = 0; k < D; ++k) {
      const std::size_t c = I * D + static_cast<std::size_t>(k);
      if (held_[c] || rigid_[c]) continue; // held: a_w = 0, the reaction takes F_m; rigid: tie()
      // A drained support holds the solid at its value and leaves the liquid free (k = 1, no F term).
      const bool drained = fixed_[c];
      const Relative r = relative(drag_[I], ms, mw, dt, Fm[k], Fw[k], vw0[k] - (drained ? value_[c] : vs0[k]), drained);
      aw_[I][k] = r.aw;
      n.f[I][k] = Fm[k] - mw * r.aw;
      if (count) darcy += r.darcy;
    }
  });
}

template <int D>
double TwoPhase<D>::solve_impermeable(NodalFields<D>& n, std::size_t I, const Vec<D>& Fm, const Vec<D>& Fw,
                                      const Vec<D>& normal, double dt) {
  // Tangential: eq. 15.5 on the components of the vectors less their normal parts (the solve is
  // linear and isotropic); normal: both phases end with one velocity (the limit Q -> oo).
  const double ms = n.m[I], mw = mw_[I];
  const Vec<D> vs0 = n.q[I] / ms, vw0 = qw_[I] / mw;
  const double Fm_n = Fm.dot(normal), Fw_n = Fw.dot(normal), vs_n = vs0.dot(normal), vw_n = vw0.dot(normal);
  const double V_n = (ms * vs_n + mw * vw_n + dt * Fm_n) / (ms + mw), aw_n = (V_n - vw_n) / dt;
  double darcy = 0.5 * dt * (Fw_n - mw * aw_n) * (vw_n - vs_n); // eq. 15.6 as Q -> oo (r' = 0)
  for (int k = 0; k < D; ++k) {
    const std::size_t c = I * D + static_cast<std::size_t>(k);
    if (held_[c] || rigid_[c]) continue; // the normal has no such component
    const Relative r = relative(drag_[I], ms, mw, dt, Fm[k] - Fm_n * normal[k], Fw[k] - Fw_n * normal[k],
                                vw0[k] - vs0[k] - (vw_n - vs_n) * normal[k], false);
    aw_[I][k] = r.aw + aw_n * normal[k];
    n.f[I][k] = Fm[k] - mw * aw_[I][k];
    darcy += r.darcy;
  }
  return darcy;
}

template <int D> void TwoPhase<D>::count_occupied(const Engine<D>& e) {
  around_.assign(mw_.size(), 0.0);
  const std::optional<CartesianGrid<D>>& grid = e.basis().nodes().grid();
  if (!grid) return;
  // The cells that hold a saturated particle, by the node number of their lower corner: those the last
  // pressure update found when the particles have not moved since (cells_ready_), else found anew.
  // (A distributed run finds them anew: its particles migrated since.)
  const Particles<D>& P = e.particles();
  const bool ready = std::exchange(cells_ready_, false) && !e.distribution() &&
                     cell_.size() == static_cast<std::size_t>(P.size());
  const Vec<D> lower = grid->lower, inverse = grid->h().cwiseInverse();
  occupied_.assign(mw_.size(), 0);
  for (int p = 0; p < P.size(); ++p) {
    if (!fluids_[static_cast<std::size_t>(P.material[p])]) continue;
    const long long cell = ready ? cell_[static_cast<std::size_t>(p)] : lattice_cell<D>(P.x[p], lower, inverse, grid->cells);
    occupied_[static_cast<std::size_t>(cell)] = 1;
  }
  // Per node the occupied cells beside it (a distributed run: summed over the ranks by exchange(),
  // whose particles are in their own cells at the start of a step, so each cell counts once).
  parallel_for(static_cast<long long>(mw_.size()), [&](long long i) {
    const Index<D> node = grid->node_index(static_cast<int>(i));
    for (int corner = 0; corner < (1 << D); ++corner) {
      Index<D> c = node;
      bool inside = true;
      for (int k = 0; k < D; ++k) {
        c[k] -= (corner >> k) & 1;
        inside = inside && c[k] >= 0 && c[k] < grid->cells[k];
      }
      if (inside && occupied_[static_cast<std::size_t>(grid->node_id(c))]) around_[static_cast<std::size_t>(i)] += 1.0;
    }
  });
}

template <int D> void TwoPhase<D>::find_surface(const Engine<D>& e) {
  std::fill(normal_.begin(), normal_.end(), Vec<D>::Zero());
  if (!e.basis().nodes().grid()) return;
  const NodalFields<D>& n = e.nodal();
  parallel_for(static_cast<long long>(mw_.size()), [&](long long i) {
    const auto I = static_cast<std::size_t>(i);
    if (drain_[I] >= 0 || !n.active[I] || !(mw_[I] > 0.0)) return;
    // a surface node: a lattice cell beside it is empty or outside the lattice
    if (around_[I] >= static_cast<double>(1 << D)) return;
    Vec<D> g = g_[I]; // the outward normal over the components the liquid is free in
    for (int k = 0; k < D; ++k)
      if (held_[I * D + static_cast<std::size_t>(k)] || rigid_[I * D + static_cast<std::size_t>(k)]) g[k] = 0.0;
    const double norm = g.norm();
    if (norm > 0.1 * g_[I].norm()) normal_[I] = g / norm; // else the held components carry the surface
  });
}

template <int D> std::vector<double> TwoPhase<D>::plate_sums(const Engine<D>& e, double t, bool forces) const {
  const NodalFields<D>& n = e.nodal();
  const char* counted = counted_nodes(e);
  std::vector<double> sums;
  for (const Plate& r : parts_.plates) {
    const int k = r.axis;
    double M = 0.0, momentum = 0.0, force = forces && !counted ? r.force * time_function(r.time, t) : 0.0;
    for (int I : r.node) {
      if (!n.active[I] || (counted && !counted[I])) continue;
      M += n.m[I], momentum += n.q[I][k];
      if (forces) force += fm_[I][k];
      if (wet_[I]) M += mw_[I], momentum += qw_[I][k];
    }
    sums.insert(sums.end(), {M, momentum, force});
  }
  return sums;
}

template <int D> void TwoPhase<D>::tie(Engine<D>& e, double t, double dt, const std::vector<double>& sums) {
  NodalFields<D>& n = e.nodal();
  for (std::size_t i = 0; i < parts_.plates.size(); ++i) {
    const Plate& r = parts_.plates[i];
    const int k = r.axis;
    const double F0 = r.force * time_function(r.time, t), F1 = r.force * time_function(r.time, t + dt);
    const double M = sums[3 * i], momentum = sums[3 * i + 1];
    const double force = e.distribution() ? sums[3 * i + 2] + F0 : sums[3 * i + 2];
    if (!(M > 0.0)) continue;
    const double V = (momentum + dt * force) / M; // the plate's velocity at the end of the step
    boundary_work_ += 0.5 * (F0 + F1) * dt * V;
    for (int I : r.node) {
      if (!n.active[I]) continue;
      n.f[I][k] = (n.m[I] * V - n.q[I][k]) / dt;
      if (wet_[I]) aw_[I][k] = (V - qw_[I][k] / mw_[I]) / dt;
    }
  }
}

template <int D> void TwoPhase<D>::nodal_velocity(Engine<D>& e, double dt) {
  ScopedPhase timer(e.timers(), Phase::nodal_update);
  const NodalFields<D>& n = e.nodal();
  parallel_for(static_cast<long long>(mw_.size()), [&](long long i) {
    const auto I = static_cast<std::size_t>(i);
    if (!wet_[I]) {
      vw_[I] = n.v[I];
      return;
    }
    Vec<D> w = qw_[I] / mw_[I] + dt * aw_[I];
    for (int k = 0; k < D; ++k)
      if (held_[I * D + static_cast<std::size_t>(k)]) w[k] = n.v[I][k];
    vw_[I] = w;
  });
  // The free water's push -pbar G_n on the liquid, -pbar (G - G_n) on the grains, over the step
  // (a distributed run: each rank's own nodes, summed by the engine).
  const char* counted = counted_nodes(e);
  double& work = counted ? rank_work_ : boundary_work_;
  for (std::size_t d = 0; d < parts_.drains.size(); ++d)
    for (int node : parts_.drains[d].node) {
      const auto I = static_cast<std::size_t>(node);
      if (drain_[I] != static_cast<int>(d) || pbar_[I] == 0.0 || !n.active[I]) continue; // each node once
      if (counted && !counted[I]) continue;
      const Vec<D> v0 = n.q[I] / n.m[I], w0 = wet_[I] ? Vec<D>(qw_[I] / mw_[I]) : v0;
      work -= 0.5 * dt * pbar_[I] * (gn_[I].dot(w0 + vw_[I]) + (g_[I] - gn_[I]).dot(v0 + n.v[I]));
    }
}

template <int D> void TwoPhase<D>::to_particles(Engine<D>& e, double dt) {
  ScopedPhase timer(e.timers(), Phase::to_particles);
  if (std::exchange(gathered_, false)) average_pressure(e);
  else update_particles(e, dt, true, true);
}

template <int D> void TwoPhase<D>::begin_rows(const Engine<D>& e, double dt) {
  const auto n = static_cast<std::size_t>(e.particles().size());
  dp_.resize(n), cell_.resize(n);
  rows_dt_ = dt;
  gathered_ = true;
}

template <int D> void TwoPhase<D>::finish_rows(Engine<D>& e, int p0, int p1, const LiquidRows<D>& rows) {
  finish<true, true>(e, rows_dt_, p0, p1, rows);
}

template <int D> void TwoPhase<D>::update_rows(Engine<D>& e, int p0, int p1) {
  if (width_ == (1 << D)) update_range<true, true, (1 << D)>(e, rows_dt_, p0, p1);
  else update_range<true, true, 0>(e, rows_dt_, p0, p1);
}

template <int D> void TwoPhase<D>::remap(Engine<D>& e, double dt) {
  ScopedPhase timer(e.timers(), Phase::to_nodes); // as the engine's musl re-projection counts
  // w_p += dt sum N a_w block by block, then the new momenta re-projected.
  scatter<true>(e, [&](int p0, int p1) {
    width_ == (1 << D) ? update_range<true, false, (1 << D)>(e, dt, p0, p1) : update_range<true, false, 0>(e, dt, p0, p1);
  });
  exchange(e, true);
  NodalFields<D>& n = e.nodal();
  parallel_for(static_cast<long long>(mw_.size()), [&](long long i) {
    const auto I = static_cast<std::size_t>(i);
    if (!wet_[I]) return void(vw_[I] = n.v[I]);
    vw_[I] = qw_[I] / mw_[I];
    for (int k = 0; k < D; ++k)
      if (held_[I * D + static_cast<std::size_t>(k)]) vw_[I][k] = n.v[I][k];
    vw_[I] += (n.v[I] - vw_[I]).dot(normal_[I]) * normal_[I]; // an impermeable surface: no normal flux
  });
  std::vector<double> sums = plate_sums(e, 0.0, false);
  if (Distribution<D>* dist = e.distribution()) dist->sum(sums);
  for (std::size_t i = 0; i < parts_.plates.size(); ++i) { // one velocity per plate: the re-projected momenta
    const Plate& r = parts_.plates[i];
    const int k = r.axis;
    const double M = sums[3 * i], momentum = sums[3 * i + 1];
    if (!(M > 0.0)) continue;
    for (int I : r.node)
      if (n.active[I]) n.v[I][k] = vw_[I][k] = momentum / M;
  }
}

template <int D> void TwoPhase<D>::update_pressure(Engine<D>& e, double dt) {
  ScopedPhase timer(e.timers(), Phase::constitutive); // as the engine's musl stress update counts
  update_particles(e, dt, false, true);
}

template <int D> void TwoPhase<D>::update_particles(Engine<D>& e, double dt, bool rate, bool pressure) {
  const int n = e.particles().size();
  if (pressure) dp_.resize(static_cast<std::size_t>(n)), cell_.resize(static_cast<std::size_t>(n));
  const bool fixed = width_ == (1 << D);
  parallel_chunks(n, [&](long long p0, long long p1) {
    const int b = static_cast<int>(p0), c = static_cast<int>(p1);
    if (rate && pressure) fixed ? update_range<true, true, (1 << D)>(e, dt, b, c) : update_range<true, true, 0>(e, dt, b, c);
    else if (rate) fixed ? update_range<true, false, (1 << D)>(e, dt, b, c) : update_range<true, false, 0>(e, dt, b, c);
    else fixed ? update_range<false, true, (1 << D)>(e, dt, b, c) : update_range<false, true, 0>(e, dt, b, c);
  });
  if (pressure) average_pressure(e);
}

template <int D>
template <bool Rate, bool Pressure, int W>
void TwoPhase<D>::update_range(Engine<D>& e, double dt, int p0, int p1) {
  const BasisTable<D>& table = e.table();
  // Plain pointers in locals: the stores below cannot alias them.
  const int* offset = table.offset.data();
  const int* node = table.node.data();
  const double* N = table.N.data();
  const Vec<D>* dN = table.dN.data();
  const int* material = e.particles().material.data();
  const PoreFluid* const* fluid_of = fluids_.data();
  LiquidRows<D> rows;
  bind(e, rows);
  for (int b0 = p0; b0 < p1; b0 += LiquidRows<D>::size) { // batches: the row sums, then their particles' update
    const int b1 = std::min(p1, b0 + LiquidRows<D>::size);
    for (int p = b0; p < b1; ++p) {
      LiquidRow<D> r;
      if (fluid_of[material[p]]) {
        const auto [e0, e1] = row_entries<W>(offset, p);
        for (int k = e0; k < e1; ++k) rows.template add<Rate, Pressure>(r, node[k], N[k], dN[k]);
      }
      rows.row[p - b0] = r;
    }
    finish<Rate, Pressure>(e, dt, b0, b1, rows);
  }
}

template <int D>
template <bool Rate, bool Pressure>
void TwoPhase<D>::finish(Engine<D>& e, double dt, int p0, int p1, const LiquidRows<D>& rows) {
  Particles<D>& P = e.particles();
  double* w = P.find_state(kLiquidVelocityField)->values.data();
  const std::optional<CartesianGrid<D>>& grid = e.basis().nodes().grid();
  Vec<D> lower = Vec<D>::Zero(), inverse = Vec<D>::Zero();
  if (grid) lower = grid->lower, inverse = grid->h().cwiseInverse();
  for (int p = p0; p < p1; ++p) {
    const PoreFluid* f = fluids_[static_cast<std::size_t>(P.material[p])];
    if (!f) continue;
    const LiquidRow<D>& r = rows.row[p - p0];
    if constexpr (Rate) Eigen::Map<Vec<D>>(w + static_cast<std::size_t>(p) * D) += dt * r.a;
    if constexpr (!Pressure) continue;
    const double n = porosity(*f, P.V0[p], P.V[p]);
    if (!(n > 0.0 && n < 1.0)) [[unlikely]]
      throw ParticleFailure{p, "porosity n = " + format_number(n) +
                                   " left (0, 1): the skeleton's volume fell to its grains' or below"};
    const auto i = static_cast<std::size_t>(p);
    dp_[i] = -dt * f->bulk_modulus / n * ((1.0 - n) * r.div_s + n * r.div_w); // eq. 15.3
    cell_[i] = grid ? lattice_cell<D>(P.x[p], lower, inverse, grid->cells) : -1;
  }
}

template <int D> int TwoPhase<D>::patch_of(long long cell, long long cells) {
  // A dense slot per lattice cell while the lattice is not much larger than the particles, else a map.
  if (cells <= 8 * static_cast<long long>(dp_.size()) + 4096) {
    if (slot_.size() != static_cast<std::size_t>(cells)) slot_.assign(static_cast<std::size_t>(cells), -1);
    int& id = slot_[static_cast<std::size_t>(cell)];
    if (id < 0) id = static_cast<int>(sums_.size()), sums_.push_back({0.0, 0.0}), used_.push_back(cell);
    return id;
  }
  const int id = number_.try_emplace(cell, static_cast<int>(sums_.size())).first->second;
  if (id == static_cast<int>(sums_.size())) sums_.push_back({0.0, 0.0});
  return id;
}

template <int D> void TwoPhase<D>::average_pressure(Engine<D>& e) {
  // Each cell's volume-weighted mean increment (eq. 15.3a), summed in particle order.
  Particles<D>& P = e.particles();
  double* pp = P.find_state(kPorePressureField)->values.data();
  const std::optional<CartesianGrid<D>>& grid = e.basis().nodes().grid();
  long long cells = 1;
  for (int k = 0; grid && k < D; ++k) cells *= grid->cells[k] + 1LL;
  const int n = P.size();
  patch_.resize(static_cast<std::size_t>(n));
  sums_.clear(), number_.clear();
  const bool distributed = e.distribution() != nullptr;
  if (distributed) distributed_means(e);
  long long last = -2;
  int id = -1;
  for (int p = 0; p < n && !distributed; ++p) {
    const auto i = static_cast<std::size_t>(p);
    if (!fluids_[static_cast<std::size_t>(P.material[p])] || cell_[i] < 0) {
      patch_[i] = -1;
      continue;
    }
    if (cell_[i] != last) last = cell_[i], id = patch_of(last, cells); // consecutive particles mostly share a cell
    patch_[i] = id;
    sums_[static_cast<std::size_t>(id)][0] += P.V[p] * dp_[i];
    sums_[static_cast<std::size_t>(id)][1] += P.V[p];
  }
  for (long long c : used_) slot_[static_cast<std::size_t>(c)] = -1; // ready for the next step
  used_.clear();
  for (std::array<double, 2>& s : sums_) s[0] /= s[1]; // each patch's mean increment, once
  // The new pressures, and in the same pass (blocks as totals() takes them: its bits) the after-step sums.
  totals_ = blocked_reduce_ranges<LiquidTotals<D>>(n, [&](long long b0, long long b1, LiquidTotals<D>& acc) {
    for (auto i = static_cast<std::size_t>(b0); i < static_cast<std::size_t>(b1); ++i) {
      if (!fluids_[static_cast<std::size_t>(P.material[i])]) continue;
      const int j = patch_[i];
      const double mean = distributed ? means_[i] : j < 0 ? dp_[i] : sums_[static_cast<std::size_t>(j)][0];
      const PoreFluid& f = *fluids_[static_cast<std::size_t>(P.material[i])];
      // eq. 15.13: the pressure's work on the increment the average leaves out
      acc.averaged += (P.V[i] - (1.0 - f.porosity) * P.V0[i]) * pp[i] * (dp_[i] - mean) / f.bulk_modulus;
      pp[i] += mean;
    }
    add_totals(e, static_cast<int>(b0), static_cast<int>(b1), acc);
  });
  if (!distributed) averaged_ += totals_.averaged; // else the ranks' sum (add_pressure_average)
  totals_ready_ = true;
  cells_ready_ = true; // the particles' cells at the step's end: the next step's start
}

template <int D> void TwoPhase<D>::distributed_means(Engine<D>& e) {
  const Particles<D>& P = e.particles();
  const CartesianGrid<D>& grid = *e.basis().nodes().grid(); // this rank's window of the lattice
  const Vec<D> inverse = grid.h().cwiseInverse();
  constexpr int corners = 1 << D;
  const auto n = static_cast<std::size_t>(P.size());
  corner_.assign(mw_.size() * corners * 2, 0.0);
  means_.assign(n, 0.0);
  // The particle's cell, up to one cell beyond the window (a particle that left this rank's cells),
  // and its corner `b`'s node in the window, or -1.
  const auto cell_of = [&](std::size_t p) {
    Index<D> c;
    for (int k = 0; k < D; ++k) {
      const double x = (P.x[p][k] - grid.lower[k]) * inverse[k];
      c[k] = std::isnan(x) ? 0 : static_cast<int>(std::floor(std::clamp(x, -1.0, grid.cells[k] + 0.5)));
    }
    return c;
  };
  const auto corner_node = [&](const Index<D>& c, int b) {
    Index<D> node;
    for (int k = 0; k < D; ++k) {
      node[k] = c[k] + ((b >> k) & 1);
      if (node[k] < 0 || node[k] > grid.cells[k]) return -1;
    }
    return grid.node_id(node);
  };
  for (std::size_t p = 0; p < n; ++p) {
    if (!fluids_[static_cast<std::size_t>(P.material[p])]) continue;
    const Index<D> c = cell_of(p);
    for (int b = 0; b < corners; ++b)
      if (const int I = corner_node(c, b); I >= 0) {
        double* s = &corner_[(static_cast<std::size_t>(I) * corners + static_cast<std::size_t>(b)) * 2];
        s[0] += P.V[p] * dp_[p], s[1] += P.V[p];
      }
  }
  e.distribution()->sum_nodal(std::array<NodalArray, 1>{NodalArray{corner_.data(), 2 * corners}});
  for (std::size_t p = 0; p < n; ++p) {
    if (!fluids_[static_cast<std::size_t>(P.material[p])]) continue;
    const Index<D> c = cell_of(p);
    const double* best = nullptr;
    for (int b = 0; b < corners; ++b)
      if (const int I = corner_node(c, b); I >= 0) {
        const double* s = &corner_[(static_cast<std::size_t>(I) * corners + static_cast<std::size_t>(b)) * 2];
        if (!best || s[1] > best[1]) best = s;
      }
    means_[p] = best ? best[0] / best[1] : dp_[p];
  }
}

template <int D> LiquidTotals<D>& LiquidTotals<D>::operator+=(const LiquidTotals& o) {
  kinetic += o.kinetic, stored += o.stored, averaged += o.averaged, momentum += o.momentum;
  wave_speed2 = std::max(wave_speed2, o.wave_speed2);
  bad = lowest(bad, o.bad);
  return *this;
}

template <int D> void TwoPhase<D>::add_totals(const Engine<D>& e, int b0, int b1, LiquidTotals<D>& acc) const {
  const Particles<D>& P = e.particles();
  const double* pp = P.find_state(kPorePressureField)->values.data();
  const double* w = P.find_state(kLiquidVelocityField)->values.data();
  for (int r0 = b0; r0 < b1;) { // runs of one material
    int r1 = r0 + 1;
    while (r1 < b1 && P.material[r1] == P.material[r0]) ++r1;
    const PoreFluid* f = fluid(P.material[r0]);
    if (!f) {
      r0 = r1;
      continue;
    }
    const double half_compliance = 0.5 / f->bulk_modulus, grains = 1.0 - f->porosity;
    // Locals: the loop keeps them in registers. The pores' volume n V = V - (1 - n_0) V0 (no division).
    double kinetic = 0.0, stored = 0.0, pores = 1.0, volume = 1.0, density = kUnbounded;
    Vec<D> momentum = Vec<D>::Zero();
    for (int p = r0; p < r1; ++p) {
      const Vec<D> wp = Eigen::Map<const Vec<D>>(w + static_cast<std::size_t>(p) * D);
      const double pressure = pp[p];
      if (!std::isfinite(pressure) || !wp.allFinite()) acc.bad = lowest(acc.bad, p);
      const double V = P.V[p], nV = V - grains * P.V0[p], mw = f->density * nV;
      kinetic += 0.5 * mw * wp.squaredNorm();
      stored += nV * pressure * pressure * half_compliance;
      momentum += mw * wp;
      if (nV * volume < pores * V) pores = nV, volume = V; // the smallest porosity as a fraction
      density = std::min(density, P.rho[p]);
    }
    acc.kinetic += kinetic, acc.stored += stored, acc.momentum += momentum;
    // The fastest wave of the run (eq. 15.7) is at most that of its stiffest skeleton, its smallest
    // porosity and its lightest skeleton: exact for a uniform run.
    double c2 = 0.0; // the skeleton's largest c^2 = M / rho_p over the run: M <= c2 rho_p for each
    e.material(P.material[r0]).max_wave_speed2(P, r0, r1, c2);
    const double n = pores / volume;
    if (n > 0.0 && n < 1.0)
      acc.wave_speed2 = std::max(acc.wave_speed2, fast_wave_speed2(c2, n, density, f->bulk_modulus,
                                                                   f->bulk_modulus / f->density));
    r0 = r1;
  }
}

template <int D> LiquidTotals<D> TwoPhase<D>::totals(const Engine<D>& e) {
  if (std::exchange(totals_ready_, false)) return totals_; // summed by the step's last pass over the particles
  return blocked_reduce_ranges<LiquidTotals<D>>(e.particles().size(), [&](long long b0, long long b1, LiquidTotals<D>& acc) {
    add_totals(e, static_cast<int>(b0), static_cast<int>(b1), acc);
  });
}

template <int D> std::vector<double> TwoPhase<D>::wave_maxima(const Engine<D>& e) {
  const Distribution<D>& dist = *e.distribution();
  const Particles<D>& P = e.particles();
  if (blocks_ < 0) { // the particles of the whole run
    double count = 0.0;
    for (int p = 0; p < P.size(); ++p) count = std::max(count, static_cast<double>(dist.global_id(p)) + 1.0);
    e.distribution()->max({&count, 1});
    blocks_ = reduction_blocks(static_cast<long long>(count));
  }
  const std::size_t materials = fluids_.size();
  std::vector<double> m(static_cast<std::size_t>(blocks_) * materials * 3, -kUnbounded);
  for (int p = 0; p < P.size(); ++p) {
    const PoreFluid* f = fluids_[static_cast<std::size_t>(P.material[p])];
    if (!f) continue;
    const auto block = static_cast<std::size_t>(dist.global_id(p) / reduction_block);
    double* g = &m[(block * materials + static_cast<std::size_t>(P.material[p])) * 3];
    double c2 = 0.0;
    e.material(P.material[p]).max_wave_speed2(P, p, p + 1, c2);
    const double n = (P.V[p] - (1.0 - f->porosity) * P.V0[p]) / P.V[p];
    g[0] = std::max(g[0], c2), g[1] = std::max(g[1], -n), g[2] = std::max(g[2], -P.rho[p]);
  }
  return m;
}

template <int D> double TwoPhase<D>::wave_speed2(std::span<const double> maxima) const {
  double c2 = 0.0;
  for (std::size_t g = 0; g + 2 < maxima.size(); g += 3) {
    const PoreFluid* f = fluids_[(g / 3) % fluids_.size()];
    const double n = -maxima[g + 1];
    if (f && n > 0.0 && n < 1.0)
      c2 = std::max(c2, fast_wave_speed2(maxima[g], n, -maxima[g + 2], f->bulk_modulus, f->bulk_modulus / f->density));
  }
  return c2;
}

template <int D> Vec<D> TwoPhase<D>::momentum(const Particles<D>& P) const {
  const StateField& w = *P.find_state(kLiquidVelocityField);
  return blocked_reduce<LiquidTotals<D>>(P.size(), [&](long long i, LiquidTotals<D>& acc) {
           const int p = static_cast<int>(i);
           if (const PoreFluid* f = fluid(P.material[p]))
             acc.momentum += porosity(*f, P.V0[p], P.V[p]) * f->density * P.V[p] * liquid_at<D>(w, p);
         })
      .momentum;
}

template struct LiquidTotals<1>;
template struct LiquidTotals<2>;
template struct LiquidTotals<3>;
template class TwoPhase<1>;
template class TwoPhase<2>;
template class TwoPhase<3>;

} // namespace otmpm
