#pragma once
/// \file bspline.hpp
/// B-spline basis functions (wobbes sect. 6.2, docs/theory.md sect. 4) on
/// open, possibly non-uniform knot vectors, and their tensor product in 2D/3D
/// with knot vectors that are advected in the `unified` mode (wobbes sect. 7,
/// Algorithm 3; docs/theory.md sect. 8 `unified`).
///
/// Vocabulary: the *vertices* v_0 < ... < v_m of one axis are the distinct
/// knots (the lattice coordinates, m cells); the *knot vector* of degree p is
/// t = {v_0 (p+1 times), v_1, ..., v_{m-1}, v_m (p+1 times)}; there are
/// n = m + p basis functions N_0 .. N_{n-1} and as many *control points*, placed
/// at the Greville abscissae xi_i = (t_{i+1} + ... + t_{i+p}) / p.
#include "otmpm/basis/basis.hpp"

#include <array>
#include <functional>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

namespace otmpm {

/// Highest B-spline degree supported; bounds the fixed-size evaluation arrays.
inline constexpr int kMaxBsplineDegree = 3;
/// Lowest degree accepted (degree 1 reproduces the linear hat functions).
inline constexpr int kMinBsplineDegree = 1;
/// Number of basis functions that do not vanish on one knot span (p + 1).
inline constexpr int kMaxBsplineSpanFunctions = kMaxBsplineDegree + 1;

/// Values and first derivatives of the p+1 B-splines that can be non-zero on
/// one knot span: N[a] = N_{first+a}(x), dN[a] = dN_{first+a}/dx, a = 0..p.
struct BsplineSpanValues {
  int first = 0;
  std::array<double, kMaxBsplineSpanFunctions> N{};
  std::array<double, kMaxBsplineSpanFunctions> dN{};
};

/// A 1D open (clamped) knot vector of degree p built from strictly increasing
/// vertices (wobbes sect. 6.2: first and last knot repeated p+1 times, so the
/// basis interpolates at the ends). Evaluates all non-zero B-splines and their
/// first derivatives at a point by the Cox-de Boor recursion (wobbes eq. after
/// (76), the triangular scheme: degree 0 -> p on the one span that contains x,
/// fixed-size arrays, no allocation). Knot span j (between vertices v_j and
/// v_{j+1}) is called *cell* j; on cell j the functions j .. j+p are non-zero.
///
/// Invariant: vertices strictly increasing, at least one cell, degree in
/// [kMinBsplineDegree, kMaxBsplineDegree].
class KnotVector {
public:
  KnotVector() = default;
  /// Open knot vector of `degree` on `vertices` (strictly increasing, >= 2).
  /// Throws InputError otherwise.
  KnotVector(std::vector<double> vertices, int degree);
  /// Uniform vertices: `cells` cells of equal width on [lower, upper]. Throws
  /// InputError unless lower < upper are finite and cells >= 1.
  static KnotVector uniform(double lower, double upper, int cells, int degree);

  int degree() const { return p_; }
  int num_cells() const { return static_cast<int>(v_.size()) - 1; }
  /// Number of basis functions = number of control points, n = cells + degree.
  int num_basis() const { return num_cells() + p_; }
  /// The distinct knots v_0 .. v_m.
  const std::vector<double>& vertices() const { return v_; }
  /// The full knot vector t_0 .. t_{n+p} (end vertices repeated p+1 times).
  const std::vector<double>& knots() const { return t_; }
  /// 1 / (t_{j+d} - t_j) at [(d - 1) knots().size() + j], d = 1..p (0 where
  /// the knots coincide): the factors of the Cox-de Boor quotients.
  const double* inv_width() const { return inv_width_.data(); }
  double lower() const { return v_.front(); }
  double upper() const { return v_.back(); }
  /// Smallest cell width (min_j v_{j+1} - v_j).
  double min_cell_width() const;

  /// Greville abscissa xi_i = (t_{i+1} + ... + t_{i+p}) / p of control point i;
  /// sum_i N_i(x) xi_i = x holds exactly (linear completeness).
  /// std::invalid_argument unless 0 <= i < num_basis().
  double greville(int i) const;
  /// All Greville abscissae, i = 0 .. n-1.
  std::vector<double> greville() const;

  /// True when x lies in [lower - r, upper + r], r = kBoundaryRoundoff * length:
  /// a point within round-off of an end is taken as being on that end.
  bool contains(double x) const;
  /// The cell j with v_j <= x < v_{j+1} (the last cell for x at the upper
  /// end). `hint` (a cell index, or -1) is tried first together with its two
  /// neighbours; otherwise a binary search. Throws BasisError naming x when
  /// !contains(x).
  int find_cell(double x, int hint = -1) const;
  /// Values and derivatives of N_j .. N_{j+p} at x on cell j (x is clamped to
  /// [lower, upper]). Cox-de Boor; no allocation. Throws std::invalid_argument
  /// unless 0 <= cell < num_cells(), BasisError for a non-finite x.
  BsplineSpanValues evaluate_on_cell(double x, int cell) const;
  /// find_cell + evaluate_on_cell.
  BsplineSpanValues evaluate(double x, int hint = -1) const;
  /// Value of the B-spline function sum_i N_i(x) c_i with coefficients c
  /// (size num_basis()), e.g. a displacement interpolated from control points.
  /// Throws std::invalid_argument for another size of c, BasisError for x
  /// outside the knot vector.
  double interpolate(double x, const std::vector<double>& c) const;

  /// The unified-approach knot update along this axis: every vertex v_j moves
  /// by the displacement u(v_j) = sum_i N_i(v_j) d_i interpolated from the
  /// control-point increments d (size num_basis()) with the current basis.
  /// Returns the advected knot vector; *this is unchanged. Throws
  /// InstabilityError (naming the cell and positions) if a cell's width would
  /// become <= 0 (the grid inverted) or naming the entry of a non-finite d,
  /// std::invalid_argument if d has the wrong size.
  /// `held`: vertices (index, position) placed there instead (a knot a wall
  /// plane holds).
  KnotVector advected(const std::vector<double>& d,
                      const std::vector<std::pair<int, double>>& held = {}) const;
  /// The index of the vertex within kBoundaryRoundoff * length of x, or -1.
  int vertex_at(double x) const;

  /// Relative distance (to the knot-vector length) within which a point just
  /// outside an end is accepted as lying on it (round-off of advected points).
  static constexpr double kBoundaryRoundoff = 1e-12;

private:
  /// sum_a N_{first+a} c_{first+a} over the span values b (interpolate()'s sum).
  double span_sum(const BsplineSpanValues& b, const std::vector<double>& c) const;
  std::vector<double> v_; ///< vertices (distinct knots)
  std::vector<double> t_; ///< full open knot vector
  std::vector<double> inv_width_; ///< inv_width(), formed once per knot vector
  int p_ = 1;
};

/// B-spline basis of degree p on a D-dimensional tensor product of open knot
/// vectors (docs/theory.md sect. 4, families `bspline2`/`bspline3`):
/// N_I(x) = prod_k N^k_{i_k}(x_k), grad N_I = (dN^0 N^1 N^2, N^0 dN^1 N^2, ...).
/// The degrees of freedom are the control points on an n_0 x .. x n_{D-1}
/// lattice, n_k = cells_k + p, ids lexicographic with axis 0 fastest, placed at
/// the Greville abscissae (so sum_I N_I x_I = x: linearly complete with respect
/// to nodes()). nodes() is a NodeSet cloud with spacing = the smallest cell
/// width of the initial grid.
///
/// Advection (unified approach, wobbes Algorithm 3 and sect. 8.3 "the knot
/// vector in each direction is updated based on the velocity field"):
/// nodes_moved(dx) assumes the motion is separable per axis - the increment
/// component k of a control point depends only on its index along axis k -
/// which holds for the wobbes benchmarks (1D bars, the axis-aligned plate).
/// Per axis k the 1D increments d^k_i are the mean of dx_I[k] over all control
/// points with lattice index i on axis k (exact for separable motion, the
/// least-squares separable part otherwise); every vertex of axis k moves by
/// u_k(v) = sum_i N^k_i(v) d^k_i (old basis). The control points are then set to
/// the Greville abscissae of the advected knots, which keeps linear
/// completeness exact. For increments that are affine per axis (translation,
/// uniform stretch, any x_k -> a_k + b_k x_k) these Greville points coincide
/// with x_I + dx_I up to round-off; otherwise they differ by O(h^2 u'') and the
/// largest such difference is reported by last_projection_distance().
template <int D> class BsplineBasis final : public Basis<D> {
public:
  /// Knot vectors from the lattice vertices of `grid` on each axis.
  BsplineBasis(const CartesianGrid<D>& grid, int degree);
  /// Knot vectors from arbitrary strictly increasing vertices per axis.
  BsplineBasis(const std::array<std::vector<double>, D>& vertices, int degree);
  /// The basis of `grid` whose degrees of freedom are only the control
  /// points with lattice index in [lo, hi) (a window of a distributed run,
  /// distributed/local_parts.hpp): the knot vectors are those of the whole
  /// lattice, nodes() holds the window's control points (local ids, axis 0
  /// fastest), and a point whose stencil leaves the window is a BasisError.
  BsplineBasis(const CartesianGrid<D>& grid, int degree, const Index<D>& lo, const Index<D>& hi);

  std::string_view kind() const override;
  const NodeSet<D>& nodes() const override { return nodes_; }
  NodeSet<D>& nodes() override { return nodes_; }
  /// Advects the knot vectors (class comment). std::invalid_argument when
  /// dx.size() != nodes().size(); InstabilityError for a non-finite increment
  /// or an inverted knot vector (then nothing changes).
  void nodes_moved(const AlignedVector<Vec<D>>& dx) override;
  /// A knot that lies on one of the planes at the next nodes_moved() moves
  /// with the plane, not by the interpolated mean increments: the wall holds
  /// the control points on its plane, and the mean of their row would lift
  /// the whole row off it as soon as some of them leave the wall (a sliding
  /// block's rebound), after which no control point is on the plane and the
  /// particles sink through the floor while the friction books less than it
  /// takes (measured: energy balance error 2.6% of the energy in 0.1 s on a
  /// block sliding at 1 m/s, 0.05% with the knot held, as linear elements).
  void hold_on_planes(std::vector<AxisPlane> planes) override { held_planes_ = std::move(planes); }
  void evaluate(const PointQuery<D>& q, Stencil<D>& out) const override;
  bool linearly_complete() const override { return true; }
  int max_stencil() const override;
  /// (p+1)^D, the stencil of every point off the knots, so that
  /// fill_basis_table writes rows in place. evaluate() drops the entries with
  /// N = 0 and grad N = 0 (points on a knot, p >= 2), which gives such a point
  /// fewer entries; the table fill then takes its general path.
  int fixed_stencil() const override { return max_stencil(); }
  /// The stencils of consecutive points in one loop
  /// (Basis::evaluate_fixed_points), with the same bits as evaluate(): per
  /// axis the cell from the point's cell hint or, without hints, the previous
  /// point's cell (each with its neighbours; else a binary search), the p+1
  /// values and derivatives by the Cox-de Boor recursion of
  /// KnotVector::evaluate_on_cell (less the terms that only add a zero, which
  /// cannot change a span whose N are all > 0), then the tensor products
  /// N = N^0 N^1 N^2 and grad N multiplied in axis order, as evaluate() does,
  /// with the degree and D as compile-time sizes (no allocation). Stops before
  /// a point outside the knot vectors (KnotVector::contains) or not finite, a
  /// point whose stencil leaves the window, and a point with an entry N = 0
  /// (on a knot: evaluate() decides which entries it keeps).
  int evaluate_fixed_points(const Vec<D>* x, int count, Index<D>* cell_hint, int* node, double* N,
                            Vec<D>* dN) const override;
  /// The knot vectors' ranges.
  std::optional<std::pair<Vec<D>, Vec<D>>> domain() const override {
    Vec<D> lo, hi;
    for (int k = 0; k < D; ++k) lo[k] = knots_[k].lower(), hi[k] = knots_[k].upper();
    return std::pair{lo, hi};
  }
  /// The element walk over knot spans starts from each point's last cell.
  PointStateUse point_state_use(bool) const override { return {.cell_hint = true}; }

  int degree() const { return degree_; }
  /// The knot vector of `axis`; std::invalid_argument unless 0 <= axis < D.
  const KnotVector& knot_vector(int axis) const {
    require<std::invalid_argument>(axis >= 0 && axis < D, "BsplineBasis::knot_vector: axis ", axis,
                                   " out of range [0, ", D, ")");
    return knots_[axis];
  }
  /// Control points per axis, n_k = cells_k + degree.
  Index<D> control_points_per_axis() const { return n_; }
  /// Flat id of the control point with lattice index ijk (axis 0 fastest),
  /// local to the window.
  int control_point_id(const Index<D>& ijk) const;
  /// First lattice index of the window on each axis (0 without one).
  const Index<D>& window_lower() const { return lo_; }
  /// A distributed run: only the control points with counted[I] != 0 (this
  /// rank's own) enter the mean increments of the knot advection, and
  /// `sum` adds the per-axis sums and counts of all ranks (in place).
  void distribute(std::vector<char> counted, std::function<void(std::span<double>)> sum) override;
  /// Largest |x_I + dx_I - xi_I| of the last nodes_moved() (0 before any).
  double last_projection_distance() const { return last_projection_; }

protected:
  /// Saves the (advected) vertices of every knot vector, "knots_0", ...
  void save_family_state(StateGroup& out) const override;
  /// Rebuilds the knot vectors from the saved vertices (same cell counts).
  void restore_family_state(const StateGroup& in) override;

private:
  void rebuild_nodes(double spacing);
  /// The knot vectors on `vertices` (the whole lattice, n_ = window_); returns the smallest cell width.
  double set_knots(const std::array<std::vector<double>, D>& vertices);
  AlignedVector<Vec<D>> greville_points() const;
  std::vector<double> mean_axis_increments(const AlignedVector<Vec<D>>& dx, int axis) const;

  std::array<KnotVector, D> knots_;
  Index<D> n_{};
  Index<D> lo_{}, window_{}; ///< the window: first index and control points per axis
  std::vector<char> counted_;
  std::function<void(std::span<double>)> sum_;
  int degree_ = 2;
  NodeSet<D> nodes_;
  double last_projection_ = 0.0;
  std::vector<AxisPlane> held_planes_; ///< hold_on_planes(), used by the next nodes_moved()
};

extern template class BsplineBasis<1>;
extern template class BsplineBasis<2>;
extern template class BsplineBasis<3>;

} // namespace otmpm
