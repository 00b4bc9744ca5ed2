/// \file engine_state.cpp
/// Engine<D>::save_state / restore_state: the state of a run that evolves
/// from step to step, as checkpoint groups (io/checkpoint.hpp). What is built
/// from the parts alone (materials, Dirichlet sets, loads, the initial grid)
/// is rebuilt by the constructor and not stored. The nodal fields are not
/// stored either: every integrator recomputes m, q, f, v, a, dx and the
/// consistent mass matrix from the particles each step before reading them,
/// and the scatter plan and transposed table are rebuilt with the basis
/// table. What is carried from one step to the next besides the particles:
/// t, dt_prev (OTM, unified), the body force's power at t (trapezoidal work), the
/// wave speed of the next CFL step and the energy balance (with the energy
/// friction dissipated).
#include "otmpm/engine/engine.hpp"
#include "otmpm/particles/particle_state.hpp"
#include "otmpm/state.hpp"

#include <algorithm>
#include <array>
#include <type_traits>
#include <utility>

namespace otmpm {

namespace {

// A member added to EnergyBalance must be saved and restored below.
static_assert(sizeof(EnergyBalance) == 11 * sizeof(double), "EnergyBalance changed: update engine_state.cpp");

template <int D> void save_vector(StateGroup& g, const std::string& name, const Vec<D>& v) {
  g.real_arrays[name] = {static_cast<std::size_t>(D), std::vector<double>(v.data(), v.data() + D)};
}
template <int D> Vec<D> restore_vector(const StateGroup& g, const std::string& name) {
  const auto& a = g.real_array(name, 1, D).values;
  Vec<D> v;
  std::copy(a.begin(), a.end(), v.data());
  return v;
}

/// The members of an EnergyBalance (const or not) by checkpoint name.
template <class E> auto energy_fields(E& e) {
  return std::array{std::pair{"energy_kinetic", &e.kinetic}, std::pair{"energy_strain", &e.strain},
                    std::pair{"energy_dissipated", &e.dissipated},
                    std::pair{"energy_external_work", &e.external_work},
                    std::pair{"energy_reaction_work", &e.reaction_work}, std::pair{"energy_initial", &e.initial},
                    std::pair{"energy_friction", &e.friction}};
}

void save_timers(StateGroup& g, const PhaseTimers& timers) {
  for (std::size_t i = 0; i < phase_names.size(); ++i)
    g.reals["seconds_" + std::string(phase_names[i])] = timers.seconds[i];
}
void restore_timers(const StateGroup& g, PhaseTimers& timers) {
  for (std::size_t i = 0; i < phase_names.size(); ++i)
    timers.seconds[i] = g.real("seconds_" + std::string(phase_names[i]));
}

/// Node positions, and whether the nodes still sit on their lattice (which
/// selects the basis evaluation path, so it is part of the state).
template <int D> void save_nodes(StateGroup& g, const NodeSet<D>& nodes) {
  save_field(g, "x", nodes.positions());
  g.integers["on_lattice"] = nodes.on_lattice() ? 1 : 0;
}
template <int D> void restore_nodes(const StateGroup& g, NodeSet<D>& nodes) {
  const bool on_lattice = g.integer("on_lattice") != 0;
  if (on_lattice && !nodes.on_lattice()) g.error("nodes on their lattice, but this scene's nodes are not");
  AlignedVector<Vec<D>> x(static_cast<std::size_t>(nodes.size())); // sized: "x" is required
  restore_field(g, "x", x, x.size());
  if (!on_lattice) nodes.set_positions(std::move(x));
}

} // namespace

template <int D> void Engine<D>::save_state(Checkpoint& out) const {
  out.dimension = D;
  StateGroup& g = out.group("engine");
  g.reals["t"] = t_;
  g.reals["dt"] = dt_;
  g.reals["dt_prev"] = dt_prev_;
  g.reals["external_power"] = external_power_;
  g.reals["wave_speed"] = wave_speed_;
  g.reals["gradient0"] = gradient0_;
  g.reals["gradient"] = gradient_;
  g.integers["step"] = step_;
  save_vector<D>(g, "reaction_impulse", reaction_impulse_);
  save_field(g, "wall_impulse", constraints_.wall_impulse());
  for (std::size_t w = 0; w < constraints_.held().size(); ++w) {
    const std::vector<char>& held = constraints_.held()[w];
    g.integer_arrays["wall_held_" + std::to_string(w)] = {1, std::vector<std::int64_t>(held.begin(), held.end())};
  }
  if (contact_) g.integer_arrays["contact_held"] = {1, std::vector<std::int64_t>(contact_->held().begin(), contact_->held().end())};
  if (contact_ && !contact_->carried().empty()) save_field(g, "contact_carried", contact_->carried());
  for (std::size_t s = 0; s < constraints_.carried().size(); ++s)
    save_field(g, "carried_" + std::to_string(s), constraints_.carried()[s]);
  g.put_reals(energy_fields(energy_));
  g.reals["energy_darcy"] = energy_.darcy; // read back when present (checkpoints of format 4 have none)
  g.reals["energy_pressure_average"] = energy_.pressure_average; // read back when present (older checkpoints have none)
  g.reals["energy_impact"] = energy_.impact; // read back when present (older checkpoints have none)
  g.reals["energy_relaxation"] = energy_.relaxation; // read back when present (older checkpoints have none)
  save_timers(g, timers_);
  StateGroup& particles = out.group("particles");
  save_particles(particles, P_);
  // The traction loads' shares per particle (< 0: not loaded): what a
  // distributed restart, which seeds nothing, loads its particles with.
  for (std::size_t i = 0; i < loads_.tractions.size(); ++i) {
    StateArray<double>& area = particles.real_arrays["traction_area_" + std::to_string(i)];
    area = {1, std::vector<double>(static_cast<std::size_t>(P_.size()), -1.0)};
    const Traction<D>& t = loads_.tractions[i];
    for (std::size_t k = 0; k < t.particle.size(); ++k) area.values[static_cast<std::size_t>(t.particle[k])] = t.area[k];
  }
  if (laid_out_.grid) { // laid out anew (NodeReset): the lattice, and the particles' cells of it
    StateGroup& n = out.group("nodes");
    n.integers["resets"] = laid_out_.resets;
    n.reals["lattice_time"] = laid_out_.time;
    save_vector<D>(n, "lattice_lower", laid_out_.grid->lower);
    save_vector<D>(n, "lattice_upper", laid_out_.grid->upper);
    n.integer_arrays["lattice_cells"] = {
        1, std::vector<std::int64_t>(laid_out_.grid->cells.begin(), laid_out_.grid->cells.end())};
    if (laid_out_.homes) {
      std::vector<std::int64_t> home;
      home.reserve(laid_out_.home.size() * D);
      for (const Index<D>& c : laid_out_.home) home.insert(home.end(), c.begin(), c.end());
      n.integer_arrays["home_cell"] = {static_cast<std::size_t>(D), std::move(home)};
    } else if (!fbar_.patch.empty()) { // restored from a checkpoint without homes: its F-bar patches
      n.integer_arrays["patch"] = {1, std::vector<std::int64_t>(fbar_.patch.begin(), fbar_.patch.end())};
    }
    std::vector<std::int64_t> absent(static_cast<std::size_t>(basis_->nodes().size()));
    for (std::size_t I = 0; I < absent.size(); ++I) absent[I] = !basis_->nodes().present(static_cast<int>(I));
    n.integer_arrays["absent"] = {1, std::move(absent)};
  }
  save_nodes(out.group("nodes"), basis_->nodes());
  StateGroup& basis = out.group("basis");
  basis.strings["kind"] = std::string(basis_->kind());
  basis_->save_state(basis);
}

template <int D> void Engine<D>::restore_state(const Checkpoint& in) {
  if (in.dimension != D)
    throw InputError(in.file + ": checkpoint of a " + std::to_string(in.dimension) + "D run, the scene is " +
                     std::to_string(D) + "D");
  const StateGroup& nodes = in.group("nodes");
  // the lattice of the last node reset, then its positions
  if (const std::optional<ResetLattice<D>> reset = reset_lattice_of<D>(in)) {
    if (!settings_.node_reset.lattice) nodes.error("nodes laid out anew, but this run cannot lay them out");
    laid_out_.time = reset->time;
    reset_nodes(&reset->grid);
    laid_out_.resets = static_cast<long>(nodes.integer("resets"));
    const auto& absent = nodes.integer_array("absent", static_cast<std::size_t>(basis_->nodes().size()), 1).values;
    std::vector<char> marks(absent.begin(), absent.end());
    const auto present = std::count(marks.begin(), marks.end(), char(0));
    if (present == 0) nodes.error("no node present");
    if (present < static_cast<std::ptrdiff_t>(marks.size())) { // as follow_body (a B-spline's are all present)
      basis_->nodes().remove(marks);
      basis_->nodes_moved({});
    }
    laid_out_.homes = nodes.has_array("home_cell");
    if (laid_out_.homes) { // the F-bar patches follow from them (assign_patches)
      auto home = home_cells_of<D>(nodes, static_cast<std::size_t>(P_.size()), reset->grid.cells);
      if (!home) nodes.error("a home cell outside the reset lattice");
      laid_out_.home = std::move(*home);
    } else if (nodes.has_array("patch")) { // written before the homes were: F-bar patches numbered per rank
      const auto& patch = nodes.integer_array("patch", static_cast<std::size_t>(P_.size()), 1).values;
      if (std::any_of(patch.begin(), patch.end(), [&](std::int64_t c) { return c < 0 || c >= P_.size(); }))
        nodes.error("an F-bar patch number out of range");
      fbar_.patch.assign(patch.begin(), patch.end());
      fbar_.patches = fbar_.patch.empty() ? 0 : 1 + *std::max_element(fbar_.patch.begin(), fbar_.patch.end());
    }
  }
  const StateGroup& g = in.group("engine");
  t_ = g.real("t");
  dt_ = g.real("dt");
  dt_prev_ = g.real("dt_prev");
  external_power_ = g.real("external_power");
  wave_speed_ = g.real("wave_speed");
  gradient0_ = g.reals.count("gradient0") ? g.real("gradient0") : 0.0;
  gradient_ = g.reals.count("gradient") ? g.real("gradient") : 0.0;
  step_ = static_cast<long>(g.integer("step"));
  reaction_impulse_ = restore_vector<D>(g, "reaction_impulse");
  restore_field(g, "wall_impulse", constraints_.wall_impulse(), constraints_.walls().size());
  constraints_.held().clear();
  for (std::size_t w = 0; g.has_array("wall_held_" + std::to_string(w)); ++w) {
    const std::string name = "wall_held_" + std::to_string(w);
    const auto& held = g.integer_array(name, nodal_.m.size(), 1).values;
    constraints_.held().emplace_back(held.begin(), held.end());
  }
  if (g.has_array("contact_held") != (contact_ != nullptr))
    g.error(contact_ ? "no contact state, but this scene has body contact" : "contact state, but this scene has no body contact");
  if (contact_) {
    const auto& held = g.integer_array("contact_held", contact_->held().size(), 1).values;
    contact_->held().assign(held.begin(), held.end());
    contact_->carried().clear();
    if (g.has_array("contact_carried"))
      restore_field(g, "contact_carried", contact_->carried(), contact_->held().size());
  }
  constraints_.carried().clear();
  for (std::size_t s = 0; g.has_array("carried_" + std::to_string(s)); ++s) {
    if (s > constraints_.walls().size()) g.error("more carried constraint momenta than walls and Dirichlet sets");
    constraints_.carried().emplace_back();
    restore_field(g, "carried_" + std::to_string(s), constraints_.carried().back(), nodal_.m.size());
  }
  g.get_reals(energy_fields(energy_));
  energy_.darcy = g.reals.count("energy_darcy") ? g.real("energy_darcy") : 0.0;
  energy_.impact = g.reals.count("energy_impact") ? g.real("energy_impact") : 0.0;
  energy_.relaxation = g.reals.count("energy_relaxation") ? g.real("energy_relaxation") : 0.0;
  energy_.pressure_average = g.reals.count("energy_pressure_average") ? g.real("energy_pressure_average") : 0.0;
  if (settings_.two_phase) {
    settings_.two_phase->set_darcy(energy_.darcy);
    settings_.two_phase->set_pressure_average(energy_.pressure_average);
    settings_.two_phase->forget_cells(); // the particles are restored below
  }
  restore_timers(g, timers_);
  const StateGroup& particles = in.group("particles");
  restore_particles(particles, P_, static_cast<std::size_t>(P_.size()));
  for (int m : P_.material)
    if (m < 0 || m >= static_cast<int>(materials_.size())) particles.error("material index out of range");
  restore_nodes(nodes, basis_->nodes());
  const StateGroup& basis = in.group("basis");
  if (basis.string("kind") != basis_->kind())
    basis.error("basis '" + basis.string("kind") + "', the scene has '" + std::string(basis_->kind()) + "'");
  basis_->restore_state(basis);
}

template <int D>
std::optional<std::vector<Index<D>>> home_cells_of(const StateGroup& nodes, std::size_t n, const Index<D>& cells) {
  const auto& values = nodes.integer_array("home_cell", n, D).values;
  std::vector<Index<D>> home(n);
  for (std::size_t i = 0; i < values.size(); ++i) {
    const std::size_t k = i % D;
    if (values[i] < 0 || values[i] >= cells[k]) return std::nullopt;
    home[i / D][k] = static_cast<int>(values[i]);
  }
  return home;
}

template <int D> std::optional<ResetLattice<D>> reset_lattice_of(const Checkpoint& ck) {
  const auto it = ck.groups.find("nodes");
  if (it == ck.groups.end() || !it->second.integers.count("resets")) return std::nullopt;
  const StateGroup& nodes = it->second;
  ResetLattice<D> r;
  r.grid.lower = restore_vector<D>(nodes, "lattice_lower");
  r.grid.upper = restore_vector<D>(nodes, "lattice_upper");
  const auto& cells = nodes.integer_array("lattice_cells", D, 1).values;
  for (int k = 0; k < D; ++k) r.grid.cells[k] = static_cast<int>(cells[static_cast<std::size_t>(k)]);
  try {
    r.grid.validate();
  } catch (const InputError& e) {
    nodes.error(std::string("the lattice of the last node reset: ") + e.what());
  }
  // (checkpoints written before the lattice followed moving boundaries: only fixed ones, t = 0)
  r.time = nodes.reals.count("lattice_time") ? nodes.real("lattice_time") : 0.0;
  return r;
}

template std::optional<ResetLattice<1>> reset_lattice_of<1>(const Checkpoint&);
template std::optional<ResetLattice<2>> reset_lattice_of<2>(const Checkpoint&);
template std::optional<ResetLattice<3>> reset_lattice_of<3>(const Checkpoint&);
template std::optional<std::vector<Index<1>>> home_cells_of<1>(const StateGroup&, std::size_t, const Index<1>&);
template std::optional<std::vector<Index<2>>> home_cells_of<2>(const StateGroup&, std::size_t, const Index<2>&);
template std::optional<std::vector<Index<3>>> home_cells_of<3>(const StateGroup&, std::size_t, const Index<3>&);
template void Engine<1>::save_state(Checkpoint&) const;
template void Engine<2>::save_state(Checkpoint&) const;
template void Engine<3>::save_state(Checkpoint&) const;
template void Engine<1>::restore_state(const Checkpoint&);
template void Engine<2>::restore_state(const Checkpoint&);
template void Engine<3>::restore_state(const Checkpoint&);

} // namespace otmpm
