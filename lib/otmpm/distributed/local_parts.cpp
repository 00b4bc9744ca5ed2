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

/// A rank's parts cut from the whole scene's (every particle seeded on
/// every rank): the path of scenes with traction loads, whose surface
/// particles are found among all particles.
template <int D>
EngineParts<D> cut_parts(const Scene& scene, const Comm& comm, const AlignedVector<Vec<D>>* positions) {
  EngineParts<D> parts = assemble_parts<D>(scene);
  Particles<D>& P = parts.particles;
  const std::size_t n = static_cast<std::size_t>(P.size());
  const bool ul = parts.mode.nodes_move();
  const CartesianGrid<D> grid = node_grid<D>(scene);
  typename Domain<D>::Setup setup;
  setup.lattice = point_lattice<D>(scene, *parts.basis, grid, ul);
  setup.nodes_move = ul;
  setup.global_particles = static_cast<long long>(n);
  setup.setup_particles = static_cast<long long>(n);
  // Home cells of all particles (every rank has them); each rank counts a
  // share for the bisection, so that the sums count every particle once.
  const AlignedVector<Vec<D>>& x = positions ? *positions : P.x;
  require<std::invalid_argument>(x.size() == n, "rank_parts: ", x.size(), " positions for ", n, " particles");
  std::vector<Index<D>> home(n), share;
  for (std::size_t p = 0; p < n; ++p) {
    home[p] = grid.cell_of(ul ? P.X[p] : x[p]);
    if (static_cast<int>(p % static_cast<std::size_t>(comm.size())) == comm.rank()) share.push_back(home[p]);
  }
  setup.decomposition = Decomposition<D>::rcb(grid.cells, comm.size(), share, comm);
  // This rank's particles, in global order, with their traction shares.
  std::vector<char> keep(n, 0);
  for (std::size_t p = 0; p < n; ++p) {
    keep[p] = setup.decomposition.owner(home[p]) == comm.rank();
    if (keep[p]) setup.global_ids.push_back(static_cast<long long>(p));
  }
  for (const Traction<D>& t : parts.loads.tractions) {
    std::vector<double> area(n, -1.0);
    for (std::size_t i = 0; i < t.particle.size(); ++i) area[static_cast<std::size_t>(t.particle[i])] = t.area[i];
    setup.traction_area.push_back(std::move(area));
  }
  PointState<D> no_state;
  std::vector<Column> columns = particle_columns(P, no_state);
  for (auto& a : setup.traction_area) columns.push_back(column_of(a));
  keep_rows(columns, keep, n);
  for (std::size_t i = 0; i < parts.loads.tractions.size(); ++i) {
    Traction<D>& t = parts.loads.tractions[i];
    t.particle.clear(), t.area.clear();
    for (std::size_t p = 0; p < setup.traction_area[i].size(); ++p)
      if (setup.traction_area[i][p] >= 0.0) t.particle.push_back(static_cast<int>(p)), t.area.push_back(setup.traction_area[i][p]);
  }
  return finish_parts<D>(scene, comm, std::move(parts), std::move(setup));
}

/// Seeding particles counted per rank in runs of this many global ids
/// (rank r counts the runs r, r + N, ...): each rank's list of (cell, count)
/// stays short, as particles of one cell are seeded together.
constexpr long long kCountRun = 4096;

/// A rank's parts seeded for its own cells only (local_parts.hpp): a
/// counting pass over the seeding (no particle stored) gives the particles
/// per cell for the bisection, a second pass stores the particles of this
/// rank's cells. Every rank runs both passes over every body alike, so a bad
/// scene fails on every rank alike.
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
    n = seed_bodies_where<D>(
        scene, h, grid,
        [&](long long id, const Vec<D>& x) {
          if ((id / kCountRun) % comm.size() != comm.rank()) return false;
          const Index<D> c = home(id, x);
          if (!cells.empty() && cells.back() == c) ++weight.back();
          else cells.push_back(c), weight.push_back(1);
          return false;
        },
        nullptr);
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
    setup.global_ids = std::move(mine.ids);
    return mine;
  };
  EngineParts<D> parts = assemble_parts<D>(scene, seed);
  if (deferred) std::rethrow_exception(deferred);
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
  if (!scene.tractions.empty()) return cut_parts<D>(scene, comm, positions);
  return seeded_parts<D>(scene, comm, positions);
}

#define OTMPM_INSTANTIATE(D)                                                                                      \
  template EngineParts<D> rank_parts<D>(const Scene&, const Comm&, const AlignedVector<Vec<D>>*);
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm::distributed
