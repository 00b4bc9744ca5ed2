#pragma once
/// \file lme_box.hpp
/// LME with the box support on an untouched uniform lattice, read from a
/// table (docs/theory.md sect. 4.9). With the isotropic Gaussian prior
/// w_I = exp(-beta |x - x_I|^2) = prod_k exp(-beta dx_k^2) and the support
/// cut per axis (node I kept while beta dx_k^2 <= -ln(tol) on every axis k,
/// a box of lattice lines instead of the ball of `lme`), the partition
/// function is a product over the axes, Z = prod_k Z_k, and the D
/// constraints sum_I N_I dx_I = 0 decouple: N_I = prod_k N^1_k(i_k) with
/// N^1_k the 1D LME function of the lines within R = h sqrt(-ln(tol) /
/// gamma_lme) along axis k, and J = diag(J_k), so grad N_I has the entries
/// dN^1_k / dx_k times the other axes' factors (molinos eq. 42, diagonal).
/// On a uniform lattice N^1_k depends only on the position u in [0, 1) of
/// the point in its cell and on how many lines exist beyond the cell on
/// each side (all within R: an interior cell; fewer: a cell within R of
/// the lattice's end): BoxAxisTable holds it, per gamma_lme = beta h^2 and
/// per such configuration, as quintic Hermite data (N^1, dN^1/du,
/// d2N^1/du^2 from the closed forms) at samples of each interval of u over
/// which the set of lines does not change. The interpolant of a partition
/// of unity with zero derivatives is 1, and that of the coordinates is u:
/// partition of unity and linear completeness hold to round-off, and the
/// values match the Newton solution within kBoxTableError
/// (tests/test_lme_box.cpp measures the bound). In the outermost cell of
/// each end the point approaches the hull's boundary, where lambda
/// diverges like -ln of the distance (the functions stay smooth): its table
/// holds lambda with that logarithm taken off and stops kBoxHullGap short
/// of the boundary. Points nearer the boundary, moved or perturbed nodes
/// and points off the lattice take the general solver with the same box
/// cut-off (lme.cpp).
/// Internal to the max-ent basis and its tests.
#include "otmpm/basis/lme.hpp"

#include <algorithm>
#include <cstddef>
#include <memory>
#include <vector>

namespace otmpm::maxent {

/// Each interval of u is sampled uniformly, kBoxMinSamples samples at
/// first, doubled until the interpolant agrees with the Newton solution at
/// the quarter points of every sample interval within kBoxRefineError in N
/// and kBoxRefineGradient in dN/du (and relative in lambda h). Near a node
/// the functions turn within ~2 exp(-gamma_lme) of it (the LME tends to the
/// hat functions as gamma_lme grows), which sets the spacing: gamma_lme 3
/// takes 256 samples per cell. A table that would need more than
/// kBoxMaxSamples per interval is not built (the general solver then takes
/// every point). Uniform samples keep the lookup free of searches.
inline constexpr int kBoxMinSamples = 16;
inline constexpr double kBoxRefineError = 1e-13;
inline constexpr double kBoxRefineGradient = 1e-12;
inline constexpr int kBoxMaxSamples = 1 << 14;
/// The most lines of a 1D support the table holds (2 r + 1, r = R / h:
/// gamma_lme >= ~0.25 at tolerance 1e-6).
inline constexpr int kBoxMaxLines = 16;
/// Entries of the arrays BoxAxisTable::evaluate writes: the lines, L and a
/// lane of padding (the interpolation runs over pairs of lanes and writes
/// them all).
inline constexpr int kBoxLanes = kBoxMaxLines + 2;
/// Whether the 1D tables hold a support of radius r = R / h (2 r + 1 lines
/// at most kBoxMaxLines; false for NaN).
inline bool box_support_fits(double r) { return 2.0 * r + 1.0 <= kBoxMaxLines; }
/// The lanes of an axis' box of `lines` lines: the lines and the
/// multiplier, rounded up to pairs.
constexpr int box_lanes(int lines) { return (lines + 2) & ~1; }
/// Bounds on |N - N_solve| and on h |dN/dx - dN_solve/dx| of the table
/// against the 1D Newton solution, for every gamma_lme and tolerance whose
/// table is built (measured: tests/test_lme_box.cpp): below the Newton
/// tolerance's effect on N (newton_tolerance 1e-12 by default: N moves by
/// ~gamma_lme 1e-12) and on grad N.
inline constexpr double kBoxTableError = 1e-12;
inline constexpr double kBoxTableGradientError = 1e-11;
/// How far short of the hull's boundary (in units of the cell) the table of
/// an outermost cell stops: nearer it the closed forms' derivatives lose
/// digits to the cancellation of terms ~1/u^k (at 2^-10 about three, within
/// the bounds above).
inline constexpr double kBoxHullGap = 1.0 / 1024;

/// The lines that exist beyond a cell on a lattice axis: `below` lines
/// below its lower line and `above` above its upper line, each counted up
/// to the table's reach (floor r: a side with `reach` lines lacks none
/// within r). An interior cell has {reach, reach}.
struct BoxEnds {
  int below = 0, above = 0;
  bool operator==(const BoxEnds&) const = default;
};

/// The 1D LME of the box support on a uniform lattice of unit spacing: lines
/// o = ceil(u - r) .. floor(u + r) relative to the cell's lower line, r =
/// sqrt(-ln(tol) / gamma), those that exist (o >= -below, o <= 1 + above).
class BoxAxisTable {
public:
  /// Requests the interior configuration whatever the reach.
  static constexpr BoxEnds interior_ends{kBoxMaxLines, kBoxMaxLines};
  /// Builds the table of gamma = beta h^2 and max_exponent = -ln(tol) for
  /// the cells with `ends` (each side counted up to the reach; a side with
  /// no line beyond the cell is the hull's boundary: the table then covers u
  /// from kBoxHullGap, or up to 1 - kBoxHullGap). Empty when r is so large
  /// that more than kBoxMaxLines lines fall within it, or when the samples
  /// would exceed kBoxMaxSamples.
  BoxAxisTable(double gamma, double max_exponent, BoxEnds ends = interior_ends);
  bool empty() const { return segments_.empty(); }
  double gamma() const { return gamma_; }
  /// Lines that must exist below a cell's lower line (floor r) and above its
  /// upper line (floor r) for the cell to be interior.
  int reach() const { return reach_; }
  /// The configuration the table was built for (each side up to the reach).
  BoxEnds ends() const { return ends_; }
  /// The most lanes evaluate() writes to N and dN (over the intervals: the
  /// lines, L and the padding to pairs).
  int max_lanes() const;
  /// The samples of the table (all intervals) and its size in bytes.
  std::size_t samples() const;
  std::size_t bytes() const;
  /// The 1D functions at u in [0, 1]: writes N[i] and dN[i] = (dN/du)
  /// dN_scale of the lines first + i, i < m, and L = lambda h; returns m and
  /// sets `first` (relative to the cell's lower line). N and dN hold
  /// kBoxLanes entries: those from m on are overwritten with scratch.
  /// Returns 0 (nothing written) when u lies within kBoxHullGap of a side
  /// that is the hull's boundary.
  int evaluate(double u, int& first, double* N, double* dN, double& L, double dN_scale = 1.0) const;
  /// evaluate()'s work, the same arithmetic: defined (inline) in
  /// lme_box.cpp only, where the lattice lookups compile it in.
  inline int lookup(double u, int& first, double* N, double* dN, double& L, double dN_scale) const;

private:
  /// An interval [a, b] of u with lines first .. first + m - 1, sampled
  /// at u_j = a + j du, j = 0 .. n: at each sample four rows of `lanes`
  /// entries (the m lines, then L, then zeros), the rows f, f', f'', f''':
  /// the quintic Hermite data of f from the first three rows and of f'
  /// from the last three (the same weights), so the derivative is
  /// interpolated, not differentiated (which would add a rounding error
  /// ~1e-16 / du), and both are sums of rows, which vectorise over the
  /// lines.
  struct Segment {
    double a = 0.0, b = 0.0, du = 0.0, inv_du = 0.0;
    int first = 0, m = 0, n = 0, lanes = 0;
    std::vector<double> data;
    int width() const { return 4 * lanes; }
  };
  /// The data of u into `row` (false: the solve failed); L with the
  /// logarithm of the hull's boundary taken off (hull_log).
  bool sample(const Segment& s, double u, double* row) const;
  /// The part of L that diverges at a side that is the hull's boundary and
  /// its first three derivatives: -ln(u) below, ln(1 - u) above.
  void hull_log(double u, double* g) const;
  /// hull_log's g[0] alone (the same bits), what a lookup adds back to L.
  double hull_log_value(double u) const;
  /// Samples s at n intervals; false when a solve fails.
  bool fill(Segment& s, int n) const;
  /// True when every sample interval of s meets the refinement bounds.
  bool accurate(const Segment& s) const;
  /// The interpolant of s at u: N[i], dN[i] dN_scale (i < m; the arrays
  /// take all s.lanes lanes), L. Defined inline in lme_box.cpp, its only user.
  static inline void interpolate(const Segment& s, double u, double* N, double* dN, double& L,
                                 double dN_scale);
  /// Samples s finely enough (see kBoxMinSamples); false when a solve
  /// fails or more than kBoxMaxSamples would be needed.
  bool build_segment(Segment& s) const;
  double gamma_, r_;
  int reach_ = 0;
  BoxEnds ends_;
  std::vector<Segment> segments_;
};

/// The tables of one lattice axis: one per configuration of lines beyond
/// the cell (BoxEnds) that its cells have.
class BoxAxisTables {
public:
  /// Builds the tables of gamma and max_exponent for an axis of `cells`
  /// cells, taking those `same` (the tables of another axis of the same
  /// gamma and cut-off, or null) has instead of building them again; empty
  /// when the interior table is not built (BoxAxisTable).
  BoxAxisTables(double gamma, double max_exponent, int cells, const BoxAxisTables* same = nullptr);
  bool empty() const { return !interior_; }
  double gamma() const { return gamma_; }
  int cells() const { return cells_; }
  /// The table of cell c of the axis, or null (a configuration whose table
  /// was not built).
  const BoxAxisTable* at(int c) const {
    const int below = std::min(c, reach_), above = std::min(cells_ - 1 - c, reach_);
    if (below == reach_ && above == reach_) return interior_.get();
    return ends_[static_cast<std::size_t>(below * (reach_ + 1) + above)].get();
  }
  /// Every table built, the interior one first.
  std::vector<const BoxAxisTable*> tables() const;
  /// The most lanes a point's evaluation writes on this axis (over its tables).
  int max_lanes() const;

private:
  double gamma_;
  int cells_, reach_ = 0;
  std::shared_ptr<const BoxAxisTable> interior_;
  /// The boundary configurations, index below (reach + 1) + above.
  std::vector<std::shared_ptr<const BoxAxisTable>> ends_;
};

/// The 1D LME of m lines at the offsets dx[i] = u - o_i (unit spacing) and
/// its derivatives in u up to the third: f[i][d] = d^d N_i / du^d, and
/// L = lambda h likewise in `L`.
struct Lme1d {
  double f[kBoxMaxLines][4];
  double L[4];
};

/// Solves the 1D LME of the lines at offsets dx (m of them) by Newton to
/// round-off and fills `out` from the closed forms. False when the solve
/// does not converge (a point outside the lines' hull).
bool solve_lme_1d(double gamma, const double* dx, int m, Lme1d& out);

/// The tables of the D axes of a lattice (shared between axes of the same
/// spacing and cell count).
template <int D> struct BoxTables {
  std::shared_ptr<const BoxAxisTables> axis[D];
  bool empty() const { return !axis[0]; }
  /// Builds the tables of `axes` for the prior's beta and cut-off; empty
  /// when the lattice is empty or an axis has no interior table.
  static BoxTables from(const LatticeAxes<D>& axes, double beta, double max_exponent);
  /// The most lanes a point's evaluation writes on any axis.
  int max_lanes() const;
};

/// The box-support LME at x on the lattice `axes` from `tables`: writes the
/// stencil (node ids ascending, N_I = prod_k N^1_k, grad N_I) to `out` and
/// the multiplier to `lambda`. False (nothing written) when x is not in a
/// cell with a table on every axis (BoxAxisTables::at).
template <int D>
bool box_table_stencil(const LatticeAxes<D>& axes, const BoxTables<D>& tables, const Vec<D>& x,
                       RowTarget<D>& out, Vec<D>& lambda);

/// The factors of the box-support LME (ProductRows) at the points p0 ..
/// p1 - 1 of x: for point p, per axis k the first line's offset lo_k (row
/// p's base = sum_k lo_k stride_k), the lines m_k and the 1D values and
/// derivatives (per unit length) at factors(p) + 2 k lanes and + (2 k + 1)
/// lanes (the lanes from m_k on scratch), the same bits box_table_stencil's
/// products start from; the multiplier to lambda[p]. `rows` sized, its
/// lanes >= tables.max_lanes(). Returns the first point not in a cell with
/// a table on every axis (its row and multiplier untouched), or p1.
template <int D>
int box_table_factor_rows(const LatticeAxes<D>& axes, const BoxTables<D>& tables,
                          const AlignedVector<Vec<D>>& x, int p0, int p1, ProductRows<D>& rows,
                          AlignedVector<Vec<D>>& lambda);

} // namespace otmpm::maxent
