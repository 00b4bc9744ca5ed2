// Contract tests: every member of each closed set - the basis families
// (basis_kinds()), the integrators (integrator_kinds()) and the material
// models (material_models()) - goes through the same checks, so that a new
// row is tested the day it is added, with no list to edit:
//
// * basis family: partition of unity, zero gradient sum, linear completeness
//   and gradient consistency where the family claims them
//   (Basis::linearly_complete), gradients against central differences,
//   stencils no larger than its row says (BasisKind::stencil_nodes: a family
//   that reaches every node gives a plausible error thousands of times
//   slower), a reach (BasisKind::reach) that covers its stencils, a basis
//   table independent of the thread count; in an engine, restart bit for
//   bit and thread independence;
// * integrator: restart bit for bit, thread independence and the energy
//   balance of the fixed-end bar (no load, fixed supports: E(t) - E(0) is the
//   scheme's own error), small, never above E(0) by more than the scheme's
//   oscillation, and closing as dt -> 0;
// * material model, with its example material (MaterialModel::example):
//   restart bit for bit, thread independence, and the energy balance with
//   the work it dissipates on a strip hitting a held end, scaled to the
//   model's wave speed.
//
// Each check takes a row, not a name: it builds its run from a standard
// scene and puts the row's member into the parts. Test-only rows show that
// any row is taken: copies of table rows under new names pass, and a row
// with too short a reach and a Shepard family that claims linear
// completeness and reaches every node are caught.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/materials/material.hpp"
#include "support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <initializer_list>
#include <map>
#include <sstream>
#include <string>
#include <vector>

using namespace otmpm;
using otmpm::test::ScopedThreads;

namespace {

/// What a member broke, one line each (empty: it keeps the contract).
using Violations = std::vector<std::string>;

std::string num(double x) {
  std::ostringstream s;
  s.precision(17);
  s << x;
  return s.str();
}

/// The violations of every part, in order.
Violations concatenated(std::initializer_list<Violations> parts) {
  Violations v;
  for (const Violations& part : parts) v.insert(v.end(), part.begin(), part.end());
  return v;
}

std::string joined(const Violations& v) {
  std::string s;
  for (const std::string& line : v) s += line + "\n";
  return s;
}

// ---------------------------------------------------------------- runs

/// The state a restart or the thread count must not change, as bytes by
/// name: every particle field and state array, time, step sizes, energies,
/// momentum, reactions and the node positions.
template <int D> std::map<std::string, std::string> state_of(const Engine<D>& e) {
  std::map<std::string, std::string> s;
  auto put = [&s](const std::string& name, const auto* data, std::size_t n) {
    s[name] = std::string(reinterpret_cast<const char*>(data), n * sizeof(*data));
  };
  e.particles().for_each_field([&](const char* name, const auto& field) { put(name, field.data(), field.size()); });
  for (const StateField& f : e.particles().state) put("state " + f.name, f.values.data(), f.values.size());
  const double clock[3] = {e.time(), e.last_dt(), static_cast<double>(e.steps())};
  put("clock", clock, 3);
  put("energy", &e.energy(), 1);
  const Vec<D> p = e.momentum();
  put("momentum", p.data(), D);
  put("reaction_impulse", e.reaction_impulse().data(), D);
  put("nodes", e.basis().nodes().positions().data(), e.basis().nodes().positions().size());
  return s;
}

/// The names whose bytes differ between two states.
Violations differences(const std::map<std::string, std::string>& a, const std::map<std::string, std::string>& b,
                       const std::string& what) {
  Violations v;
  for (const auto& [name, bytes] : a)
    if (!b.count(name) || b.at(name) != bytes) v.push_back(what + ": '" + name + "' differs");
  return v;
}

template <int D> using PartsMaker = std::function<EngineParts<D>()>;

/// Restart bit for bit (a checkpoint after `before` steps, restored into a
/// fresh engine, `after` more steps) and the same bits with 1 and 2 threads.
template <int D> Violations run_contract(const PartsMaker<D>& make, int before, int after) {
  Violations v;
  std::map<std::string, std::string> straight, restarted, one, two;
  Checkpoint ck;
  {
    Engine<D> e(make());
    for (int s = 0; s < before; ++s) e.step();
    e.save_state(ck);
    for (int s = 0; s < after; ++s) e.step();
    straight = state_of(e);
  }
  {
    Engine<D> e(make());
    e.restore_state(ck);
    for (int s = 0; s < after; ++s) e.step();
    restarted = state_of(e);
  }
  for (int threads : {1, 2}) {
    const ScopedThreads scope(threads);
    Engine<D> e(make());
    for (int s = 0; s < before + after; ++s) e.step();
    (threads == 1 ? one : two) = state_of(e);
  }
  for (const std::string& line : differences(straight, restarted, "restart")) v.push_back(line);
  for (const std::string& line : differences(one, two, "1 against 2 threads")) v.push_back(line);
  return v;
}

// ---------------------------------------------------------------- basis families

/// The options of `k` on a lattice of spacing h: the defaults, and for a
/// family that uses particle sizes those of 2 x 2 particles per cell.
template <int D> BasisOptions options_for(const BasisKind& k, const Vec<D>& h) {
  BasisOptions opt;
  opt.kind = std::string(k.name);
  if (k.particle_size)
    for (int a = 0; a < D; ++a) opt.particle_half_width[a] = h[a] / 4.0;
  return opt;
}

template <int D> std::unique_ptr<Basis<D>> make_family(const BasisKind& k, const BasisOptions& opt, NodeSet<D> nodes) {
  if constexpr (D == 1) return k.make1(opt, std::move(nodes));
  else if constexpr (D == 2) return k.make2(opt, std::move(nodes));
  else return k.make3(opt, std::move(nodes));
}

/// The identities of family `k` on the unit box in D dimensions, at uniform
/// points, points next to the boundary and points next to nodes.
template <int D> Violations basis_identities(const BasisKind& k) {
  Violations v;
  const int cells = test::cells_for<D>();
  const CartesianGrid<D> grid = test::unit_grid<D>(cells);
  const auto b = make_family<D>(k, options_for<D>(k, grid.h()), NodeSet<D>::cartesian(grid));
  const std::string at = std::string(k.name) + " " + std::to_string(D) + "D: ";
  const auto pts = test::unit_box_points<D>(b->nodes(), 40, 7u);
  const test::Identities<D> id = test::check_identities<D>(*b, pts);
  // Round-off of sums of O(1) terms over a stencil; completeness to the
  // max-ent Newton tolerance (1e-12 h) with room for the sums.
  if (id.partition > 1e-12) v.push_back(at + "sum N_I - 1 = " + num(id.partition));
  if (id.gradient_sum > 1e-12) v.push_back(at + "|sum grad N_I| / sum |grad N_I| = " + num(id.gradient_sum));
  if (b->linearly_complete() && id.completeness > 1e-10)
    v.push_back(at + "claims linear completeness, |sum N_I x_I - x| / h = " + num(id.completeness));
  if (b->linearly_complete() && id.gradient_consistency > 1e-9)
    v.push_back(at + "claims linear completeness, |sum x_I (x) grad N_I - I| = " + num(id.gradient_consistency));
  if (id.min_N < 0.0) v.push_back(at + "a negative N_I = " + num(id.min_N));
  // Central differences of step 2e-6 h: truncation ~1e-11, round-off ~1e-10
  // relative to h grad N ~ 1 (a point within 2e-6 h of a hat's kink is
  // unlikely among 30).
  const double fd = test::max_fd_gradient_error<D>(*b, 3u, 2e-6);
  if (fd > 1e-6) v.push_back(at + "grad N_I against central differences: " + num(fd) + " (h grad N)");
  // Stencil sizes on the uniform lattice: the row's estimate (what run --check
  // and the memory estimate assume) within 1.5, and never above max_stencil.
  Stencil<D> st;
  double total = 0.0;
  int largest = 0;
  for (const Vec<D>& x : pts) {
    test::evaluate_at(*b, x, st);
    total += st.size();
    largest = std::max(largest, st.size());
  }
  const double mean = total / static_cast<double>(pts.size()), expected = k.stencil_nodes(options_for<D>(k, grid.h()), D);
  if (mean > 1.5 * expected) v.push_back(at + "mean stencil " + num(mean) + " nodes, the row expects " + num(expected));
  if (largest > b->max_stencil()) v.push_back(at + "a stencil of " + std::to_string(largest) + " > max_stencil()");
  return v;
}

/// The row's reach (BasisKind::reach, what a distributed run's windows hold)
/// covers the family's stencils: on the unit lattice of D dimensions, every
/// node of the stencil of a point in cell c has the lattice index c - below
/// .. c + above per axis, of cells + points_beyond_cells per axis (node ids
/// axis 0 fastest).
template <int D> Violations basis_reach(const BasisKind& k) {
  const std::string at = std::string(k.name) + " (" + std::to_string(D) + "D): ";
  if (!k.reach) return {at + "the row declares no reach (BasisKind::reach)"};
  const int cells = D == 3 ? 6 : 8;
  const CartesianGrid<D> grid = test::unit_grid<D>(cells);
  const auto b = make_family<D>(k, options_for<D>(k, grid.h()), NodeSet<D>::cartesian(grid));
  const LatticeReach r = k.reach(b->search_radius(), grid.h()[0], D);
  const int n = cells + r.points_beyond_cells;
  if (b->nodes().size() != static_cast<int>(std::pow(n, D)))
    return {at + std::to_string(b->nodes().size()) + " points, the reach says " + std::to_string(n) +
            " per axis"};
  std::mt19937 rng(5);
  Stencil<D> st;
  for (int i = 0; i < 200; ++i) {
    const Vec<D> x = test::random_in_box<D>(rng, Vec<D>::Zero(), Vec<D>::Ones());
    test::evaluate_at(*b, x, st);
    for (int e = 0; e < st.size(); ++e)
      for (int a = 0, id = st.node[e]; a < D; ++a, id /= n) {
        const int index = id % n, c = std::min(cells - 1, static_cast<int>(x[a] * cells));
        if (index < c - r.below || index > c + r.above)
          return {at + "a point in cell " + std::to_string(c) + " reaches point " + std::to_string(index) +
                  " on axis " + std::to_string(a) + ", beyond the row's reach -" + std::to_string(r.below) +
                  "/+" + std::to_string(r.above)};
      }
  }
  return {};
}

/// The basis table of 3000 points filled with 1 and 2 threads: the same bits.
Violations basis_table_threads(const BasisKind& k) {
  const CartesianGrid<2> grid = test::unit_grid<2>(16);
  const auto b = make_family<2>(k, options_for<2>(k, grid.h()), NodeSet<2>::cartesian(grid));
  std::mt19937 rng(11);
  AlignedVector<Vec<2>> x;
  for (int i = 0; i < 3000; ++i) x.push_back(test::random_in_box<2>(rng, Vec<2>(0.01, 0.01), Vec<2>(0.99, 0.99)));
  BasisTable<2> t[2];
  for (int threads : {1, 2}) {
    const ScopedThreads scope(threads);
    fill_basis_table(*b, x, nullptr, nullptr, t[threads - 1]);
  }
  const bool same = t[0].offset == t[1].offset && t[0].node == t[1].node && t[0].N == t[1].N &&
                    std::memcmp(t[0].dN.data(), t[1].dN.data(), t[0].dN.size() * sizeof(Vec<2>)) == 0 &&
                    t[0].dN.size() == t[1].dN.size();
  return same ? Violations{} : Violations{std::string(k.name) + ": the basis table differs with 1 and 2 threads"};
}

/// A free 2D block (12 288 particles: two scatter blocks and several
/// thread chunks) with a non-uniform velocity of up to 0.02 `c` (the
/// material's wave speed), `mode`, `integrator`, `basis`, `mass`, material
/// `material` (TOML of one [[material]] named m).
std::string block_scene(const std::string& mode, const std::string& integrator, const std::string& basis,
                        const std::string& mass, const std::string& material, double c = 1.0) {
  return "[simulation]\ndimension = 2\nmode = \"" + mode + "\"\nintegrator = \"" + integrator +
         "\"\nt_end = 100.0\ncfl = 0.2\nmass = \"" + mass + "\"\n[basis]\nkind = \"" + basis + "\"\n" +
         "[grid]\nlower = [-0.25, -0.25]\nupper = [1.25, 1.0]\ncells = [96, 80]\n" + material +
         "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.0, 0.0]\nupper = [1.0, 0.75]\n"
         "particles_per_cell = 2\nvelocity = [" + num(0.01 * c) + ", " + num(-0.005 * c) + "]\n"
         "velocity_profile = \"sin_x\"\n[[initial_velocity]]\nlower = [0.0, 0.0]\nupper = [0.25, 0.75]\n"
         "velocity = [" + num(-0.02 * c) + ", " + num(0.01 * c) + "]\n";
}

const std::string kUnitElastic = "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1.0\n"
                                 "young = 1.0\npoisson = 0.3\n";

/// Family `k` in an engine: the block (mpm, npc, lumped) with the family
/// put into the parts on the scene's lattice.
Violations basis_run(const BasisKind& k) {
  const Scene scene = parse_scene(block_scene("mpm", "npc", "linear", "lumped", kUnitElastic), "contract.toml");
  const PartsMaker<2> make = [&] {
    EngineParts<2> parts = assemble_parts<2>(scene);
    const CartesianGrid<2> grid = *parts.basis->nodes().grid();
    parts.basis = make_family<2>(k, options_for<2>(k, grid.h()), NodeSet<2>::cartesian(grid));
    return parts;
  };
  Violations v = run_contract<2>(make, 6, 6);
  for (std::string& line : v) line = std::string(k.name) + " in an engine: " + line;
  return v;
}

Violations basis_contract(const BasisKind& k) {
  return concatenated({basis_identities<1>(k), basis_identities<2>(k), basis_identities<3>(k),
                       basis_reach<2>(k), basis_reach<3>(k), basis_table_threads(k), basis_run(k)});
}

// ---------------------------------------------------------------- integrators

/// The mode, basis and mass an integrator's row asks for.
std::string mode_of(const IntegratorKind& k) { return k.needs_ul ? "ul" : "mpm"; }
std::string basis_of(const IntegratorKind& k) { return k.needs_bspline ? "bspline2" : "linear"; }
std::string mass_of(const IntegratorKind& k) {
  return k.consistent_by_default || k.needs_consistent_mass ? "consistent" : "lumped";
}

/// Puts integrator `k` into parts assembled for another integrator (npc)
/// with the same mode, basis and mass, as the assembler would.
template <int D> void use_integrator(const IntegratorKind& k, EngineParts<D>& parts) {
  parts.settings.step = k.step<D>();
  parts.settings.parameters = k.default_parameters();
}

/// `relaxed`: with pic_relaxation_time = 1e-3 where the integrator takes
/// it (its W_v is part of the energy compared), else nothing to check.
Violations integrator_run(const IntegratorKind& k, bool relaxed = false) {
  if (relaxed && !k.takes("pic_relaxation_time")) return {};
  const Scene scene =
      parse_scene(block_scene(mode_of(k), "npc", basis_of(k), mass_of(k), kUnitElastic), "contract.toml");
  const PartsMaker<2> make = [&] {
    EngineParts<2> parts = assemble_parts<2>(scene);
    use_integrator(k, parts);
    if (relaxed) parts.settings.parameters.values["pic_relaxation_time"] = 1e-3;
    return parts;
  };
  Violations v = run_contract<2>(make, 6, 6);
  for (std::string& line : v) line = std::string(k.name) + (relaxed ? " relaxed: " : ": ") + line;
  return v;
}

/// The fixed-end bar of test_energy.cpp: [0, 1], E = rho = 1, h = 1/8, its
/// first mode v = 0.01 sin(pi x) for two periods (t_end = 4). Returns the
/// largest |E(t) - E(0)| / E(0) and E(t_end) / E(0).
std::pair<double, double> bar_drift(const IntegratorKind& k, double cfl) {
  const std::string text =
      "[simulation]\ndimension = 1\nmode = \"" + mode_of(k) + "\"\nintegrator = \"npc\"\nt_end = 4.0\ncfl = " +
      num(cfl) + "\nmass = \"" + mass_of(k) + "\"\n[basis]\nkind = \"" + basis_of(k) + "\"\n" +
      "[grid]\nlower = [-0.25]\nupper = [1.25]\ncells = [12]\n"
      "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1.0\nyoung = 1.0\npoisson = 0.0\n"
      "[[body]]\nname = \"bar\"\nmaterial = \"m\"\nlower = [0.0]\nupper = [1.0]\nparticles_per_cell = 2\n"
      "velocity = [0.01]\nvelocity_profile = \"sin_x\"\n"
      "[[boundary]]\nname = \"left\"\nlower = [0.0]\nupper = [0.0]\nfix = [true]\n"
      "[[boundary]]\nname = \"right\"\nlower = [1.0]\nupper = [1.0]\nfix = [true]\n";
  EngineParts<1> parts = assemble_parts<1>(parse_scene(text, "bar.toml"));
  use_integrator(k, parts);
  Engine<1> e(std::move(parts));
  double worst = 0.0;
  while (e.time() < e.settings().t_end * (1.0 - 1e-12)) {
    e.step();
    worst = std::max(worst, std::abs(e.energy().balance_error()));
  }
  return {worst / e.energy().initial, e.energy().total() / e.energy().initial};
}

/// The energy contract: the drift of the fixed-end bar at cfl 0.1 below 0.25
/// (npc, the most dissipative, measures 0.21), at most 1% of E(0) gained
/// at t_end (the schemes' oscillation: otm measures 1.0032), and at half the
/// step either at most 0.6 of it (first order in dt gives 0.5) or already
/// below 1e-3 (a scheme that conserves the first mode).
Violations integrator_energy(const IntegratorKind& k) {
  Violations v;
  const auto [drift, end] = bar_drift(k, 0.1);
  const auto [half, end_half] = bar_drift(k, 0.05);
  MESSAGE(std::string(k.name) << ": energy drift " << drift << " at cfl 0.1, " << half << " at 0.05; E(t_end)/E(0) "
                              << end << ", " << end_half);
  const std::string at = std::string(k.name) + ": fixed-end bar: ";
  if (!(drift < 0.25)) v.push_back(at + "energy drift " + num(drift) + " at cfl 0.1");
  if (!(end <= 1.01 && end_half <= 1.01)) v.push_back(at + "energy gained: E(t_end)/E(0) = " + num(std::max(end, end_half)));
  if (!(half <= 0.6 * drift || half < 1e-3))
    v.push_back(at + "the drift does not close with dt: " + num(drift) + " -> " + num(half));
  return v;
}

Violations integrator_contract(const IntegratorKind& k) {
  return concatenated({integrator_run(k), integrator_run(k, true), integrator_energy(k)});
}

// ---------------------------------------------------------------- material models

/// The example material of model `m` as a [[material]] named "m", its
/// density and its wave speed sqrt(E / rho).
struct Example {
  std::string toml;
  MaterialParameters params;
  double c = 0.0;
};

Example example_of(const MaterialModel& m) {
  Example ex;
  ex.params.name = "m";
  ex.params.model = std::string(m.name);
  for (const ParameterValue& p : m.example) {
    if (p.key == "density") ex.params.density = p.value;
    else if (p.key == "young") ex.params.young = p.value;
    else if (p.key == "poisson") ex.params.poisson = p.value;
    else ex.params.extra[std::string(p.key)] = p.value;
  }
  // The scene runs linear_elastic with the example's elastic constants; the
  // model goes into the parts (put_material).
  ex.toml = "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = " + num(ex.params.density) +
            "\nyoung = " + num(ex.params.young) + "\npoisson = " + num(ex.params.poisson) + "\n";
  ex.c = std::sqrt(ex.params.young / ex.params.density);
  return ex;
}

/// Model `m` with its example put into the parts, with its state arrays.
template <int D> void put_material(const MaterialModel& m, const Example& ex, EngineParts<D>& parts) {
  if constexpr (D == 1) parts.materials[0] = m.make1(ex.params);
  else if constexpr (D == 2) parts.materials[0] = m.make2(ex.params);
  else parts.materials[0] = m.make3(ex.params);
  for (const StateSpec& s : parts.materials[0]->state())
    parts.particles.add_state(std::string(s.name), s.width, s.initial.data());
}

Violations material_run(const MaterialModel& m) {
  const Example ex = example_of(m);
  // Velocities of up to 0.02 c: strains of that order, beyond yield for
  // the plastic examples (j2: sigma_y / E = 2.5e-4).
  const Scene scene = parse_scene(block_scene("mpm", "npc", "linear", "lumped", ex.toml, ex.c), "contract.toml");
  const PartsMaker<2> make = [&] {
    EngineParts<2> parts = assemble_parts<2>(scene);
    put_material(m, ex, parts);
    return parts;
  };
  Violations v = run_contract<2>(make, 6, 6);
  for (std::string& line : v) line = std::string(m.name) + ": " + line;
  return v;
}

/// The strip of test_plastic_runs.cpp (0.1 m x 5 mm, plane strain, the
/// right end held, the bottom on rollers, the top free) scaled to the
/// example: the whole strip hits the held end at v0 = 1e-3 c (5 m/s for
/// steel; compression, so that a granular model bears stress, with a free
/// side, so that it shears), t_end = L / c; musl, linear. The balance E + W_p - E(0) -
/// W within 2% of E(0), as that test measures for j2 and drucker_prager, and
/// the dissipated work never negative.
Violations material_energy(const MaterialModel& m) {
  const Example ex = example_of(m);
  const std::string text =
      "[simulation]\ndimension = 2\nmode = \"mpm\"\nintegrator = \"musl\"\nt_end = " + num(0.1 / ex.c) +
      "\ncfl = 0.1\n[basis]\nkind = \"linear\"\n"
      "[grid]\nlower = [-0.01, 0.0]\nupper = [0.1, 0.01]\ncells = [22, 2]\n" + ex.toml +
      "[[body]]\nname = \"bar\"\nmaterial = \"m\"\nlower = [0.0, 0.0]\nupper = [0.1, 0.005]\n"
      "velocity = [" + num(1e-3 * ex.c) + ", 0.0]\n"
      "[[boundary]]\nname = \"end\"\nlower = [0.1, 0.0]\nupper = [0.1, 0.005]\nfix = [true, false]\n"
      "[[boundary]]\nname = \"bottom\"\nlower = [-0.01, 0.0]\nupper = [0.1, 0.0]\nfix = [false, true]\n";
  EngineParts<2> parts = assemble_parts<2>(parse_scene(text, "strip.toml"));
  put_material(m, ex, parts);
  Engine<2> e(std::move(parts));
  while (e.time() < e.settings().t_end * (1.0 - 1e-12)) e.step();
  const EnergyBalance& E = e.energy();
  MESSAGE(std::string(m.name) << ": strip balance " << E.balance_error() / E.initial << " E0, dissipated "
                              << E.dissipated / E.initial << " E0");
  Violations v;
  const std::string at = std::string(m.name) + ": strip: ";
  if (!(std::abs(E.balance_error()) <= 0.02 * E.initial))
    v.push_back(at + "|E + W_p - E0 - W| = " + num(std::abs(E.balance_error()) / E.initial) + " E0");
  if (!(E.dissipated >= 0.0)) v.push_back(at + "negative dissipated work " + num(E.dissipated));
  return v;
}

Violations material_contract(const MaterialModel& m) { return concatenated({material_run(m), material_energy(m)}); }

// ---------------------------------------------------------------- test-only rows

/// Shepard's inverse-distance weights over every node, w_I = 1 / |x - x_I|^2:
/// a partition of unity with zero gradient sum that is not linearly
/// complete, yet claims to be, and whose stencil is the whole lattice.
template <int D> class ShepardBasis final : public Basis<D> {
public:
  explicit ShepardBasis(NodeSet<D> nodes) : nodes_(std::move(nodes)) {}
  std::string_view kind() const override { return "shepard_test"; }
  const NodeSet<D>& nodes() const override { return nodes_; }
  NodeSet<D>& nodes() override { return nodes_; }
  void nodes_moved(const AlignedVector<Vec<D>>&) override {}
  bool linearly_complete() const override { return true; } // the deliberate lie
  int max_stencil() const override { return nodes_.size(); }
  void evaluate(const PointQuery<D>& q, Stencil<D>& out) const override {
    const int n = nodes_.size();
    out.clear();
    double W = 0.0;
    Vec<D> dW = Vec<D>::Zero();
    std::vector<double> w(static_cast<std::size_t>(n));
    AlignedVector<Vec<D>> dw(static_cast<std::size_t>(n));
    for (int I = 0; I < n; ++I) {
      const Vec<D> r = q.x - nodes_.position(I);
      const double r2 = std::max(r.squaredNorm(), 1e-300);
      w[I] = 1.0 / r2;
      dw[I] = -2.0 * r / (r2 * r2);
      W += w[I];
      dW += dw[I];
    }
    for (int I = 0; I < n; ++I) out.push(I, w[I] / W, (dw[I] - (w[I] / W) * dW) / W);
  }

private:
  NodeSet<D> nodes_;
};

template <int D> std::unique_ptr<Basis<D>> make_shepard(const BasisOptions&, NodeSet<D> nodes) {
  return std::make_unique<ShepardBasis<D>>(std::move(nodes));
}

double shepard_stencil(const BasisOptions&, int dim) { return std::pow(2.0, dim); }

} // namespace

TEST_CASE("contract: every basis family of basis_kinds()") {
  for (const BasisKind& k : basis_kinds()) {
    CAPTURE(k.name);
    const Violations v = basis_contract(k);
    CHECK_MESSAGE(v.empty(), joined(v));
  }
}

TEST_CASE("contract: every integrator of integrator_kinds()") {
  for (const IntegratorKind& k : integrator_kinds()) {
    CAPTURE(k.name);
    const Violations v = integrator_contract(k);
    CHECK_MESSAGE(v.empty(), joined(v));
  }
}

TEST_CASE("contract: every material model of material_models(), with its example material") {
  for (const MaterialModel* m : material_models()) {
    CAPTURE(m->name);
    REQUIRE_MESSAGE(!m->example.empty(), "model ", std::string(m->name), " declares no example material");
    const Violations v = material_contract(*m);
    CHECK_MESSAGE(v.empty(), joined(v));
  }
}

TEST_CASE("contract: rows that are not in the tables are taken as they are, a broken family is caught") {
  // Copies of table rows under new names: the checks find them by the row,
  // never by name, so they pass as the originals do.
  BasisKind linear_copy = basis_kind("linear");
  linear_copy.name = "linear_test";
  const Violations basis = basis_contract(linear_copy);
  CHECK_MESSAGE(basis.empty(), joined(basis));
  IntegratorKind musl_copy = integrator_kind("musl");
  musl_copy.name = "musl_test";
  const Violations integrator = integrator_contract(musl_copy);
  CHECK_MESSAGE(integrator.empty(), joined(integrator));
  MaterialModel neo_copy = *find_material_model("neo_hookean");
  neo_copy.name = "neo_hookean_test";
  const Violations material = material_contract(neo_copy);
  CHECK_MESSAGE(material.empty(), joined(material));

  // A row that declares too short a reach (a distributed run's windows would
  // miss nodes its stencils use).
  BasisKind short_reach = linear_copy;
  short_reach.reach = [](double, double, int) { return LatticeReach{.below = 0, .above = 0}; };
  CHECK(joined(basis_reach<2>(short_reach)).find("beyond the row's reach") != std::string::npos);

  // A family that lies about its completeness and reaches every node.
  const BasisKind shepard{.name = "shepard_test",
                          .description = "inverse-distance weights over all nodes (broken on purpose)",
                          .needs_lattice = false,
                          .stencil_nodes = shepard_stencil,
                          .make1 = make_shepard<1>,
                          .make2 = make_shepard<2>,
                          .make3 = make_shepard<3>};
  const std::string found = joined(concatenated({basis_identities<1>(shepard), basis_identities<2>(shepard)}));
  CHECK(found.find("shepard_test 2D: claims linear completeness, |sum N_I x_I - x| / h") != std::string::npos);
  CHECK(found.find("shepard_test 2D: mean stencil") != std::string::npos);
  CHECK(found.find("sum N_I - 1") == std::string::npos); // what it gets right is not reported
}
