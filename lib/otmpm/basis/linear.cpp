/// \file linear.cpp
/// The `linear` family (tensor-product hat functions on an untouched Cartesian
/// lattice; isoparametric multilinear elements - 2-node segments, Q4, Q8 - on a
/// perturbed or moved lattice) and the `ugimp` family (uniform GIMP,
/// Bardenhagen & Kober 2004), docs/theory.md sect. 4.
#include "otmpm/basis/linear.hpp"

#include "otmpm/basis/families.hpp"
#include "otmpm/parallel.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <limits>
#include <type_traits>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace otmpm {

namespace detail {

Weight1D ugimp_weight(double xi, double h, double lp) {
  const double r = std::abs(xi);
  const double sign = xi < 0.0 ? -1.0 : 1.0;
  if (r < lp) return {1.0 - (xi * xi + lp * lp) / (2.0 * h * lp), -xi / (h * lp)};
  if (r <= h - lp) return {1.0 - r / h, -sign / h};
  if (r < h + lp) {
    const double gap = h + lp - r;
    return {gap * gap / (4.0 * h * lp), -sign * gap / (2.0 * h * lp)};
  }
  return {};
}

} // namespace detail

namespace {

/// The nodes of one axis that carry a weight at the point, with the 1D weight
/// and its derivative (at most M of them).
template <int M> struct AxisWeights {
  int count = 0;
  std::array<int, M> node{};
  std::array<double, M> w{};
  std::array<double, M> dw{};

  void push(int i, double s, double ds) {
    node[count] = i;
    w[count] = s;
    dw[count] = ds;
    ++count;
  }
};

/// Appends the tensor product of the per-axis weights to `out`:
/// N = prod_k w_k, (grad N)_k = dw_k prod_{j != k} w_j (axis 0 fastest).
template <int D, int M>
void push_tensor_product(const CartesianGrid<D>& g, const std::array<AxisWeights<M>, D>& axes, Stencil<D>& out) {
  std::array<int, D> j{};
  for (;;) {
    Index<D> ijk;
    double N = 1.0;
    Vec<D> grad = Vec<D>::Ones();
    for (int k = 0; k < D; ++k) {
      ijk[k] = axes[k].node[j[k]];
      N *= axes[k].w[j[k]];
      for (int m = 0; m < D; ++m) grad[m] *= (m == k ? axes[k].dw[j[k]] : axes[k].w[j[k]]);
    }
    out.push(g.node_id(ijk), N, grad);
    int k = 0;
    for (; k < D; ++k) {
      if (++j[k] < axes[k].count) break;
      j[k] = 0;
    }
    if (k == D) return;
  }
}

/// "(lower) .. (upper)" for messages.
template <int D> std::string box_text(const CartesianGrid<D>& g) {
  return format_point<D>(g.lower) + " .. " + format_point<D>(g.upper);
}

/// Points within this fraction of a cell outside the grid (or, for the
/// isoparametric map, with |xi_k| <= 1 + this) count as inside: round-off of a
/// point on the boundary or on a face. `linear` clamps them onto it; for
/// `ugimp` the weights are defined there anyway (ghost weight merged).
constexpr double kInsideTolerance = 1e-12;

/// The grid box widened by kInsideTolerance cells, its bounds formed once
/// (a basis tests every point against it).
template <int D> struct WidenedBox {
  Vec<D> lo = Vec<D>::Zero(), hi = Vec<D>::Zero();
  WidenedBox() = default;
  explicit WidenedBox(const CartesianGrid<D>& g) {
    const Vec<D> slack = kInsideTolerance * g.h();
    for (int k = 0; k < D; ++k) lo[k] = g.lower[k] - slack[k], hi[k] = g.upper[k] + slack[k];
  }
  /// True when x lies in the box (false for NaN).
  bool contains(const Vec<D>& x) const {
    for (int k = 0; k < D; ++k)
      if (!(x[k] >= lo[k] && x[k] <= hi[k])) return false;
    return true;
  }
};

template <int D> std::string point_text(const PointQuery<D>& q) {
  return "point " + format_point<D>(q.x) + (q.id >= 0 ? " (id " + std::to_string(q.id) + ")" : std::string());
}

// ---------------------------------------------------------------------------
// Isoparametric multilinear element (2-node segment, Q4, Q8)
// ---------------------------------------------------------------------------

/// Number of vertices of a D-dimensional multilinear element.
template <int D> constexpr int kCorners = 1 << D;

/// Newton on the inverse map stops when the natural-coordinate step is below
/// this; the error after that step is O(step^2), far below round-off.
constexpr double kNewtonStepTolerance = 1e-10;
constexpr int kMaxNewtonIterations = 30;
/// Natural coordinates beyond this are "far outside": stop Newton, walk on.
constexpr double kFarOutside = 4.0;
/// Extra steps allowed to the element walk beyond the lattice diameter.
constexpr int kWalkSlack = 8;
/// Cells remembered by the walk to notice that it goes round in a cycle.
constexpr int kWalkMemory = 4;

/// Shape functions of the reference element [-1, 1]^D at xi:
/// N_a = prod_k (1 + s_ak xi_k) / 2 with s_ak = +-1 from bit k of corner a.
template <int D> struct ReferenceShape {
  std::array<double, kCorners<D>> N;
  std::array<Vec<D>, kCorners<D>> dN; // dN_a / dxi

  explicit ReferenceShape(const Vec<D>& xi) {
    // the two 1D factors of each axis, f[k][0] for s = -1 and f[k][1] for s = +1
    std::array<std::array<double, 2>, D> f;
    constexpr std::array<double, 2> df{0.5 * -1.0, 0.5 * 1.0};
    for (int k = 0; k < D; ++k) {
      f[k][0] = 0.5 * (1.0 + -1.0 * xi[k]);
      f[k][1] = 0.5 * (1.0 + 1.0 * xi[k]);
    }
    for (int a = 0; a < kCorners<D>; ++a) {
      N[a] = 1.0;
      dN[a] = Vec<D>::Ones();
      for (int k = 0; k < D; ++k) {
        const int b = (a >> k) & 1;
        N[a] *= f[k][b];
        for (int m = 0; m < D; ++m) dN[a][m] *= (m == k ? df[b] : f[k][b]);
      }
    }
  }
};

/// The element of lattice cell c: its vertex ids, positions x_a, and the
/// map x(xi) = sum_a N_a(xi) x_a expanded in monomials,
/// x(xi) = sum_S c_S prod_{k in S} xi_k with c_S = 2^-D sum_a x_a prod_{k in S} s_ak
/// (S a subset of the axes, as a bit mask), so that Newton's x(xi) and J(xi)
/// cost a few multiply-adds.
template <int D> struct Element {
  /// prod_{k in S} s_ak = (-1)^(number of k in S with bit k of a clear)
  static constexpr std::array<std::array<double, kCorners<D>>, kCorners<D>> kSign = [] {
    std::array<std::array<double, kCorners<D>>, kCorners<D>> t{};
    for (int S = 0; S < kCorners<D>; ++S)
      for (int a = 0; a < kCorners<D>; ++a)
        t[S][a] = std::popcount(static_cast<unsigned>(S & ~a)) % 2 != 0 ? -1.0 : 1.0;
    return t;
  }();

  std::array<int, kCorners<D>> id;
  std::array<Vec<D>, kCorners<D>> x;
  std::array<Vec<D>, kCorners<D>> c;

  Element() = default;
  Element(const CartesianGrid<D>& g, const NodeSet<D>& nodes, const Index<D>& cell) {
    const int base = g.node_id(cell);
    std::array<int, D> stride;
    for (int k = 0, st = 1; k < D; st *= g.cells[k] + 1, ++k) stride[k] = st;
    for (Vec<D>& v : c) v.setZero();
    for (int a = 0; a < kCorners<D>; ++a) {
      id[a] = base;
      for (int k = 0; k < D; ++k) id[a] += ((a >> k) & 1) * stride[k];
      x[a] = nodes.position(id[a]);
      // (+-1) x_a is x_a or its negation exactly: the sum of +-x_a in corner order
      for (int S = 0; S < kCorners<D>; ++S) c[S] += kSign[S][a] * x[a];
    }
    for (Vec<D>& v : c) v /= kCorners<D>;
  }
  /// Position x(xi) and Jacobian J = dx/dxi, (J)_km = dx_k / dxi_m.
  void map(const Vec<D>& xi, Vec<D>& pos, Mat<D>& J) const {
    std::array<double, kCorners<D>> mono; // mono[S] = prod_{k in S} xi_k
    mono[0] = 1.0;
    for (int S = 1; S < kCorners<D>; ++S) mono[S] = mono[S & (S - 1)] * xi[std::countr_zero(static_cast<unsigned>(S))];
    pos = c[0];
    J.setZero();
    for (int S = 1; S < kCorners<D>; ++S) {
      pos += mono[S] * c[S];
      for (int m = 0; m < D; ++m)
        if (S & (1 << m)) J.col(m) += mono[S ^ (1 << m)] * c[S];
    }
  }
};

enum class InverseStatus { inside, outside, failed };

/// What the first Newton step of inverse_map reads, x(0) and J(0) (its
/// determinant and inverse): the same for every point of the element, so a
/// run of points in one element forms it once. The same bits as forming it
/// in the step.
template <int D> struct NewtonStart {
  Vec<D> pos;
  Mat<D> J_inverse;
  double det = 0.0;

  NewtonStart() = default;
  explicit NewtonStart(const Element<D>& e) {
    Mat<D> J;
    e.map(Vec<D>::Zero(), pos, J);
    det = J.determinant();
    J_inverse = J.inverse();
  }
};

/// Solves x(xi) = x for xi by Newton from the element centre. `affine`
/// receives the first iterate, J(0)^{-1} (x - x(0)): the parallelogram
/// estimate, which tells the side of a point outside the element reliably
/// (Newton itself may converge to a spurious preimage of the folded bilinear
/// extension there). On `outside` xi is Newton's estimate; on `failed`
/// (singular Jacobian or no convergence) xi is meaningless.
template <int D>
InverseStatus inverse_map(const Element<D>& e, const NewtonStart<D>& start, const Vec<D>& x, Vec<D>& xi,
                          Vec<D>& affine) {
  xi.setZero();
  affine.setConstant(std::numeric_limits<double>::quiet_NaN());
  for (int it = 0; it < kMaxNewtonIterations; ++it) {
    Vec<D> pos = start.pos;
    Mat<D> J;
    double det = start.det;
    if (it > 0) {
      e.map(xi, pos, J);
      det = J.determinant();
    }
    if (!(std::abs(det) > 0.0) || !std::isfinite(det)) return InverseStatus::failed;
    const Vec<D> step = (it > 0 ? Mat<D>(J.inverse()) : start.J_inverse) * (pos - x);
    xi -= step;
    if (it == 0) affine = xi;
    if (!xi.allFinite()) return InverseStatus::failed;
    if (xi.cwiseAbs().maxCoeff() > kFarOutside) return InverseStatus::outside;
    if (step.cwiseAbs().maxCoeff() <= kNewtonStepTolerance)
      return xi.cwiseAbs().maxCoeff() <= 1.0 + kInsideTolerance ? InverseStatus::inside : InverseStatus::outside;
  }
  return InverseStatus::failed;
}

/// True when x lies in the bounding box of the element's vertices widened by
/// `slack`: a cheap necessary condition for containment.
template <int D> bool in_bounding_box(const Element<D>& e, const Vec<D>& x, double slack) {
  Vec<D> lo = e.x[0], hi = e.x[0];
  for (int a = 1; a < kCorners<D>; ++a) {
    lo = lo.cwiseMin(e.x[a]);
    hi = hi.cwiseMax(e.x[a]);
  }
  return ((x.array() >= lo.array() - slack) && (x.array() <= hi.array() + slack)).all();
}

// ---------------------------------------------------------------------------
// linear
// ---------------------------------------------------------------------------

/// Linear Lagrange basis on the lattice topology of a structured node set:
/// tensor-product hat functions N_I = prod_k (1 - |x_k - x_Ik| / h_k) while the
/// nodes sit on their Cartesian lattice; isoparametric multilinear elements
/// (N_a(xi(x)) with the inverse map by Newton, grad N_a = J^{-T} dN_a/dxi)
/// once the lattice is perturbed or moved. Partition of unity and linear
/// completeness hold exactly (to round-off) at every point of the node set.
template <int D> class LinearBasis final : public Basis<D> {
public:
  explicit LinearBasis(NodeSet<D> nodes) : nodes_(std::move(nodes)) {
    if (!nodes_.grid())
      throw InputError("linear basis needs a structured grid (cartesian or perturbed), not a node cloud");
    grid_ = *nodes_.grid();
    h_ = grid_.h();
    const WidenedBox<D> box(grid_);
    for (int k = 0, s = 1; k < D; s *= grid_.cells[k] + 1, ++k) {
      lattice_.lo[k] = box.lo[k];
      lattice_.hi[k] = box.hi[k];
      lattice_.lower[k] = grid_.lower[k];
      lattice_.h[k] = h_[k];
      lattice_.d[k][1] = 1.0 / h_[k];
      lattice_.d[k][0] = -lattice_.d[k][1];
      lattice_.last_cell[k] = grid_.cells[k] - 1;
      lattice_.last[k] = grid_.cells[k] - 1;
      lattice_.stride[k] = s;
    }
    for (int a = 0; a < kCorners<D>; ++a) {
      lattice_.corner_offset[a] = 0;
      for (int k = 0; k < D; ++k) lattice_.corner_offset[a] += ((a >> k) & 1) * lattice_.stride[k];
    }
  }

  std::string_view kind() const override { return "linear"; }
  const NodeSet<D>& nodes() const override { return nodes_; }
  NodeSet<D>& nodes() override { return nodes_; }
  /// Nothing to refresh: evaluate() switches to the isoparametric map as soon
  /// as the node set is no longer on its lattice.
  void nodes_moved(const AlignedVector<Vec<D>>&) override {}
  bool linearly_complete() const override { return true; }
  int max_stencil() const override { return kCorners<D>; }
  int fixed_stencil() const override { return kCorners<D>; }
  /// The element walk of the isoparametric map (a perturbed or moving
  /// lattice) starts from each point's last cell; the lattice hats need none.
  PointStateUse point_state_use(bool nodes_move) const override {
    return {.cell_hint = nodes_move || !nodes_.on_lattice()};
  }

  void evaluate(const PointQuery<D>& q, Stencil<D>& out) const override {
    out.clear();
    require_finite_query(kind(), q);
    if (nodes_.on_lattice())
      evaluate_on_lattice(q, out);
    else
      evaluate_isoparametric(q, out);
  }

  /// The lattice hat functions written straight into the caller's arrays
  /// (the basis table): corner a of the cell has bit k of a set when it is
  /// the upper node on axis k. The isoparametric case goes through evaluate().
  bool evaluate_fixed(const PointQuery<D>& q, int* node, double* N, Vec<D>* dN) const override {
    if (!nodes_.on_lattice()) return false;
    require_finite_query(kind(), q);
    lattice_hats(q, node, N, dN);
    return true;
  }

  /// The lattice hats of consecutive points in one loop (no per-point query,
  /// no virtual call), the same bits as evaluate_fixed(). Stops before the
  /// first point outside the widened grid box (or not finite). Once the
  /// nodes left their lattice: in 1D the segments of segments_run, in 2D and
  /// 3D the elements of elements_run.
  int evaluate_fixed_points(const Vec<D>* x, int count, Index<D>* cell_hint, int* node, double* N,
                            Vec<D>* dN) const override {
    if (!nodes_.on_lattice()) {
      if constexpr (D == 1) return segments_run(x, count, cell_hint, node, N, dN);
      return elements_run(x, count, cell_hint, node, N, dN);
    }
    return cell_hint ? hats_run<true>(x, count, cell_hint, node, N, dN) : hats_run<false>(x, count, nullptr, node, N, dN);
  }

  /// The compact rows of the points x on the untouched lattice
  /// (LatticeRows; locate_row() of each point, so each t_k and base is the
  /// one the table's hats start from).
  bool evaluate_lattice_rows(const AlignedVector<Vec<D>>& x, LatticeRows<D>& rows) const override {
    if (!nodes_.on_lattice()) return false;
    const auto n = static_cast<long long>(x.size());
    rows.base.resize(x.size());
    rows.t.resize(x.size());
    for (int a = 0; a < kCorners<D>; ++a) rows.corner_offset[a] = lattice_.corner_offset[a];
    rows.d = lattice_.d;
    std::atomic<bool> inside{true};
    parallel_chunks(n, [&](long long p0, long long p1) {
      std::conditional_t<(D < 3), const Lattice, const Lattice&> L = lattice_;
      int* base = rows.base.data();
      Vec<D>* t = rows.t.data();
      for (auto p = p0; p < p1; ++p)
        if (!locate_row(L, x[p], base[p], t[p])) return inside.store(false, std::memory_order_relaxed);
    });
    return inside.load();
  }

private:
  /// What the lattice hats read, in one place (in 1D and 2D copied to a
  /// local before a batch, so that the compiler need not reload it after
  /// every store to the output arrays, which could alias a member).
  struct Lattice {
    double lo[D], hi[D];  ///< the grid box widened by kInsideTolerance cells (WidenedBox)
    double lower[D], h[D];
    std::array<std::array<double, 2>, D> d; ///< d N / d x_k of the lower / upper 1D hat: -1/h_k, 1/h_k
    int last_cell[D];     ///< cells - 1 per axis
    double last[D];       ///< last_cell as a double (the two-lane hats)
    int stride[D];        ///< node-id stride per axis
    int corner_offset[kCorners<D>]; ///< node id of corner a minus that of corner 0
  };

  template <bool Hint>
  int hats_run(const Vec<D>* x, int count, Index<D>* cell_hint, int* node, double* N, Vec<D>* dN) const {
    constexpr int S = kCorners<D>;
    // A local copy stays in registers in 1D and 2D; in 3D it spills and
    // costs more instructions than reading the member (callgrind).
    std::conditional_t<(D < 3), const Lattice, const Lattice&> L = lattice_;
    for (int i = 0; i < count; ++i)
      if (!hats(L, x[i], node + i * S, N + i * S, dN + i * S, Hint ? cell_hint + i : nullptr)) return i;
    return count;
  }

  /// Hat functions of the cell containing x. A point on an interior cell face
  /// belongs to the cell above it (the one floor() picks); on the upper grid
  /// boundary to the last cell. All 2^D vertices are kept, also those with
  /// N = 0 on a face, because their one-sided gradient is not zero.
  void evaluate_on_lattice(const PointQuery<D>& q, Stencil<D>& out) const {
    out.node.resize(kCorners<D>);
    out.N.resize(kCorners<D>);
    out.dN.resize(kCorners<D>);
    lattice_hats(q, out.node.data(), out.N.data(), out.dN.data());
  }

  /// The 2^D hat functions of the cell containing q.x into node/N/dN
  /// (hats()); BasisError when q.x is outside the widened grid box.
  void lattice_hats(const PointQuery<D>& q, int* node, double* N, Vec<D>* dN) const {
    if (!hats(lattice_, q.x, node, N, dN, q.cell_hint))
      throw BasisError("linear basis: " + point_text(q) + " is outside the grid " + box_text(grid_));
  }

  /// The 2^D hat functions of the cell containing x into node/N/dN, and that
  /// cell into *cell when not null; false (nothing written) when x is outside
  /// the widened grid box or not finite. Corner a has bit k set when it is
  /// the upper node on axis k (axis 0 fastest). With the 1D factors w_k (1 -
  /// t_k lower, t_k upper) and d_k (-1/h_k, 1/h_k): N = w_0 w_1 w_2 and
  /// (grad N)_k the same product with d_k in place of w_k, multiplied left
  /// to right in axis order (the bits of the tests and state hashes).
  [[gnu::always_inline]] static inline bool hats(const Lattice& L, const Vec<D>& x, int* node, double* N, Vec<D>* dN,
                                                 Index<D>* cell) {
#if defined(__SSE2__)
    if constexpr (D > 1) return hats_in_lanes(L, x, node, N, dN, cell);
#endif
    int base = 0;
    Vec<D> t;
    if (!locate(L, x, base, t, cell)) return false;
    for (int a = 0; a < kCorners<D>; ++a) node[a] = base + L.corner_offset[a];
    hat_products<D>(t, L.d, N, dN);
    return true;
  }

  /// locate() for a lattice row: in lanes in 2D and 3D (locate_in_lanes).
  [[gnu::always_inline]] static inline bool locate_row(const Lattice& L, const Vec<D>& x, int& base,
                                                       Vec<D>& t) {
#if defined(__SSE2__)
    if constexpr (D > 1) return locate_in_lanes(L, x, base, t);
#endif
    return locate(L, x, base, t, nullptr);
  }

  /// The cell index of coordinate xk along axis k, and xk's place t_k in
  /// [0, 1] in that cell; xk inside the widened box.
  [[gnu::always_inline]] static inline int axis_cell(const Lattice& L, int k, double xk, double& tk) {
    const double u = (xk - L.lower[k]) / L.h[k];
    // u >= -1e-12 here (the box), so truncation, clamped, is floor, clamped
    const int c = std::clamp(static_cast<int>(u), 0, L.last_cell[k]);
    tk = std::clamp(u - c, 0.0, 1.0);
    return c;
  }

  /// The cell of x: the id of its lowest corner into base and x's place t_k
  /// in [0, 1] in it along each axis (and the cell into *cell when not
  /// null); false when x is outside the widened grid box or not finite.
  [[gnu::always_inline]] static inline bool locate(const Lattice& L, const Vec<D>& x, int& base, Vec<D>& t,
                                                   Index<D>* cell) {
    for (int k = 0; k < D; ++k)
      if (!(x[k] >= L.lo[k] && x[k] <= L.hi[k])) return false; // also for NaN
    base = 0;
    for (int k = 0; k < D; ++k) {
      const int c = axis_cell(L, k, x[k], t[k]);
      base += L.stride[k] * c;
      if (cell) (*cell)[k] = c;
    }
    return true;
  }

#if defined(__SSE2__)
  /// Axes 0 and 1 of hats() in the two lanes of SSE2 registers: the
  /// cell's indices c_0, c_1 and the pairs the products take, w_0 = (1 -
  /// t_0, t_0), w_1 = (1 - t_1, t_1), and per lower / upper node of axis 0
  /// (d_0, w_0) and of axis 1 (w_1, d_1). Every value comes from the
  /// operations of the generic form on the same operands, so the table has
  /// its bits: the cell index clamps u to [0, last] before truncating, which
  /// for the u >= -1e-12 of the widened box is the generic clamp of the
  /// truncation; t = clamp(u - c, 0, 1) by maxpd / minpd, which return the
  /// bound where u - c equals it (u - c is never -0 here: x - x rounds to
  /// +0). False when x_0 or x_1 is outside the box or not finite.
  struct PairHats {
    __m128d w0, w1, a0, a1, b0, b1;
    int c0, c1;
  };
  /// The cell indices (c_0, c_1) and places (t_0, t_1) of x on axes 0 and 1
  /// in lanes, as described above; false when either is outside the box or
  /// not finite.
  [[gnu::always_inline]] static inline bool pair_place(const Lattice& L, const double* x, __m128i& c,
                                                       __m128d& t) {
    const __m128d xv = _mm_loadu_pd(x);
    const __m128d in = _mm_and_pd(_mm_cmpge_pd(xv, _mm_loadu_pd(L.lo)), _mm_cmple_pd(xv, _mm_loadu_pd(L.hi)));
    if (_mm_movemask_pd(in) != 3) return false; // also for NaN
    const __m128d zero = _mm_setzero_pd();
    const __m128d u = _mm_div_pd(_mm_sub_pd(xv, _mm_loadu_pd(L.lower)), _mm_loadu_pd(L.h));
    c = _mm_cvttpd_epi32(_mm_min_pd(_mm_max_pd(u, zero), _mm_loadu_pd(L.last)));
    t = _mm_min_pd(_mm_max_pd(_mm_sub_pd(u, _mm_cvtepi32_pd(c)), zero), _mm_set1_pd(1.0));
    return true;
  }
  [[gnu::always_inline]] static inline bool pair_hats(const Lattice& L, const double* x, PairHats& p) {
    __m128i c;
    __m128d t;
    if (!pair_place(L, x, c, t)) return false;
    const __m128d one = _mm_set1_pd(1.0);
    p.c0 = _mm_cvtsi128_si32(c);
    p.c1 = _mm_cvtsi128_si32(_mm_shuffle_epi32(c, 1));
    const __m128d s = _mm_sub_pd(one, t); // (1 - t_0, 1 - t_1)
    p.w0 = _mm_unpacklo_pd(s, t);
    p.w1 = _mm_unpackhi_pd(s, t);
    const __m128d d0 = _mm_loadu_pd(L.d[0].data()), d1 = _mm_loadu_pd(L.d[1].data());
    p.a0 = _mm_unpacklo_pd(d0, p.w0);
    p.a1 = _mm_unpackhi_pd(d0, p.w0);
    p.b0 = _mm_unpacklo_pd(p.w1, d1);
    p.b1 = _mm_unpackhi_pd(p.w1, d1);
    return true;
  }

  /// locate() in 2D and 3D with axes 0 and 1 in lanes (pair_place) and axis
  /// 2 as locate() takes it: the same bits, one division fewer.
  [[gnu::always_inline]] static inline bool locate_in_lanes(const Lattice& L, const Vec<D>& x, int& base,
                                                            Vec<D>& t) {
    __m128i c;
    __m128d t01;
    if (!pair_place(L, x.data(), c, t01)) return false;
    base = L.stride[0] * _mm_cvtsi128_si32(c) + L.stride[1] * _mm_cvtsi128_si32(_mm_shuffle_epi32(c, 1));
    _mm_storeu_pd(t.data(), t01);
    if constexpr (D == 3) {
      if (!(x[2] >= L.lo[2] && x[2] <= L.hi[2])) return false;
      base += L.stride[2] * axis_cell(L, 2, x[2], t[2]);
    }
    return true;
  }

  /// hats() in 2D and 3D with axes 0 and 1 in lanes (pair_hats) and axis 2
  /// as the generic form takes it: the same bits.
  [[gnu::always_inline]] static inline bool hats_in_lanes(const Lattice& L, const Vec<D>& x, int* node, double* N,
                                                          Vec<D>* dN, Index<D>* cell) {
    PairHats p;
    if (!pair_hats(L, x.data(), p)) return false;
    int base = L.stride[0] * p.c0 + L.stride[1] * p.c1;
    double w2[2] = {1.0, 1.0};
    int c2 = 0;
    if constexpr (D == 3) {
      if (!(x[2] >= L.lo[2] && x[2] <= L.hi[2])) return false;
      double t;
      c2 = axis_cell(L, 2, x[2], t);
      w2[0] = 1.0 - t, w2[1] = t;
      base += L.stride[2] * c2;
    }
    if (cell) {
      (*cell)[0] = p.c0, (*cell)[1] = p.c1;
      if constexpr (D == 3) (*cell)[2] = c2;
    }
    for (int a = 0; a < kCorners<D>; ++a) node[a] = base + L.corner_offset[a];
    const __m128d ww_lo = _mm_mul_pd(p.w0, _mm_unpacklo_pd(p.w1, p.w1)); // w_0 w_1 of corners 0, 1
    const __m128d ww_hi = _mm_mul_pd(p.w0, _mm_unpackhi_pd(p.w1, p.w1)); // of corners 2, 3
    const __m128d dw[4] = {_mm_mul_pd(p.a0, p.b0), _mm_mul_pd(p.a1, p.b0), _mm_mul_pd(p.a0, p.b1),
                           _mm_mul_pd(p.a1, p.b1)}; // (d_0 w_1, w_0 d_1) of corners 0 - 3
    if constexpr (D == 2) {
      _mm_storeu_pd(N, ww_lo);
      _mm_storeu_pd(N + 2, ww_hi);
      for (int a = 0; a < 4; ++a) _mm_storeu_pd(dN[a].data(), dw[a]);
    } else {
      const double ww[4] = {_mm_cvtsd_f64(ww_lo), _mm_cvtsd_f64(_mm_unpackhi_pd(ww_lo, ww_lo)), _mm_cvtsd_f64(ww_hi),
                            _mm_cvtsd_f64(_mm_unpackhi_pd(ww_hi, ww_hi))};
      for (int a2 = 0; a2 < 2; ++a2) {
        const __m128d w = _mm_set1_pd(w2[a2]);
        _mm_storeu_pd(N + 4 * a2, _mm_mul_pd(ww_lo, w));
        _mm_storeu_pd(N + 4 * a2 + 2, _mm_mul_pd(ww_hi, w));
        for (int a = 0; a < 4; ++a) {
          _mm_storeu_pd(dN[4 * a2 + a].data(), _mm_mul_pd(dw[a], w));
          dN[4 * a2 + a][2] = ww[a] * L.d[2][a2];
        }
      }
    }
    return true;
  }
#endif

  /// Finds the element containing x and evaluates its shape functions there.
  /// Start: the hint, else the Cartesian guess. Walk: to the neighbour across
  /// the face the point lies beyond, by the affine estimate of xi. A walk that
  /// reaches the lattice boundary, goes round in a cycle (possible on a
  /// strongly distorted lattice) or runs too long hands over to an exhaustive
  /// search in growing rings of cells around where it stopped.
  void evaluate_isoparametric(const PointQuery<D>& q, Stencil<D>& out) const {
    Index<D> c = start_cell(q);
    int max_steps = kWalkSlack;
    for (int k = 0; k < D; ++k) max_steps += grid_.cells[k];
    std::array<Index<D>, kWalkMemory> recent;
    recent.fill(c);
    for (int step = 0; step < max_steps; ++step) {
      const Element<D> e(grid_, nodes_, c);
      Vec<D> xi, affine;
      const InverseStatus st = inverse_map(e, NewtonStart<D>(e), q.x, xi, affine);
      if (st == InverseStatus::inside) return finish(e, xi, c, q, out);
      const bool affine_outside = affine.allFinite() && affine.cwiseAbs().maxCoeff() > 1.0 + kInsideTolerance;
      if (!affine_outside && st == InverseStatus::failed) break;
      Index<D> next = c;
      if (!walk(next, affine_outside ? affine : xi)) break;
      if (std::find(recent.begin(), recent.end(), next) != recent.end()) break;
      recent[static_cast<std::size_t>(step % kWalkMemory)] = c;
      c = next;
    }
    search_rings(c, q, out);
  }

  /// Tries every cell at Chebyshev distance r = 0, 1, ... of `centre` whose
  /// vertex bounding box holds the point, until the whole lattice is covered.
  void search_rings(const Index<D>& centre, const PointQuery<D>& q, Stencil<D>& out) const {
    const double slack = kInsideTolerance * nodes_.spacing();
    int r_max = 0;
    for (int k = 0; k < D; ++k) r_max = std::max({r_max, centre[k], grid_.cells[k] - 1 - centre[k]});
    bool distorted = false;
    for (int r = 0; r <= r_max; ++r) {
      Index<D> lo, hi;
      for (int k = 0; k < D; ++k) {
        lo[k] = std::max(0, centre[k] - r);
        hi[k] = std::min(grid_.cells[k] - 1, centre[k] + r);
      }
      Index<D> c = lo;
      for (;;) {
        int dist = 0;
        for (int k = 0; k < D; ++k) dist = std::max(dist, std::abs(c[k] - centre[k]));
        if (dist == r) {
          const Element<D> e(grid_, nodes_, c);
          if (in_bounding_box(e, q.x, slack)) {
            Vec<D> xi, affine;
            const InverseStatus st = inverse_map(e, NewtonStart<D>(e), q.x, xi, affine);
            if (st == InverseStatus::inside) return finish(e, xi, c, q, out);
            distorted = distorted || st == InverseStatus::failed;
          }
        }
        int k = 0;
        for (; k < D; ++k) {
          if (++c[k] <= hi[k]) break;
          c[k] = lo[k];
        }
        if (k == D) break;
      }
    }
    if (distorted)
      throw BasisError("linear basis: the inverse isoparametric map did not converge for " + point_text(q) +
                       " (an element around it is too distorted)");
    throw BasisError("linear basis: " + point_text(q) + " is outside the node set (no element contains it)");
  }

  void finish(const Element<D>& e, const Vec<D>& xi, const Index<D>& c, const PointQuery<D>& q,
              Stencil<D>& out) const {
    push_element(e, xi, q, out);
    if (q.cell_hint) *q.cell_hint = c;
  }

  Index<D> start_cell(const PointQuery<D>& q) const { return start_cell(q.cell_hint, q.x); }
  /// The hint when it names a cell of the grid, else the Cartesian guess for x.
  Index<D> start_cell(const Index<D>* hint, const Vec<D>& x) const {
    if (hint) {
      bool valid = true;
      for (int k = 0; k < D; ++k) valid = valid && (*hint)[k] >= 0 && (*hint)[k] < grid_.cells[k];
      if (valid) return *hint;
    }
    return grid_.cell_of(x);
  }

  /// Moves c one element along the axis where xi lies furthest outside
  /// [-1, 1] and a neighbour exists; false when there is none.
  bool walk(Index<D>& c, const Vec<D>& xi) const {
    int best = -1;
    double excess = 0.0;
    for (int k = 0; k < D; ++k) {
      const double e = std::abs(xi[k]) - 1.0;
      const int to = c[k] + (xi[k] > 0.0 ? 1 : -1);
      if (e > kInsideTolerance && e > excess && to >= 0 && to < grid_.cells[k]) {
        best = k;
        excess = e;
      }
    }
    if (best < 0) return false;
    c[best] += xi[best] > 0.0 ? 1 : -1;
    return true;
  }

  void push_element(const Element<D>& e, const Vec<D>& xi, const PointQuery<D>& q, Stencil<D>& out) const {
    std::array<int, kCorners<D>> node;
    std::array<double, kCorners<D>> N;
    std::array<Vec<D>, kCorners<D>> dN;
    const double det = element_values(e, xi, node.data(), N.data(), dN.data());
    if (!(det > 0.0))
      throw BasisError("linear basis: the element containing " + point_text(q) +
                       " is inverted or degenerate (det J = " + std::to_string(det) + ")");
    for (int a = 0; a < kCorners<D>; ++a) out.push(node[a], N[a], dN[a]);
  }

  /// N_a(xi) and grad N_a = J^{-T} dN_a/dxi of the element at xi (clamped
  /// to [-1, 1]^D), written to node/N/dN when det J > 0; returns det J.
  static double element_values(const Element<D>& e, Vec<D> xi, int* node, double* N, Vec<D>* dN) {
    xi = xi.cwiseMax(-1.0).cwiseMin(1.0);
    const ReferenceShape<D> s(xi);
    Vec<D> pos;
    Mat<D> J;
    e.map(xi, pos, J);
    const double det = J.determinant();
    if (!(det > 0.0)) return det;
    const Mat<D> JinvT = J.inverse().transpose();
    for (int a = 0; a < kCorners<D>; ++a) {
      node[a] = e.id[a];
      N[a] = s.N[a];
      dN[a] = JinvT * s.dN[a];
    }
    return det;
  }

  /// The elements one elements_run() has formed (with their first Newton
  /// step), in kElementSlots slots by the id of the cell's first vertex: the
  /// points of a cell come in a few runs (particles are usually listed along
  /// lines), so most of them find their element formed. A slot is valid for
  /// one call (its `call` number): the nodes move between calls.
  struct FormedElement {
    unsigned long long call = 0;
    int base = -1;
    Element<D> e;
    NewtonStart<D> start;
  };
  static constexpr int kElementSlots = 256;

  /// 2D and 3D off the lattice: consecutive points each in the element of
  /// its start cell (start_cell: the hint, else the Cartesian guess), by
  /// the operations of evaluate() when its walk ends where it starts; each
  /// element and its first Newton step formed once per call where the
  /// slots keep it. Stops before the first point that is not finite, not
  /// inside that element or in an inverted one (evaluate() walks on or
  /// reports it).
  int elements_run(const Vec<D>* x, int count, Index<D>* cell_hint, int* node, double* N, Vec<D>* dN) const {
    constexpr int S = kCorners<D>;
    thread_local std::vector<FormedElement> slots(kElementSlots);
    thread_local unsigned long long calls = 0;
    const unsigned long long call = ++calls;
    for (int p = 0; p < count; ++p) {
      if (!x[p].allFinite()) return p;
      const Index<D> c = start_cell(cell_hint ? &cell_hint[p] : nullptr, x[p]);
      const int base = grid_.node_id(c);
      FormedElement& f = slots[static_cast<std::size_t>(base % kElementSlots)];
      if (f.call != call || f.base != base) {
        f.e = Element<D>(grid_, nodes_, c);
        f.start = NewtonStart<D>(f.e);
        f.call = call;
        f.base = base;
      }
      Vec<D> xi, affine;
      if (inverse_map(f.e, f.start, x[p], xi, affine) != InverseStatus::inside) return p;
      if (!(element_values(f.e, xi, node + p * S, N + p * S, dN + p * S) > 0.0)) return p;
      if (cell_hint) cell_hint[p] = c;
    }
    return count;
  }

  /// 1D off the lattice (moved or perturbed nodes), consecutive points each
  /// in the segment of its start cell (start_cell: the hint, else the
  /// Cartesian guess), by the operations Element, inverse_map and
  /// push_element make for D = 1, in the same order - evaluate()'s bits
  /// without their general loops, the stencil and its copy. Stops before
  /// the first point that is not finite or not inside that segment (its
  /// element walk and errors are evaluate()'s).
  int segments_run(const Vec<D>* x, int count, Index<D>* cell_hint, int* node, double* N, Vec<D>* dN) const
    requires(D == 1)
  {
    const Vec<D>* pos = nodes_.positions().data();
    for (int p = 0; p < count; ++p) {
      const double xp = x[p][0];
      if (!std::isfinite(xp)) return p;
      const int c = start_cell(cell_hint ? &cell_hint[p] : nullptr, x[p])[0];
      const int id = grid_.node_id(Index<D>{c});
      const double x0 = pos[id][0], x1 = pos[id + 1][0];
      // Element: c_S = 2^-D sum_a +-x_a, summed from zero in corner order
      const double c0 = ((0.0 + x0) + x1) / 2, c1 = ((0.0 + -x0) + x1) / 2;
      double xi;
      if (!segment_inverse(c0, c1, xp, xi)) return p;
      // push_element: J = c1 (> 0 required), grad N_a = (1 / J) dN_a / dxi
      const double J = 0.0 + 1.0 * c1;
      if (!(J > 0.0)) return p;
      xi = std::min(std::max(xi, -1.0), 1.0);
      const double inv_J = 1.0 / J;
      node[2 * p] = id;
      node[2 * p + 1] = id + 1;
      N[2 * p] = 0.5 * (1.0 + -xi);
      N[2 * p + 1] = 0.5 * (1.0 + xi);
      dN[2 * p][0] = inv_J * (0.5 * -1.0);
      dN[2 * p + 1][0] = inv_J * (0.5 * 1.0);
      if (cell_hint) cell_hint[p][0] = c;
    }
    return count;
  }

  /// inverse_map for D = 1 on the segment x(xi) = c0 + xi c1, its Newton
  /// iterations from xi = 0 operation by operation; true when it ends inside.
  static bool segment_inverse(double c0, double c1, double x, double& xi) {
    xi = 0.0;
    for (int it = 0; it < kMaxNewtonIterations; ++it) {
      const double pos = c0 + (1.0 * xi) * c1, J = 0.0 + 1.0 * c1;
      if (!(std::abs(J) > 0.0) || !std::isfinite(J)) return false;
      const double step = (1.0 / J) * (pos - x);
      xi -= step;
      if (!std::isfinite(xi) || std::abs(xi) > kFarOutside) return false;
      if (std::abs(step) <= kNewtonStepTolerance) return std::abs(xi) <= 1.0 + kInsideTolerance;
    }
    return false;
  }

  NodeSet<D> nodes_;
  CartesianGrid<D> grid_;
  Vec<D> h_; ///< lattice spacing per axis
  Lattice lattice_{}; ///< the widened grid box, grid_ and h_ as the lattice hats read them
};

// ---------------------------------------------------------------------------
// ugimp
// ---------------------------------------------------------------------------

/// Nodes per axis with a non-zero uGIMP weight: the support |xi| < h + lp is
/// an open interval of length 2 (h + lp) <= 3 h, so 3 nodes, or 4 when
/// lp = h/2 and round-off keeps both end nodes.
constexpr int kUgimpAxisCapacity = 4;
constexpr int kUgimpAxisTypical = 3;
/// lp counts as h/2 (the 4-node case) within this relative margin.
constexpr double kHalfCellMargin = 1e-9;

/// Uniform GIMP: S_I(x_p) = (1/V_p) int_{Omega_p} N_I dx, the hat function
/// averaged over the particle box of half-width lp (Bardenhagen & Kober 2004),
/// a tensor product of detail::ugimp_weight per axis.
///
/// Grid edge: a particle box that pokes out of the grid would need the ghost
/// node one cell outside. Its weight (and gradient) is given to the boundary
/// node of that axis, i.e. the boundary node's hat function is continued as 1
/// outside the grid. Partition of unity and sum grad S = 0 therefore hold at
/// every point of the grid; what is lost there, for points within lp of the
/// edge, is linear completeness (sum S_I x_I != x, sum x_I (x) grad S_I != I).
template <int D> class UgimpBasis final : public Basis<D> {
public:
  UgimpBasis(NodeSet<D> nodes, const Vec<D>& half_width) : nodes_(std::move(nodes)), lp_(half_width) {
    if (!nodes_.grid() || nodes_.layout() != NodeLayout::cartesian || !nodes_.on_lattice())
      throw InputError("ugimp needs an unperturbed Cartesian grid (got a " + layout_text() + " node set)");
    grid_ = *nodes_.grid();
    h_ = grid_.h();
    box_ = WidenedBox<D>(grid_);
    for (int k = 0; k < D; ++k)
      if (!(lp_[k] > 0.0 && lp_[k] <= 0.5 * h_[k] * (1.0 + kHalfCellMargin)))
        throw InputError("ugimp: particle half-width on axis " + std::to_string(k) + " must be in (0, h/2] = (0, " +
                         std::to_string(0.5 * h_[k]) + "], got " + std::to_string(lp_[k]) +
                         " (l_p = h / (2 particles_per_cell))");
  }

  std::string_view kind() const override { return "ugimp"; }
  const NodeSet<D>& nodes() const override { return nodes_; }
  NodeSet<D>& nodes() override { return nodes_; }
  void nodes_moved(const AlignedVector<Vec<D>>&) override {
    throw InputError("ugimp needs an unperturbed Cartesian grid: its nodes cannot move (use mode = \"mpm\")");
  }
  /// Only away from the grid edge (see the class comment).
  bool linearly_complete() const override { return false; }
  int max_stencil() const override {
    int n = 1;
    for (int k = 0; k < D; ++k)
      n *= 2.0 * lp_[k] < h_[k] * (1.0 - kHalfCellMargin) ? kUgimpAxisTypical : kUgimpAxisCapacity;
    return n;
  }

  void evaluate(const PointQuery<D>& q, Stencil<D>& out) const override {
    out.clear();
    require_finite_query(kind(), q);
    if (!nodes_.on_lattice())
      throw BasisError("ugimp: the nodes moved off their Cartesian lattice; cannot evaluate " + point_text(q));
    if (!box_.contains(q.x))
      throw BasisError("ugimp: " + point_text(q) + " is outside the grid " + box_text(grid_));
    std::array<AxisWeights<kUgimpAxisCapacity>, D> axes;
    for (int k = 0; k < D; ++k) axis_weights(k, q.x[k], axes[k]);
    push_tensor_product<D, kUgimpAxisCapacity>(grid_, axes, out);
    if (q.cell_hint) *q.cell_hint = grid_.cell_of(q.x);
  }

private:
  /// Weights of the nodes i-1 .. i+2 around the cell i containing x on axis
  /// k; ghost nodes (-1, cells+1) are merged into the boundary node.
  void axis_weights(int k, double x, AxisWeights<kUgimpAxisCapacity>& a) const {
    const double s = (x - grid_.lower[k]) / h_[k];
    const int i = std::clamp(static_cast<int>(std::floor(s)), 0, grid_.cells[k] - 1);
    for (int j = i - 1; j <= i + 2; ++j) {
      const double xj = (j == grid_.cells[k]) ? grid_.upper[k] : grid_.lower[k] + j * h_[k];
      const detail::Weight1D w = detail::ugimp_weight(x - xj, h_[k], lp_[k]);
      if (w.S == 0.0) continue; // outside the support, where dS = 0 too
      const int node = std::clamp(j, 0, grid_.cells[k]);
      if (a.count > 0 && a.node[a.count - 1] == node) {
        a.w[a.count - 1] += w.S;
        a.dw[a.count - 1] += w.dS;
      } else {
        a.push(node, w.S, w.dS);
      }
    }
  }

  std::string layout_text() const {
    if (!nodes_.grid() || nodes_.layout() == NodeLayout::cloud) return "cloud";
    if (nodes_.layout() == NodeLayout::perturbed) return "perturbed";
    return "moved Cartesian";
  }

  NodeSet<D> nodes_;
  CartesianGrid<D> grid_;
  Vec<D> h_;
  Vec<D> lp_;
  WidenedBox<D> box_;
};

} // namespace

template <int D> std::unique_ptr<Basis<D>> make_linear_basis(NodeSet<D> nodes) {
  return std::make_unique<LinearBasis<D>>(std::move(nodes));
}

template <int D> std::unique_ptr<Basis<D>> make_ugimp_basis(NodeSet<D> nodes, const Vec<D>& half_width) {
  return std::make_unique<UgimpBasis<D>>(std::move(nodes), half_width);
}

template std::unique_ptr<Basis<1>> make_linear_basis<1>(NodeSet<1>);
template std::unique_ptr<Basis<2>> make_linear_basis<2>(NodeSet<2>);
template std::unique_ptr<Basis<3>> make_linear_basis<3>(NodeSet<3>);
template std::unique_ptr<Basis<1>> make_ugimp_basis<1>(NodeSet<1>, const Vec<1>&);
template std::unique_ptr<Basis<2>> make_ugimp_basis<2>(NodeSet<2>, const Vec<2>&);
template std::unique_ptr<Basis<3>> make_ugimp_basis<3>(NodeSet<3>, const Vec<3>&);

} // namespace otmpm
