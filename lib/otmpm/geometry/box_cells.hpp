#pragma once
/// \file box_cells.hpp
/// Where the particles of a box's cells sit and what volume each gets: the
/// pattern of a cell (Gauss-Legendre points or sub-cell centres) and the
/// cells of a box, seeded cell by cell.
#include "otmpm/core.hpp"
#include "otmpm/interrupt.hpp"

#include <string_view>
#include <vector>

namespace otmpm {

/// Gauss-Legendre points (in [-1, 1]) and weights (sum 2) of order n >= 1.
void gauss_legendre(int n, std::vector<double>& points, std::vector<double>& weights);

/// Where particles sit in a cell along one axis and what share of the cell
/// each gets: `s` in [0, 1] (fractions of the cell) and weights `w` summing
/// to 1, for n particles per axis - at the Gauss-Legendre points ("gauss",
/// weights = Gauss weights) or at the centres of n equal sub-cells
/// ("cell_centres", equal weights).
void cell_pattern(std::string_view placement, int n, std::vector<double>& s, std::vector<double>& w);

/// The particles of a box [lower, upper] cut into `cells` cells per axis,
/// n^D particles per cell placed by cell_pattern, cell by cell: cell(c,
/// seed) calls seed(x, V, extent) for the particles of cell c (axis 0
/// fastest): x the position, V = prod of weights x cell volume, extent per
/// axis the particle's share of the cell (weight x cell size; cell size / n
/// for equal shares), so that V = prod extent. A cell alone gives the bits
/// it gives among all of them (a rank of a distributed run seeds only its
/// own cells).
template <int D> class BoxCells {
public:
  BoxCells(const Vec<D>& lower, const Vec<D>& upper, const Index<D>& cells, int n, std::string_view placement)
      : lower_(lower), cells_(cells), n_(n), equal_(placement != "gauss") {
    cell_pattern(placement, n, s_, w_);
    for (int k = 0; k < D; ++k) size_[k] = (upper[k] - lower[k]) / cells[k];
  }
  const Index<D>& cells() const { return cells_; }
  const Vec<D>& size() const { return size_; }
  /// Particles per axis and cell.
  int per_axis() const { return n_; }
  /// Coordinate k of the particles q (0 <= q < n along axis k) of the cells
  /// with index c along axis k: the bits cell() gives. It grows with c and
  /// q (each rounding is monotone), so the particles of a block of cells lie
  /// in the box of its first and last particles' coordinates.
  double coordinate(int k, int c, int q) const { return lower_[k] + (c + s_[static_cast<std::size_t>(q)]) * size_[k]; }
  template <class Seed> void cell(const Index<D>& c, Seed&& seed) const {
    Vec<D> len;
    Index<D> q{};
    while (true) {
      Vec<D> x;
      double V = 1.0;
      for (int k = 0; k < D; ++k) {
        x[k] = coordinate(k, c[k], q[k]);
        V *= w_[q[k]] * size_[k];
        len[k] = equal_ ? size_[k] / n_ : w_[q[k]] * size_[k];
      }
      seed(x, V, len);
      int k = 0;
      while (k < D && ++q[k] == n_) q[k++] = 0;
      if (k == D) break;
    }
  }

private:
  Vec<D> lower_, size_;
  Index<D> cells_;
  int n_;
  bool equal_;
  std::vector<double> s_, w_;
};

/// Calls seed(x, V, extent) for the particles of every cell of a BoxCells
/// (cells in lattice order, axis 0 fastest, then the particles of each cell likewise).
template <int D, class Seed>
void seed_box_cells(const Vec<D>& lower, const Vec<D>& upper, const Index<D>& cells, int n, std::string_view placement,
                    Seed&& seed) {
  const BoxCells<D> box(lower, upper, cells, n, placement);
  Index<D> c{};
  while (true) {
    box.cell(c, seed);
    int k = 0;
    while (k < D && ++c[k] == cells[k]) c[k++] = 0;
    if (k == D) break;
    if (k > 0) interrupt_point("seeding a body"); // once per row of cells
  }
}

} // namespace otmpm
