/// \file domain.cpp
/// One rank's share of a distributed run (domain.hpp): migration, failure
/// agreement and the consistent mass solve by conjugate gradients.
#include "otmpm/distributed/domain.hpp"

#include <cmath>
#include <limits>
#include <new>

namespace otmpm::distributed {

template <int D>
Domain<D>::Domain(const Comm& comm, Setup s)
    : comm_(comm), lattice_(std::move(s.lattice)), decomposition_(std::move(s.decomposition)),
      exchange_(lattice_, decomposition_, comm.rank()), nodes_move_(s.nodes_move),
      gid_(std::move(s.global_ids)), global_particles_(s.global_particles), hint_offset_(s.hint_offset),
      traction_area_(std::move(s.traction_area)), window_basis_(std::move(s.window_basis)),
      window_dirichlet_(std::move(s.window_dirichlet)), reset_lattice_(std::move(s.reset_lattice)),
      reset_window_(std::move(s.reset_window)) {
  stats_.setup_particles = s.setup_particles;
  stats_.setup_points = s.setup_points;
  stats_.steps = s.steps;
  staying_ = interior_box(lattice_.grid, decomposition_.box(comm_.rank()));
  find_neighbours();
  find_guard();
}

template <int D> void Domain<D>::find_guard() {
  const Window<D>& w = exchange_.window();
  guard_.assign(static_cast<std::size_t>(w.size()), 0);
  if (lattice_.guard == 0) return;
  for (int i = 0; i < w.size(); ++i) {
    const Index<D> ijk = w.index(i);
    for (int k = 0; k < D; ++k) {
      const bool low = w.box.lo[k] > 0 && ijk[k] < w.box.lo[k] + lattice_.guard;
      const bool high = w.box.hi[k] < lattice_.points[k] && ijk[k] >= w.box.hi[k] - lattice_.guard;
      if (low || high) guard_[static_cast<std::size_t>(i)] = 1;
    }
  }
}

template <int D> void Domain<D>::check_support(const BasisTable<D>& table) const {
  if (lattice_.guard == 0) return;
  for (int p = 0; p < table.rows(); ++p)
    for (int e = table.begin(p); e < table.end(p); ++e)
      if (guard_[static_cast<std::size_t>(table.node[e])])
        throw ParticleFailure{p, "its basis support reaches the outer layer of the nodes rank " +
                                     std::to_string(comm_.rank()) +
                                     " holds: in ul mode a particle keeps the cell it was seeded in while the lattice "
                                     "moves, and this one drifted too far from it (run with fewer ranks)"};
}

template <int D> void Domain<D>::find_neighbours() {
  neighbours_.clear();
  IndexBox<D> near = decomposition_.box(comm_.rank());
  for (int k = 0; k < D; ++k) --near.lo[k], ++near.hi[k];
  for (int q = 0; q < decomposition_.ranks(); ++q)
    if (q != comm_.rank() && !near.intersect(decomposition_.box(q)).empty()) neighbours_.push_back(q);
}

template <int D> void Domain<D>::before_step(Engine<D>& e) {
  ++stats_.steps;
  if (nodes_move_) return;
  const Clock clock(stats_);
  if (departures_) migrate(e);
  departures_ = true; // until the next after-step reduction says otherwise
  if (window_basis_ && stats_.steps % kRebalanceCheck == 0) rebalance(e);
}

template <int D> void Domain<D>::shift_hints(Engine<D>& e, int sign) const {
  for (Index<D>& h : e.basis().point_state().cell_hint)
    for (int k = 0; k < D; ++k) h[k] += sign * hint_offset_[k];
}

template <int D> void Domain<D>::rebalance(Engine<D>& e) {
  const Particles<D>& P = e.particles();
  // After before_step's migration (or a step that needed none), every
  // particle's home cell is in this rank's box.
  if (decomposition_.imbalance(P.size(), comm_) <= kImbalanceThreshold) return;
  ++stats_.rebalances;
  std::vector<Index<D>> home(static_cast<std::size_t>(P.size()));
  for (int p = 0; p < P.size(); ++p) home[static_cast<std::size_t>(p)] = home_cell(P.x[p], P.X[p]);
  decomposition_ = Decomposition<D>::rcb(lattice_.grid.cells, comm_.size(), home, comm_);
  staying_ = interior_box(lattice_.grid, decomposition_.box(comm_.rank()));
  find_neighbours();
  migrate(e); // to the new owners (cell hints local to the old window)
  shift_hints(e, +1);
  exchange_ = NodeExchange<D>(lattice_, decomposition_, comm_.rank());
  find_guard();
  const Window<D>& w = exchange_.window();
  std::unique_ptr<Basis<D>> basis = window_basis_(w, hint_offset_);
  Dirichlet<D> dirichlet = window_dirichlet_(w, *basis);
  e.repartition(std::move(basis), std::move(dirichlet));
  shift_hints(e, -1); // local to the new window
}

template <int D>
LatticePart<D> Domain<D>::lay_out(Engine<D>& e, const CartesianGrid<D>& grid, double t, bool restart) {
  require<std::logic_error>(reset_lattice_ && reset_window_,
                            "Domain::lay_out: this run cannot lay its nodes out anew");
  const Clock clock(stats_);
  if (!restart) { // (even on the same lattice: the particles' cells are those of x now, their F-bar patches)
    lattice_ = reset_lattice_(grid);
    const Particles<D>& P = e.particles();
    std::vector<Index<D>> home(static_cast<std::size_t>(P.size()));
    for (int p = 0; p < P.size(); ++p) home[static_cast<std::size_t>(p)] = grid.cell_of(P.x[p]);
    decomposition_ = Decomposition<D>::rcb(grid.cells, comm_.size(), home, comm_);
    find_neighbours();
    migrate(e, &home);
  }
  exchange_ = NodeExchange<D>(lattice_, decomposition_, comm_.rank());
  find_guard();
  return reset_window_(lattice_, decomposition_.box(comm_.rank()), exchange_.window(), t, hint_offset_);
}

template <int D> std::vector<Column> Domain<D>::columns(Engine<D>& e) {
  std::vector<Column> c = particle_columns(e.particles(), e.basis().point_state());
  c.push_back(column_of(gid_));
  for (auto& a : traction_area_) c.push_back(column_of(a));
  return c;
}

template <int D> void Domain<D>::migrate(Engine<D>& e, const std::vector<Index<D>>* home) {
  Particles<D>& P = e.particles();
  const std::size_t n = static_cast<std::size_t>(P.size());
  const IndexBox<D>& mine = decomposition_.box(comm_.rank());
  std::vector<int> dest(n, -1);
  double flags[2] = {0.0, 0.0}; // some particle leaves; some goes to a rank that is not a neighbour
  for (std::size_t p = 0; p < n; ++p) {
    if (!home && !nodes_move_ && staying_.contains(P.x[p])) continue; // home cell: the cell of x
    const Index<D> c = home ? (*home)[p] : home_cell(P.x[p], P.X[p]);
    if (mine.contains(c)) continue;
    dest[p] = decomposition_.owner(c);
    flags[0] = 1.0;
    if (!std::binary_search(neighbours_.begin(), neighbours_.end(), dest[p])) flags[1] = 1.0;
  }
  comm_.max(flags);
  ++stats_.reductions;
  if (flags[0] == 0.0) return;
  if (test_allocation_fails("migration", e.steps())) throw std::bad_alloc();
  shift_hints(e, +1); // hints travel as global cells
  const std::vector<Column> cols = columns(e);
  std::vector<char> keep(n, 1);
  std::vector<Bytes> received;
  const bool far = flags[1] != 0.0;
  std::vector<Bytes> out(far ? static_cast<std::size_t>(comm_.size()) : neighbours_.size());
  for (std::size_t p = 0; p < n; ++p) {
    if (dest[p] < 0) continue;
    keep[p] = 0;
    ++stats_.migrated;
    const std::size_t to = far ? static_cast<std::size_t>(dest[p])
                               : static_cast<std::size_t>(std::lower_bound(neighbours_.begin(), neighbours_.end(),
                                                                           dest[p]) - neighbours_.begin());
    pack_row(cols, p, out[to]);
  }
  received = far ? comm_.alltoall(std::move(out)) : comm_.exchange(neighbours_, out, neighbours_);
  keep_rows(cols, keep, n);
  std::size_t count = 0;
  for (std::size_t p = 0; p < n; ++p) count += keep[p];
  for (const Bytes& in : received) count = append_rows(cols, in, count);
  shift_hints(e, -1);
  // The Verlet lists belong to particle indices that changed: start afresh
  // (they change the cost of the next basis evaluation, never its result).
  e.basis().point_state().neighbours = NeighbourLists<D>();
  rebuild_tractions(e);
}

template <int D> void Domain<D>::rebuild_tractions(Engine<D>& e) const {
  auto& loads = e.loads().tractions;
  for (std::size_t i = 0; i < loads.size() && i < traction_area_.size(); ++i) {
    loads[i].particle.clear();
    loads[i].area.clear();
    for (std::size_t p = 0; p < traction_area_[i].size(); ++p)
      if (traction_area_[i][p] >= 0.0) {
        loads[i].particle.push_back(static_cast<int>(p));
        loads[i].area.push_back(traction_area_[i][p]);
      }
  }
}

template <int D> void Domain<D>::reduce(std::span<double> sums, std::span<double> maxima) {
  const Clock clock(stats_);
  ++stats_.reductions;
  std::vector<double> m(maxima.begin(), maxima.end());
  m.push_back(pending_ ? 1.0 : 0.0); // a deferred failure anywhere
  comm_.reduce(sums, m);
  std::copy(m.begin(), m.end() - 1, maxima.begin());
  if (m.back() > 0.0) agree(nullptr);
}

template <int D> void Domain<D>::defer(const LocalFailure& failure) {
  const long long key = failure.key >= LocalFailure::kNoParticle ? LocalFailure::kNoParticle + comm_.rank() : failure.key;
  if (!pending_ || key < pending_->key) {
    pending_ = failure;
    pending_->key = key;
  }
}

template <int D> void Domain<D>::agree(const LocalFailure* given) {
  const Clock clock(stats_);
  ++stats_.reductions;
  if (given) defer(*given);
  const LocalFailure* failure = pending_ ? &*pending_ : nullptr;
  constexpr long long none = std::numeric_limits<long long>::max();
  const long long key = failure ? failure->key : none;
  const long long best = comm_.min(static_cast<std::int64_t>(key));
  if (best == none) return;
  const int winner = static_cast<int>(comm_.min(static_cast<std::int64_t>(key == best ? comm_.rank() : comm_.size())));
  const bool mine = comm_.rank() == winner;
  std::string message = comm_.broadcast(
      mine ? std::string(failure->memory ? "M" : failure->deferred ? "D" : failure->instability ? "I" : "B") +
                 failure->message
           : "",
      winner);
  const char kind = message.front();
  message.erase(0, 1);
  pending_.reset();
  if (kind == 'M') throw DeferredOutOfMemory(message);
  if (kind == 'D') throw DeferredInstability(message);
  if (kind == 'I') throw InstabilityError(message);
  throw InputError(message);
}

// ---------------------------------------------------------------- consistent mass

namespace {

/// q = M p on this rank's particles (partial sums; the caller sums them over
/// the ranks): q_I = sum_p N_Ip m_p sum_J N_Jp p_J.
template <int D>
void mass_times(const BasisTable<D>& table, const std::vector<double>& m_p, const AlignedVector<Vec<D>>& p,
                AlignedVector<Vec<D>>& q) {
  std::fill(q.begin(), q.end(), Vec<D>::Zero());
  for (int a = 0; a < table.rows(); ++a) {
    Vec<D> s = Vec<D>::Zero();
    for (int e = table.begin(a); e < table.end(a); ++e) s += table.N[e] * p[table.node[e]];
    s *= m_p[static_cast<std::size_t>(a)];
    for (int e = table.begin(a); e < table.end(a); ++e) q[table.node[e]] += table.N[e] * s;
  }
}

} // namespace

template <int D>
void Domain<D>::constrained_rows_product(const BasisTable<D>& table, const std::vector<double>& m_p,
                                         const std::vector<char>& active, const std::vector<char>& constrained,
                                         const AlignedVector<Vec<D>>& y, AlignedVector<Vec<D>>& rho) {
  const std::size_t n = y.size();
  AlignedVector<Vec<D>> free(n);
  for (std::size_t I = 0; I < n; ++I)
    for (int k = 0; k < D; ++k)
      free[I][k] = active[I] && !constrained[I * D + static_cast<std::size_t>(k)] ? y[I][k] : 0.0;
  rho.resize(n);
  mass_times(table, m_p, free, rho);
  NodalArray field{rho.data()->data(), D};
  stats_.halo_bytes += exchange_.sum(comm_, {&field, 1});
  for (std::size_t I = 0; I < n; ++I)
    for (int k = 0; k < D; ++k)
      if (!constrained[I * D + static_cast<std::size_t>(k)]) rho[I][k] = 0.0;
}

template <int D>
void Domain<D>::solve_consistent_mass(const BasisTable<D>& table, const std::vector<double>& m_p,
                                      const std::vector<double>& m_lumped, const std::vector<char>& active,
                                      const std::vector<char>& constrained, const AlignedVector<Vec<D>>& r,
                                      AlignedVector<Vec<D>>& y) {
  // Conjugate gradients on the free components, preconditioned by the
  // lumped mass (the row sums of M), all D components in one pass per
  // iteration; dot products over the owned nodes, summed over the ranks.
  const std::size_t n = r.size();
  const std::vector<char>& owned = exchange_.owned();
  std::vector<Vec<D>> mask(n, Vec<D>::Zero());
  for (std::size_t I = 0; I < n; ++I)
    for (int k = 0; k < D; ++k) mask[I][k] = active[I] && !constrained[I * D + static_cast<std::size_t>(k)] ? 1.0 : 0.0;
  AlignedVector<Vec<D>> x(n, Vec<D>::Zero()), res(n), z(n), p(n), q(n);
  auto precondition = [&] {
    for (std::size_t I = 0; I < n; ++I) z[I] = active[I] ? Vec<D>(res[I] / m_lumped[I]) : Vec<D>::Zero();
  };
  // dot(a, b) and dot(c, d) over the owned nodes, per component, summed over the ranks
  auto dots = [&](const AlignedVector<Vec<D>>& a, const AlignedVector<Vec<D>>& b, const AlignedVector<Vec<D>>& c,
                  const AlignedVector<Vec<D>>& d, Vec<D>& ab, Vec<D>& cd) {
    double s[2 * D] = {};
    for (std::size_t I = 0; I < n; ++I)
      if (owned[I])
        for (int k = 0; k < D; ++k) s[k] += a[I][k] * b[I][k], s[D + k] += c[I][k] * d[I][k];
    comm_.sum(s);
    for (int k = 0; k < D; ++k) ab[k] = s[k], cd[k] = s[D + k];
  };
  for (std::size_t I = 0; I < n; ++I) res[I] = r[I].cwiseProduct(mask[I]);
  precondition();
  p = z;
  Vec<D> rz, bb;
  dots(res, z, res, res, rz, bb);
  std::array<bool, D> done{};
  std::array<double, D> best;    // smallest relative residual so far
  std::array<int, D> since{};    // iterations since it last halved
  best.fill(std::numeric_limits<double>::infinity());
  for (int k = 0; k < D; ++k) done[static_cast<std::size_t>(k)] = bb[k] == 0.0;
  int it = 0;
  double worst = 0.0;
  for (; it < kMassMaxIterations && !std::all_of(done.begin(), done.end(), [](bool b) { return b; }); ++it) {
    mass_times(table, m_p, p, q);
    NodalArray field{q.data()->data(), D};
    stats_.halo_bytes += exchange_.sum(comm_, {&field, 1});
    for (std::size_t I = 0; I < n; ++I) q[I] = q[I].cwiseProduct(mask[I]);
    Vec<D> pq, unused;
    dots(p, q, p, q, pq, unused);
    Vec<D> alpha = Vec<D>::Zero();
    for (int k = 0; k < D; ++k)
      if (!done[static_cast<std::size_t>(k)]) alpha[k] = rz[k] / pq[k];
    for (std::size_t I = 0; I < n; ++I) {
      x[I] += alpha.cwiseProduct(p[I]);
      res[I] -= alpha.cwiseProduct(q[I]);
    }
    precondition();
    Vec<D> rz_new, rr;
    dots(res, z, res, res, rz_new, rr);
    worst = 0.0;
    for (int k = 0; k < D; ++k) {
      const std::size_t kk = static_cast<std::size_t>(k);
      if (done[kk]) continue;
      const double rel = std::sqrt(rr[k] / bb[k]);
      if (!std::isfinite(rel))
        throw InstabilityError("consistent mass: conjugate gradients met a non-finite residual (component " +
                               std::to_string(k) + ")");
      worst = std::max(worst, rel);
      if (rel < 0.5 * best[kk]) best[kk] = rel, since[kk] = 0;
      else ++since[kk];
      // converged, or stalled at round-off (the recursive residual no longer falls)
      if (rel <= kMassTolerance || (rel <= kMassStall && since[kk] >= kMassStallIterations)) done[kk] = true;
    }
    Vec<D> beta = Vec<D>::Zero();
    for (int k = 0; k < D; ++k)
      if (!done[static_cast<std::size_t>(k)]) beta[k] = rz_new[k] / rz[k];
    for (std::size_t I = 0; I < n; ++I) p[I] = z[I] + beta.cwiseProduct(p[I]);
    rz = rz_new;
  }
  ++stats_.cg_solves;
  stats_.cg_iterations += it;
  stats_.cg_worst_residual = std::max(stats_.cg_worst_residual, worst);
  if (!std::all_of(done.begin(), done.end(), [](bool b) { return b; }))
    throw InstabilityError("consistent mass: conjugate gradients did not converge in " +
                           std::to_string(kMassMaxIterations) + " iterations (relative residual " +
                           format_number(worst) + ")");
  y.resize(n);
  for (std::size_t I = 0; I < n; ++I) y[I] = x[I].cwiseProduct(mask[I]);
}

template class Domain<1>;
template class Domain<2>;
template class Domain<3>;

} // namespace otmpm::distributed
