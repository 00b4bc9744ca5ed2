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

double KnotVector::greville(int i) const {
  require<std::invalid_argument>(i >= 0 && i < num_basis(), "KnotVector::greville: control point i = ", i,
                                 " out of range [0, ", num_basis(), ")");
  double s = 0.0;
  for (int j = i + 1; j <= i + p_; ++j) s += t_[j];
  return s / p_;
}

std::vector<double> KnotVector::greville() const {
  std::vector<double> xi(static_cast<std::size_t>(num_basis()));
  for (int i = 0; i < num_basis(); ++i) xi[i] = greville(i);
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
  const int s = cell + p_; // knot span index: t_s = v_cell, t_{s+1} = v_{cell+1}
  // B[r] holds N_{s-d+r}^d(x), r = 0..d, while the degree d rises from 0 to p.
  std::array<double, kMaxBsplineSpanFunctions> B{};
  std::array<double, kMaxBsplineSpanFunctions> prev{};
  BsplineSpanValues out;
  out.first = cell;
  B[0] = 1.0;
  for (int d = 1; d <= p_; ++d) {
    prev = B;
    for (int r = 0; r <= d; ++r) {
      const int j = s - d + r;
      // Cox-de Boor: N_j^d = (x - t_j)/(t_{j+d} - t_j) N_j^{d-1}
      //                    + (t_{j+d+1} - x)/(t_{j+d+1} - t_{j+1}) N_{j+1}^{d-1};
      // N_j^{d-1} = prev[r-1], N_{j+1}^{d-1} = prev[r]. Both denominators
      // contain the non-empty span [t_s, t_{s+1}] whenever the term is present.
      const double left = r >= 1 ? prev[r - 1] / (t_[j + d] - t_[j]) : 0.0;
      const double right = r <= d - 1 ? prev[r] / (t_[j + d + 1] - t_[j + 1]) : 0.0;
      B[r] = (x - t_[j]) * left + (t_[j + d + 1] - x) * right;
      if (d == p_) out.dN[r] = d * (left - right); // dN_j^p = p (N_j^{p-1}/.. - N_{j+1}^{p-1}/..)
    }
  }
  for (int r = 0; r <= p_; ++r) out.N[r] = B[r];
  return out;
}

BsplineSpanValues KnotVector::evaluate(double x, int hint) const {
  return evaluate_on_cell(x, find_cell(x, hint));
}

double KnotVector::interpolate(double x, const std::vector<double>& c) const {
  require<std::invalid_argument>(c.size() == static_cast<std::size_t>(num_basis()), "KnotVector::interpolate: c has ",
                                 c.size(), " coefficients for ", num_basis(), " basis functions");
  const BsplineSpanValues b = evaluate(x);
  double u = 0.0;
  for (int a = 0; a <= p_; ++a) u += b.N[a] * c[b.first + a];
  return u;
}

KnotVector KnotVector::advected(const std::vector<double>& d) const {
  require<std::invalid_argument>(d.size() == static_cast<std::size_t>(num_basis()), "KnotVector::advected: d has ",
                                 d.size(), " increments for ", num_basis(), " control points");
  for (std::size_t i = 0; i < d.size(); ++i)
    require<InstabilityError>(std::isfinite(d[i]), "KnotVector::advected: increment d[", i, "] = ", d[i],
                              " is not finite");
  std::vector<double> w(v_.size());
  for (std::size_t j = 0; j < v_.size(); ++j) w[j] = v_[j] + interpolate(v_[j], d);
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
  for (int k = 0; k < D; ++k) moved[k] = knots_[k].advected(mean_axis_increments(dx, k));
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

template class BsplineBasis<1>;
template class BsplineBasis<2>;
template class BsplineBasis<3>;

template <int D>
std::unique_ptr<Basis<D>> make_bspline_basis(const CartesianGrid<D>& grid, int degree) {
  return std::make_unique<BsplineBasis<D>>(grid, degree);
}

template std::unique_ptr<Basis<1>> make_bspline_basis<1>(const CartesianGrid<1>&, int);
template std::unique_ptr<Basis<2>> make_bspline_basis<2>(const CartesianGrid<2>&, int);
template std::unique_ptr<Basis<3>> make_bspline_basis<3>(const CartesianGrid<3>&, int);

} // namespace otmpm
