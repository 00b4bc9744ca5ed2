#pragma once
/// \file lattice.hpp
/// The points of a basis (lattice nodes, or B-spline control points) over
/// the cells of the node lattice, as a distributed run divides them: which
/// cell each point belongs to (its owner is that cell's owner), which
/// points the particles of a cell reach (the support), and from that each
/// rank's window of points - its own points and the ghost layer its
/// particles need (docs/architecture.md, "Distributed runs").
#include "otmpm/distributed/decomposition.hpp"
#include "otmpm/engine/distribution.hpp"
#include "otmpm/io/parallel_io.hpp"
#include "otmpm/nodes/node_set.hpp"

#include <cmath>
#include <limits>

namespace otmpm::distributed {

template <int D> struct PointLattice {
  CartesianGrid<D> grid; ///< the node lattice: its cells are what the ranks divide
  Index<D> points{};     ///< points per axis: cells + 1 (nodes) or cells + degree (B-splines)
  int shift = 0;         ///< point i belongs to cell clamp(i - shift) on each axis
  /// A particle in cell c reaches the points c - below[k] .. c + above[k] on axis k.
  Index<D> below{}, above{};
  /// Layers of points around that reach whose use by a stencil stops the
  /// run (`ul` mode: a support that reaches them may go further).
  int guard = 0;

  /// The cell point index i belongs to on axis k.
  int cell_of_point(int i, int k) const { return std::clamp(i - shift, 0, grid.cells[k] - 1); }
  /// The points that belong to the cells of `cells` (the points a rank owns).
  IndexBox<D> owned_points(const IndexBox<D>& cells) const;
  /// The points the particles of `cells` reach, with the owned points: a
  /// rank's window (owned and ghost points).
  IndexBox<D> window(const IndexBox<D>& cells) const;
  /// Global id of a point (axis 0 fastest, as the families number them).
  long long point_id(const Index<D>& i) const {
    long long id = 0;
    for (int k = D - 1; k >= 0; --k) id = id * points[k] + i[k];
    return id;
  }
  /// Lattice index of global point id.
  Index<D> point_index(long long id) const {
    Index<D> i;
    for (int k = 0; k < D; ++k) {
      i[k] = static_cast<int>(id % points[k]);
      id /= points[k];
    }
    return i;
  }
};

/// The rows of the points of `box` in an array of all points of `L` in
/// point_id order (a checkpoint's per-point arrays): one block per layer of
/// the last axis in 3D, one block in 1D and 2D.
template <int D> std::vector<RowBlock> point_blocks(const PointLattice<D>& L, const IndexBox<D>& box) {
  if (box.empty()) return {};
  const long long stride = D >= 2 ? L.points[0] : 1, count = D >= 2 ? box.extent(1) : 1;
  std::vector<RowBlock> blocks;
  Index<D> at = box.lo;
  for (int layer = D == 3 ? box.lo[D - 1] : 0; layer < (D == 3 ? box.hi[D - 1] : 1); ++layer) {
    if constexpr (D == 3) at[2] = layer;
    blocks.push_back({L.point_id(at), stride, count, box.extent(0)});
  }
  return blocks;
}

/// The positions certainly inside the cells of `box` on `grid`: per axis an
/// open interval shrunk by a margin far above the rounding of
/// CartesianGrid::cell_of() (1e-6 of a cell plus 1e-13 of the coordinates'
/// magnitude), unbounded where the box reaches the grid's edge (cell_of()
/// clamps there). A position inside has its cell_of() in `box`; one outside
/// (or NaN) must be decided by cell_of() itself. Migration tests every
/// particle with it per step: a division and a floor() per axis fewer.
template <int D> PositionBox<D> interior_box(const CartesianGrid<D>& grid, const IndexBox<D>& box) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  PositionBox<D> in;
  for (int k = 0; k < D; ++k) {
    const double h = (grid.upper[k] - grid.lower[k]) / grid.cells[k];
    const double margin = 1e-6 * h + 1e-13 * (std::abs(grid.lower[k]) + std::abs(grid.upper[k]));
    in.lo[k] = box.lo[k] <= 0 ? -inf : grid.lower[k] + box.lo[k] * h + margin;
    in.hi[k] = box.hi[k] >= grid.cells[k] ? inf : grid.lower[k] + box.hi[k] * h - margin;
  }
  return in;
}

/// Local ids of the points of a window box (axis 0 fastest) and back.
template <int D> struct Window {
  IndexBox<D> box;
  int size() const { return static_cast<int>(box.count()); }
  int local_id(const Index<D>& i) const {
    int id = 0;
    for (int k = D - 1; k >= 0; --k) id = id * box.extent(k) + (i[k] - box.lo[k]);
    return id;
  }
  Index<D> index(int id) const {
    Index<D> i;
    for (int k = 0; k < D; ++k) {
      i[k] = box.lo[k] + id % box.extent(k);
      id /= box.extent(k);
    }
    return i;
  }
};

template <int D> IndexBox<D> PointLattice<D>::owned_points(const IndexBox<D>& cells) const {
  IndexBox<D> b;
  for (int k = 0; k < D; ++k) {
    b.lo[k] = cells.lo[k] == 0 ? 0 : cells.lo[k] + shift;
    b.hi[k] = cells.hi[k] == grid.cells[k] ? points[k] : cells.hi[k] + shift;
  }
  return b;
}

template <int D> IndexBox<D> PointLattice<D>::window(const IndexBox<D>& cells) const {
  const IndexBox<D> own = owned_points(cells);
  IndexBox<D> b;
  for (int k = 0; k < D; ++k) {
    b.lo[k] = std::min(own.lo[k], std::max(0, cells.lo[k] - below[k] - guard));
    b.hi[k] = std::max(own.hi[k], std::min(points[k], cells.hi[k] + above[k] + guard));
  }
  return b;
}

} // namespace otmpm::distributed
