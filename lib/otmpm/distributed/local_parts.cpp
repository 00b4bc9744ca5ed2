/// \file local_parts.cpp
/// A rank's share of the engine parts (local_parts.hpp).
#include "otmpm/distributed/local_parts.hpp"

#include "otmpm/assembly/assembler.hpp"
#include "otmpm/assembly/seeding.hpp"
#include "otmpm/basis/bspline.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/basis/lme.hpp"
#include "otmpm/integrators/integrator.hpp"

#include <cmath>
#include <exception>

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

/// The point lattice of the scene's basis (`probe`: probe_basis; `radius`:
/// its search radius, or the whole lattice's when that differs): which
/// points, which cell each belongs to, and how far the particles of a cell reach.
template <int D>
PointLattice<D> point_lattice(const Scene& scene, const Basis<D>& probe, double radius, const CartesianGrid<D>& grid,
                              bool ul) {
  PointLattice<D> L;
  L.grid = grid;
  const BasisKind& kind = basis_kind(scene.basis.kind);
  const Vec<D> h = grid.h();
  for (int k = 0; k < D; ++k) {
    L.points[k] = grid.cells[k] + 1;
    L.below[k] = 0, L.above[k] = 1; // linear: the cell's corners
  }
  if (kind.bspline) {
    const int degree = dynamic_cast<const BsplineBasis<D>&>(probe).degree();
    // an open uniform knot vector over the cells: cells + degree control points per axis
    for (int k = 0; k < D; ++k) L.points[k] = grid.cells[k] + degree;
    L.shift = degree / 2;
    for (int k = 0; k < D; ++k) L.above[k] = degree; // cell c: control points c .. c + p
  } else if (kind.particle_size) {
    for (int k = 0; k < D; ++k) L.below[k] = 1, L.above[k] = 2; // uGIMP: |x - x_I| < h + l_p
  } else if (radius > 0.0) {
    for (int k = 0; k < D; ++k) {
      const int r = static_cast<int>(std::ceil(radius / h[k]));
      L.below[k] = r, L.above[k] = r + 1;
    }
  }
  if (ul) {
    for (int k = 0; k < D; ++k) L.below[k] += kAdvectedSlack, L.above[k] += kAdvectedSlack;
    L.guard = 1;
  }
  return L;
}

/// The basis of the scene on a window: B-splines on the whole lattice's
/// knots with the window's control points; the lattice families on the
/// window's part of the lattice (a perturbed lattice's positions drawn for
/// the window from the grid's random stream, NodeSet::perturbed_positions).
/// Also gives the global cell of the basis' local cell 0 (its cell hints
/// are local to it). Never builds the whole lattice.
template <int D>
std::function<std::unique_ptr<Basis<D>>(const Window<D>&, Index<D>&)>
window_basis_factory(const Scene& scene, const Basis<D>& probe, const PointLattice<D>& L) {
  const CartesianGrid<D> grid = L.grid;
  if (basis_kind(scene.basis.kind).bspline) {
    const int degree = dynamic_cast<const BsplineBasis<D>&>(probe).degree();
    return [grid, degree](const Window<D>& w, Index<D>& hint_offset) -> std::unique_ptr<Basis<D>> {
      hint_offset = {};
      return std::make_unique<BsplineBasis<D>>(grid, degree, w.box.lo, w.box.hi);
    };
  }
  const bool perturbed = scene.grid.kind == "perturbed";
  const double fraction = scene.grid.perturbation;
  const unsigned seed = scene.grid.seed;
  const BasisOptions options = basis_options<D>(scene);
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

/// The lattice part of a rank (assemble_parts' `lattice`): the basis on its
/// window and the Dirichlet entries found there; the Domain's set-up gets
/// the point lattice and the factories of both (rebalancing). The check
/// that each boundary box selects a node counts the points each rank owns,
/// summed over the ranks (a boundary is found once, on the whole lattice).
/// `decomposed` false: the bisection failed (its error is raised after the
/// assembly), only the probe is built.
template <int D>
LatticePart<D> rank_lattice(const Scene& scene, const Comm& comm, const CartesianGrid<D>& grid, bool decomposed,
                            typename Domain<D>::Setup& setup) {
  const bool ul = scene.simulation.nodes_move();
  LatticePart<D> part;
  std::unique_ptr<Basis<D>> probe = probe_basis<D>(scene, grid);
  setup.setup_points = probe->nodes().size();
  double radius = probe->search_radius();
  if (!decomposed) {
    setup.lattice = point_lattice<D>(scene, *probe, radius, grid, ul);
    part.basis = std::move(probe);
    return part;
  }
  const IndexBox<D> cells = setup.decomposition.box(comm.rank());
  if (radius_from_nodes(scene)) {
    // the owned nodes do not depend on the radius (only the ghost layers do)
    const IndexBox<D> own = point_lattice<D>(scene, *probe, radius, grid, ul).owned_points(cells);
    radius = perturbed_search_radius<D>(scene, comm, grid, own);
  }
  setup.lattice = point_lattice<D>(scene, *probe, radius, grid, ul);
  const PointLattice<D>& L = setup.lattice;
  Window<D> w;
  w.box = L.window(cells);
  setup.window_basis = window_basis_factory<D>(scene, *probe, L);
  probe.reset();
  part.basis = setup.window_basis(w, setup.hint_offset);
  setup.setup_points += w.size();
  const bool from_basis = basis_kind(scene.basis.kind).bspline || scene.grid.kind == "perturbed";
  const IndexBox<D> own = L.owned_points(cells);
  std::vector<char> owned(static_cast<std::size_t>(w.size()));
  for (int i = 0; i < w.size(); ++i) owned[static_cast<std::size_t>(i)] = own.contains(w.index(i)) ? 1 : 0;
  std::vector<long long> selected;
  part.dirichlet = window_boundaries<D>(scene.boundaries, grid, from_basis, w, *part.basis, &owned, &selected);
  std::vector<std::int64_t> total(selected.begin(), selected.end());
  comm.sum(total);
  require_boundary_nodes(scene, std::vector<long long>(total.begin(), total.end()));
  setup.window_dirichlet = [boundaries = scene.boundaries, grid, from_basis](const Window<D>& v, const Basis<D>& b) {
    return window_boundaries<D>(boundaries, grid, from_basis, v, b);
  };
  return part;
}

/// The Domain of a rank whose particles (parts.particles, setup.global_ids),
/// decomposition and window basis (rank_lattice) are chosen.
template <int D>
EngineParts<D> finish_parts(const Comm& comm, EngineParts<D> parts, typename Domain<D>::Setup setup) {
  // No rebalancing with walls, nor with an integrator that carries its
  // constraints' momentum: a wall's held nodes (its contact state) and the
  // carried momenta are per node of the window and stay where they are;
  // particles still migrate.
  const auto carries = [&] {
    for (const IntegratorKind& k : integrator_kinds())
      if (k.carries_constraints && k.step<D>() == parts.settings.step) return true;
    return false;
  };
  if (!parts.walls.empty() || carries()) setup.window_basis = nullptr;
  auto domain = std::make_shared<Domain<D>>(comm, std::move(setup));
  if (auto* b = dynamic_cast<BsplineBasis<D>*>(parts.basis.get()))
    b->distribute(domain->owned_nodes(), [&comm](std::span<double> v) { comm.sum(v); });
  parts.distribution = std::move(domain);
  return parts;
}

/// Seeding particles counted per rank in runs of this many global ids
/// (rank r counts the runs r, r + N, ...): each rank's list of (cell, count)
/// stays short, as particles of one cell are seeded together.
constexpr long long kCountRun = 4096;

/// A rank's parts seeded for its own cells only (local_parts.hpp): a
/// counting pass over the seeding (no particle stored) gives the particles
/// per cell for the bisection, a second pass stores the particles of this
/// rank's cells. Every rank runs both passes over every body alike, so a bad
/// scene fails on every rank alike. Traction loads find their surface
/// particles in the counting pass (TractionSurfaces: one entry per column).
template <int D>
EngineParts<D> seeded_parts(const Scene& scene, const Comm& comm, const AlignedVector<Vec<D>>* positions) {
  typename Domain<D>::Setup setup;
  const bool ul = scene.simulation.nodes_move();
  long long n = 0;
  // An error of the decomposition (too few cells) is raised after the rest
  // of the assembly, as when the whole scene was assembled first.
  std::exception_ptr deferred;
  auto seed = [&](const Vec<D>& h, const CartesianGrid<D>& grid) {
    SeededBodies<D> mine;
    // The home cell: of the checkpoint's position (a restart in `mpm` mode) or of the seeded one.
    auto home = [&](long long id, const Vec<D>& x) {
      return grid.cell_of(!ul && positions && id < static_cast<long long>(positions->size())
                              ? (*positions)[static_cast<std::size_t>(id)]
                              : x);
    };
    std::vector<Index<D>> cells;
    std::vector<std::int64_t> weight;
    // Traction loads: their surface particles among all (every rank sees every seed here).
    std::shared_ptr<TractionSurfaces<D>> surfaces;
    if (!scene.tractions.empty()) surfaces = std::make_shared<TractionSurfaces<D>>(scene, kBoxTolerance * grid.h().minCoeff());
    // Every rank reads every particle file in both passes: one that fails
    // alone (a file rewritten while the ranks read it) fails all (agree_on).
    agree_on(comm, [&] {
      n = seed_bodies_where<D>(
          scene, h, grid,
          [&](long long id, const Vec<D>& x) {
            if (surfaces) surfaces->visit(id, x);
            if ((id / kCountRun) % comm.size() != comm.rank()) return false;
            const Index<D> c = home(id, x);
            if (!cells.empty() && cells.back() == c) ++weight.back();
            else cells.push_back(c), weight.push_back(1);
            return false;
          },
          nullptr);
    });
    // a file that every rank read without an error but not alike
    if (const auto fewest = comm.min(static_cast<std::int64_t>(n)), most = comm.max(static_cast<std::int64_t>(n));
        fewest != most)
      throw InputError("the ranks counted from " + std::to_string(fewest) + " to " + std::to_string(most) +
                       " particles in the scene's bodies: a particle file read differently by the ranks (rewritten "
                       "while they read it, or not the same on every node)");
    if (surfaces) surfaces->finish();
    mine.surfaces = surfaces;
    try {
      if (positions)
        require<std::invalid_argument>(static_cast<long long>(positions->size()) == n, "rank_parts: ",
                                       positions->size(), " positions for ", n, " particles");
      setup.decomposition = Decomposition<D>::rcb(grid.cells, comm.size(), cells, weight, comm);
    } catch (...) {
      deferred = std::current_exception();
      return mine;
    }
    std::vector<Index<D>>().swap(cells);
    std::vector<std::int64_t>().swap(weight);
    agree_on(comm, [&] {
      seed_bodies_where<D>(
          scene, h, grid,
          [&](long long id, const Vec<D>& x) { return setup.decomposition.owner(home(id, x)) == comm.rank(); },
          &mine);
    });
    setup.global_ids = mine.ids; // a copy: the assembler reads mine.ids (traction surfaces)
    return mine;
  };
  auto lattice = [&](const CartesianGrid<D>& grid) {
    return rank_lattice<D>(scene, comm, grid, !deferred, setup);
  };
  EngineParts<D> parts = assemble_parts<D>(scene, seed, lattice);
  if (deferred) std::rethrow_exception(deferred);
  // The traction loads' shares of this rank's particles (they move with them).
  for (const Traction<D>& t : parts.loads.tractions) {
    std::vector<double> area(static_cast<std::size_t>(parts.particles.size()), -1.0);
    for (std::size_t i = 0; i < t.particle.size(); ++i) area[static_cast<std::size_t>(t.particle[i])] = t.area[i];
    setup.traction_area.push_back(std::move(area));
  }
  setup.nodes_move = ul;
  setup.global_particles = n;
  setup.setup_particles = parts.particles.size();
  return finish_parts<D>(comm, std::move(parts), std::move(setup));
}

} // namespace

template <int D>
EngineParts<D> rank_parts(const Scene& scene, const Comm& comm, const AlignedVector<Vec<D>>* positions) {
  if (comm.size() == 1) return assemble_parts<D>(scene);
  return seeded_parts<D>(scene, comm, positions);
}

#define OTMPM_INSTANTIATE(D)                                                                                      \
  template EngineParts<D> rank_parts<D>(const Scene&, const Comm&, const AlignedVector<Vec<D>>*);
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm::distributed
