/// \file engine.cpp
/// The engine's construction, its step and the stages the integrators drive
/// (engine.hpp); the after-step checks and energies are in monitor.cpp, the
/// checkpoint state in engine_state.cpp.
#include "otmpm/engine/engine.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/engine/channel_walls.hpp"
#include "otmpm/engine/scatter.hpp"
#include "otmpm/engine/two_phase_scatter.hpp"
#include "otmpm/particles/particles_box.hpp"

#include "otmpm/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <new>
#include <numeric>
#include <unordered_map>
#include <utility>

namespace otmpm {

namespace {

/// Particles whose velocity gradient is gathered before their materials
/// update them (a batch on the stack, one virtual call per run of a material).
constexpr int kStressBatch = 64;

/// ul: a node lighter than this fraction of the heaviest node moves with
/// the material it carries (Engine::advect_nodes). The lattice a body fills
/// has none (its lightest node, a corner, carries 1/2^D of the heaviest);
/// a node the material barely reaches carries far less. The rule asks
/// nothing of the layout: on a node cloud (a mesh's vertices) it moves a
/// light node by its material's mass-weighted displacement alike.
constexpr double kLightNode = 1e-2;

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

/// How far from a node its shape function reaches (NodeView::reach), on
/// nodes that stay where they are: the search radius of a family that
/// searches nodes; on a lattice, half the cells a node's stencil spans
/// (LatticeReach: below + above + 1) times the lattice's largest spacing,
/// twice that on a perturbed lattice (whose nodes sit up to half a cell
/// off); for B-splines the same with their knot span. Unbounded on a mesh's
/// vertices, whose elements' sizes vary, and on nodes that move (`ul`: their
/// supports deform with the body).
template <int D> double wall_reach(const Basis<D>& basis, bool nodes_move) {
  if (nodes_move) return std::numeric_limits<double>::infinity();
  if (basis.search_radius() > 0.0) return basis.search_radius();
  const BasisKind* family = find_basis_kind(basis.kind());
  const NodeSet<D>& nodes = basis.nodes();
  const auto& grid = nodes.grid();
  if (!family || !family->reach || (!grid && !family->bspline)) return std::numeric_limits<double>::infinity();
  const double h = grid ? grid->h().maxCoeff() : nodes.spacing();
  const LatticeReach r = family->reach(0.0, h, D);
  return 0.5 * (r.below + r.above + 1) * h * (nodes.layout() == NodeLayout::perturbed ? 2.0 : 1.0);
}

/// The visited nodes of `n` when they are a part of the nodes, or null when
/// the loops visit every node (or, before the first step, none is listed).
template <int D> const std::vector<int>* visit_list(const NodalFields<D>& n) {
  const bool every = n.visited.size() == n.m.size() || n.visited.empty();
  return every ? nullptr : &n.visited;
}

/// The nodes at positions x with the masses, active and visited nodes of
/// `n` and the basis' reach (the walls' passes).
template <int D>
NodeView<D> node_view(const AlignedVector<Vec<D>>& x, const NodalFields<D>& n, const Basis<D>& basis,
                      bool nodes_move) {
  return {x, n.m, n.active, n.active_nodes, wall_reach(basis, nodes_move), visit_list(n)};
}

/// What the integrator's row says it needs (StepNeeds): the particle fields
/// it keeps are allocated at their values at t = 0 when the parts lack them;
/// the node mode, the basis, the mass and the parameters it runs with must
/// be there. std::invalid_argument naming the integrator and the need.
template <int D>
void provide_step_needs(const StepSettings<D>& s, const NodeMode<D>& mode, const Basis<D>& basis, Particles<D>& P) {
  using E = std::invalid_argument;
  const StepNeeds& needs = s.step.needs;
  const std::string who = "Engine: integrator '" + std::string(s.step.name) + "' ";
  const auto n = static_cast<std::size_t>(P.size());
  if (needs.acceleration && P.a.empty()) P.a.assign(n, Vec<D>::Zero());
  if (needs.previous_position && P.x_prev.empty()) P.x_prev = P.x;
  require<E>(P.a.empty() || P.a.size() == n, "Engine: the particle accelerations have ", P.a.size(), " entries, not ", n);
  require<E>(P.x_prev.empty() || P.x_prev.size() == n, "Engine: the previous positions have ", P.x_prev.size(),
             " entries, not ", n);
  require<E>(!needs.advected_nodes || mode.nodes_move(),
             who + "needs nodes that move with the body (NodeMode::advected, mode ul)");
  const BasisKind* family = find_basis_kind(basis.kind());
  require<E>(!needs.bspline || (family && family->bspline), who + "needs a B-spline basis, not '",
             std::string(basis.kind()), "'");
  require<E>(!needs.consistent_mass || s.consistent_mass,
             who + "needs the consistent mass (StepSettings::consistent_mass = true)");
  for (const ParameterSpec& p : needs.parameters) {
    const auto it = s.parameters.values.find(p.key);
    require<E>(it != s.parameters.values.end(), who + "reads parameter '", std::string(p.key),
               "', which StepSettings::parameters lacks (IntegratorKind::default_parameters() has the defaults)");
    const std::string problem = p.check(it->second);
    require<E>(problem.empty(), who + "parameter '", std::string(p.key), "': ", problem);
  }
}

} // namespace

template <int D> void NodalFields<D>::resize(int n) {
  m.assign(n, 0.0);
  q.assign(n, Vec<D>::Zero());
  v = f = a = dx = reaction = q;
  active.assign(n, 0);
  active_nodes.clear();
  visited.clear();
}

template <int D> void NodalFields<D>::zero(int I) {
  const auto i = static_cast<std::size_t>(I);
  m[i] = 0.0;
  active[i] = 0;
  for (AlignedVector<Vec<D>>* field : {&q, &v, &f, &a, &dx, &reaction})
    if (i < field->size()) (*field)[i] = Vec<D>::Zero();
}

/// A channel's side walls (channel_walls.hpp): plane strain only, on materials
/// that give the out-of-plane stress.
template <int D>
void start_channel(const SideWalls& walls, const Particles<D>& P, Distribution<D>* ranks, bool saturated,
                   const std::vector<std::unique_ptr<Material<D>>>& materials,
                   std::unique_ptr<ChannelWalls<D>>& channel) {
  require<InputError>(D == 2, "[channel]: side walls bound a plane-strain body: the run must be 2D");
  require<InputError>(!saturated, SideWalls::refusal_saturated());
  for (const auto& m : materials) try {
      m->out_of_plane_stress(P, 0, 0, nullptr); // a model without it throws
    } catch (const std::logic_error&) {
      throw InputError("[channel]: material '" + m->name() +
                       "' does not give the out-of-plane stress sigma_zz " +
                       "that presses on the side walls");
    }
  channel = std::make_unique<ChannelWalls<D>>(walls);
  channel->distribute(ranks); // the nodal mean of sigma_zz summed over the ranks
}

/// The side walls' force on every particle for a pass of the step dt (eq. 6.7).
template <int D>
void channel_forces(std::unique_ptr<ChannelWalls<D>>& channel, const Particles<D>& P, StepRows<D>& rows,
                    int nodes, const std::vector<std::unique_ptr<Material<D>>>& materials, double dt) {
  if (!channel) return;
  channel->compute(P, rows.full(), nodes, dt, [&](int p0, int p1, double* out) {
    materials[static_cast<std::size_t>(P.material[p0])]->out_of_plane_stress(P, p0, p1, out);
  });
}

template <int D>
Engine<D>::Engine(EngineParts<D> parts)
    : basis_(std::move(parts.basis)), mode_(parts.mode), P_(std::move(parts.particles)),
      materials_(std::move(parts.materials)), loads_(std::move(parts.loads)), settings_(parts.settings),
      dist_(std::move(parts.distribution)) {
  scatter_ = std::make_unique<ParticleToNodes<D>>();
  check_parts();
  provide_step_needs(settings_, mode_, *basis_, P_);
  const int nodes = basis_->nodes().size();
  const int bodies = P_.body.empty() ? 1 : 1 + *std::max_element(P_.body.begin(), P_.body.end());
  require<InputError>(!(parts.contact && dist_), "[contact]: body-body contact is not available in distributed "
                                                 "runs (MPI); run the scene on one process");
  fbar_.nodal.distribute(dist_.get()); // fbar_nodal's sums over the ranks
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
  settings_.two_phase.reset(); // a liquid phase is the engine's own, from parts.two_phase
  if (parts.two_phase) { // before the materials bind to their state: it adds arrays of its own
    require<std::invalid_argument>(!mode_.nodes_move() && !settings_.consistent_mass && !contact_ &&
                                       constraints_.walls().empty() &&
                                       !(loads_.body_force && loads_.body_force->field),
                                   "Engine: saturated bodies need the fixed grid (mode mpm), the lumped mass, no "
                                   "body contact, no walls and a body force without a field");
    settings_.two_phase = std::make_shared<TwoPhase<D>>(std::move(*parts.two_phase), P_, constraints_.dirichlet(), nodes);
  }
  bool needs_F = false;
  for (const auto& m : materials_) needs_F = needs_F || m->needs_deformation_gradient();
  needs_F = needs_F || basis_->point_state_use(mode_.nodes_move()).deformation; // basis.metric = "deformation"
  if (needs_F && P_.F.empty()) P_.F.assign(static_cast<std::size_t>(P_.size()), Mat<D>::Identity());
  for (const auto& m : materials_) m->bind(P_);
  if (parts.side_walls)
    start_channel(*parts.side_walls, P_, dist_.get(), settings_.two_phase != nullptr, materials_, channel_);
  if (mode_.nodes_move() && basis_->search_radius() > 0.0) follow_body(P_.X);
  require<InputError>(
      !(settings_.node_reset.below > 0.0 && (!mode_.nodes_move() || !settings_.node_reset.lattice)),
      "simulation.node_reset: the nodes are laid out anew only in ul mode, with the lattice's builder "
      "(NodeReset::lattice)");
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
  require<E>(settings_.step.function != nullptr, "Engine: no step function (StepSettings::step: IntegratorKind::step<D>())");
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
    dt = settings_.cfl * cfl_spacing() / c;
  }
  return std::min(dt, settings_.t_end - t_);
}

template <int D> double Engine<D>::cfl_spacing() const {
  double g[2] = {gradient0_, gradient_};
  if (dist_ && mode_.nodes_move() && basis_->search_radius() > 0.0) dist_->max({g, 2});
  const double ratio = g[1] > 0.0 ? g[0] / g[1] : 1.0;
  double h = mode_.cfl_spacing(*basis_, settings_.h, node_spacing0_, ratio);
  if (dist_ && mode_.nodes_move()) dist_->min({&h, 1}); // the ranks' smallest (monotone in the spacing)
  return h;
}

template <int D> void Engine<D>::step() {
  if (dist_) dist_->before_step(*this);
  if (reset_due()) reset_nodes();
  dt_ = stable_dt();
  if (!(dt_ > 0.0) || !std::isfinite(dt_))
    unstable("time step " + format_number(dt_) + " is not positive and finite");
  if (dt_prev_ == 0.0) dt_prev_ = dt_;
  transfer_.clear(); // what a step did not book (otm)
  step_sums_.ready = false; // until the step's last pass takes them (ToParticles::last)
  loads_.traction_positions(P_, traction_start_);
  if (mode_.nodes_move()) x_start_.assign(P_.x.begin(), P_.x.end());
  if (channel_) channel_->start(P_);
  try {
    settings_.step.function(*this, {t_, dt_, dt_prev_, step_, settings_.parameters, P_, nodal_});
  } catch (const ParticleFailure& f) {
    unstable(f.particle, f.what);
  }
  if (channel_) *ledger().friction += channel_->loss(P_); // eq. 6.8 (summed over the ranks with the energies)
  const double t0 = t_, dt_prev0 = dt_prev_;
  t_ += dt_;
  ++step_;
  dt_prev_ = dt_;
  try {
    ScopedPhase timer(timers_, Phase::to_particles); // as the sums a step's last pass takes count
    sum_particles(true);                             // checks, energies, wave speed
  } catch (const DeferredInstability&) { // a rank failed inside the step: stop there, as a serial run does
    t_ = t0, dt_prev_ = dt_prev0, --step_;
    throw;
  } catch (const DeferredOutOfMemory&) {
    t_ = t0, dt_prev_ = dt_prev0, --step_;
    throw;
  }
  // Trapezoidal rule: exact for a constant load on a uniformly accelerating
  // body, where the one-sided rule would leave an O(dt) error in the balance.
  const double power = global_power(t_, momentum_);
  double work = 0.5 * dt_ * (external_power_ + power);
  // The tractions' work on the loaded particles' motion, what it cannot see,
  // and the body force's on the momentum the fixed components do not take.
  // Saturated bodies: the free water's work on each rank's drained nodes.
  TwoPhase<D>* liquid = settings_.two_phase.get();
  double rank[4] = {0.0, 0.0, std::exchange(held_work_, 0.0), liquid ? liquid->take_rank_work() : 0.0};
  if (!loads_.tractions.empty())
    rank[0] = loads_.traction_work(t0, t_, P_, traction_start_), rank[1] = loads_.unresolved_work(t_, P_);
  if (dist_ && (loads_.any() || liquid)) dist_->sum(rank);
  work += rank[0] - rank[2];
  unresolved_work_ = rank[1];
  if (liquid) work += liquid->take_boundary_work() + rank[3]; // the rigid plates, the free water
  energy_.external_work += work;
  external_power_ = power;
  check_energy();
}

bool test_allocation_fails(std::string_view site, long step) {
  static const auto [where, at] = [] {
    const char* v = std::getenv("OTMPM_TEST_FAIL_ALLOCATION");
    const std::string text = v ? v : "";
    const auto colon = text.find(':');
    const std::string name = colon == std::string::npos ? "basis" : text.substr(0, colon);
    const std::string number = colon == std::string::npos ? text : text.substr(colon + 1);
    return std::pair{name, v ? std::strtol(number.c_str(), nullptr, 10) : -1L};
  }();
  static bool failed = false;
  if (failed || at < 0 || site != where || step < at) return false;
  failed = true;
  return true;
}

template <int D> void Engine<D>::evaluate_basis() {
  ScopedPhase timer(timers_, Phase::basis);
  fbar_.ready = false; // a pass that failed in the last step may have left it set
  // Every particle gets an empty row until the ranks stop on a failure
  // (fallible() names the particle by its global id).
  const auto empty_rows = [&] {
    rows_.compact = rows_.factored = false;
    rows_.table = BasisTable<D>{};
    rows_.table.offset.assign(static_cast<std::size_t>(P_.size()) + 1, 0);
    rows_.width = 0;
    scatter_->invalidate(rows_.width);
    list_visited_nodes();
  };
  // The compact lattice rows or the product rows (StepRows) where no part of
  // the step reads the table (TableReaders). In 3D the passes take more
  // instructions to rebuild the eight linear entries than to read them, and
  // still run faster where the table leaves the caches (docs/performance.md).
  const bool lattice = TableReaders{.nodes_move = mode_.nodes_move(),
                                    .ranks = dist_ != nullptr,
                                    .contact = contact_ != nullptr,
                                    .two_phase = settings_.two_phase != nullptr,
                                    .fbar = settings_.volumetric != Volumetric::none,
                                    .consistent_mass = settings_.consistent_mass,
                                    .side_walls = channel_ != nullptr}
                           .none();
  const auto table_rows = [&] {
    const bool may_move = mode_.nodes_move() && basis_->search_radius() > 0.0;
    if (may_move) moved_.resize(P_.x.size(), Vec<D>::Zero());
    const long long moved_before = basis_->moved_points();
    basis_->evaluate_points(P_.x, rows_.table, P_.F.empty() ? nullptr : &P_.F, may_move ? &moved_ : nullptr);
    if (basis_->moved_points() != moved_before) move_into_hull();
    if (contact_) contact_->remap(rows_.table, P_.body);
    rows_.width = linear_row_width(rows_.table);
    scatter_->invalidate(rows_.width);
  };
  fallible([&] {
    try {
      if (test_allocation_fails("basis", step_)) throw std::bad_alloc();
      rows_.compact = rows_.factored = rows_.built = false;
      if (lattice && basis_->evaluate_lattice_rows(P_.x, rows_.lattice)) {
        rows_.compact = true, rows_.width = 1 << D;
        scatter_->invalidate(rows_.width);
      } else if (lattice && basis_->evaluate_product_rows(P_.x, rows_.product)) {
        rows_.factored = true, rows_.width = 0;
        scatter_->invalidate(rows_.width);
      }
      if (!rows_.compact && !rows_.factored) table_rows();
      list_visited_nodes();
      if (dist_) dist_->check_support(rows_.table);
      if (settings_.volumetric == Volumetric::fbar) assign_patches();
      if (mode_.nodes_move() && basis_->search_radius() > 0.0) measure_gradients();
    } catch (const BasisError& e) {
      if (!dist_) unstable(std::string("basis evaluation failed: ") + e.what());
      empty_rows();
      throw;
    } catch (const std::bad_alloc&) { // the table freed: the step goes on with empty rows to the reduction
      if (dist_) empty_rows();
      throw;
    }
  });
}

template <int D> void Engine<D>::to_nodes(const ToNodes<D>& what) {
  ScopedPhase timer(timers_, Phase::to_nodes);
  if (what.forces && !loads_.uniform() && loads_.any()) loads_.particle_forces(what.t, P_, fext_);
  if (what.forces) channel_forces(channel_, P_, rows_, static_cast<int>(nodal_.m.size()), materials_, dt_);
  to_nodes_with(what, [](int, int) {});
  exchange_sums(what.mass, what.w != nullptr, what.forces || what.split);
  if (what.mass) finish_mass();
  // The step's first sums (every integrator's): the body force's work on the
  // momentum its fixed components do not take (docs/theory.md eq. 11.1c;
  // saturated bodies book it with the liquid's, eq. 15.14).
  if (what.mass && what.w == &P_.v && !settings_.two_phase)
    held_work_ = dt_ * constraints_.held_body_power(loads_.body_force_at(t_), nodal_.q, nodal_.m);
}

template <int D>
template <class Update>
void Engine<D>::to_nodes_with(const ToNodes<D>& what, Update&& update) {
  const bool q = what.w != nullptr;
  require<std::invalid_argument>(!what.split || (q && what.a && what.mass && !what.forces),
                                 "Engine::to_nodes: split momenta need w, a and the mass, and no forces");
  require<std::invalid_argument>(!what.liquid || (q && what.mass && what.forces && !what.split),
                                 "Engine::to_nodes: the liquid's sums go with the mass, momenta and forces");
  if (what.split) to_nodes_impl<true, true, false, true>(what, update);
  else if (what.mass && q && what.forces) to_nodes_impl<true, true, true>(what, update);
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
  // the side walls press with sigma_zz before the update (the pass's start)
  channel_forces(channel_, P_, rows_, static_cast<int>(nodal_.m.size()), materials_, dt_);
  fallible([&] {
    // F-bar: the forces' patch means need every new stress first. With few
    // scatter blocks per thread the updates also run first, in chunks the
    // threads share: one block's plastic particles would hold its thread.
    const bool first = average_volumetric(g) || few_scatter_blocks(P_.size());
    if (first)
      parallel_chunks(P_.size(), [&](long long p0, long long p1) {
        update_stress_range(g, static_cast<int>(p0), static_cast<int>(p1));
      });
    to_nodes_impl<false, false, true>(what, [&](int p0, int p1) {
      if (!first) update_stress_range(g, p0, p1);
    });
  });
  fbar_.ready = false;
  exchange_sums(false, false, true);
}

template <int D> void Engine<D>::to_particles_then_to_nodes(const ToParticles<D>& move, const ToNodes<D>& what) {
  // Its time counts in the to_nodes phase.
  ScopedPhase timer(timers_, Phase::to_nodes);
  require<std::invalid_argument>(!what.mass, "Engine::to_particles_then_to_nodes: the mass does not follow a move");
  if (move.rate) book_transfer(move);
  if (what.forces && !loads_.uniform() && loads_.any()) loads_.particle_forces(what.t, P_, fext_);
  if (what.forces) channel_forces(channel_, P_, rows_, static_cast<int>(nodal_.m.size()), materials_, dt_);
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
template <bool Mass, bool Momentum, bool Forces, bool Split, class Update>
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
  const Vec<D>* side = Forces && channel_ ? channel_->force(P_.size()) : nullptr; // the side walls' f_p
  // F-bar: the patch's mean stress in place of the particle's (volumetric.hpp, docs/theory.md eq. 9.10)
  const double* shift = !Forces                                    ? nullptr
                        : settings_.volumetric == Volumetric::fbar ? fbar_.mean_stress_shift(P_)
                        : settings_.volumetric == Volumetric::fbar_nodal
                            ? fbar_.nodal_mean_stress_shift(P_, table(), static_cast<int>(nodal_.m.size()))
                            : nullptr;
  const double c = what.c;
  // Inlined also where the liquid's sums join it (TwoPhase::scatter_with; measured: called, its
  // payload returned through memory, it took twice the time).
  auto prep = [=](int p) __attribute__((always_inline)) {
    Payload w;
    w.m = m[p];
    if (Split) {
      w.mw = m[p] * vw[p];
      w.fext = m[p] * va[p];
    } else if (Momentum) {
      w.mw = m[p] * vw[p];
      if (va) w.mw += (m[p] * c) * va[p];
    }
    if (Forces) {
      w.Vs = V[p] * sigma[p];
      if (shift) w.Vs.diagonal().array() += V[p] * shift[p];
      w.fext = uniform ? Vec<D>(m[p] * b) : fext ? fext[p] : Vec<D>::Zero();
      if (side) w.fext += side[p];
    }
    return w;
  };
  const NodeSumsAdd<D, Mass, Momentum, Forces, Split> add{};
  auto merge = [&](int I, const NodeSums<D>& acc) {
    if (Mass) nodal_.m[I] += acc.m;
    if (Momentum) nodal_.q[I] += acc.q;
    if (Forces || Split) nodal_.f[I] += acc.f;
  };
  auto clear = [&](int I0, int I1) {
    if (Mass) std::fill(nodal_.m.begin() + I0, nodal_.m.begin() + I1, 0.0);
    if (Momentum) std::fill(nodal_.q.begin() + I0, nodal_.q.begin() + I1, Vec<D>::Zero());
    if (Forces || Split) std::fill(nodal_.f.begin() + I0, nodal_.f.begin() + I1, Vec<D>::Zero());
  };
  if constexpr (Mass && Momentum && Forces && !Split)
    if (what.liquid) return what.liquid->scatter_with(*this, update, prep, add, merge, clear);
  const int nodes = static_cast<int>(nodal_.m.size());
  if (rows_.compact)
    scatter_->run(rows_.lattice, nodes, update, prep, add, merge, clear, visit_list(nodal_));
  else if (rows_.factored)
    scatter_->run(rows_.product, nodes, update, prep, add, merge, clear, visit_list(nodal_));
  else
    scatter_->run(rows_.table, nodes, update, prep, add, merge, clear, visit_list(nodal_));
}

/// The nodes the step's nodal loops visit (NodalFields::visited), after the
/// basis table is built: on a fixed grid (`mpm`) in a serial run without body
/// contact, saturated bodies or the consistent mass, and while fewer than half
/// the nodes were active in the last step, the nodes of the table's rows and
/// the constrained ones; the nodes that leave the list are zeroed, so that
/// every other node holds the zero fields a loop over all nodes would give
/// it. Every node otherwise.
template <int D> void Engine<D>::list_visited_nodes() {
  const int nodes = static_cast<int>(nodal_.m.size());
  std::vector<int>& list = nodal_.visited;
  // Listing costs a pass over the table and the nodes: worth it when the
  // last step's active nodes were fewer than half the nodes. From every node
  // to a list nothing needs zeroing: a loop over all nodes leaves the nodes
  // outside the rows and the constrained ones at zero.
  const bool every = mode_.nodes_move() || contact_ || dist_ || settings_.two_phase ||
                     settings_.consistent_mass || 2 * nodal_.active_nodes.size() >= static_cast<std::size_t>(nodes);
  if (every) {
    if (static_cast<int>(list.size()) != nodes) {
      list.resize(static_cast<std::size_t>(nodes));
      std::iota(list.begin(), list.end(), 0);
    }
    return;
  }
  nodal_.listed.assign(static_cast<std::size_t>(nodes), 0);
  char* mark = nodal_.listed.data();
  // Each thread marks the nodes of its own particles' rows (their table
  // entries stay in its caches); a node two threads mark gets the same 1.
  // The bounds and pointers in locals: a char store may alias any memory,
  // so members read in the loop would be loaded again after every mark.
  parallel_chunks(P_.size(), [&](long long p0, long long p1) {
    char* const marks = mark;
    const auto on = [marks](int I) { std::atomic_ref<char>(marks[I]).store(1, std::memory_order_relaxed); };
    if (rows_.compact) { // a particle in the cell of the one before marks nothing new
      const LatticeRows<D>& r = rows_.lattice;
      const std::array<int, LatticeRows<D>::kCorners> offset = r.corner_offset;
      const int* lowest = r.base.data();
      for (auto p = static_cast<int>(p0), last = -1; p < p1; ++p) {
        if (lowest[p] == last) continue;
        last = lowest[p];
        for (const int o : offset) on(last + o);
      }
      return;
    }
    if (rows_.factored) { // a particle of the box of the one before marks nothing new
      const ProductRows<D>& r = rows_.product;
      for (auto p = static_cast<int>(p0), last = -1; p < p1; ++p) {
        if (r.base[p] == last && r.m[p] == r.m[p - 1]) continue; // (last is -1 at p0)
        last = r.base[p];
        r.visit_nodes(p, on);
      }
      return;
    }
    const int* node = rows_.table.node.data();
    const int e1 = rows_.table.end(static_cast<int>(p1) - 1);
    for (int e = rows_.table.begin(static_cast<int>(p0)); e < e1; ++e) on(node[e]);
  });
  for (const int I : constraints_.fixed_nodes()) mark[I] = 1;
  if (static_cast<int>(list.size()) < nodes)
    parallel_for(static_cast<long long>(list.size()), [&](long long i) {
      if (!mark[list[static_cast<std::size_t>(i)]]) nodal_.zero(list[static_cast<std::size_t>(i)]);
    });
  parallel_list(
      nodes,
      [mark, nodes](long long begin, long long end, std::vector<int>& listed) {
        for (auto I0 = static_cast<int>(begin); I0 < end; I0 += 8) { // eight flags at a time: most nodes are not listed
          std::uint64_t any = 0;
          if (I0 + 8 <= nodes) std::memcpy(&any, mark + I0, 8);
          else any = 1;
          if (any == 0) continue;
          for (int I = I0; I < std::min(I0 + 8, nodes); ++I)
            if (mark[I]) listed.push_back(I);
        }
      },
      list);
}

template <int D> void Engine<D>::finish_mass() {
  const int nodes = static_cast<int>(nodal_.m.size());
  // The largest nodal mass: a maximum, exact in any grouping (the nodes not
  // visited have none).
  const std::vector<int>& visited = nodal_.visited;
  double m_max = blocked_reduce<MaxOf>(static_cast<long long>(visited.size()), [&](long long i, MaxOf& acc) {
    acc.value = std::max(acc.value, nodal_.m[visited[i]]);
  }).value;
  if (dist_) dist_->max({&m_max, 1});
  const double m_min = settings_.mass_tolerance * m_max;
  // The flags and the list of the active nodes in one pass (raw pointers:
  // a char store may alias the vectors' own).
  const double* m = nodal_.m.data();
  char* active = nodal_.active.data();
  parallel_filter(
      visited,
      [m, active, m_min](int I) {
        const bool on = m[I] > m_min;
        active[I] = on;
        return on;
      },
      nodal_.active_nodes);
  light_.clear();
  if (mode_.nodes_move()) // the lattice's own nodes fill their cells: none is light (sect. 3)
    for (int I = 0; I < nodes; ++I)
      if (nodal_.m[I] > 0.0 && nodal_.m[I] < kLightNode * m_max) light_.push_back(I);
  if (mass_matrix_) assemble_mass_matrix();
  if (contact_) contact_mass_gradient();
}

/// The consistent mass of this step, factorised; a singular one stops the
/// run naming the node, where it is, and what to change.
template <int D> void Engine<D>::assemble_mass_matrix() {
  try {
    mass_matrix_->assemble(table(), P_.m, nodal_.active, constraints_.constrained(),
                           static_cast<int>(nodal_.m.size()));
  } catch (const SingularMassError& e) {
    if (e.node < 0) throw;
    unstable(
        "consistent mass matrix: singular at node " + std::to_string(e.node) + " at " +
        format_point<D>(basis_->nodes().positions()[e.node]) +
        " (a cell its particles fill only partly: its shape function is, at the particles, a combination of "
        "the others'); the lumped mass (simulation.mass = \"lumped\", not with unified) needs no filled "
        "cells (user guide, 'Consistent mass on partly filled cells')");
  }
}

template <int D> void Engine<D>::contact_mass_gradient() {
  AlignedVector<Vec<D>>& g = contact_->mass_gradient();
  auto update = [](int, int) {};
  auto prep = [&](int p) { return P_.m[p]; };
  auto add = [](NodeSums<D>& acc, double, const Vec<D>& dN, double m) { acc.q += m * dN; };
  auto merge = [&](int I, const NodeSums<D>& acc) { g[I] += acc.q; };
  auto clear = [&](int I0, int I1) { std::fill(g.begin() + I0, g.begin() + I1, Vec<D>::Zero()); };
  scatter_->run(table(), static_cast<int>(g.size()), update, prep, add, merge, clear);
}

template <int D> const AlignedVector<Vec<D>>& Engine<D>::field_positions() const {
  return contact_ ? field_positions_ : basis_->nodes().positions();
}

namespace {
/// y_I = r_I / m_I of the lumped mass on an active node, 0 on the others (Engine::solve_mass).
template <int D> Vec<D> lumped_solve(const NodalFields<D>& n, int I, const Vec<D>& r) {
  return n.active[I] ? Vec<D>(r / n.m[I]) : Vec<D>::Zero();
}
} // namespace

template <int D>
void Engine<D>::solve_mass(const AlignedVector<Vec<D>>& r, AlignedVector<Vec<D>>& y, double c) {
  ScopedPhase timer(timers_, Phase::nodal_update);
  const int n = static_cast<int>(r.size());
  y.resize(n);
  const bool lumped = !settings_.consistent_mass;
  const std::vector<int>& visited = nodal_.visited; // the others hold zero in r and y
  parallel_for(static_cast<long long>(visited.size()), [&](long long i) {
    const int I = visited[i];
    y[I] = lumped ? lumped_solve(nodal_, I, r[I]) : Vec<D>::Zero();
  });
  if (lumped) return;
  if (dist_)
    dist_->solve_consistent_mass(table(), P_.m, nodal_.m, nodal_.active, constraints_.constrained(), r, y);
  else mass_matrix_->solve(r, y);
  // The fixed components: what the lumped mass gives them (the constraints
  // then set them; their change reaches the particles from there).
  const std::vector<char>& fixed = constraints_.constrained();
  for (int I : constraints_.fixed_nodes())
    for (int k = 0; k < D; ++k)
      if (nodal_.active[I] && fixed[static_cast<std::size_t>(I) * D + k]) y[I][k] = r[I][k] / nodal_.m[I];
  if (c > 0.0) book_inertial_reaction(y, c);
}

template <int D>
void Engine<D>::solve_mass_add(const AlignedVector<Vec<D>>& r, AlignedVector<Vec<D>>& y, double c,
                               AlignedVector<Vec<D>>& v, double s, const AlignedVector<Vec<D>>* q) {
  if (settings_.consistent_mass) {
    solve_mass(r, y, c);
    if (q) solve_mass(*q, v);
    ScopedPhase timer(timers_, Phase::nodal_update);
    const std::vector<int>& visited = nodal_.visited;
    parallel_for(static_cast<long long>(visited.size()),
                 [&](long long i) { v[visited[i]] += s * y[visited[i]]; });
    return;
  }
  ScopedPhase timer(timers_, Phase::nodal_update);
  y.resize(r.size());
  if (q) v.resize(q->size());
  const std::vector<int>& visited = nodal_.visited; // the others hold zero in r, q, y and v
  parallel_for(static_cast<long long>(visited.size()), [&](long long i) {
    const int I = visited[i];
    y[I] = lumped_solve(nodal_, I, r[I]);
    if (q) v[I] = lumped_solve(nodal_, I, (*q)[I]);
    v[I] += s * y[I];
  });
}

template <int D> void Engine<D>::book_inertial_reaction(const AlignedVector<Vec<D>>& y, double c) {
  // The distributed product is collective: every rank takes it when any
  // rank holds a fixed node (a rank without one would leave the others waiting).
  double any = constraints_.fixed_nodes().empty() ? 0.0 : 1.0;
  if (dist_) dist_->max({&any, 1});
  if (any == 0.0) return;
  AlignedVector<Vec<D>> rho(y.size(), Vec<D>::Zero());
  if (dist_)
    dist_->constrained_rows_product(table(), P_.m, nodal_.active, constraints_.constrained(), y, rho);
  else mass_matrix_->constrained_rows_product(y, rho);
  constraints_.book_reaction(rho, c, ledger());
}

template <int D> void Engine<D>::constrain_velocity(AlignedVector<Vec<D>>& v, const WallEffect<D>& effect) {
  ScopedPhase timer(timers_, Phase::nodal_update);
  // A distributed run books this rank's owned nodes, summed over the ranks after the step.
  const NodeView<D> nodes = node_view(field_positions(), nodal_, *basis_, mode_.nodes_move());
  const Ledger<D> books = ledger();
  constraints_.apply_velocity(v, nodes, effect, books, step_ == 0);
  if (contact_)
    contact_->apply(v, {nodal_.m, nodal_.active, constraints_.constrained()}, effect, *books.friction, *books.impact);
  if (constraints_.walls().empty()) return;
  // The walls' changes the particles take up in this step (book_transfer;
  // not explicit_alpha's, which its kept rate hands on over later steps):
  // the walls change active nodes only.
  const bool transfer = effect.impulse && effect.booking != Booking::carried;
  std::vector<std::pair<int, Vec<D>>>& touched = transfer_.touched;
  touched.clear();
  constraints_.apply_walls(v, nodes, t_, dt_, effect, books, transfer ? &touched : nullptr);
  // The nodes whose velocity the walls changed: each node's first entry
  // holds its velocity before them.
  std::stable_sort(touched.begin(), touched.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (std::size_t i = 0; i < touched.size(); ++i) {
    const int I = touched[i].first;
    if ((i == 0 || touched[i - 1].first != I) && v[I] != touched[i].second)
      transfer_.note(static_cast<std::size_t>(I), constraints_, nodal_.v.size());
  }
}

template <int D>
template <class Change, class Rows, class NodesOf>
double WallTransfer<D>::booked(Change&& change, const Rows& rows, const Particles<D>& P,
                               const std::vector<double>& m, const Constraints<D>& c,
                               NodesOf&& nodes_of) const {
  auto normal_part = [&](std::size_t I) -> Vec<D> {
    const Vec<D>& n = axis[I];
    if (n == Vec<D>::Zero()) return n;
    return n.dot(change(static_cast<int>(I))) * n;
  };
  // The nodes in ascending order (the others add zero).
  std::vector<int> ascending(noted);
  std::sort(ascending.begin(), ascending.end());
  const auto none_noted = [&](int p0, int p1) { // the rows of particles [p0, p1) reach no noted node
    int lo, hi;
    nodes_of(p0, p1, lo, hi);
    const auto first = std::lower_bound(ascending.begin(), ascending.end(), lo);
    return first == ascending.end() || *first > hi;
  };
  const double particles = blocked_reduce_ranges<double>(P.size(), [&](long long p0, long long p1,
                                                                       double& acc) {
    if (none_noted(static_cast<int>(p0), static_cast<int>(p1))) return; // every particle adds zero
    for (auto p = static_cast<int>(p0); p < p1; ++p) {
      char near = 0; // a node of the row is noted (else h is zero)
      rows.visit_row(p, [&](int I, double, const Vec<D>&) { near |= is_noted[static_cast<std::size_t>(I)]; });
      if (!near) continue;
      Vec<D> h = Vec<D>::Zero();
      rows.visit_row(p, [&](int I, double N, const Vec<D>&) { h += N * normal_part(I); });
      if (h == Vec<D>::Zero()) continue;
      Vec<D> d = Vec<D>::Zero();
      rows.visit_row(p, [&](int I, double N, const Vec<D>&) { d += N * change(I); });
      acc += P.m[p] * h.dot(2.0 * d - h);
    }
  });
  double nodes = 0.0;
  for (const int I : ascending)
    if (c.counts(I)) {
      const Vec<D> g = normal_part(static_cast<std::size_t>(I));
      nodes += m[static_cast<std::size_t>(I)] * g.dot(2.0 * change(I) - g);
    }
  return 0.5 * (nodes - particles);
}

template <int D> void Engine<D>::book_transfer(const ToParticles<D>& what) {
  if (!transfer_.any()) return;
  // with the consistent mass the nodes' kinetic energy is the particles' (T = 0)
  const auto change = [&](int I) {
    Vec<D> d = what.c_rate * (*what.rate)[I];
    if (what.kick) d += (*what.kick)[I];
    return d;
  };
  const auto nodes_of = [&](int p0, int p1, int& lo, int& hi) { rows_.node_range(p0, p1, lo, hi); };
  if (!settings_.consistent_mass)
    *ledger().impact += rows_.view([&](const auto view) {
      return transfer_.booked(change, view, P_, nodal_.m, constraints_, nodes_of);
    });
  transfer_.clear();
}

template <int D> void Engine<D>::book_held(const AlignedVector<Vec<D>>& rate) {
  ScopedPhase timer(timers_, Phase::nodal_update);
  constraints_.book_held({t_, dt_, step_ == 0, nodal_.f, rate}, nodal_.q,
                         node_view(field_positions(), nodal_, *basis_, mode_.nodes_move()), ledger());
  // The nodes a wall holds: the particles take their kick up (book_transfer;
  // the inactive nodes get none).
  if (constraints_.held().empty()) return;
  std::vector<int> kicked;
  parallel_filter(nodal_.active_nodes, [&](int I) { return nodal_.q[I] != Vec<D>::Zero(); }, kicked);
  for (const int I : kicked) transfer_.note(I, constraints_, nodal_.v.size()); // it keeps only the nodes a wall holds
}

template <int D>
void Engine<D>::book_carried(double alpha_m, double gamma, bool first, const AlignedVector<Vec<D>>& a_n) {
  const Carried<D> step{alpha_m, gamma, dt_, first, nodal_.reaction, nodal_.v, a_n, nodal_.a};
  constraints_.book_carried(step, ledger());
  if (contact_) contact_->book_carried(step, nodal_.active, *ledger().friction);
}

template <int D> void Engine<D>::constrain_increment(AlignedVector<Vec<D>>& dx) const {
  ScopedPhase timer(timers_, Phase::nodal_update);
  constraints_.apply_increment(dx, dt_);
  if (contact_) contact_->apply_to_increment(dx, {nodal_.m, nodal_.active, constraints_.constrained()});
  if (constraints_.walls().empty()) return;
  const NodeView<D> nodes = node_view(field_positions(), nodal_, *basis_, mode_.nodes_move());
  constraints_.apply_walls_to_increment(dx, nodes, t_, dt_);
}

template <int D> void Engine<D>::apply_dirichlet_force(AlignedVector<Vec<D>>& f, double c) {
  // A distributed run: this rank's owned nodes, summed over the ranks after the step (sum_particles).
  constraints_.apply_force(f, nodal_.reaction, c, ledger());
}

template <int D> void Engine<D>::to_particles(const ToParticles<D>& what) {
  to_particles_and_update_stress(what, {});
}

template <int D>
void Engine<D>::to_particles_and_update_stress(const ToParticles<D>& what, const Gradient<D>& g) {
  ScopedPhase timer(timers_, Phase::to_particles);
  if (what.rate) book_transfer(what);
  fallible([&] {
    const Gradient<D> own = average_volumetric(g) ? Gradient<D>{} : g;
    if (what.last && !what.relaxes() && !settings_.two_phase)
      return to_particles_and_sum(what, own); // (liquid: two_phase)
    parallel_chunks(P_.size(), [&](long long begin, long long end) {
      to_particles_on(what, own, static_cast<int>(begin), static_cast<int>(end));
    });
  });
  fbar_.ready = false;
  if (!what.relaxes()) return;
  // PIC relaxation (ToParticles::pic), the kinetic energy it removes summed
  // in fixed blocks (the same bits for any thread count) and booked as W_v.
  const Vec<D>* pic = what.pic->data();
  const double share = what.pic_share;
  *ledger().relaxation += rows_.view([&](const auto view) {
    return blocked_reduce<double>(P_.size(), [&](long long q, double& removed) {
      const int p = static_cast<int>(q);
      Vec<D> u = Vec<D>::Zero();
      view.visit_row(p, [&](int I, double N, const Vec<D>&) { u += N * pic[I]; });
      const Vec<D> v = P_.v[p] + share * (u - P_.v[p]);
      removed += 0.5 * P_.m[p] * (P_.v[p].squaredNorm() - v.squaredNorm());
      P_.v[p] = v;
    });
  });
}

template <int D>
void Engine<D>::to_particles_on(const ToParticles<D>& what, const Gradient<D>& g, int begin, int end) {
  const bool rate = what.rate != nullptr, move = what.move != nullptr, field = g.field != nullptr;
  if (what.liquid) { // saturated bodies: the liquid's particle update in the same pass
    require<std::invalid_argument>(rate && move && !what.kick, "Engine::to_particles: the liquid needs a rate and a move");
    if (field) return to_particles_range<true, true, true, false, true>(what, g, begin, end);
    ToParticles<D> solid = what; // F-bar: the liquid's rows after the chunk's stress update
    solid.liquid = nullptr;
    to_particles_on(solid, g, begin, end);
    return what.liquid->update_rows(*this, begin, end);
  }
  if (what.kick) {
    require<std::invalid_argument>(rate && move && !field, "Engine::to_particles: a kick needs a rate and a move");
    to_particles_range<true, true, false, true>(what, g, begin, end);
  } else if (rate && move && field) to_particles_range<true, true, true>(what, g, begin, end);
  else if (rate && move) to_particles_range<true, true, false>(what, g, begin, end);
  else if (rate && field) to_particles_range<true, false, true>(what, g, begin, end);
  else if (rate) to_particles_range<true, false, false>(what, g, begin, end);
  else if (move && field) to_particles_range<false, true, true>(what, g, begin, end);
  else if (move) to_particles_range<false, true, false>(what, g, begin, end);
  else if (field) to_particles_range<false, false, true>(what, g, begin, end);
  else if (fbar_.ready) update_materials(begin, end, fbar_.H.data() + begin);
}

template <int D>
template <bool Rate, bool Move, bool Field, bool Kick, bool Liquid>
void Engine<D>::to_particles_range(const ToParticles<D>& what, const Gradient<D>& g, int begin, int end) {
  rows_.view([&](const auto view) {
    to_particles_rows<Rate, Move, Field, Kick, Liquid>(what, g, begin, end, view);
  });
}

template <int D>
template <bool Rate, bool Move, bool Field, bool Kick, bool Liquid, class View>
void Engine<D>::to_particles_rows(const ToParticles<D>& what, const Gradient<D>& g, int begin, int end,
                                  const View view) {
  // Plain pointers and factors in locals: the stores to the particles below
  // cannot alias them, so the loops keep them in registers.
  const Vec<D>* rate = Rate ? what.rate->data() : nullptr;
  const Vec<D>* move = Move ? what.move->data() : nullptr;
  const Vec<D>* field = Field ? g.field->data() : nullptr;
  const Vec<D>* kick = Kick ? what.kick->data() : nullptr;
  Vec<D>* rate_out = what.rate_out ? what.rate_out->data() : nullptr;
  const double c_rate = what.c_rate, c_move = what.c_move, c = g.c;
  Vec<D>* v = P_.v.data();
  Vec<D>* x = P_.x.data();
  const Mat<D>* averaged = fbar_.ready ? fbar_.H.data() : nullptr; // F-bar: H_p from average_volumetric
  Mat<D> H[kStressBatch];
  [[maybe_unused]] LiquidRows<D> liquid; // Liquid: the liquid's row sums of the batch
  static_assert(kStressBatch <= LiquidRows<D>::size);
  if constexpr (Liquid) what.liquid->bind(*this, liquid);
  for (int p0 = begin; p0 < end; p0 += kStressBatch) {
    const int p1 = std::min(end, p0 + kStressBatch);
    // What particle p takes from its row's sums (r, u, k, G).
    const auto take = [&](int p, const Vec<D>& r, const Vec<D>& u, const Vec<D>& k, const Mat<D>& G)
        __attribute__((always_inline)) {
      if constexpr (Rate) {
        if (rate_out) rate_out[p] = r;
        v[p] += c_rate * r;
      }
      if constexpr (Kick) v[p] += k;
      if constexpr (Move) x[p] += c_move * u;
      if constexpr (Field) H[p - p0] = c * G;
    };
    int p = p0;
    // The compact lattice rows two at a time (the same bits, TwoRowSums).
    if constexpr (requires { requires View::pairs; } && !Liquid)
      for (; p + 1 < p1; p += 2) {
        TwoRowSums<D, Rate, Kick, Move, Field> s{.rate = rate, .kick = kick, .move = move, .field = field};
        view.visit_two_rows(
            p, [&s](int I, int J, CornerPair N, const CornerPair* dN)
                   __attribute__((always_inline)) { s.add(I, J, N, dN); });
        for (int l = 0; l < 2; ++l)
          take(p + l, s.lane(s.r, l), s.lane(s.u, l), s.lane(s.k, l), s.gradient(l));
      }
    for (; p < p1; ++p) {
      Vec<D> r = Vec<D>::Zero(), u = Vec<D>::Zero(), k = Vec<D>::Zero();
      Mat<D> G = Mat<D>::Zero();
      [[maybe_unused]] LiquidRow<D> l;
      view.visit_row(
          p, [&](int I, double N, const Vec<D>& dN) __attribute__((always_inline)) {
            if constexpr (Rate) r += N * rate[I];
            if constexpr (Kick) k += N * kick[I];
            if constexpr (Move) u += N * move[I];
            if constexpr (Field) G.noalias() += field[I] * dN.transpose();
            if constexpr (Liquid) liquid.add(l, I, N, dN);
          });
      if constexpr (Liquid) liquid.row[p - p0] = l;
      take(p, r, u, k, G);
    }
    if constexpr (Field) update_materials(p0, p1, H);
    else if (averaged) update_materials(p0, p1, averaged + p0);
    if constexpr (Liquid) what.liquid->finish_rows(*this, p0, p1, liquid);
  }
}

template <int D> void Engine<D>::update_stress(const Gradient<D>& g) {
  ScopedPhase timer(timers_, Phase::constitutive);
  fallible([&] {
    average_volumetric(g);
    parallel_chunks(P_.size(), [&](long long begin, long long end) {
      update_stress_range(g, static_cast<int>(begin), static_cast<int>(end));
    });
  });
  fbar_.ready = false;
}

template <int D> void Engine<D>::update_stress_range(const Gradient<D>& g, int p0, int p1) {
  if (fbar_.ready) update_materials(p0, p1, fbar_.H.data() + p0);
  else to_particles_range<false, false, true>({}, g, p0, p1);
}

template <int D> void Engine<D>::move_into_hull() {
  parallel_for(P_.size(), [&](long long p) {
    P_.x[p] += moved_[p];
    moved_[p].setZero();
  });
}

template <int D> void Engine<D>::follow_body(const AlignedVector<Vec<D>>& x) {
  NodeSet<D>& nodes = basis_->nodes();
  if (!nodes.grid() || !nodes.on_lattice()) return; // a cloud or a perturbed lattice: every node is the material's
  const CartesianGrid<D>& grid = *nodes.grid();
  std::vector<double> used(static_cast<std::size_t>(nodes.size()), 0.0);
  for (int p = 0; p < P_.size(); ++p) { // the corners of the cell that holds particle p
    const Index<D> cell = grid.cell_of(x[p]);
    for (int c = 0; c < (1 << D); ++c) {
      Index<D> corner = cell;
      for (int k = 0; k < D; ++k) corner[k] += (c >> k) & 1;
      used[static_cast<std::size_t>(grid.node_id(corner))] = 1.0;
    }
  }
  if (dist_) dist_->sum_nodal(std::array<NodalArray, 1>{NodalArray{used.data(), 1}}); // cells of other ranks' particles
  std::vector<char> absent(used.size());
  for (std::size_t I = 0; I < used.size(); ++I) absent[I] = used[I] == 0.0;
  if (std::find(absent.begin(), absent.end(), char(0)) == absent.end()) return; // a rank without particles
  nodes.remove(absent);
  basis_->nodes_moved({});
}

namespace {
/// The box of this process' particles' extents: each a cube of its volume
/// about x_p (node reset).
template <int D> std::pair<Vec<D>, Vec<D>> particles_extent(const Particles<D>& P) {
  return particles_box(P, [&](int p) { return Vec<D>::Constant(0.5 * std::pow(P.V[p], 1.0 / D)); });
}

/// NodeReset::planes: a reset lattice's box [lo, hi] at time t ends on a
/// boundary plane that the particles lie on one side of (their extents may
/// reach past it by rounding or growth), so that the plane holds nodes of a
/// family whose domain the nodes carry.
template <int D>
void end_on_planes(const Particles<D>& P, Distribution<D>* dist, const NodeReset<D>& reset, double t, Vec<D>& lo,
                   Vec<D>& hi) {
  auto [xlo, xhi] = particles_box(P);
  if (dist) {
    dist->min({xlo.data(), static_cast<std::size_t>(D)});
    dist->max({xhi.data(), static_cast<std::size_t>(D)});
  }
  for (const auto& [k, c0] : reset.planes) {
    const double c = c0 + reset.velocity[k] * t;
    if (xlo[k] >= c) lo[k] = std::max(lo[k], c);
    if (xhi[k] <= c) hi[k] = std::min(hi[k], c);
  }
}
} // namespace

namespace {

/// The planes of the walls whose normal is a coordinate axis, where they are
/// at t and how far they move in dt (Basis::hold_on_planes).
template <int D> std::vector<AxisPlane> axis_planes(const std::vector<Wall<D>>& walls, double t, double dt) {
  std::vector<AxisPlane> planes;
  for (const Wall<D>& w : walls)
    for (int k = 0; k < D; ++k)
      if (std::abs(w.normal[k]) == 1.0)
        planes.push_back({k, w.point[k] + w.velocity[k] * t, w.velocity[k] * dt});
  return planes;
}

} // namespace

template <int D> bool Engine<D>::reset_due() const {
  if (!(settings_.node_reset.below > 0.0) || settings_.dt) return false;
  if (const auto domain = basis_->domain()) { // a particle may leave the domain the nodes carry within a step
    // where each particle's velocity takes it in the last step's dt, either way
    const auto [lo, hi] = particles_box(P_, [&](int p) { return (P_.v[p].cwiseAbs() * dt_prev_).eval(); });
    double inside = (lo.array() >= domain->first.array()).all() && (hi.array() <= domain->second.array()).all();
    if (dist_) dist_->min({&inside, 1});
    if (inside == 0.0) return true;
  }
  if (!basis_->nodes().grid()) return cfl_spacing() < settings_.node_reset.below * settings_.h; // mesh vertices
  // A lattice's own spacing against the laid-out one's (a searching family's CFL spacing, from its
  // gradients, can be small on a fresh lattice at a body's edge, where a reset gains nothing).
  double h = basis_->nodes().min_spacing() / node_spacing0_;
  if (dist_) dist_->min({&h, 1}); // the same on every rank
  return h < settings_.node_reset.below;
}

template <int D> void Engine<D>::reset_nodes(const CartesianGrid<D>* given) {
  CartesianGrid<D> grid;
  if (given) {
    grid = *given;
  } else { // the grid's lines around every particle's extent
    const CartesianGrid<D> lines = settings_.node_reset.lines_at(t_);
    const Vec<D> h = lines.h();
    auto [lo, hi] = particles_extent(P_);
    if (dist_) { // the extent of every rank's particles
      dist_->min({lo.data(), static_cast<std::size_t>(D)});
      dist_->max({hi.data(), static_cast<std::size_t>(D)});
    }
    if (basis_->domain()) end_on_planes(P_, dist_.get(), settings_.node_reset, t_, lo, hi);
    for (int k = 0; k < D; ++k) {
      const double a = std::floor((lo[k] - lines.lower[k]) / h[k]), b = std::ceil((hi[k] - lines.lower[k]) / h[k]);
      grid.lower[k] = lines.lower[k] + a * h[k];
      grid.upper[k] = lines.lower[k] + b * h[k];
      grid.cells[k] = static_cast<int>(std::max(1.0, b - a));
    }
    grid.validate();
  }
  if (!given) laid_out_.time = t_;
  // distributed: the cells bisected afresh, the particles sent to their owners, this rank's window
  LatticePart<D> part;
  try {
    part = dist_ ? dist_->lay_out(*this, grid, laid_out_.time, given != nullptr)
                 : settings_.node_reset.lattice(grid, laid_out_.time);
  } catch (const InputError& e) { // the scene was read; the state the run reached cannot be laid out
    if (given) throw;               // a restart's lattice: its checkpoint does not fit the scene
    unstable("the nodes could not be laid out anew on the lattice " + format_point<D>(grid.lower) + " - " +
             format_point<D>(grid.upper) + " around the particles: " + e.what());
  }
  const AlignedVector<Vec<D>> wall_impulse = constraints_.wall_impulse(); // the walls keep their impulse
  basis_ = std::move(part.basis);
  const int nodes = basis_->nodes().size();
  constraints_ = Constraints<D>(std::move(part.dirichlet), constraints_.walls(), nodes);
  constraints_.wall_impulse() = wall_impulse;
  if (dist_) {
    constraints_.count_only(dist_->owned_nodes());
    basis_->distribute(dist_->owned_nodes(), [this](std::span<double> v) { dist_->sum(v); });
  }
  nodal_.resize(nodes);
  scatter_->invalidate(0);
  if (mass_matrix_) mass_matrix_ = std::make_unique<MassMatrix<D>>(basis_->fixed_stencil() > 0);
  laid_out_.grid = grid;
  if (!given) { // each particle's home: its cell now, by which lay_out placed it (a restart restores them)
    laid_out_.home.resize(static_cast<std::size_t>(P_.size()));
    for (int p = 0; p < P_.size(); ++p) laid_out_.home[static_cast<std::size_t>(p)] = grid.cell_of(P_.x[p]);
    laid_out_.homes = true;
  }
  if (!given && basis_->search_radius() > 0.0) follow_body(P_.x); // a restart restores the node set's
  basis_->bind_points(P_.size(), true); // the multipliers and hints belonged to the old nodes
  node_spacing0_ = basis_->nodes().min_spacing();
  if (dist_) dist_->min({&node_spacing0_, 1});
  gradient_ = gradient0_; // a fresh lattice: the gradients of t = 0 until the next table
  fbar_.patch.clear();    // the cells of the new lattice
  if (!given) ++laid_out_.resets;
}

template <int D> void Engine<D>::measure_gradients() {
  const AlignedVector<Vec<D>>& dN = table().dN;
  double g2 = blocked_reduce<MaxOf>(static_cast<long long>(dN.size()), [&](long long e, MaxOf& acc) {
    acc.value = std::max(acc.value, dN[static_cast<std::size_t>(e)].squaredNorm());
  }).value;
  gradient_ = std::sqrt(std::max(g2, 0.0)); // this rank's (stable_dt takes the ranks' largest)
  if (gradient0_ == 0.0) gradient0_ = gradient_;
}

template <int D> void Engine<D>::assign_patches() {
  // ul: the cell of the lattice the nodes were laid out on that held the
  // particle then (t = 0, or the last node reset: its home), fixed until the next
  const bool own = mode_.nodes_move();
  if (own && fbar_.patch.size() == static_cast<std::size_t>(P_.size())) return;
  const std::optional<CartesianGrid<D>>& lattice = laid_out_.grid         ? laid_out_.grid
                                                   : settings_.patch_grid ? settings_.patch_grid
                                                                          : basis_->nodes().grid();
  require<std::invalid_argument>(lattice.has_value(), "Engine: volumetric = fbar needs the lattice of its patches "
                                                      "(StepSettings::patch_grid); the node set is a cloud");
  const CartesianGrid<D>& grid = *lattice;
  // A cell's key: its lower corner's lattice index (and the body, with contact),
  // in 64 bits; the keys are numbered in particle order as they first appear.
  std::unordered_map<long long, long long> number;
  fbar_.patch.resize(static_cast<std::size_t>(P_.size()));
  for (int p = 0; p < P_.size(); ++p) {
    const Index<D> c = own && laid_out_.grid && laid_out_.homes
                           ? laid_out_.home[static_cast<std::size_t>(p)]
                           : grid.cell_of(own && !laid_out_.grid ? P_.X[p] : P_.x[p]);
    long long key = contact_ ? P_.body[p] : 0;
    for (int k = D - 1; k >= 0; --k) key = key * (grid.cells[k] + 1LL) + c[k];
    fbar_.patch[static_cast<std::size_t>(p)] =
        number.try_emplace(key, static_cast<long long>(number.size())).first->second;
  }
  fbar_.patches = static_cast<long long>(number.size());
}

template <int D> bool Engine<D>::average_volumetric(const Gradient<D>& g) {
  if (settings_.volumetric == Volumetric::none || D == 1 || !g.field) return false;
  fbar_.H.resize(static_cast<std::size_t>(P_.size()));
  const Vec<D>* field = g.field->data();
  const double c = g.c;
  const BasisTable<D>& t = table();
  parallel_for(P_.size(), [&](long long p) { // the arithmetic of to_particles_rows' gradient
    Mat<D> G = Mat<D>::Zero();
    for (int e = t.begin(static_cast<int>(p)); e < t.end(static_cast<int>(p)); ++e)
      G.noalias() += field[t.node[e]] * t.dN[e].transpose();
    fbar_.H[p] = c * G;
  });
  if (settings_.volumetric == Volumetric::fbar_nodal)
    fbar_.nodal.apply(t, static_cast<int>(nodal_.m.size()), P_.V.data(), fbar_.H.data(), P_.size());
  else
    fbar_.average.apply(fbar_.patch, fbar_.patches, P_.V.data(), fbar_.H.data(), P_.size());
  fbar_.ready = true;
  return true;
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

template <int D> void Engine<D>::advect_nodes(const AlignedVector<Vec<D>>& increments) {
  if (!mode_.nodes_move()) return;
  ScopedPhase timer(timers_, Phase::nodal_update);
  const std::optional<AlignedVector<Vec<D>>> own = light_increments(increments);
  const AlignedVector<Vec<D>>& dx = own ? *own : increments;
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
  basis_->hold_on_planes(axis_planes(constraints_.walls(), t_, dt_));
  mode_.advect(*basis_, dx);
}

template <int D>
std::optional<AlignedVector<Vec<D>>> Engine<D>::light_increments(const AlignedVector<Vec<D>>& dx) {
  double any = light_.empty() || contact_ ? 0.0 : 1.0;
  if (dist_) dist_->max({&any, 1});
  if (any == 0.0) return std::nullopt;
  const int nodes = static_cast<int>(nodal_.m.size());
  AlignedVector<Vec<D>> carried(static_cast<std::size_t>(nodes), Vec<D>::Zero()); // sum_p N_Ip m_p dx_p
  auto update = [](int, int) {};
  auto prep = [&](int p) { return Vec<D>(P_.m[p] * (P_.x[p] - x_start_[p])); };
  auto add = [](NodeSums<D>& acc, double N, const Vec<D>&, const Vec<D>& w) { acc.q += N * w; };
  auto merge = [&](int I, const NodeSums<D>& acc) { carried[I] += acc.q; };
  auto clear = [&](int I0, int I1) { std::fill(carried.begin() + I0, carried.begin() + I1, Vec<D>::Zero()); };
  scatter_->run(table(), nodes, update, prep, add, merge, clear);
  if (dist_) {
    const NodalArray sums[] = {{carried.data()->data(), D}};
    dist_->sum_nodal(sums);
  }
  AlignedVector<Vec<D>> own = dx;
  for (int I : light_) own[I] = carried[I] / nodal_.m[I];
  constrain_increment(own);
  return own;
}

template <int D> double Engine<D>::global_power(double t, const Vec<D>& momentum) const {
  double power = loads_.power(t, P_, momentum); // without a field: b . momentum, already global
  if (dist_ && loads_.body_force && loads_.body_force->field) dist_->sum({&power, 1});
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
  } catch (const std::bad_alloc&) { // every rank ends "out of memory", not only this one
    failure.memory = true;
    failure.message = when + "rank " + std::to_string(dist_->rank()) + " could not get the memory it needed";
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
