/// \file local_parts.cpp
/// A rank's share of the engine parts (local_parts.hpp).
#include "otmpm/distributed/local_parts.hpp"

#include "otmpm/assembly/assembler.hpp"
#include "otmpm/assembly/seeding.hpp"
#include "otmpm/basis/bspline.hpp"
#include "otmpm/basis/kinds.hpp"

#include <cmath>
#include <exception>

namespace otmpm::distributed {

namespace {

/// Cells of slack around the support in `ul` mode: the particles keep the
/// cell they were seeded in while the lattice moves, and may drift from it.
constexpr int kAdvectedSlack = 2;

/// The point lattice of the scene's basis: which points, which cell each
/// belongs to, and how far the particles of a cell reach.
template <int D>
PointLattice<D> point_lattice(const Scene& scene, const Basis<D>& basis, const CartesianGrid<D>& grid, bool ul) {
  PointLattice<D> L;
  L.grid = grid;
  const BasisKind& kind = basis_kind(scene.basis.kind);
  const Vec<D> h = grid.h();
  for (int k = 0; k < D; ++k) {
    L.points[k] = grid.cells[k] + 1;
    L.below[k] = 0, L.above[k] = 1; // linear: the cell's corners
  }
  if (kind.bspline) {
    const auto& b = dynamic_cast<const BsplineBasis<D>&>(basis);
    L.points = b.control_points_per_axis();
    L.shift = b.degree() / 2;
    for (int k = 0; k < D; ++k) L.above[k] = b.degree(); // cell c: control points c .. c + p
  } else if (kind.particle_size) {
    for (int k = 0; k < D; ++k) L.below[k] = 1, L.above[k] = 2; // uGIMP: |x - x_I| < h + l_p
  } else if (basis.search_radius() > 0.0) {
    for (int k = 0; k < D; ++k) {
      const int r = static_cast<int>(std::ceil(basis.search_radius() / h[k]));
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
/// window's part of the lattice (a perturbed lattice's positions copied from
/// the whole lattice, which the factory keeps). Also gives the global cell
/// of the basis' local cell 0 (its cell hints are local to it).
template <int D>
std::function<std::unique_ptr<Basis<D>>(const Window<D>&, Index<D>&)>
window_basis_factory(const Scene& scene, const Basis<D>& global, const PointLattice<D>& L) {
  const CartesianGrid<D> grid = L.grid;
  if (basis_kind(scene.basis.kind).bspline) {
    const int degree = dynamic_cast<const BsplineBasis<D>&>(global).degree();
    return [grid, degree](const Window<D>& w, Index<D>& hint_offset) -> std::unique_ptr<Basis<D>> {
      hint_offset = {};
      return std::make_unique<BsplineBasis<D>>(grid, degree, w.box.lo, w.box.hi);
    };
  }
  std::shared_ptr<const AlignedVector<Vec<D>>> moved;
  if (!global.nodes().on_lattice()) moved = std::make_shared<AlignedVector<Vec<D>>>(global.nodes().positions());
  const BasisOptions options = basis_options<D>(scene);
  return [grid, moved, options, L](const Window<D>& w, Index<D>& hint_offset) -> std::unique_ptr<Basis<D>> {
    hint_offset = w.box.lo;
    CartesianGrid<D> g;
    Index<D> last;
    for (int k = 0; k < D; ++k) last[k] = w.box.hi[k] - 1, g.cells[k] = w.box.extent(k) - 1;
    g.lower = grid.node_position(w.box.lo);
    g.upper = grid.node_position(last);
    NodeSet<D> nodes = NodeSet<D>::cartesian(g);
    if (moved) {
      AlignedVector<Vec<D>> x(static_cast<std::size_t>(w.size()));
      for (int i = 0; i < w.size(); ++i) x[static_cast<std::size_t>(i)] = (*moved)[static_cast<std::size_t>(L.point_id(w.index(i)))];
      nodes.set_positions(std::move(x));
    }
    return make_basis<D>(options, std::move(nodes));
  };
}

/// The basis, the constraints and the Domain of a rank whose particles
/// (parts.particles, setup.global_ids) and decomposition are chosen.
template <int D>
EngineParts<D> finish_parts(const Scene& scene, const Comm& comm, EngineParts<D> parts,
                            typename Domain<D>::Setup setup) {
  // The basis and constraints on this rank's window of the point lattice.
  Window<D> w;
  w.box = setup.lattice.window(setup.decomposition.box(comm.rank()));
  setup.window_basis = window_basis_factory<D>(scene, *parts.basis, setup.lattice);
  parts.basis = setup.window_basis(w, setup.hint_offset);
  // No rebalancing with walls: a wall's held nodes (its contact state, per
  // node of the window) stay where they are; particles still migrate.
  if (!parts.walls.empty()) setup.window_basis = nullptr;
  setup.dirichlet = std::move(parts.dirichlet);
  parts.dirichlet = window_dirichlet<D>(setup.dirichlet, setup.lattice, w);
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
    seed_bodies_where<D>(
        scene, h, grid,
        [&](long long id, const Vec<D>& x) { return setup.decomposition.owner(home(id, x)) == comm.rank(); },
        &mine);
    setup.global_ids = mine.ids; // a copy: the assembler reads mine.ids (traction surfaces)
    return mine;
  };
  EngineParts<D> parts = assemble_parts<D>(scene, seed);
  if (deferred) std::rethrow_exception(deferred);
  // The traction loads' shares of this rank's particles (they move with them).
  for (const Traction<D>& t : parts.loads.tractions) {
    std::vector<double> area(static_cast<std::size_t>(parts.particles.size()), -1.0);
    for (std::size_t i = 0; i < t.particle.size(); ++i) area[static_cast<std::size_t>(t.particle[i])] = t.area[i];
    setup.traction_area.push_back(std::move(area));
  }
  const CartesianGrid<D> grid = node_grid<D>(scene);
  setup.lattice = point_lattice<D>(scene, *parts.basis, grid, ul);
  setup.nodes_move = ul;
  setup.global_particles = n;
  setup.setup_particles = parts.particles.size();
  return finish_parts<D>(scene, comm, std::move(parts), std::move(setup));
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
