/// \file bspline.cpp
/// Cox-de Boor evaluation on open knot vectors, the tensor-product B-spline
/// basis and the unified-approach knot advection (see bspline.hpp).
#include "otmpm/basis/bspline.hpp"
#include "otmpm/basis/families.hpp"
#include "otmpm/state.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace otmpm {

namespace {

void check_degree(int degree) {
  require(degree >= kMinBsplineDegree && degree <= kMaxBsplineDegree, "B-spline degree ", degree,
          " not supported (use ", kMinBsplineDegree, " .. ", kMaxBsplineDegree, ")");
}

/// N[r] = N_{cell+r}(x) and dN[r] = dN_{cell+r}/dx, r = 0..P, of the open
/// knot vector t (degree P) on cell `cell` at x in [v_cell, v_{cell+1}]: the
/// triangular Cox-de Boor scheme (wobbes eq. after (76)), degree 0 -> P on
/// the span s = cell + P, t_s = v_cell, t_{s+1} = v_{cell+1}. B[r] holds
/// N_{s-d+r}^d(x), r = 0..d, while the degree d rises from 0 to P:
///   N_j^d = (x - t_j)/(t_{j+d} - t_j) N_j^{d-1} + (t_{j+d+1} - x)/(t_{j+d+1} - t_{j+1}) N_{j+1}^{d-1},
/// j = s - d + r, N_j^{d-1} = B[r-1], N_{j+1}^{d-1} = B[r] (the terms with r - 1 < 0
/// or r > d - 1 absent: 0). Both denominators contain the non-empty span, so
/// neither is 0. The quotient B[r] / (t_{s+r+1} - t_{s+r+1-d}) is the right
/// term of r and the left term of r + 1, formed once, as the product of B[r]
/// with the knot vector's reciprocal width inv_width[(d-1) knots + s+r+1-d]
/// (a division per quotient and point would bound the batch's speed: three
/// per point and axis for bspline2); dN_j^P = P (left - right). The degree as
/// a compile-time constant unrolls the loops; no allocation.
///
/// Exact = false leaves out the absent terms, (x - t_j) 0 at r = 0 and
/// (t_{j+d+1} - x) 0 at r = d. Adding such a zero to y gives y unless y is
/// itself a zero (then its sign may change: -0 + +0 = +0), and products,
/// quotients and sums of values that differ only in the sign of a zero again
/// differ only so: level by level the two variants differ in signs of zeros
/// only. A span with every N_r > 0 therefore gets the same bits, dN_r too
/// (left - right is a zero only when both quotients are, and then N_r = 0).
/// The batch uses it for such spans only (smallest_entry); evaluate_on_cell,
/// whose zero values are output, keeps the exact operations.
template <int P, bool Exact = true>
[[gnu::always_inline]] inline void cox_de_boor(const double* t, const double* inv_width, std::size_t knots, double x,
                                               int cell, double* N, double* dN) {
  const int s = cell + P;
  double B[P + 1] = {1.0};
#pragma GCC unroll 4
  for (int d = 1; d <= P; ++d) {
    double q[P];
    const double* const w = inv_width + static_cast<std::size_t>(d - 1) * knots + (s + 1 - d);
#pragma GCC unroll 4
    for (int r = 0; r < d; ++r) q[r] = B[r] * w[r];
#pragma GCC unroll 4
    for (int r = 0; r <= d; ++r) {
      const double left = r >= 1 ? q[r - 1] : 0.0;
      const double right = r < d ? q[r] : 0.0;
      if (Exact || (r > 0 && r < d))
        B[r] = (x - t[s - d + r]) * left + (t[s + r + 1] - x) * right;
      else
        B[r] = r == 0 ? (t[s + 1] - x) * right : (x - t[s]) * left;
      if (d == P) dN[r] = d * (left - right);
    }
  }
  for (int r = 0; r <= P; ++r) N[r] = B[r];
}

} // namespace

// ---------------------------------------------------------------------------
// KnotVector
// ---------------------------------------------------------------------------

KnotVector::KnotVector(std::vector<double> vertices, int degree) : v_(std::move(vertices)), p_(degree) {
  check_degree(degree);
  require(v_.size() >= 2, "KnotVector: vertices needs at least two entries (one cell), got ", v_.size());
  for (std::size_t j = 0; j + 1 < v_.size(); ++j)
    require(v_[j] < v_[j + 1] && std::isfinite(v_[j]) && std::isfinite(v_[j + 1]),
            "KnotVector: vertices must be finite and strictly increasing: v[", j, "] = ", v_[j], ", v[", j + 1,
            "] = ", v_[j + 1]);
  t_.reserve(v_.size() + 2 * static_cast<std::size_t>(p_));
  t_.insert(t_.end(), static_cast<std::size_t>(p_), v_.front());
  t_.insert(t_.end(), v_.begin(), v_.end());
  t_.insert(t_.end(), static_cast<std::size_t>(p_), v_.back());
  inv_width_.assign(static_cast<std::size_t>(p_) * t_.size(), 0.0);
  for (int d = 1; d <= p_; ++d)
    for (std::size_t j = 0; j + static_cast<std::size_t>(d) < t_.size(); ++j)
      if (t_[j + d] > t_[j]) inv_width_[static_cast<std::size_t>(d - 1) * t_.size() + j] = 1.0 / (t_[j + d] - t_[j]);
}

KnotVector KnotVector::uniform(double lower, double upper, int cells, int degree) {
  require(cells >= 1 && std::isfinite(lower) && std::isfinite(upper) && lower < upper,
          "KnotVector::uniform: needs finite lower < upper and cells >= 1, got lower = ", lower, ", upper = ", upper,
          ", cells = ", cells);
  std::vector<double> v(static_cast<std::size_t>(cells) + 1);
  const double h = (upper - lower) / cells;
  for (int j = 0; j <= cells; ++j) v[j] = lower + h * j;
  v.back() = upper; // exact end despite round-off in lower + h * cells
  return KnotVector(std::move(v), degree);
}

double KnotVector::min_cell_width() const {
  double w = v_[1] - v_[0];
  for (std::size_t j = 1; j + 1 < v_.size(); ++j) w = std::min(w, v_[j + 1] - v_[j]);
  return w;
}

namespace {

/// (t_{i+1} + ... + t_{i+p}) / p, summed left to right from 0.0.
inline double greville_of(const double* t, int i, int p) {
  double s = 0.0;
  for (int j = i + 1; j <= i + p; ++j) s += t[j];
  return s / p;
}

/// u(v_j) = sum_a N_{j+a}(v_j) d_{j+a} on cell j (the last cell for the last
/// vertex), added to v_j: the advected vertices, with the operations of
/// evaluate_on_cell (v_j needs no clamp) and span_sum, degree P unrolled.
template <int P>
void advect_vertices(const std::vector<double>& t, const std::vector<double>& inv_width, const std::vector<double>& v,
                     const std::vector<double>& d, std::vector<double>& w) {
  const int cells = static_cast<int>(v.size()) - 1;
  for (int j = 0; j <= cells; ++j) {
    const int cell = std::min(j, cells - 1);
    double N[P + 1], dN[P + 1];
    cox_de_boor<P>(t.data(), inv_width.data(), t.size(), v[j], cell, N, dN);
    double u = 0.0;
    for (int a = 0; a <= P; ++a) u += N[a] * d[cell + a];
    w[j] = v[j] + u;
  }
}

} // namespace

double KnotVector::greville(int i) const {
  require<std::invalid_argument>(i >= 0 && i < num_basis(), "KnotVector::greville: control point i = ", i,
                                 " out of range [0, ", num_basis(), ")");
  return greville_of(t_.data(), i, p_);
}

std::vector<double> KnotVector::greville() const {
  std::vector<double> xi(static_cast<std::size_t>(num_basis()));
  for (int i = 0; i < num_basis(); ++i) xi[i] = greville_of(t_.data(), i, p_);
  return xi;
}

bool KnotVector::contains(double x) const {
  const double r = kBoundaryRoundoff * (upper() - lower());
  return x >= lower() - r && x <= upper() + r; // false for NaN
}

int KnotVector::find_cell(double x, int hint) const {
  if (!contains(x))
    throw BasisError("B-spline: point " + format_number(x) + " outside the knot vector [" +
                     format_number(lower()) + ", " + format_number(upper()) + "]");
  const int m = num_cells();
  auto in_cell = [&](int j) {
    return j >= 0 && j < m && v_[j] <= x && (x < v_[j + 1] || j == m - 1);
  };
  if (hint >= 0) {
    for (int j : {hint, hint + 1, hint - 1})
      if (in_cell(j)) return j;
  }
  if (x <= v_.front()) return 0;
  if (x >= v_.back()) return m - 1;
  // first vertex strictly greater than x; the cell starts one before it
  const auto it = std::upper_bound(v_.begin(), v_.end(), x);
  return static_cast<int>(it - v_.begin()) - 1;
}

BsplineSpanValues KnotVector::evaluate_on_cell(double x, int cell) const {
  require<std::invalid_argument>(cell >= 0 && cell < num_cells(), "KnotVector::evaluate_on_cell: cell ", cell,
                                 " out of range [0, ", num_cells(), ")");
  require<BasisError>(std::isfinite(x), "KnotVector::evaluate_on_cell: x = ", x, " is not finite");
  x = std::clamp(x, lower(), upper());
  BsplineSpanValues out;
  out.first = cell;
  switch (p_) {
  case 1: cox_de_boor<1>(t_.data(), inv_width_.data(), t_.size(), x, cell, out.N.data(), out.dN.data()); break;
  case 2: cox_de_boor<2>(t_.data(), inv_width_.data(), t_.size(), x, cell, out.N.data(), out.dN.data()); break;
  default: // p_ <= kMaxBsplineDegree
    cox_de_boor<3>(t_.data(), inv_width_.data(), t_.size(), x, cell, out.N.data(), out.dN.data());
    break;
  }
  return out;
}

BsplineSpanValues KnotVector::evaluate(double x, int hint) const {
  return evaluate_on_cell(x, find_cell(x, hint));
}

double KnotVector::interpolate(double x, const std::vector<double>& c) const {
  require<std::invalid_argument>(c.size() == static_cast<std::size_t>(num_basis()), "KnotVector::interpolate: c has ",
                                 c.size(), " coefficients for ", num_basis(), " basis functions");
  return span_sum(evaluate(x), c);
}

double KnotVector::span_sum(const BsplineSpanValues& b, const std::vector<double>& c) const {
  double u = 0.0;
  for (int a = 0; a <= p_; ++a) u += b.N[a] * c[b.first + a];
  return u;
}

int KnotVector::vertex_at(double x) const {
  const double r = kBoundaryRoundoff * (upper() - lower());
  const auto it = std::lower_bound(v_.begin(), v_.end(), x - r);
  return it != v_.end() && *it <= x + r ? static_cast<int>(it - v_.begin()) : -1;
}

KnotVector KnotVector::advected(const std::vector<double>& d,
                                const std::vector<std::pair<int, double>>& held) const {
  require<std::invalid_argument>(d.size() == static_cast<std::size_t>(num_basis()), "KnotVector::advected: d has ",
                                 d.size(), " increments for ", num_basis(), " control points");
  for (std::size_t i = 0; i < d.size(); ++i)
    require<InstabilityError>(std::isfinite(d[i]), "KnotVector::advected: increment d[", i, "] = ", d[i],
                              " is not finite");
  // u(v_j): interpolate() on find_cell's cell of v_j, without the search
  std::vector<double> w(v_.size());
  switch (p_) {
  case 1: advect_vertices<1>(t_, inv_width_, v_, d, w); break;
  case 2: advect_vertices<2>(t_, inv_width_, v_, d, w); break;
  default: advect_vertices<3>(t_, inv_width_, v_, d, w); break; // p_ <= kMaxBsplineDegree
  }
  for (const auto& [j, x] : held) w[static_cast<std::size_t>(j)] = x;
  for (std::size_t j = 0; j + 1 < w.size(); ++j)
    if (!(w[j] < w[j + 1]))
      throw InstabilityError("B-spline knot vector inverted: cell " + std::to_string(j) + " [" +
                             format_number(v_[j]) + ", " + format_number(v_[j + 1]) +
                             "] would move to [" + format_number(w[j]) + ", " +
                             format_number(w[j + 1]) + "]");
  return KnotVector(std::move(w), p_);
}

// ---------------------------------------------------------------------------
// BsplineBasis
// ---------------------------------------------------------------------------

namespace {

template <int D> std::array<std::vector<double>, D> lattice_vertices(const CartesianGrid<D>& grid) {
  grid.validate();
  std::array<std::vector<double>, D> v;
  for (int k = 0; k < D; ++k) {
    const int m = grid.cells[k];
    v[k].resize(static_cast<std::size_t>(m) + 1);
    const double h = (grid.upper[k] - grid.lower[k]) / m;
    for (int j = 0; j <= m; ++j) v[k][j] = grid.lower[k] + h * j;
    v[k].back() = grid.upper[k];
  }
  return v;
}

} // namespace

template <int D> BsplineBasis<D>::BsplineBasis(const CartesianGrid<D>& grid, int degree)
    : BsplineBasis(lattice_vertices(grid), degree) {}

template <int D>
BsplineBasis<D>::BsplineBasis(const std::array<std::vector<double>, D>& vertices, int degree)
    : degree_(degree) {
  rebuild_nodes(set_knots(vertices));
}

template <int D> double BsplineBasis<D>::set_knots(const std::array<std::vector<double>, D>& vertices) {
  check_degree(degree_);
  double spacing = 0.0;
  for (int k = 0; k < D; ++k) {
    knots_[k] = KnotVector(vertices[k], degree_);
    n_[k] = window_[k] = knots_[k].num_basis();
    const double w = knots_[k].min_cell_width();
    spacing = k == 0 ? w : std::min(spacing, w);
  }
  return spacing;
}

template <int D>
BsplineBasis<D>::BsplineBasis(const CartesianGrid<D>& grid, int degree, const Index<D>& lo, const Index<D>& hi)
    : degree_(degree) {
  // The whole lattice's knots, the window's control points only (never the whole lattice's).
  const double spacing = set_knots(lattice_vertices(grid));
  for (int k = 0; k < D; ++k) {
    require<std::invalid_argument>(0 <= lo[k] && lo[k] < hi[k] && hi[k] <= n_[k], "BsplineBasis: window [", lo[k],
                                   ", ", hi[k], ") of axis ", k, " outside [0, ", n_[k], ")");
    lo_[k] = lo[k];
    window_[k] = hi[k] - lo[k];
  }
  rebuild_nodes(spacing);
}

template <int D>
void BsplineBasis<D>::distribute(std::vector<char> counted, std::function<void(std::span<double>)> sum) {
  require<std::invalid_argument>(counted.size() == static_cast<std::size_t>(nodes_.size()),
                                 "BsplineBasis::distribute: ", counted.size(), " flags for ", nodes_.size(),
                                 " control points");
  counted_ = std::move(counted);
  sum_ = std::move(sum);
}

template <int D> std::string_view BsplineBasis<D>::kind() const {
  static constexpr std::string_view names[] = {"bspline0", "bspline1", "bspline2", "bspline3"};
  return names[degree_];
}

template <int D> int BsplineBasis<D>::max_stencil() const {
  int s = 1;
  for (int k = 0; k < D; ++k) s *= degree_ + 1;
  return s;
}

template <int D> int BsplineBasis<D>::control_point_id(const Index<D>& ijk) const {
  int id = 0;
  for (int k = D - 1; k >= 0; --k) id = id * window_[k] + (ijk[k] - lo_[k]);
  return id;
}

template <int D> AlignedVector<Vec<D>> BsplineBasis<D>::greville_points() const {
  std::array<std::vector<double>, D> xi;
  int total = 1;
  for (int k = 0; k < D; ++k) {
    xi[k] = knots_[k].greville();
    total *= window_[k];
  }
  AlignedVector<Vec<D>> x(static_cast<std::size_t>(total));
  for (int id = 0; id < total; ++id) {
    int rest = id;
    for (int k = 0; k < D; ++k) {
      x[id][k] = xi[k][lo_[k] + rest % window_[k]];
      rest /= window_[k];
    }
  }
  return x;
}

template <int D> void BsplineBasis<D>::rebuild_nodes(double spacing) {
  nodes_ = NodeSet<D>::cloud(greville_points(), spacing);
}

template <int D>
std::vector<double> BsplineBasis<D>::mean_axis_increments(const AlignedVector<Vec<D>>& dx, int axis) const {
  const std::size_t n = static_cast<std::size_t>(n_[axis]);
  // sum and count of the increments of each index along the axis, in one
  // array so that a distributed run adds both over the ranks in one go
  std::vector<double> sums(2 * n, 0.0);
  int stride = 1;
  for (int k = 0; k < axis; ++k) stride *= window_[k];
  for (std::size_t id = 0; id < dx.size(); ++id) {
    if (!counted_.empty() && !counted_[id]) continue;
    const std::size_t i = static_cast<std::size_t>(lo_[axis] + (static_cast<int>(id) / stride) % window_[axis]);
    sums[i] += dx[id][axis];
    sums[n + i] += 1.0;
  }
  if (sum_) sum_(sums);
  for (std::size_t i = 0; i < n; ++i) sums[i] /= sums[n + i];
  sums.resize(n);
  return sums;
}

template <int D> void BsplineBasis<D>::nodes_moved(const AlignedVector<Vec<D>>& dx) {
  require<std::invalid_argument>(dx.size() == static_cast<std::size_t>(nodes_.size()),
                                 "BsplineBasis::nodes_moved: dx has ", dx.size(), " increments for ", nodes_.size(),
                                 " control points");
  std::array<KnotVector, D> moved;
  for (int k = 0; k < D; ++k) {
    std::vector<std::pair<int, double>> held; // the knots on the walls' planes move with them
    for (const AxisPlane& plane : held_planes_)
      if (const int j = knots_[k].vertex_at(plane.at); plane.axis == k && j >= 0)
        held.emplace_back(j, plane.at + plane.by);
    moved[k] = knots_[k].advected(mean_axis_increments(dx, k), held);
  }
  held_planes_.clear();
  knots_ = std::move(moved); // commit only once every axis succeeded

  const AlignedVector<Vec<D>> xi = greville_points();
  double dist = 0.0;
  for (int I = 0; I < nodes_.size(); ++I) dist = std::max(dist, (nodes_.position(I) - xi[I]).norm());
  last_projection_ = dist;
  nodes_.set_positions(xi);
}

template <int D> void BsplineBasis<D>::save_family_state(StateGroup& out) const {
  for (int k = 0; k < D; ++k) out.real_arrays["knots_" + std::to_string(k)].values = knots_[k].vertices();
  out.reals["last_projection"] = last_projection_;
}

template <int D> void BsplineBasis<D>::restore_family_state(const StateGroup& in) {
  std::array<KnotVector, D> knots;
  for (int k = 0; k < D; ++k) {
    const std::string name = "knots_" + std::to_string(k);
    const auto& v = in.real_array(name, knots_[k].vertices().size(), 1).values;
    try {
      knots[k] = KnotVector(v, degree_);
    } catch (const InputError& e) {
      in.error(name + ": " + e.what());
    }
  }
  knots_ = std::move(knots);
  last_projection_ = in.real("last_projection");
}

template <int D> void BsplineBasis<D>::evaluate(const PointQuery<D>& q, Stencil<D>& out) const {
  out.clear();
  require_finite_query(kind(), q);
  for (int k = 0; k < D; ++k) {
    if (!knots_[k].contains(q.x[k])) {
      std::ostringstream msg;
      msg << "B-spline basis: point " << format_point<D>(q.x);
      if (q.id >= 0) msg << " (point " << q.id << ")";
      msg << " outside the knot vectors: axis " << k << " spans [" << format_number(knots_[k].lower())
          << ", " << format_number(knots_[k].upper()) << "]";
      throw BasisError(msg.str());
    }
  }
  std::array<BsplineSpanValues, D> b;
  for (int k = 0; k < D; ++k) {
    const int hint = q.cell_hint ? (*q.cell_hint)[k] : -1;
    const int cell = knots_[k].find_cell(q.x[k], hint);
    if (q.cell_hint) (*q.cell_hint)[k] = cell;
    b[k] = knots_[k].evaluate_on_cell(q.x[k], cell);
  }
  for (int k = 0; k < D; ++k)
    if (b[k].first < lo_[k] || b[k].first + degree_ >= lo_[k] + window_[k])
      throw BasisError("B-spline basis: point " + format_point<D>(q.x) + " needs control points " +
                       std::to_string(b[k].first) + " .. " + std::to_string(b[k].first + degree_) + " of axis " +
                       std::to_string(k) + ", outside this rank's window [" + std::to_string(lo_[k]) + ", " +
                       std::to_string(lo_[k] + window_[k]) + ")");
  const int per_axis = degree_ + 1;
  const int count = max_stencil();
  out.node.reserve(static_cast<std::size_t>(count));
  out.N.reserve(static_cast<std::size_t>(count));
  out.dN.reserve(static_cast<std::size_t>(count));
  for (int e = 0; e < count; ++e) {
    // local tensor index a (axis 0 fastest) -> control point first + a
    Index<D> ijk{};
    double N = 1.0;
    Vec<D> g = Vec<D>::Ones();
    int rest = e;
    for (int k = 0; k < D; ++k) {
      const int a = rest % per_axis;
      rest /= per_axis;
      ijk[k] = b[k].first + a;
      N *= b[k].N[a];
      for (int l = 0; l < D; ++l) g[l] *= (l == k ? b[k].dN[a] : b[k].N[a]);
    }
    // Entries with N = 0 and grad N = 0 contribute nothing; entries with N = 0
    // but a one-sided non-zero gradient (degree 1 on a knot) are kept so that
    // sum grad N = 0 holds exactly.
    if (N == 0.0 && g.isZero(0.0)) continue;
    out.push(control_point_id(ijk), N, g);
  }
}

// ---------------------------------------------------------------------------
// The batch (evaluate_fixed_points)
// ---------------------------------------------------------------------------

namespace {

/// What the batch reads of one axis: the knot vector, the window and the
/// control-point stride, copied once per batch into a local array (which the
/// stores to the output arrays cannot alias, so it stays in registers).
struct BatchAxis {
  const double* t = nullptr;   ///< the full knot vector t_0 .. t_{n+p}
  const double* inv_width = nullptr; ///< KnotVector's reciprocal widths
  std::size_t knots = 0;       ///< n + p + 1
  const double* v = nullptr;   ///< the vertices v_0 .. v_m
  int cells = 0;               ///< m
  double lower = 0.0;          ///< v_0 (the clamp of evaluate_on_cell)
  double upper = 0.0;          ///< v_m
  double inside_lo = 0.0;      ///< KnotVector::contains: x >= inside_lo ...
  double inside_hi = 0.0;      ///< ... and x <= inside_hi
  int first_lo = 0;            ///< the window: first control point of a cell >= first_lo ...
  int first_hi = 0;            ///< ... and <= first_hi
  int stride = 1;              ///< control-point id stride of the axis (window-local)
};

/// The cell of x among the m cells of the vertices v, by KnotVector::
/// find_cell's search (out of line: rare once the hints are set).
[[gnu::noinline]] int search_cell(const double* v, int m, double x) {
  if (x <= v[0]) return 0;
  if (x >= v[m]) return m - 1;
  return static_cast<int>(std::upper_bound(v, v + m + 1, x) - v) - 1;
}

/// The cell of x on one axis, for an x that KnotVector::contains: the cell
/// KnotVector::find_cell returns. Its test (v_j <= x < v_{j+1}, or the last
/// cell) holds for at most one cell (none below v_0, where the answer is
/// cell 0), so the hint and its neighbours only save the search.
[[gnu::always_inline]] inline int locate(const BatchAxis& a, double x, int hint) {
  const double* v = a.v;
  const int m = a.cells;
  for (const int j : {hint, hint + 1, hint - 1})
    if (j >= 0 && j < m && v[j] <= x && (x < v[j + 1] || j == m - 1)) return j;
  return search_cell(v, m, x);
}

/// span_values: evaluate_on_cell's clamp, then the Cox-de Boor recursion
/// without the absent terms (the same bits for a span with every N_r > 0).
template <int P>
[[gnu::always_inline]] inline void span_values(const BatchAxis& a, double x, int cell, double* N, double* dN) {
  cox_de_boor<P, false>(a.t, a.inv_width, a.knots, std::clamp(x, a.lower, a.upper), cell, N, dN);
}

/// (P + 1)^D, the entries of a stencil.
template <int D, int P> constexpr int kSpanEntries = D == 1 ? P + 1 : D == 2 ? (P + 1) * (P + 1) : (P + 1) * (P + 1) * (P + 1);

/// Writes the tensor-product stencil of the per-axis values n, g (entry e =
/// a0 + (P+1) a1 + (P+1)^2 a2, node base + a0 + a1 stride_1 + a2 stride_2):
/// N = (n0 n1) n2 and (grad N)_k the same product with g_k in place of n_k,
/// multiplied left to right in axis order as BsplineBasis::evaluate does.
template <int D, int P>
[[gnu::always_inline]] inline void tensor_product(const BatchAxis* ax, const double (&n)[D][P + 1],
                                                  const double (&g)[D][P + 1], int base, int* node, double* N,
                                                  Vec<D>* dN) {
  constexpr int W = P + 1;
  if constexpr (D == 1) {
    for (int a = 0; a < W; ++a) {
      node[a] = base + a;
      N[a] = n[0][a];
      dN[a][0] = g[0][a];
    }
  } else if constexpr (D == 2) {
    for (int a1 = 0; a1 < W; ++a1)
      for (int a0 = 0; a0 < W; ++a0) {
        const int e = a0 + W * a1;
        node[e] = base + a0 + a1 * ax[1].stride;
        N[e] = n[0][a0] * n[1][a1];
        dN[e][0] = g[0][a0] * n[1][a1];
        dN[e][1] = n[0][a0] * g[1][a1];
      }
  } else {
    for (int a1 = 0; a1 < W; ++a1)
      for (int a0 = 0; a0 < W; ++a0) {
        const double nn = n[0][a0] * n[1][a1], gn = g[0][a0] * n[1][a1], ng = n[0][a0] * g[1][a1];
        const int id = base + a0 + a1 * ax[1].stride;
        for (int a2 = 0; a2 < W; ++a2) {
          const int e = a0 + W * a1 + W * W * a2;
          node[e] = id + a2 * ax[2].stride;
          N[e] = nn * n[2][a2];
          dN[e][0] = gn * n[2][a2];
          dN[e][1] = ng * n[2][a2];
          dN[e][2] = nn * g[2][a2];
        }
      }
  }
}

/// The smallest entry N of the stencil: (min_a n0[a] min_a n1[a]) min_a n2[a],
/// the product of entry (argmin0, argmin1, ...) itself; every other entry is
/// at least as large (B-splines are >= 0 and rounded products are monotone).
template <int D, int P> [[gnu::always_inline]] inline double smallest_entry(const double (&n)[D][P + 1]) {
  double m = 1.0;
  for (int k = 0; k < D; ++k) {
    double mk = n[k][0];
    for (int a = 1; a <= P; ++a) mk = std::min(mk, n[k][a]);
    m = k == 0 ? mk : m * mk;
  }
  return m;
}

/// The batch of BsplineBasis<D>::evaluate_fixed_points for degree P; Hint:
/// cell hints are read from and written to cell_hint (else the previous
/// point's cells are the hint).
template <int D, int P, bool Hint>
int bspline_run(const std::array<BatchAxis, D>& axes, const Vec<D>* x, int count, Index<D>* cell_hint, int* node,
                double* N, Vec<D>* dN) {
  constexpr int S = kSpanEntries<D, P>;
  const std::array<BatchAxis, D> ax = axes;
  Index<D> last{};
  for (int i = 0; i < count; ++i) {
    const Vec<D>& xi = x[i];
    for (int k = 0; k < D; ++k)
      if (!(xi[k] >= ax[k].inside_lo && xi[k] <= ax[k].inside_hi)) return i; // also for NaN
    double n[D][P + 1], g[D][P + 1];
    Index<D> cell;
    int base = 0;
#pragma GCC unroll 3
    for (int k = 0; k < D; ++k) {
      const int c = locate(ax[k], xi[k], Hint ? cell_hint[i][k] : last[k]);
      if (c < ax[k].first_lo || c > ax[k].first_hi) return i; // leaves the window
      span_values<P>(ax[k], xi[k], c, n[k], g[k]);
      base += (c - ax[k].first_lo) * ax[k].stride;
      cell[k] = c;
    }
    if (!(smallest_entry<D, P>(n) > 0.0)) return i; // on a knot: evaluate() drops entries
    tensor_product<D, P>(ax.data(), n, g, base, node + i * S, N + i * S, dN + i * S);
    if constexpr (Hint) cell_hint[i] = cell;
    last = cell;
  }
  return count;
}

template <int D, int P>
int bspline_batch(const std::array<BatchAxis, D>& ax, const Vec<D>* x, int count, Index<D>* cell_hint, int* node,
                  double* N, Vec<D>* dN) {
  return cell_hint ? bspline_run<D, P, true>(ax, x, count, cell_hint, node, N, dN)
                   : bspline_run<D, P, false>(ax, x, count, nullptr, node, N, dN);
}

} // namespace

template <int D>
int BsplineBasis<D>::evaluate_fixed_points(const Vec<D>* x, int count, Index<D>* cell_hint, int* node, double* N,
                                           Vec<D>* dN) const {
  std::array<BatchAxis, D> ax;
  for (int k = 0, stride = 1; k < D; stride *= window_[k], ++k) {
    const KnotVector& kv = knots_[k];
    const double r = KnotVector::kBoundaryRoundoff * (kv.upper() - kv.lower()); // as in contains()
    ax[k] = {.t = kv.knots().data(),
             .inv_width = kv.inv_width(),
             .knots = kv.knots().size(),
             .v = kv.vertices().data(),
             .cells = kv.num_cells(),
             .lower = kv.lower(),
             .upper = kv.upper(),
             .inside_lo = kv.lower() - r,
             .inside_hi = kv.upper() + r,
             .first_lo = lo_[k],
             .first_hi = lo_[k] + window_[k] - 1 - degree_,
             .stride = stride};
  }
  switch (degree_) {
  case 1: return bspline_batch<D, 1>(ax, x, count, cell_hint, node, N, dN);
  case 2: return bspline_batch<D, 2>(ax, x, count, cell_hint, node, N, dN);
  case 3: return bspline_batch<D, 3>(ax, x, count, cell_hint, node, N, dN);
  default: return -1; // no batch for this degree
  }
}

template class BsplineBasis<1>;
template class BsplineBasis<2>;
template class BsplineBasis<3>;

template <int D>
std::unique_ptr<Basis<D>> make_bspline_basis(const CartesianGrid<D>& grid, int degree) {
  return std::make_unique<BsplineBasis<D>>(grid, degree);
}

template <int D>
std::unique_ptr<Basis<D>> make_bspline_window(const CartesianGrid<D>& grid, int degree, const Index<D>& lo,
                                              const Index<D>& hi) {
  return std::make_unique<BsplineBasis<D>>(grid, degree, lo, hi);
}

template std::unique_ptr<Basis<1>> make_bspline_basis<1>(const CartesianGrid<1>&, int);
template std::unique_ptr<Basis<2>> make_bspline_basis<2>(const CartesianGrid<2>&, int);
template std::unique_ptr<Basis<3>> make_bspline_basis<3>(const CartesianGrid<3>&, int);
template std::unique_ptr<Basis<1>> make_bspline_window<1>(const CartesianGrid<1>&, int, const Index<1>&,
                                                          const Index<1>&);
template std::unique_ptr<Basis<2>> make_bspline_window<2>(const CartesianGrid<2>&, int, const Index<2>&,
                                                          const Index<2>&);
template std::unique_ptr<Basis<3>> make_bspline_window<3>(const CartesianGrid<3>&, int, const Index<3>&,
                                                          const Index<3>&);

} // namespace otmpm
