/// \file local_parts.cpp
/// A rank's share of the engine parts (local_parts.hpp).
#include "otmpm/distributed/local_parts.hpp"

#include "otmpm/assembly/assembler.hpp"
#include "otmpm/assembly/seeding.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/basis/lme.hpp"
#include "otmpm/distributed/share_seeding.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/particles/particle_state.hpp"
#include "otmpm/scene/resources.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <exception>
#include <optional>

namespace otmpm::distributed {

namespace {

/// Cells of slack around the support in `ul` mode: the particles keep the
/// cell they were seeded in while the lattice moves, and may drift from it.
constexpr int kAdvectedSlack = 2;

/// Cells per axis of the basis probe (at most: the lattice's when fewer),
/// enough for every family (a cubic B-spline, an LME stencil).
constexpr int kProbeCells = 4;

/// The scene's basis on a few cells at the lower corner of the node lattice,
/// with the whole lattice's spacing: what the point lattice needs to know of
/// the family (the B-spline degree, the search radius, which depends on the
/// spacing only) and the errors of the scene's basis options, without the
/// whole lattice. (The LME `node_spacing` metric on a perturbed grid takes
/// its search radius from every node: perturbed_search_radius.)
template <int D> std::unique_ptr<Basis<D>> probe_basis(const Scene& scene, const CartesianGrid<D>& grid) {
  const BasisOptions options = basis_options<D>(scene);
  try {
    CartesianGrid<D> g;
    Index<D> corner;
    for (int k = 0; k < D; ++k) corner[k] = g.cells[k] = std::min(grid.cells[k], kProbeCells);
    g.lower = grid.lower;
    g.upper = grid.node_position(corner);
    return make_basis<D>(options, NodeSet<D>::cartesian(g, grid.h().minCoeff()));
  } catch (const InputError& e) {
    input_error(scene.basis_where, e.what());
  }
}

/// True when the scene's basis takes its search radius from every node's
/// nearest neighbour: the node_spacing metric (LME, the family that adapts
/// its metric) on a perturbed grid.
bool radius_from_nodes(const Scene& scene) {
  return scene.grid.kind == "perturbed" && basis_kind(scene.basis.kind).adapts_metric &&
         scene.basis.metric == "node_spacing";
}

/// Layers of nodes around a rank's own nodes that hold every node within 4 h
/// of them (a perturbed node moves less than h / 2 on each axis, so nodes m
/// layers apart are more than (m - 1) h apart), and every nearest-node
/// search ends within 4 h (the next node along an axis is nearer than
/// sqrt(4 + (D - 1)) h).
constexpr int kNearestLayers = 5;

/// The search radius of LME with the node_spacing metric on a perturbed
/// grid, as the basis on the whole lattice has it (maxent::
/// node_spacing_search_radius of the largest nearest-node distance): each
/// rank searches the nearest node of each of its own nodes among its nodes
/// and kNearestLayers more, then the ranks take the largest.
template <int D>
double perturbed_search_radius(const Scene& scene, const Comm& comm, const CartesianGrid<D>& grid,
                               const IndexBox<D>& own) {
  IndexBox<D> box;
  for (int k = 0; k < D; ++k) {
    box.lo[k] = std::max(0, own.lo[k] - kNearestLayers);
    box.hi[k] = std::min(grid.cells[k] + 1, own.hi[k] + kNearestLayers);
  }
  const double h = grid.h().minCoeff();
  const NodeSet<D> nodes = NodeSet<D>::cloud(
      NodeSet<D>::perturbed_positions(grid, scene.grid.perturbation, scene.grid.seed, box.lo, box.hi), h);
  nodes.prepare_search();
  Window<D> w;
  w.box = box;
  double largest = 0.0;
  for (int i = 0; i < w.size(); ++i)
    if (own.contains(w.index(i))) largest = std::max(largest, maxent::nearest_node_distance(nodes, i, h));
  return maxent::node_spacing_search_radius(basis_options<D>(scene), h, comm.max(largest));
}

/// The point lattice of the scene's basis (`radius`: its search radius, or
/// the whole lattice's when that differs): which points, which cell each
/// belongs to, and how far the particles of a cell reach - the family's
/// reach (BasisKind::reach).
template <int D>
PointLattice<D> point_lattice(const Scene& scene, double radius, const CartesianGrid<D>& grid, bool ul) {
  PointLattice<D> L;
  L.grid = grid;
  const BasisKind& kind = basis_kind(scene.basis.kind);
  const Vec<D> h = grid.h();
  for (int k = 0; k < D; ++k) {
    const LatticeReach r = kind.reach(radius, h[k], D);
    L.points[k] = grid.cells[k] + r.points_beyond_cells;
    L.below[k] = r.below, L.above[k] = r.above;
    if (k == 0) L.shift = r.shift;
  }
  if (ul) {
    for (int k = 0; k < D; ++k) L.below[k] += kAdvectedSlack, L.above[k] += kAdvectedSlack;
    L.guard = 1;
  }
  return L;
}

/// The point lattice of the scene's basis as the rank that owns `cells`
/// builds its window on it (collective: the LME node_spacing metric on a
/// perturbed grid takes its radius from every rank's nodes).
template <int D>
PointLattice<D> rank_point_lattice(const Scene& scene, const Comm& comm, const CartesianGrid<D>& grid,
                                   const IndexBox<D>& cells) {
  const bool ul = scene.simulation.nodes_move();
  double radius = probe_basis<D>(scene, grid)->search_radius();
  if (radius_from_nodes(scene)) {
    // the owned nodes do not depend on the radius (only the ghost layers do)
    const IndexBox<D> own = point_lattice<D>(scene, radius, grid, ul).owned_points(cells);
    radius = perturbed_search_radius<D>(scene, comm, grid, own);
  }
  return point_lattice<D>(scene, radius, grid, ul);
}

/// What rank r of `d` holds on the point lattice `L` with `particles`
/// particles (RankShare), and its neighbours in the nodal exchange (`links`).
template <int D>
RankShare rank_share(const PointLattice<D>& L, const Decomposition<D>& d, int r, long long particles,
                     std::vector<HaloLink>& links) {
  RankShare s;
  s.particles = particles;
  const IndexBox<D> window = L.window(d.box(r)), own = L.owned_points(d.box(r));
  s.points = window.count();
  for (int q = 0; q < d.ranks(); ++q) {
    if (q == r) continue;
    const HaloLink link{q, window.intersect(L.owned_points(d.box(q))).count(),
                        own.intersect(L.window(d.box(q))).count()};
    if (link.ghosts + link.shared == 0) continue;
    links.push_back(link);
    ++s.neighbours;
    s.ghosts += link.ghosts;
    s.halo += link.ghosts + link.shared;
  }
  return s;
}

/// Refuses (InputError on every rank: the lowest rank over its limit) a
/// rank whose share - rank r holds particles[r] particles and the window of
/// its cells of `d` on `L` - has more than kMaxRankNodes lattice points or
/// exceeds its memory limit (check_rank_resources).
template <int D>
void check_rank_memory(const Scene& scene, const Comm& comm, const PointLattice<D>& L, const Decomposition<D>& d,
                       const std::vector<std::int64_t>& particles) {
  SceneSize mine;
  mine.particles = static_cast<double>(particles[static_cast<std::size_t>(comm.rank())]);
  mine.nodes = static_cast<double>(L.window(d.box(comm.rank())).count());
  const double total = comm.sum(estimate_resources(scene, mine, d.ranks()).bytes);
  agree_on(comm, [&] {
    if (mine.nodes > kMaxRankNodes)
      throw InputError("rank " + std::to_string(comm.rank()) + " of " + std::to_string(d.ranks()) + " would hold " +
                       format_number(mine.nodes) + " lattice points with its ghosts; at most " +
                       format_number(kMaxRankNodes) + " per rank are allowed (run on more ranks)");
    check_rank_resources(scene, mine, comm.rank(), d.ranks(), total);
  });
}

/// The basis of the scene on a window: a family whose points are not the
/// lattice's nodes by its window constructor (B-splines: the whole
/// lattice's knots with the window's control points, BasisKind::window);
/// the lattice families on the window's part of the lattice (a perturbed
/// lattice's positions drawn for the window from the grid's random stream,
/// NodeSet::perturbed_positions). Also gives the global cell of the basis'
/// local cell 0 (its cell hints are local to it). Never builds the whole lattice.
template <int D>
std::function<std::unique_ptr<Basis<D>>(const Window<D>&, Index<D>&)>
window_basis_factory(const Scene& scene, const PointLattice<D>& L, bool cartesian = false) {
  const CartesianGrid<D> grid = L.grid;
  const BasisOptions options = basis_options<D>(scene);
  if (const WindowFactory<D> window = basis_kind(scene.basis.kind).window<D>()) {
    return [grid, options, window](const Window<D>& w, Index<D>& hint_offset) -> std::unique_ptr<Basis<D>> {
      hint_offset = {};
      return window(options, grid, w.box.lo, w.box.hi);
    };
  }
  const bool perturbed = !cartesian && scene.grid.kind == "perturbed";
  const double fraction = scene.grid.perturbation;
  const unsigned seed = scene.grid.seed;
  return [grid, perturbed, fraction, seed, options](const Window<D>& w,
                                                    Index<D>& hint_offset) -> std::unique_ptr<Basis<D>> {
    hint_offset = w.box.lo;
    CartesianGrid<D> g;
    Index<D> last;
    for (int k = 0; k < D; ++k) last[k] = w.box.hi[k] - 1, g.cells[k] = w.box.extent(k) - 1;
    g.lower = grid.node_position(w.box.lo);
    g.upper = grid.node_position(last);
    NodeSet<D> nodes = NodeSet<D>::cartesian(g);
    if (perturbed) nodes.set_positions(NodeSet<D>::perturbed_positions(grid, fraction, seed, w.box.lo, w.box.hi));
    return make_basis<D>(options, std::move(nodes));
  };
}

/// The Dirichlet entries of the scene's boundary boxes on a window (local
/// ids), found on the positions the whole lattice gives its points there: a
/// B-spline's control points and a perturbed lattice's nodes as the window
/// basis has them (the same bits), a Cartesian lattice's from the grid
/// (the window basis' own grid may round them differently). `counted` and
/// `selected`: boundary_entries.
template <int D>
Dirichlet<D> window_boundaries(const std::vector<BoundarySection>& boundaries, const CartesianGrid<D>& grid,
                               bool from_basis, const Window<D>& w, const Basis<D>& basis,
                               const std::vector<char>* counted = nullptr, std::vector<long long>* selected = nullptr) {
  const double h = grid.h().minCoeff();
  if (from_basis) {
    const NodeSet<D>& nodes = basis.nodes();
    return boundary_entries<D>(
        boundaries, nodes.size(), [&nodes](int i) { return nodes.position(i); }, h, counted, selected);
  }
  return boundary_entries<D>(
      boundaries, w.size(), [&grid, &w](int i) { return grid.node_position(w.index(i)); }, h, counted, selected);
}

/// window_boundaries on the window `w` of the rank that owns `cells` of
/// `L`, checked: each box must select a node of the whole lattice (the
/// points each rank owns, counted over the ranks; collective).
template <int D>
Dirichlet<D> checked_boundaries(const Scene& scene, const std::vector<BoundarySection>& boundaries,
                                const Comm& comm, const PointLattice<D>& L, const IndexBox<D>& cells,
                                bool from_basis, const Window<D>& w, const Basis<D>& basis) {
  const IndexBox<D> own = L.owned_points(cells);
  std::vector<char> owned(static_cast<std::size_t>(w.size()));
  for (int i = 0; i < w.size(); ++i) owned[static_cast<std::size_t>(i)] = own.contains(w.index(i)) ? 1 : 0;
  std::vector<long long> selected;
  Dirichlet<D> d = window_boundaries<D>(boundaries, L.grid, from_basis, w, basis, &owned, &selected);
  std::vector<std::int64_t> total(selected.begin(), selected.end());
  comm.sum(total);
  require_boundary_nodes(scene, std::vector<long long>(total.begin(), total.end()));
  return d;
}

/// The node reset of a `ul` run on the ranks (Domain::lay_out): the point
/// lattice of a new node lattice (the serial reset's Cartesian lattice on
/// the scene grid's lines), and the basis and the Dirichlet entries of the
/// boundary boxes at time t on a rank's window of it.
template <int D> void reset_hooks(const Scene& scene, const Comm& comm, typename Domain<D>::Setup& setup) {
  if (!(node_reset_fraction(scene) > 0)) return;
  setup.reset_lattice = [scene](const CartesianGrid<D>& grid) {
    return point_lattice<D>(scene, probe_basis<D>(scene, grid)->search_radius(), grid, true);
  };
  setup.reset_window = [scene, &comm](const PointLattice<D>& L, const IndexBox<D>& cells, const Window<D>& w,
                                      double t, Index<D>& hint_offset) {
    LatticePart<D> part;
    part.basis = window_basis_factory<D>(scene, L, true)(w, hint_offset);
    const bool from_basis = static_cast<bool>(basis_kind(scene.basis.kind).window<D>());
    part.dirichlet =
        checked_boundaries<D>(scene, boundaries_at(scene, t), comm, L, cells, from_basis, w, *part.basis);
    return part;
  };
}

/// The lattice part of a rank (assemble_parts' `lattice`): the basis on its
/// window and the Dirichlet entries found there; the Domain's set-up gets
/// the point lattice and the factories of both (rebalancing). The check
/// that each boundary box selects a node counts the points each rank owns,
/// summed over the ranks (a boundary is found once, on the whole lattice).
/// `decomposed` false: the bisection failed (its error is raised after the
/// assembly), only the probe is built; true: setup.lattice is this rank's
/// rank_point_lattice (found before the particles were kept).
template <int D>
LatticePart<D> rank_lattice(const Scene& scene, const Comm& comm, const CartesianGrid<D>& grid, bool decomposed,
                            typename Domain<D>::Setup& setup) {
  LatticePart<D> part;
  std::unique_ptr<Basis<D>> probe = probe_basis<D>(scene, grid);
  setup.setup_points = probe->nodes().size();
  if (!decomposed) {
    setup.lattice = point_lattice<D>(scene, probe->search_radius(), grid, scene.simulation.nodes_move());
    part.basis = std::move(probe);
    return part;
  }
  const IndexBox<D> cells = setup.decomposition.box(comm.rank());
  const PointLattice<D>& L = setup.lattice;
  Window<D> w;
  w.box = L.window(cells);
  setup.window_basis = window_basis_factory<D>(scene, L);
  probe.reset();
  part.basis = setup.window_basis(w, setup.hint_offset);
  setup.setup_points += w.size();
  const bool from_basis = basis_kind(scene.basis.kind).window<D>() || scene.grid.kind == "perturbed";
  part.dirichlet = checked_boundaries<D>(scene, scene.boundaries, comm, L, cells, from_basis, w, *part.basis);
  setup.window_dirichlet = [boundaries = scene.boundaries, grid, from_basis](const Window<D>& v, const Basis<D>& b) {
    return window_boundaries<D>(boundaries, grid, from_basis, v, b);
  };
  return part;
}

/// The Domain of a rank whose particles (parts.particles, setup.global_ids),
/// decomposition and window basis (rank_lattice) are chosen.
/// InputError (on every rank) for a rigid plate of saturated bodies that
/// selects no node of the whole lattice (each rank counts its own nodes).
template <int D> void require_plate_nodes(const Scene& scene, const Comm& comm, const EngineParts<D>& parts) {
  if (!parts.two_phase) return;
  const std::vector<char>& owned = parts.distribution->owned_nodes();
  std::vector<std::int64_t> count;
  for (const Plate& plate : parts.two_phase->plates)
    count.push_back(std::count_if(plate.node.begin(), plate.node.end(),
                                  [&owned](int I) { return owned[static_cast<std::size_t>(I)] != 0; }));
  comm.sum(count);
  for (std::size_t i = 0; i < count.size(); ++i)
    if (count[i] == 0) input_error(scene.plates[i].where, "plate '" + scene.plates[i].name + "' selects no node of the grid");
}

template <int D>
EngineParts<D> finish_parts(const Scene& scene, const Comm& comm, EngineParts<D> parts,
                            typename Domain<D>::Setup setup) {
  // No rebalancing with walls, with saturated bodies, nor with an
  // integrator that carries its constraints' momentum: a wall's held nodes
  // (its contact state), the liquid's held, drained and plate nodes and the
  // carried momenta are per node of the window and stay where they are;
  // particles still migrate.
  if (!parts.walls.empty() || parts.two_phase || parts.settings.step.needs.carries_constraints)
    setup.window_basis = nullptr;
  auto domain = std::make_shared<Domain<D>>(comm, std::move(setup));
  parts.basis->distribute(domain->owned_nodes(), [&comm](std::span<double> v) { comm.sum(v); });
  parts.distribution = std::move(domain);
  require_plate_nodes<D>(scene, comm, parts);
  return parts;
}

/// InputError for a scene whose nodes are its mesh bodies' vertices
/// (nodes = "mesh"): a distributed run splits a lattice of nodes.
void require_lattice_nodes(const Scene& scene) {
  for (std::size_t i = 0; i < scene.bodies.size(); ++i)
    if (scene.bodies[i].nodes == "mesh")
      input_error(scene.locate("body." + scene.bodies[i].name + ".nodes"),
                  "the mesh's vertices as nodes run in one process only (a distributed run divides the cells of "
                  "a node lattice among its ranks): run without mpirun, or use nodes = \"lattice\"");
}

/// InputError for saturated bodies on a basis whose points are not the
/// lattice's nodes (B-splines' control points): the liquid's cells and
/// surfaces are the node lattice's, which a rank's window of control points
/// does not give.
template <int D> void require_liquid_on_nodes(const Scene& scene) {
  if (saturated(scene) && basis_kind(scene.basis.kind).window<D>())
    input_error(scene.locate("basis.kind"), "saturated bodies on a basis of control points (\"" + scene.basis.kind +
                                                "\") run in one process only: run without mpirun, or take a basis "
                                                "on the lattice's nodes (such as \"linear\" or \"lme\")");
}

} // namespace

template <int D> EngineParts<D> seeded_parts(const Scene& scene, const Comm& comm) {
  require_lattice_nodes(scene);
  require_liquid_on_nodes<D>(scene);
  typename Domain<D>::Setup setup;
  ShareSeeding<D> share;
  auto seed = [&](const Vec<D>& h, const CartesianGrid<D>& grid) {
    // each rank's memory, checked before its particles and nodes are allocated
    auto check = [&](const ShareSeeding<D>& s) {
      setup.lattice = rank_point_lattice<D>(scene, comm, grid, s.decomposition.box(comm.rank()));
      check_rank_memory<D>(scene, comm, setup.lattice, s.decomposition, s.per_rank);
      return true;
    };
    SeededBodies<D> mine = share_seeding<D>(scene, comm, h, grid, share, check);
    setup.decomposition = share.decomposition;
    setup.global_ids = mine.ids; // a copy: the assembler reads mine.ids (traction surfaces)
    return mine;
  };
  auto lattice = [&](const CartesianGrid<D>& grid) {
    return rank_lattice<D>(scene, comm, grid, !share.deferred, setup);
  };
  EngineParts<D> parts = assemble_parts<D>(scene, seed, lattice);
  if (share.deferred) std::rethrow_exception(share.deferred);
  // The traction loads' shares of this rank's particles (they move with them).
  for (const Traction<D>& t : parts.loads.tractions) {
    std::vector<double> area(static_cast<std::size_t>(parts.particles.size()), -1.0);
    for (std::size_t i = 0; i < t.particle.size(); ++i) area[static_cast<std::size_t>(t.particle[i])] = t.area[i];
    setup.traction_area.push_back(std::move(area));
  }
  setup.nodes_move = scene.simulation.nodes_move();
  reset_hooks<D>(scene, comm, setup);
  setup.global_particles = share.particles;
  setup.setup_particles = parts.particles.size();
  return finish_parts<D>(scene, comm, std::move(parts), std::move(setup));
}

template <int D> RankPlan plan_ranks(const Scene& scene, const Comm& comm) {
  require_lattice_nodes(scene);
  require_liquid_on_nodes<D>(scene);
  const CartesianGrid<D> grid = node_grid<D>(scene);
  ShareSeeding<D> share;
  RankPlan plan;
  auto report = [&](const ShareSeeding<D>& s) {
    const PointLattice<D> L = rank_point_lattice<D>(scene, comm, grid, s.decomposition.box(comm.rank()));
    check_rank_memory<D>(scene, comm, L, s.decomposition, s.per_rank);
    const RankShare mine =
        rank_share<D>(L, s.decomposition, comm.rank(), s.per_rank[static_cast<std::size_t>(comm.rank())], plan.links);
    Bytes packed;
    put(packed, mine);
    for (const Bytes& in : comm.allgather(packed)) plan.ranks.push_back(Reader(in).get<RankShare>());
    plan.particles = s.particles;
    plan.points = 1;
    for (int k = 0; k < D; ++k) plan.points *= L.points[k];
    return false;
  };
  share_seeding<D>(scene, comm, grid_spacing<D>(scene), grid, share, report);
  if (share.deferred) std::rethrow_exception(share.deferred);
  return plan;
}

namespace {

/// The decomposition of the run that wrote checkpoint `ck` (its group
/// "decomposition") when it ran on `ranks` ranks; none otherwise.
/// InputError when that tree does not divide `cells` cells.
template <int D>
std::optional<Decomposition<D>> stored_decomposition(const Checkpoint& ck, const Index<D>& cells, int ranks) {
  const auto it = ck.groups.find("decomposition");
  if (it == ck.groups.end()) return std::nullopt;
  const StateGroup& g = it->second;
  if (g.integer("ranks") != ranks) return std::nullopt;
  const auto& tree = g.integer_arrays.find("tree");
  std::optional<Decomposition<D>> d;
  if (tree != g.integer_arrays.end()) d = Decomposition<D>::from_tree(cells, ranks, tree->second.values);
  if (!d) g.error("its decomposition over " + std::to_string(ranks) + " ranks does not divide the scene's lattice");
  return d;
}

/// The global ids of `count` particle rows that start at row `first` of
/// the checkpoint, now in `rows`: its array particles/global_id, or (a
/// serial run's checkpoint, whose rows are in that order) first, first + 1, ...
std::vector<long long> row_ids(Checkpoint& rows, long long first, long long count) {
  StateGroup& g = rows.group("particles");
  const auto it = g.integer_arrays.find("global_id");
  if (it != g.integer_arrays.end()) {
    const auto& v = g.integer_array("global_id", static_cast<std::size_t>(count), 1).values;
    return {v.begin(), v.end()};
  }
  std::vector<long long> ids(static_cast<std::size_t>(count));
  for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = first + static_cast<long long>(i);
  g.integer_arrays["global_id"] = {1, std::vector<std::int64_t>(ids.begin(), ids.end())};
  return ids;
}

/// Calls f(array) for every particle array (checkpoint_row_kind) of `ck`, in a fixed order.
template <class F> void for_each_particle_array(Checkpoint& ck, F&& f) {
  for (auto& [gname, g] : ck.groups) {
    for (auto& [name, a] : g.real_arrays)
      if (checkpoint_row_kind(gname, name) == RowKind::particle) f(a);
    for (auto& [name, a] : g.integer_arrays)
      if (checkpoint_row_kind(gname, name) == RowKind::particle) f(a);
  }
}

/// Sends row i of every particle array of `block` to rank dest[i]; `rows`
/// gets the rows this rank receives (the arrays of `block`, empty there),
/// in the order of their global ids (which travel in particles/global_id).
void route_rows(const Comm& comm, Checkpoint& block, const std::vector<int>& dest, Checkpoint& rows) {
  std::vector<Bytes> out(static_cast<std::size_t>(comm.size()));
  for_each_particle_array(block, [&](auto& a) {
    const std::size_t bytes = a.cols * sizeof(a.values[0]);
    for (std::size_t i = 0; i < dest.size(); ++i)
      put_bytes(out[static_cast<std::size_t>(dest[i])], a.values.data() + i * a.cols, bytes);
    a.values = {}; // sent: freed before the rows come in
  });
  for (auto& [gname, g] : block.groups) { // the same arrays, empty, in `rows`
    for (auto& [name, a] : g.real_arrays)
      if (checkpoint_row_kind(gname, name) == RowKind::particle) rows.group(gname).real_arrays[name] = {a.cols, {}};
    for (auto& [name, a] : g.integer_arrays)
      if (checkpoint_row_kind(gname, name) == RowKind::particle) rows.group(gname).integer_arrays[name] = {a.cols, {}};
  }
  // A message holds each array's rows in turn (the sender packed array by array).
  std::vector<std::size_t> row_bytes;
  for_each_particle_array(rows, [&](auto& a) { row_bytes.push_back(a.cols * sizeof(a.values[0])); });
  std::size_t width = 0;
  for (std::size_t b : row_bytes) width += b;
  std::vector<Bytes> in = comm.alltoall(std::move(out));
  for (Bytes& msg : in) {
    const std::size_t n = width ? msg.size() / width : 0;
    std::size_t at = 0, k = 0;
    for_each_particle_array(rows, [&](auto& a) {
      const std::size_t old = a.values.size();
      a.values.resize(old + n * a.cols);
      std::memcpy(a.values.data() + old, msg.data() + at, n * row_bytes[k]);
      at += n * row_bytes[k++];
    });
    Bytes().swap(msg); // unpacked
  }
  order_by_global_id(rows);
}

/// The home cells on `grid` of the `count` particle rows `block` of
/// checkpoint `ck`: after a node reset the cells of its lattice that the
/// checkpoint holds (nodes/home_cell: InputError on every rank for one
/// outside it), else the cell of x on the fixed grid (mpm), of X on the
/// initial lattice (ul).
template <int D>
std::vector<Index<D>> row_homes(const Scene& scene, const Comm& comm, const Checkpoint& ck, const Checkpoint& block,
                                const CartesianGrid<D>& grid, long long count) {
  std::vector<Index<D>> home(static_cast<std::size_t>(count));
  if (reset_lattice_of<D>(ck)) {
    auto stored = home_cells_of<D>(block.group("nodes"), home.size(), grid.cells);
    agree_on(comm, [&] {
      if (!stored) ck.group("nodes").error("a home cell outside the reset lattice");
    });
    return std::move(*stored);
  }
  const auto& x =
      block.group("particles").real_array(scene.simulation.nodes_move() ? "X" : "x", home.size(), D).values;
  for (std::size_t i = 0; i < home.size(); ++i) home[i] = grid.cell_of(Eigen::Map<const Vec<D>>(x.data() + i * D));
  return home;
}

/// This rank's particle rows of a restart from `ck` into `rows` (in the
/// order of its particles) and their global ids, with the decomposition:
/// the checkpoint's when its run had as many ranks, else a fresh bisection
/// of the cells weighted by the particles' home cells (each rank reads
/// 1/N of the rows, finds their cells and sends them to their owners).
template <int D>
std::vector<long long> restart_rows(const Scene& scene, const Comm& comm, const Checkpoint& ck,
                                    const CartesianGrid<D>& grid, Decomposition<D>& decomposition, Checkpoint& rows,
                                    const std::function<void(const std::vector<std::int64_t>&)>& check) {
  const long long n = checkpoint_rows(ck, RowKind::particle), P = comm.size(), r = comm.rank();
  if (auto kept = stored_decomposition<D>(ck, grid.cells, comm.size())) {
    decomposition = std::move(*kept);
    const StateGroup& g = ck.group("decomposition");
    const auto& counts = g.integer_array("rows_per_rank", static_cast<std::size_t>(P), 1).values;
    long long first = 0, total = 0;
    for (long long q = 0; q < P; ++q) (q < r ? first : total) += counts[static_cast<std::size_t>(q)];
    if (first + total != n) g.error("its ranks' rows do not add up to the " + std::to_string(n) + " particles");
    check(counts);
    const long long count = counts[static_cast<std::size_t>(r)];
    read_checkpoint_rows(ck, RowKind::particle, {{first, 1, 1, count}}, rows);
    return row_ids(rows, first, count);
  }
  const long long first = n * r / P, count = n * (r + 1) / P - first;
  Checkpoint block;
  read_checkpoint_rows(ck, RowKind::particle, {{first, 1, 1, count}}, block);
  row_ids(block, first, count);
  require_reset_homes<D>(ck, block, comm.size());
  const std::vector<Index<D>> home = row_homes<D>(scene, comm, ck, block, grid, count);
  std::vector<Index<D>> cells;
  std::vector<std::int64_t> weight;
  for (const Index<D>& c : home) {
    if (!cells.empty() && cells.back() == c) ++weight.back();
    else cells.push_back(c), weight.push_back(1);
  }
  decomposition = Decomposition<D>::rcb(grid.cells, comm.size(), cells, weight, comm);
  std::vector<int> dest(home.size());
  std::vector<std::int64_t> per_rank(static_cast<std::size_t>(P), 0);
  for (std::size_t i = 0; i < home.size(); ++i) ++per_rank[static_cast<std::size_t>(dest[i] = decomposition.owner(home[i]))];
  comm.sum(per_rank);
  check(per_rank);
  route_rows(comm, block, dest, rows);
  const auto& ids = rows.group("particles").integer_arrays.at("global_id").values;
  return {ids.begin(), ids.end()};
}

} // namespace

template <int D> EngineParts<D> rank_parts(const Scene& scene, const Comm& comm) {
  if (comm.size() == 1) return assemble_parts<D>(scene);
  return seeded_parts<D>(scene, comm);
}

template <int D>
EngineParts<D> restart_parts(const Scene& scene, const Comm& comm, const Checkpoint& ck, Checkpoint& rows) {
  require_lattice_nodes(scene);
  require_liquid_on_nodes<D>(scene);
  typename Domain<D>::Setup setup;
  reset_hooks<D>(scene, comm, setup);
  // after a node reset: its lattice, divided as its run divided it
  const std::optional<ResetLattice<D>> reset = reset_lattice_of<D>(ck);
  if (reset && !setup.reset_lattice)
    ck.group("nodes").error("nodes laid out anew, but this run cannot lay them out");
  const CartesianGrid<D> grid = reset ? reset->grid : node_grid<D>(scene);
  const long long n = checkpoint_rows(ck, RowKind::particle);
  rows = checkpoint_head(ck);
  // each rank's memory, checked before its rows are read (or sent to it)
  auto check = [&](const std::vector<std::int64_t>& per_rank) {
    setup.lattice = reset ? setup.reset_lattice(grid)
                          : rank_point_lattice<D>(scene, comm, grid, setup.decomposition.box(comm.rank()));
    check_rank_memory<D>(scene, comm, setup.lattice, setup.decomposition, per_rank);
  };
  std::vector<long long> ids = restart_rows<D>(scene, comm, ck, grid, setup.decomposition, rows, check);
  SeededBodies<D> share;
  const StateGroup& particles = rows.group("particles");
  restore_particles(particles, share.particles, ids.size());
  share.ids = ids;
  for (std::size_t i = 0; i < scene.tractions.size(); ++i)
    share.traction_area.push_back(
        particles.real_array("traction_area_" + std::to_string(i), ids.size(), 1).values);
  setup.traction_area = share.traction_area;
  const long long particles_here = static_cast<long long>(ids.size());
  auto seed = [&](const Vec<D>&, const CartesianGrid<D>&) { return std::move(share); };
  auto lattice = [&](const CartesianGrid<D>& g) {
    if (!reset) return rank_lattice<D>(scene, comm, g, true, setup);
    const IndexBox<D> cells = setup.decomposition.box(comm.rank());
    const Window<D> w{setup.lattice.window(cells)};
    setup.setup_points += w.size();
    return setup.reset_window(setup.lattice, cells, w, reset->time, setup.hint_offset);
  };
  EngineParts<D> parts = assemble_parts<D>(scene, seed, lattice);
  setup.nodes_move = scene.simulation.nodes_move();
  setup.global_ids = std::move(ids);
  setup.global_particles = n;
  setup.setup_particles = particles_here;
  const auto& dg = rows.groups.find("decomposition");
  setup.steps = dg != rows.groups.end() && dg->second.integers.count("steps") ? dg->second.integer("steps")
                                                                                : rows.group("engine").integer("step");
  return finish_parts<D>(scene, comm, std::move(parts), std::move(setup));
}

template <int D> void require_reset_homes(const Checkpoint& ck, const Checkpoint& rows, int ranks) {
  if (!reset_lattice_of<D>(ck)) return;
  const auto nodes = rows.groups.find("nodes");
  if (nodes != rows.groups.end() && nodes->second.has_array("home_cell")) return;
  const auto it = ck.groups.find("decomposition");
  const long long written = it == ck.groups.end() ? 1 : it->second.integer("ranks");
  if (written == ranks) return;
  ck.group("nodes").error(
      "its run laid the nodes out anew (simulation.node_reset) on " + std::to_string(written) +
      (written == 1 ? " process" : " ranks") +
      " and holds no home cells of its particles (an older otmpm's checkpoint, or a restart's of one); it "
      "restarts on as many (" +
      (written == 1 ? std::string("without mpirun") : "mpirun -np " + std::to_string(written)) +
      "): its ranks' particles and F-bar patches follow that run's lattice");
}

#define OTMPM_INSTANTIATE(D)                                                                                      \
  template void require_reset_homes<D>(const Checkpoint&, const Checkpoint&, int);                            \
  template EngineParts<D> rank_parts<D>(const Scene&, const Comm&);                                           \
  template EngineParts<D> seeded_parts<D>(const Scene&, const Comm&);                                         \
  template RankPlan plan_ranks<D>(const Scene&, const Comm&);                                                 \
  template EngineParts<D> restart_parts<D>(const Scene&, const Comm&, const Checkpoint&, Checkpoint&);
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm::distributed
