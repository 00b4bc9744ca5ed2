#include "otmpm/engine/engine.hpp"

#include "otmpm/engine/parallel.hpp"
#include "otmpm/reference/solutions.hpp"
#include "otmpm/scene/validate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace otmpm {

namespace {
/// Nodes within this fraction of h of a Dirichlet box belong to it.
constexpr double box_tolerance = 1e-6;
/// Floor of the energy reference of the runaway monitor (J), so that a body
/// at rest with no load never trips it.
constexpr double energy_floor = 1e-300;

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

Integrator parse_integrator(const std::string& name) {
  if (name == "fe") return Integrator::fe;
  if (name == "musl") return Integrator::musl;
  if (name == "npc") return Integrator::npc;
  if (name == "otm") return Integrator::otm;
  if (name == "unified") return Integrator::unified;
  throw InputError("unknown integrator '" + name + "' (expected fe, musl, npc, otm or unified)");
}

std::string to_string(Integrator integrator) {
  switch (integrator) {
  case Integrator::fe: return "fe";
  case Integrator::musl: return "musl";
  case Integrator::npc: return "npc";
  case Integrator::otm: return "otm";
  case Integrator::unified: return "unified";
  }
  return "?";
}

double time_function(const TimeFunction& g, double t) {
  if (g.kind != "ramp") return 1.0;
  // molinos eq. 45: g(t) = 0.5 (sin(2 pi t / T - pi / 2) + 1) up to T/2, then 1:
  // a smooth ramp from 0 (zero slope) to 1 (zero slope) at T/2.
  if (t >= 0.5 * g.period) return 1.0;
  return 0.5 * (std::sin(2.0 * std::numbers::pi * t / g.period - 0.5 * std::numbers::pi) + 1.0);
}

template <int D> void NodalFields<D>::resize(int n) {
  m.assign(n, 0.0);
  q.assign(n, Vec<D>::Zero());
  v = f = a = dx = reaction = q;
  active.assign(n, 0);
}

template <int D> Engine<D>::Engine(const Scene& scene) : scene_(scene) {
  validate_scene(scene_, D); // a Scene built in code has not been through parse_scene
  const SimulationSection& sim = scene_.simulation;
  mode_ = sim.mode == "ul" ? NodeMode::ul : NodeMode::mpm;
  integrator_ = parse_integrator(sim.integrator);
  if ((integrator_ == Integrator::otm || integrator_ == Integrator::unified) && mode_ != NodeMode::ul)
    input_error(scene_.locate("simulation.integrator"),
                "integrator '" + sim.integrator + "' runs only with simulation.mode = \"ul\"");
  if (integrator_ == Integrator::unified && scene_.basis.kind.rfind("bspline", 0) != 0)
    input_error(scene_.locate("basis.kind"), "integrator 'unified' needs a B-spline basis");
  for (const MaterialSection& ms : scene_.materials) {
    Material m;
    m.name = ms.name;
    m.model = Material::parse_model(ms.model);
    m.density = ms.density;
    m.young = ms.young;
    m.poisson = ms.poisson;
    any_finite_strain_ = any_finite_strain_ || m.finite_strain();
    materials_.push_back(m);
  }
  for (int k = 0; k < D; ++k)
    grid_h_[k] = (scene_.grid.upper[k] - scene_.grid.lower[k]) / scene_.grid.cells[k];
  P_ = seed_particles<D>(scene_, grid_h_);
  P_.has_F = any_finite_strain_ || mode_ == NodeMode::ul;
  if (integrator_ == Integrator::otm) P_.x_prev = P_.x;
  build_nodes_and_basis();
  nodal_.resize(basis_->nodes().size());
  build_dirichlet();
  exact_ = make_exact_solution<D>(scene_);
  build_tractions();
  // A manufactured solution starts from its own velocity field (wobbes 8.3:
  // u = 0 but v != 0 at t = 0).
  if (exact_ && exact_->has_body_force())
    for (int p = 0; p < P_.size(); ++p) P_.v[p] = exact_->velocity(P_.X[p], 0.0);
  if (scene_.body_force) {
    for (int k = 0; k < D; ++k) body_force_[k] = scene_.body_force->value[k];
    has_body_force_ = true;
  }
  if (exact_ && exact_->has_body_force()) has_body_force_ = true;
  if (scene_.simulation.mass == "consistent" || integrator_ == Integrator::unified)
    mass_matrix_ = std::make_unique<MassMatrix<D>>();
  for (const Material& m : materials_) p_modulus_.push_back(m.p_modulus(D));
  uniform_body_force_ = has_body_force_ && tractions_.empty() && !(exact_ && exact_->has_body_force());
  allocate_fields();
  after_step(); // initial checks, energy and wave speed
  energy_.initial = energy_.total();
  external_power_ = external_power(0.0, momentum_);
}

template <int D> void Engine<D>::allocate_fields() {
  const auto& fields = scene_.output.fields;
  auto wanted = [&](const char* f) { return std::find(fields.begin(), fields.end(), f) != fields.end(); };
  const std::string_view kind = basis_->kind();
  const bool maxent = kind == "lme" || kind == "maxent";
  // The hint serves the element walk on moved/perturbed lattices and B-splines.
  const bool lattice_fixed = mode_ == NodeMode::mpm && scene_.grid.kind != "perturbed";
  const bool hint = !maxent && !(lattice_fixed && (kind == "linear" || kind == "ugimp"));
  P_.allocate_optional(integrator_ == Integrator::npc || wanted("a"), P_.has_F || wanted("F"), maxent, hint);
  if (tractions_.empty()) AlignedVector<Vec<D>>().swap(P_.length0);
}

template <int D> Engine<D>::~Engine() = default;

template <int D> void Engine<D>::build_nodes_and_basis() {
  CartesianGrid<D> grid;
  for (int k = 0; k < D; ++k) {
    grid.lower[k] = scene_.grid.lower[k];
    grid.upper[k] = scene_.grid.upper[k];
    grid.cells[k] = scene_.grid.cells[k];
  }
  if (mode_ == NodeMode::ul) { // nodes discretise only the material domain
    for (int k = 0; k < D; ++k) {
      grid.lower[k] = scene_.bodies.front().lower[k];
      grid.upper[k] = scene_.bodies.front().upper[k];
      for (const BodySection& b : scene_.bodies) {
        grid.lower[k] = std::min(grid.lower[k], b.lower[k]);
        grid.upper[k] = std::max(grid.upper[k], b.upper[k]);
      }
      grid.cells[k] = std::max(1, static_cast<int>(std::lround((grid.upper[k] - grid.lower[k]) / grid_h_[k])));
    }
  }
  grid.validate();
  domain_lower_ = grid.lower;
  domain_upper_ = grid.upper;
  NodeSet<D> nodes = scene_.grid.kind == "perturbed"
                         ? NodeSet<D>::perturbed(grid, scene_.grid.perturbation, scene_.grid.seed)
                         : NodeSet<D>::cartesian(grid);
  BasisOptions opt = scene_.basis;
  try {
    basis_ = make_basis<D>(opt, std::move(nodes));
  } catch (const InputError& e) {
    input_error(scene_.basis_where, e.what());
  }
  h_min0_ = grid.h().minCoeff();
  node_spacing0_ = basis_->nodes().min_spacing();
}

template <int D> void Engine<D>::build_dirichlet() {
  const NodeSet<D>& nodes = basis_->nodes();
  const double tol = box_tolerance * h_min0_;
  for (const BoundarySection& bs : scene_.boundaries) {
    int selected = 0;
    for (int I = 0; I < nodes.size(); ++I) {
      const Vec<D>& x = nodes.position(I);
      bool inside = true;
      for (int k = 0; k < D; ++k)
        inside = inside && x[k] >= bs.lower[k] - tol && x[k] <= bs.upper[k] + tol;
      if (!inside) continue;
      dirichlet_.node.push_back(I);
      dirichlet_.fix.push_back(bs.fix);
      dirichlet_.value.push_back(bs.value);
      ++selected;
    }
    if (selected == 0)
      input_error(bs.where, "boundary '" + bs.name + "' selects no node of the " +
                                std::string(mode_ == NodeMode::ul ? "material" : "grid") + " node set");
  }
  dirichlet_nodes_ = dirichlet_.node;
  std::sort(dirichlet_nodes_.begin(), dirichlet_nodes_.end());
  dirichlet_nodes_.erase(std::unique(dirichlet_nodes_.begin(), dirichlet_nodes_.end()), dirichlet_nodes_.end());
}

template <int D> void Engine<D>::build_tractions() {
  for (const TractionSection& ts : scene_.tractions) {
    TractionLoad<D> load;
    for (int k = 0; k < D; ++k) load.value[k] = ts.value[k];
    load.time = ts.time;
    load.value.cwiseAbs().maxCoeff(&load.axis);
    for (int p = 0; p < P_.size(); ++p) {
      bool inside = true;
      for (int k = 0; k < D; ++k) inside = inside && P_.x[p][k] >= ts.lower[k] && P_.x[p][k] <= ts.upper[k];
      if (inside) load.particle.push_back(p);
    }
    if (load.particle.empty()) input_error(ts.where, "traction box selects no particle");
    if (ts.function == "wobbes_traction_bar") {
      const auto* bar = dynamic_cast<const TractionBar<D>*>(exact_.get());
      if (!bar)
        input_error(ts.where, "traction function 'wobbes_traction_bar' needs reference.solution = \"traction_bar\"");
      load.axis = 0;
      load.history = [bar](double t) { return bar->traction(t); };
    } else if (!ts.function.empty()) {
      input_error(ts.where, "unknown traction function '" + ts.function + "' (expected wobbes_traction_bar)");
    }
    tractions_.push_back(std::move(load));
  }
}

template <int D> double Engine<D>::stable_dt() const {
  double dt;
  if (scene_.simulation.dt) {
    dt = *scene_.simulation.dt;
  } else {
    const double c = wave_speed_; // max_p max(c_p, |v_p|), from after_step()
    double h = h_min0_;
    if (mode_ == NodeMode::ul) h *= basis_->nodes().min_spacing() / node_spacing0_;
    dt = scene_.simulation.cfl * h / c;
  }
  return std::min(dt, scene_.simulation.t_end - t_);
}

template <int D> void Engine<D>::step() {
  dt_ = stable_dt();
  if (!(dt_ > 0.0) || !std::isfinite(dt_))
    throw InstabilityError("step " + std::to_string(step_) + ", t = " + format_number(t_) +
                           ": time step " + format_number(dt_) + " is not positive and finite");
  if (dt_prev_ == 0.0) dt_prev_ = dt_;
  switch (integrator_) {
  case Integrator::fe: step_fe(*this, false); break;
  case Integrator::musl: step_fe(*this, true); break;
  case Integrator::npc: step_npc(*this); break;
  case Integrator::otm: step_otm(*this); break;
  case Integrator::unified: step_unified(*this); break;
  }
  t_ += dt_;
  ++step_;
  dt_prev_ = dt_;
  after_step(); // checks, energies, wave speed
  // Trapezoidal rule: exact for a constant load on a uniformly accelerating
  // body, where the one-sided rule would leave an O(dt) error in the balance.
  const double power = external_power(t_, momentum_);
  energy_.external_work += 0.5 * dt_ * (external_power_ + power);
  external_power_ = power;
  check_energy();
}

template <int D> void Engine<D>::evaluate_basis() {
  ScopedPhase timer(timers_, Phase::basis);
  try {
    const bool maxent = basis_->kind() == "lme" || basis_->kind() == "maxent";
    fill_basis_table(*basis_, P_.x, maxent ? &P_.lambda : nullptr, &P_.cell_hint, table_, &neighbours_);
    columns_valid_ = false;
    blocks_.valid = false;
  } catch (const BasisError& e) {
    throw InstabilityError("step " + std::to_string(step_) + ", t = " + format_number(t_) +
                           ": basis evaluation failed: " + e.what());
  }
}

template <int D> void Engine<D>::plan_scatter() {
  if (blocks_.valid) return;
  blocks_.valid = true;
  const int n = P_.size(), nodes = static_cast<int>(nodal_.m.size());
  const int count = (n + scatter_block - 1) / scatter_block;
  blocks_.lo.assign(static_cast<std::size_t>(count), nodes);
  blocks_.hi.assign(static_cast<std::size_t>(count), -1);
  parallel_chunks(count, team_size(n), [&](long long b0, long long b1) {
    for (long long b = b0; b < b1; ++b) {
      const int e0 = table_.begin(static_cast<int>(b * scatter_block));
      const int e1 = table_.end(static_cast<int>(std::min<long long>(n, (b + 1) * scatter_block)) - 1);
      int lo = nodes, hi = -1; // locals: the loop vectorises
      for (int e = e0; e < e1; ++e) {
        lo = std::min(lo, table_.node[e]);
        hi = std::max(hi, table_.node[e]);
      }
      blocks_.lo[b] = lo;
      blocks_.hi[b] = hi;
    }
  });
  blocks_.offset.assign(static_cast<std::size_t>(count) + 1, 0);
  for (int b = 0; b < count; ++b)
    blocks_.offset[b + 1] = blocks_.offset[b] + std::max(0, blocks_.hi[b] - blocks_.lo[b] + 1);
  // Spatially coherent particle order (as seeded): each node lies in the
  // range of one or two blocks. Otherwise the gather over node columns.
  blocks_.compact = blocks_.offset.back() <= max_block_overlap * std::max(nodes, 1);
}

template <int D>
template <class Update, class Prep, class Add, class Merge, class Clear>
void Engine<D>::scatter(Update&& update, Prep&& prep, Add&& add, Merge&& merge, Clear&& clear) {
  plan_scatter();
  const int n = P_.size(), nodes = static_cast<int>(nodal_.m.size());
  if (!blocks_.compact) return gather_columns(update, prep, add, merge, clear);
  const int count = static_cast<int>(blocks_.lo.size());
  blocks_.buffer.resize(static_cast<std::size_t>(blocks_.offset.back()));
  // 1. every block sums its particles, in particle order, into its own range
  parallel_chunks(count, team_size(n), [&](long long b0, long long b1) {
    for (int b = static_cast<int>(b0); b < b1; ++b) scatter_block_sums(b, update, prep, add);
  });
  // 2. every node adds the block sums in block order (threads own node ranges)
  parallel_chunks(nodes, team_size(n), [&](long long I0, long long I1) {
    clear(static_cast<int>(I0), static_cast<int>(I1));
    for (int b = 0; b < count; ++b) {
      const NodeSums<D>* buf = blocks_.buffer.data() + blocks_.offset[b] - blocks_.lo[b];
      for (int I = std::max<int>(static_cast<int>(I0), blocks_.lo[b]), end = std::min<int>(static_cast<int>(I1) - 1, blocks_.hi[b]); I <= end; ++I)
        merge(I, buf[I]);
    }
  });
}

template <int D>
template <class Update, class Prep, class Add>
void Engine<D>::scatter_block_sums(int b, Update& update, Prep& prep, Add& add) {
  const bool entries = blocks_.hi[b] >= blocks_.lo[b];
  NodeSums<D>* buf = entries ? blocks_.buffer.data() + blocks_.offset[b] - blocks_.lo[b] : nullptr;
  if (entries) std::fill(buf + blocks_.lo[b], buf + blocks_.hi[b] + 1, NodeSums<D>{});
  const int begin = b * scatter_block, end = std::min(P_.size(), begin + scatter_block);
  update(begin, end);
  for (int p = begin; p < end; ++p) {
    const auto w = prep(p);
    for (int e = table_.begin(p); e < table_.end(p); ++e) add(buf[table_.node[e]], e, w);
  }
}

template <int D>
template <class Update, class Prep, class Add, class Merge, class Clear>
void Engine<D>::gather_columns(Update&& update, Prep&& prep, Add&& add, Merge&& merge, Clear&& clear) {
  const int nodes = static_cast<int>(nodal_.m.size());
  parallel_chunks(P_.size(), [&](long long p0, long long p1) { update(static_cast<int>(p0), static_cast<int>(p1)); });
  if (!columns_valid_) transpose_basis_table(table_, nodes, columns_);
  columns_valid_ = true;
  const std::vector<int>& off = columns_.offset;
  parallel_chunks(nodes, team_size(static_cast<long long>(table_.entries())), [&](long long I0, long long I1) {
    clear(static_cast<int>(I0), static_cast<int>(I1));
    for (int I = static_cast<int>(I0); I < I1; ++I) {
      NodeSums<D> acc{};
      for (int k = off[I]; k < off[I + 1]; ++k) add(acc, columns_.entry[k], prep(columns_.particle[k]));
      merge(I, acc);
    }
  });
}

template <int D> void Engine<D>::project_mass() { to_nodes({.mass = true}); }

template <int D>
void Engine<D>::project_momentum(const AlignedVector<Vec<D>>& w, double c, const AlignedVector<Vec<D>>* a) {
  to_nodes({.w = &w, .c = c, .a = a});
}

template <int D> void Engine<D>::compute_forces(double t) { to_nodes({.forces = true, .t = t}); }

template <int D> void Engine<D>::to_nodes(const ToNodes<D>& what) {
  ScopedPhase timer(timers_, Phase::to_nodes);
  if (what.forces) prepare_external_forces(what.t);
  const bool q = what.w != nullptr;
  if (what.mass && q && what.forces) to_nodes_impl<true, true, true>(what);
  else if (what.mass && q) to_nodes_impl<true, true, false>(what);
  else if (what.mass && what.forces) to_nodes_impl<true, false, true>(what);
  else if (what.mass) to_nodes_impl<true, false, false>(what);
  else if (q && what.forces) to_nodes_impl<false, true, true>(what);
  else if (q) to_nodes_impl<false, true, false>(what);
  else if (what.forces) to_nodes_impl<false, false, true>(what);
  if (what.mass) finish_mass();
}

template <int D>
template <bool Mass, bool Momentum, bool Forces>
void Engine<D>::to_nodes_impl(const ToNodes<D>& what) {
  const Vec<D> b = uniform_body_force_ ? body_force_at(what.t) : Vec<D>::Zero();
  const bool field = !fext_.empty(), uniform = uniform_body_force_;
  struct Payload { // what particle p carries to each of its nodes
    double m;
    Vec<D> mw, fext;
    Mat<D> Vs;
  };
  auto update = [&](int p0, int p1) {
    if (what.stress_from) update_stress_range(*what.stress_from, what.dt, p0, p1);
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
  scatter(update, prep, add, merge, clear);
}

template <int D> void Engine<D>::prepare_external_forces(double t) {
  if (uniform_body_force_ || (!has_body_force_ && tractions_.empty())) return;
  fext_.assign(P_.size(), Vec<D>::Zero());
  for_each_external_force(t, [&](int p, const Vec<D>& force) { fext_[p] += force; });
}

template <int D> void Engine<D>::finish_mass() {
  const int nodes = static_cast<int>(nodal_.m.size());
  // The largest nodal mass: a maximum, exact in any grouping.
  const double m_max = blocked_reduce<MaxOf>(nodes, [&](long long I, MaxOf& acc) {
    acc.value = std::max(acc.value, nodal_.m[I]);
  }).value;
  const double m_min = scene_.simulation.mass_tolerance * m_max;
  parallel_for(nodes, [&](long long I) { nodal_.active[I] = nodal_.m[I] > m_min; });
  if (!mass_matrix_) return;
  if (constrained_.empty()) { // the Dirichlet sets never change
    constrained_.assign(nodal_.m.size() * D, 0);
    for (std::size_t i = 0; i < dirichlet_.node.size(); ++i)
      for (int k = 0; k < D; ++k)
        if (dirichlet_.fix[i][k]) constrained_[dirichlet_.node[i] * D + k] = 1;
  }
  mass_matrix_->assemble(table_, P_.m, nodal_.active, constrained_, nodes);
}

template <int D>
template <class Visit>
void Engine<D>::for_each_external_force(double t, Visit&& visit) const {
  if (has_body_force_) {
    const Vec<D> b = body_force_at(t);
    const bool mms = exact_ && exact_->has_body_force();
    for (int p = 0; p < P_.size(); ++p)
      visit(p, Vec<D>(P_.m[p] * (mms ? Vec<D>(b + exact_->body_force(P_.X[p], t)) : b)));
  }
  for (const TractionLoad<D>& load : tractions_) {
    Vec<D> traction = load.value * time_function(load.time, t);
    if (load.history) traction[load.axis] = load.history(t);
    for (int p : load.particle) visit(p, Vec<D>(traction * (P_.V0[p] / P_.length0[p][load.axis])));
  }
}

template <int D> Vec<D> Engine<D>::body_force_at(double t) const {
  return body_force_ * (scene_.body_force ? time_function(scene_.body_force->time, t) : 1.0);
}

template <int D> double Engine<D>::external_power(double t) const {
  return external_power(t, uniform_body_force_ ? momentum() : Vec<D>::Zero());
}

template <int D> double Engine<D>::external_power(double t, const Vec<D>& momentum) const {
  if (uniform_body_force_) // sum_p m_p b(t) . v_p = b(t) . sum_p m_p v_p
    return body_force_at(t).dot(momentum);
  double power = 0.0;
  for_each_external_force(t, [&](int p, const Vec<D>& force) { power += force.dot(P_.v[p]); });
  return power;
}

template <int D> void Engine<D>::check_energy() const {
  // A boundary moving at a prescribed velocity puts energy into a body at rest
  // in the first step, before its reaction (computed from the forces at the
  // start of the step in fe/musl/otm/unified) has done any work: the kinetic
  // energy of the prescribed nodal motion, sum 1/2 m_I v_Ik^2, covers that
  // (zero for fixed supports).
  double boundary_kinetic = 0.0;
  for (std::size_t i = 0; i < dirichlet_.node.size(); ++i)
    for (int k = 0; k < D; ++k)
      if (dirichlet_.fix[i][k])
        boundary_kinetic += 0.5 * nodal_.m[dirichlet_.node[i]] * dirichlet_.value[i][k] * dirichlet_.value[i][k];
  const double reference =
      std::max(energy_.initial + std::abs(energy_.external_work) + std::abs(energy_.reaction_work) + boundary_kinetic,
               energy_floor);
  const double total = energy_.total();
  if (total > scene_.simulation.energy_limit * reference)
    throw InstabilityError("step " + std::to_string(step_) + ", t = " + format_number(t_) +
                           ": runaway energy: kinetic + strain = " + format_number(total) +
                           " J exceeds " + format_number(scene_.simulation.energy_limit) +
                           " x (initial energy + |external work| + |reaction work| + boundary kinetic energy) = " + format_number(reference) + " J");
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

template <int D> void Engine<D>::apply_dirichlet_velocity(AlignedVector<Vec<D>>& v) const {
  for (std::size_t i = 0; i < dirichlet_.node.size(); ++i)
    for (int k = 0; k < D; ++k)
      if (dirichlet_.fix[i][k]) v[dirichlet_.node[i]][k] = dirichlet_.value[i][k];
}

template <int D> void Engine<D>::apply_dirichlet_force(AlignedVector<Vec<D>>& f) {
  // Only Dirichlet nodes carry a reaction (it stays zero elsewhere).
  for (int I : dirichlet_nodes_) nodal_.reaction[I].setZero();
  for (std::size_t i = 0; i < dirichlet_.node.size(); ++i) {
    const int I = dirichlet_.node[i];
    for (int k = 0; k < D; ++k)
      if (dirichlet_.fix[i][k]) {
        // -= keeps the reaction of a node listed by two boundaries (its f is
        // zero the second time); the work uses the prescribed velocity, which
        // is what every integrator sets on this component during the step.
        nodal_.reaction[I][k] -= f[I][k];
        energy_.reaction_work -= dt_ * f[I][k] * dirichlet_.value[i][k];
        f[I][k] = 0.0;
      }
  }
  // In node order, as a sum over all nodes would add them (the others add zero).
  for (int I : dirichlet_nodes_) reaction_impulse_ += dt_ * nodal_.reaction[I];
}

template <int D>
void Engine<D>::interpolate(const AlignedVector<Vec<D>>& y, AlignedVector<Vec<D>>& out) const {
  out.resize(P_.size());
  parallel_for(P_.size(), [&](long long p) { out[p] = interpolate(static_cast<int>(p), y); });
}

template <int D> void Engine<D>::to_particles(const ToParticles<D>& what) {
  ScopedPhase timer(timers_, Phase::to_particles);
  parallel_chunks(P_.size(), [&](long long begin, long long end) {
    for (int p = static_cast<int>(begin); p < end; ++p) {
      Vec<D> r = Vec<D>::Zero(), u = Vec<D>::Zero();
      Mat<D> G = Mat<D>::Zero();
      for (int e = table_.begin(p); e < table_.end(p); ++e) {
        const int I = table_.node[e];
        if (what.rate) r += table_.N[e] * (*what.rate)[I];
        if (what.move) u += table_.N[e] * (*what.move)[I];
        if (what.grad) G.noalias() += (*what.grad)[I] * table_.dN[e].transpose();
      }
      if (what.rate) {
        if (what.rate_out) (*what.rate_out)[p] = r;
        P_.v[p] += what.c_rate * r;
      }
      if (what.move) P_.x[p] += what.c_move * u;
      if (what.grad) update_particle_stress(p, what.c_grad * G);
    }
  });
}

template <int D> void Engine<D>::advect_nodes(const AlignedVector<Vec<D>>& dx) {
  if (mode_ != NodeMode::ul) return;
  ScopedPhase timer(timers_, Phase::nodal_update);
  basis_->nodes().advect(dx);
  basis_->nodes_moved(dx);
}

template <int D>
void Engine<D>::update_stress(const AlignedVector<Vec<D>>& v_nodes, double dt) {
  ScopedPhase timer(timers_, Phase::constitutive);
  parallel_chunks(P_.size(), [&](long long begin, long long end) {
    update_stress_range(v_nodes, dt, static_cast<int>(begin), static_cast<int>(end));
  });
}

template <int D>
void Engine<D>::update_stress_range(const AlignedVector<Vec<D>>& v_nodes, double dt, int p0, int p1) {
  for (int p = p0; p < p1; ++p) update_particle_stress(p, dt * nodal_gradient(table_, p, v_nodes));
}

template <int D> void Engine<D>::update_particle_stress(int p, const Mat<D>& H) {
  const Material& mat = materials_[P_.material[p]];
  if (P_.has_F) P_.F[p] = (Mat<D>::Identity() + H) * P_.F[p];
  if (!mat.finite_strain()) {
    const Mat<D> d_eps = 0.5 * (H + H.transpose());
    P_.eps[p] += d_eps;
    P_.sigma[p] += elastic_stress_increment<D>(mat, d_eps);
    const double dilation = 1.0 + d_eps.trace();
    if (!(dilation > 0.0)) unstable(p, "volume change 1 + tr(d_eps) = " + format_number(dilation) + " <= 0");
    P_.rho[p] /= dilation;
    P_.V[p] = P_.m[p] / P_.rho[p];
    return;
  }
  const double J = P_.F[p].determinant();
  if (!(J > 0.0)) unstable(p, "det F = " + format_number(J) + " <= 0");
  P_.V[p] = J * P_.V0[p];
  P_.rho[p] = P_.m[p] / P_.V[p];
  P_.sigma[p] = cauchy_stress<D>(mat, P_.F[p]);
  P_.eps[p] = 0.5 * (P_.F[p] + P_.F[p].transpose()) - Mat<D>::Identity();
}

template <int D>
void Engine<D>::update_stress_from_increment(const AlignedVector<Vec<D>>& dx) {
  // G_p - I = sum dx_I (x) grad N_Ip equals dt L_p with L from v_I = dx_I / dt.
  update_stress(dx, 1.0);
}

namespace {
/// Per-particle sums of the after-step pass (added block by block; the
/// momentum as momentum() adds it, so it has its bits).
template <int D> struct ParticleSums {
  double kinetic = 0.0, strain = 0.0, wave_speed2 = 0.0;
  Vec<D> momentum = Vec<D>::Zero();
  ParticleSums& operator+=(const ParticleSums& o) {
    kinetic += o.kinetic;
    strain += o.strain;
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

template <int D> void Engine<D>::after_step() { sum_particles(true); }

template <int D> void Engine<D>::sum_particles(bool check) {
  // Checks in particle order within each chunk: the lowest failing particle
  // is reported, as a serial loop would.
  const auto s = blocked_reduce<ParticleSums<D>>(P_.size(), [&](long long p, ParticleSums<D>& acc) {
    if (check) check_particle(static_cast<int>(p));
    const double v2 = P_.v[p].squaredNorm();
    acc.kinetic += 0.5 * P_.m[p] * v2;
    acc.momentum += P_.m[p] * P_.v[p];
    acc.strain += P_.V[p] * strain_energy_density<D>(P_.sigma[p], P_.eps[p]);
    const double c2 = p_modulus_[P_.material[p]] / P_.rho[p];
    acc.wave_speed2 = std::max({acc.wave_speed2, c2, v2});
  });
  energy_.kinetic = s.kinetic;
  energy_.strain = s.strain;
  wave_speed_ = std::sqrt(s.wave_speed2);
  momentum_ = s.momentum;
}

template <int D> void Engine<D>::unstable(int p, const std::string& what) const {
  throw InstabilityError("step " + std::to_string(step_) + ", t = " + format_number(t_) +
                         ": particle " + std::to_string(p) + " at " + format_point<D>(P_.x[p]) + ": " + what);
}

template <int D> void Engine<D>::check_particle(int p) const {
  if (!P_.x[p].allFinite() || !P_.v[p].allFinite()) unstable(p, "position or velocity is not finite");
  if (!P_.sigma[p].allFinite()) unstable(p, "stress is not finite");
  if (mode_ != NodeMode::mpm) return;
  for (int k = 0; k < D; ++k)
    if (!(P_.x[p][k] > domain_lower_[k] && P_.x[p][k] < domain_upper_[k]))
      unstable(p, "left the grid [" + format_point<D>(domain_lower_) + ", " + format_point<D>(domain_upper_) +
                      "] (enlarge the grid or shorten t_end)");
  // Warn one step ahead: at the last step's size and the particle's velocity,
  // the next step would carry it out of the grid.
  const Vec<D> next = P_.x[p] + dt_ * P_.v[p];
  for (int k = 0; k < D; ++k)
    if (!(next[k] > domain_lower_[k] && next[k] < domain_upper_[k]))
      unstable(p, "moving at " + format_point<D>(P_.v[p]) + ", it would leave the grid in the next step (grid [" +
                      format_point<D>(domain_lower_) + ", " + format_point<D>(domain_upper_) +
                      "]; enlarge the grid or shorten t_end)");
}

template <int D> void Engine<D>::check_particles_inside() const {
  if (mode_ != NodeMode::mpm) return;
  for (int p = 0; p < P_.size(); ++p) check_particle(p);
}

template class Engine<1>;
template class Engine<2>;
template class Engine<3>;
template struct NodalFields<1>;
template struct NodalFields<2>;
template struct NodalFields<3>;

} // namespace otmpm
