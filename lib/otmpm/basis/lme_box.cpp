// LME with the box support on a uniform lattice, read from a table
// (lme_box.hpp, docs/theory.md sect. 4.9).
//
// Choices made here
// -----------------
// * Units: the table works in cell units (spacing 1, offsets dx = u - o),
//   where the 1D problem depends on gamma = beta h^2 and the cut-off only;
//   lambda = L / h, d lambda / dx = (dL / du) / h^2, dN/dx = (dN/du) / h.
// * Intervals: the lines within r of u change where u - r or u + r is an
//   integer, at frac(r) and 1 - frac(r); between them every function is
//   smooth and is sampled on its own (both ends of an interval with the
//   interval's lines, the one-sided limits).
// * Quintic Hermite: the closed forms give N and its first three
//   derivatives at each sample; N is interpolated from (N, N', N'') and
//   dN/du from (N', N'', N''') with an error O(du^6) each. Near a node the
//   functions turn within a length ~J = sum N dx^2 ~ 2 exp(-gamma) (the LME
//   tends to the hat functions as gamma grows), which sets the uniform
//   spacing of the samples (lme_box.hpp, kBoxMinSamples).
#include "otmpm/basis/lme_box.hpp"

#include "otmpm/basis/lme_lattice.hpp"

#include <algorithm>
#include <cmath>

namespace otmpm::maxent {

namespace {

/// Newton iterations of the 1D solve at most (interior points converge in
/// fewer than 10 from L = 0).
constexpr int kMaxIterations1d = 200;
/// Largest Newton step in L (cell units): keeps every exponent change below
/// kMaxStep1d r without a line search.
constexpr double kMaxStep1d = 2.0;

/// The weights p_i = exp(-gamma dx_i^2 + L dx_i - shift) (shift: their
/// largest exponent), Z = sum p, the mean offset and the variance.
struct Moments1d {
  double Z = 0.0, mean = 0.0, var = 0.0;
};

Moments1d moments_1d(double gamma, double L, const double* dx, int m, double* p) {
  double shift = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < m; ++i) shift = std::max(shift, dx[i] * (L - gamma * dx[i]));
  Moments1d s;
  double s1 = 0.0, s2 = 0.0;
  for (int i = 0; i < m; ++i) {
    p[i] = std::exp(dx[i] * (L - gamma * dx[i]) - shift);
    s.Z += p[i];
    s1 += p[i] * dx[i];
    s2 += p[i] * dx[i] * dx[i];
  }
  s.mean = s1 / s.Z;
  s.var = s2 / s.Z - s.mean * s.mean;
  return s;
}

/// The quintic Hermite basis at s in [0, 1]: h[0..5], the weights of f0,
/// f0', f0'', f1, f1', f1'' with the derivatives in units of the interval.
[[gnu::always_inline]] inline void hermite5(double s, double* h) {
  const double s2 = s * s, s3 = s2 * s, s4 = s3 * s, s5 = s4 * s;
  h[0] = 1.0 - 10.0 * s3 + 15.0 * s4 - 6.0 * s5;
  h[1] = s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5;
  h[2] = 0.5 * (s2 - 3.0 * s3 + 3.0 * s4 - s5);
  h[3] = 1.0 - h[0];
  h[4] = -4.0 * s3 + 7.0 * s4 - 3.0 * s5;
  h[5] = 0.5 * (s3 - 2.0 * s4 + s5);
}

} // namespace

bool solve_lme_1d(double gamma, const double* dx, int m, Lme1d& out) {
  double p[kBoxMaxLines];
  if (m < 2 || m > kBoxMaxLines) return false;
  double L = 0.0;
  Moments1d s;
  for (int it = 0;; ++it) {
    s = moments_1d(gamma, L, dx, m, p);
    if (!(s.var > 0.0) || !std::isfinite(s.mean)) return false;
    const double step = std::clamp(-s.mean / s.var, -kMaxStep1d, kMaxStep1d);
    if (std::abs(step) <= 1e-15 * (1.0 + std::abs(L))) break;
    if (it >= kMaxIterations1d) return false;
    L += step;
  }
  // The closed forms at the solution (a = dx - mean, sum N a = 0 to
  // round-off): N' = -N a / J with J = sum N a^2; J' = sum N' a^2; J'' =
  // sum N'' a^2 - 2 (as sum N' a = -1);
  //   N''  = -(N' a + N) / J + N a c2,                  c2 = J' / J^2,
  //   N''' = -(N'' a + 2 N') / J + 2 (N' a + N) c2 + N a c3,
  //                                          c3 = J'' / J^2 - 2 J'^2 / J^3;
  // L' = 2 gamma - 1 / J, L'' = c2, L''' = c3.
  const double J = s.var, inv_J = 1.0 / J;
  double dJ = 0.0, d2J = -2.0;
  for (int i = 0; i < m; ++i) {
    const double a = dx[i] - s.mean;
    out.f[i][0] = p[i] / s.Z;
    out.f[i][1] = -out.f[i][0] * a * inv_J;
    dJ += out.f[i][1] * a * a;
  }
  const double c2 = dJ * inv_J * inv_J;
  for (int i = 0; i < m; ++i) {
    const double a = dx[i] - s.mean, N = out.f[i][0], N1 = out.f[i][1];
    out.f[i][2] = -(N1 * a + N) * inv_J + N * a * c2;
    d2J += out.f[i][2] * a * a;
  }
  const double c3 = d2J * inv_J * inv_J - 2.0 * dJ * dJ * inv_J * inv_J * inv_J;
  for (int i = 0; i < m; ++i) {
    const double a = dx[i] - s.mean, N = out.f[i][0], N1 = out.f[i][1], N2 = out.f[i][2];
    out.f[i][3] = -(N2 * a + 2.0 * N1) * inv_J + 2.0 * (N1 * a + N) * c2 + N * a * c3;
  }
  out.L[0] = L;
  out.L[1] = 2.0 * gamma - inv_J;
  out.L[2] = c2;
  out.L[3] = c3;
  return true;
}

BoxAxisTable::BoxAxisTable(double gamma, double max_exponent, BoxEnds ends)
    : gamma_(gamma), r_(std::sqrt(max_exponent / gamma)) {
  if (!(r_ > 0.0) || !box_support_fits(r_)) return;
  reach_ = static_cast<int>(std::floor(r_));
  ends_ = {std::max(0, std::min(ends.below, reach_)), std::max(0, std::min(ends.above, reach_))};
  // the interval ends: 0 (kBoxHullGap at the hull's boundary), frac(r),
  // 1 - frac(r), 1 (1 - kBoxHullGap)
  const double lo = ends_.below == 0 ? kBoxHullGap : 0.0, hi = ends_.above == 0 ? 1.0 - kBoxHullGap : 1.0;
  std::vector<double> bounds{lo, hi};
  for (const double b : {r_ - std::floor(r_), std::ceil(r_) - r_})
    if (b > lo && b < hi) bounds.push_back(b);
  std::sort(bounds.begin(), bounds.end());
  bounds.erase(std::unique(bounds.begin(), bounds.end()), bounds.end());
  for (std::size_t e = 0; e + 1 < bounds.size(); ++e) {
    Segment s;
    s.a = bounds[e];
    s.b = bounds[e + 1];
    const double mid = 0.5 * (s.a + s.b);
    // the lines within r of the interval that exist
    s.first = std::max(static_cast<int>(std::ceil(mid - r_)), -ends_.below);
    s.m = std::min(static_cast<int>(std::floor(mid + r_)), 1 + ends_.above) - s.first + 1;
    s.lanes = box_lanes(s.m);
    if (!build_segment(s)) {
      segments_.clear();
      return;
    }
    segments_.push_back(std::move(s));
  }
}

double BoxAxisTable::hull_log_value(double u) const {
  double g0 = 0.0;
  if (ends_.below == 0) g0 -= std::log(u);
  if (ends_.above == 0) g0 += std::log(1.0 - u);
  return g0;
}

void BoxAxisTable::hull_log(double u, double* g) const {
  g[0] = hull_log_value(u);
  for (int d = 1; d < 4; ++d) g[d] = 0.0;
  if (ends_.below == 0) { // -ln(u)
    g[1] -= 1.0 / u;
    g[2] += 1.0 / (u * u);
    g[3] -= 2.0 / (u * u * u);
  }
  if (ends_.above == 0) { // ln(1 - u)
    const double v = 1.0 - u;
    g[1] -= 1.0 / v;
    g[2] -= 1.0 / (v * v);
    g[3] -= 2.0 / (v * v * v);
  }
}

bool BoxAxisTable::sample(const Segment& s, double u, double* row) const {
  double dx[kBoxMaxLines];
  for (int i = 0; i < s.m; ++i) dx[i] = u - (s.first + i);
  Lme1d f;
  if (!solve_lme_1d(gamma_, dx, s.m, f)) return false;
  // lambda diverges at the hull's boundary like its logarithm; the rest is smooth
  double g[4];
  hull_log(u, g);
  for (int d = 0; d < 4; ++d) f.L[d] -= g[d];
  for (int d = 0; d < 4; ++d) {
    double* r = row + d * s.lanes;
    for (int i = 0; i < s.lanes; ++i) r[i] = i < s.m ? f.f[i][d] : i == s.m ? f.L[d] : 0.0;
  }
  return true;
}

namespace {
/// The lanes of BoxAxisTable::interpolate: N[i] and dN[i] from the sample
/// rows f0 and f1 (4 n entries each) with the Hermite weights w; n = N > 0
/// lanes fixed at compile time (the loop unrolled), else `lanes`. Each lane
/// the same arithmetic in the same order either way.
template <int Lanes>
[[gnu::always_inline]] inline void hermite_lanes(const double* __restrict f0, const double* __restrict f1,
                                                 const double (&w)[6], double dN_scale, int lanes,
                                                 double* __restrict N, double* __restrict dN) {
  const int n = Lanes > 0 ? Lanes : lanes;
  for (int i = 0; i < n; ++i) {
    N[i] = w[0] * f0[i] + w[1] * f0[n + i] + w[2] * f0[2 * n + i] + w[3] * f1[i] + w[4] * f1[n + i] +
           w[5] * f1[2 * n + i];
    dN[i] = (w[0] * f0[n + i] + w[1] * f0[2 * n + i] + w[2] * f0[3 * n + i] + w[3] * f1[n + i] +
             w[4] * f1[2 * n + i] + w[5] * f1[3 * n + i]) *
            dN_scale;
  }
}
} // namespace

[[gnu::always_inline]] inline void BoxAxisTable::interpolate(const Segment& s, double u, double* __restrict N,
                                                             double* __restrict dN, double& L,
                                                             double dN_scale) {
  const double t = std::clamp((u - s.a) * s.inv_du, 0.0, static_cast<double>(s.n));
  const int j = std::min(static_cast<int>(t), s.n - 1);
  double h[6];
  hermite5(t - j, h);
  // the weights of (f, f', f'') at both ends in units of u
  const double du = s.du;
  const double w[6] = {h[0], h[1] * du, h[2] * du * du, h[3], h[4] * du, h[5] * du * du};
  const int n = s.lanes;
  const double* __restrict f0 = s.data.data() + static_cast<std::size_t>(j) * static_cast<std::size_t>(4 * n);
  const double* __restrict f1 = f0 + 4 * n;
  // every lane straight into N and dN (the lines, then L and padding); the
  // common widths unrolled (gamma_lme about 1.5 - 12 at the default cut-off)
  switch (n) {
  case 4:
    hermite_lanes<4>(f0, f1, w, dN_scale, n, N, dN);
    break;
  case 6:
    hermite_lanes<6>(f0, f1, w, dN_scale, n, N, dN);
    break;
  case 8:
    hermite_lanes<8>(f0, f1, w, dN_scale, n, N, dN);
    break;
  default:
    hermite_lanes<0>(f0, f1, w, dN_scale, n, N, dN);
  }
  L = N[s.m];
}

bool BoxAxisTable::fill(Segment& s, int n) const {
  s.n = n;
  s.du = (s.b - s.a) / n;
  s.inv_du = n / (s.b - s.a);
  const auto width = static_cast<std::size_t>(s.width());
  s.data.resize(static_cast<std::size_t>(n + 1) * width);
  for (int j = 0; j <= n; ++j)
    if (!sample(s, j == n ? s.b : s.a + j * s.du, s.data.data() + static_cast<std::size_t>(j) * width))
      return false;
  return true;
}

bool BoxAxisTable::accurate(const Segment& s) const {
  std::vector<double> exact(static_cast<std::size_t>(s.width())), N(static_cast<std::size_t>(s.lanes)),
      dN(static_cast<std::size_t>(s.lanes));
  for (int j = 0; j < s.n; ++j)
    for (const double t : {0.25, 0.5, 0.75}) {
      const double x = s.a + (j + t) * s.du;
      if (!sample(s, x, exact.data())) return false;
      double L;
      interpolate(s, x, N.data(), dN.data(), L, 1.0);
      const double g0 = hull_log_value(x);
      L += g0;
      const auto lanes = static_cast<std::size_t>(s.lanes);
      for (std::size_t i = 0; i < static_cast<std::size_t>(s.m); ++i)
        if (!(std::abs(N[i] - exact[i]) <= kBoxRefineError &&
              std::abs(dN[i] - exact[lanes + i]) <= kBoxRefineGradient))
          return false;
      const double L_exact = exact[static_cast<std::size_t>(s.m)] + g0;
      if (!(std::abs(L - L_exact) <= kBoxRefineGradient * (1.0 + std::abs(L_exact)))) return false;
    }
  return true;
}

bool BoxAxisTable::build_segment(Segment& s) const {
  for (int n = kBoxMinSamples; n <= kBoxMaxSamples; n *= 2) {
    if (!fill(s, n)) return false;
    if (accurate(s)) return true;
  }
  return false;
}

int BoxAxisTable::max_lanes() const {
  int m = 0;
  for (const Segment& s : segments_) m = std::max(m, s.lanes);
  return m;
}

int BoxAxisTables::max_lanes() const {
  int m = 0;
  for (const BoxAxisTable* t : tables()) m = std::max(m, t->max_lanes());
  return m;
}

template <int D> int BoxTables<D>::max_lanes() const {
  int m = 0;
  for (int k = 0; k < D && axis[k]; ++k) m = std::max(m, axis[k]->max_lanes());
  return m;
}

std::size_t BoxAxisTable::samples() const {
  std::size_t n = 0;
  for (const Segment& s : segments_) n += static_cast<std::size_t>(s.n) + 1;
  return n;
}

std::size_t BoxAxisTable::bytes() const {
  std::size_t n = 0;
  for (const Segment& s : segments_) n += s.data.size() * sizeof(double);
  return n;
}

int BoxAxisTable::evaluate(double u, int& first, double* N, double* dN, double& L, double dN_scale) const {
  return lookup(u, first, N, dN, L, dN_scale);
}

[[gnu::always_inline]] inline int BoxAxisTable::lookup(double u, int& first, double* N, double* dN, double& L,
                                                       double dN_scale) const {
  if (u < segments_.front().a || u > segments_.back().b)
    return 0; // within kBoxHullGap of the hull's boundary
  std::size_t k = 0;
  while (k + 1 < segments_.size() && u > segments_[k].b) ++k;
  const Segment& s = segments_[k];
  interpolate(s, u, N, dN, L, dN_scale);
  if (ends_.below == 0 || ends_.above == 0) L += hull_log_value(u);
  first = s.first;
  return s.m;
}

BoxAxisTables::BoxAxisTables(double gamma, double max_exponent, int cells, const BoxAxisTables* same)
    : gamma_(gamma), cells_(cells) {
  if (same && same->empty()) return; // the interior table of gamma is not built
  auto interior = same ? same->interior_ : std::make_shared<const BoxAxisTable>(gamma, max_exponent);
  if (interior->empty()) return;
  reach_ = interior->reach();
  // the configurations the axis' cells have
  ends_.resize(static_cast<std::size_t>((reach_ + 1) * (reach_ + 1)));
  for (int c = 0; c < cells; ++c) {
    const BoxEnds e{std::min(c, reach_), std::min(cells - 1 - c, reach_)};
    if (e == BoxEnds{reach_, reach_}) continue;
    const auto index = static_cast<std::size_t>(e.below * (reach_ + 1) + e.above);
    auto& slot = ends_[index];
    if (slot) continue;
    if (same && same->ends_[index]) {
      slot = same->ends_[index];
      continue;
    }
    auto table = std::make_shared<const BoxAxisTable>(gamma, max_exponent, e);
    if (!table->empty()) slot = std::move(table);
  }
  interior_ = std::move(interior);
}

std::vector<const BoxAxisTable*> BoxAxisTables::tables() const {
  std::vector<const BoxAxisTable*> all;
  if (interior_) all.push_back(interior_.get());
  for (const auto& t : ends_)
    if (t) all.push_back(t.get());
  return all;
}

template <int D>
BoxTables<D> BoxTables<D>::from(const LatticeAxes<D>& axes, double beta, double max_exponent) {
  BoxTables t;
  if (axes.empty()) return t;
  for (int k = 0; k < D; ++k) {
    const double gamma = beta * axes.h[k] * axes.h[k];
    const int cells = static_cast<int>(axes.coord[k].size()) - 1;
    // an axis of the same spacing: its tables, whole if it has as many cells
    const BoxAxisTables* same = nullptr;
    for (int l = 0; l < k && !t.axis[k]; ++l)
      if (t.axis[l]->gamma() == gamma) {
        same = t.axis[l].get();
        if (same->cells() == cells) t.axis[k] = t.axis[l];
      }
    if (!t.axis[k]) t.axis[k] = std::make_shared<const BoxAxisTables>(gamma, max_exponent, cells, same);
    if (t.axis[k]->empty()) return BoxTables{};
  }
  return t;
}

namespace {

/// One axis of a point's box: lines lo .. lo + m - 1 with the 1D values n
/// and their derivatives d (per unit length).
struct BoxAxis {
  int lo = 0, m = 0;
  double n[kBoxLanes], d[kBoxLanes];
};

/// Axis k of the box of coordinate xk from its tables: its first line lo,
/// lines m, values n and derivatives d (per unit length; each array takes
/// the table's lanes, those from m on scratch) and the multiplier; false
/// when xk is not in a cell with a table (BoxAxisTables::at).
template <int D>
bool box_axis(const LatticeAxes<D>& axes, const BoxAxisTables& tables, int k, double xk, int& lo, int& m,
              double* n, double* d, double& lambda) {
  const std::vector<double>& X = axes.coord[k];
  const double inv_h = axes.inv_h[k];
  const double ug = (xk - X.front()) * inv_h;
  if (!(ug >= 0.0)) return false; // below the lattice, or NaN
  const int last = static_cast<int>(X.size()) - 1;
  if (!(ug < last)) return false;
  const int c = static_cast<int>(ug);
  const BoxAxisTable* table = tables.at(c);
  if (!table) return false;
  const double u = std::clamp((xk - X[static_cast<std::size_t>(c)]) * inv_h, 0.0, 1.0);
  int first;
  double L;
  m = table->lookup(u, first, n, d, L, inv_h);
  if (m == 0) return false; // next to the hull's boundary
  lo = c + first;
  lambda = L * inv_h;
  return true;
}

/// The box's stencil from its axes, node ids ascending (axis 0 innermost,
/// stride 1; the last axis outermost): N_I the product of the axes' factors
/// and grad N_I (component k: axis k's derivative times the other axes'
/// factors), written to node, N and dN (D doubles per entry). Axis 0 read
/// through local restrict pointers and the rows written by index: the
/// stores then reload nothing. M0 > 0: axis 0 has M0 lines (a row's loop
/// unrolled, without the set-up of a loop of unknown length); 0: any.
template <int D, int M0>
void write_box(const LatticeAxes<D>& axes, const BoxAxis (&a)[D], int* __restrict node, double* __restrict N,
               double* __restrict dN) {
  const int m0 = M0 > 0 ? M0 : a[0].m, lo0 = a[0].lo;
  const double* __restrict n0 = a[0].n;
  const double* __restrict d0 = a[0].d;
  const int m1 = D > 1 ? a[1 % D].m : 1, m2 = D > 2 ? a[2 % D].m : 1;
  int q = 0;
  for (int i2 = 0; i2 < m2; ++i2) {
    for (int i1 = 0; i1 < m1; ++i1, q += m0) {
      double w = 1.0;               // the product of the factors of axes 1 and 2
      double g[D > 1 ? D : 2] = {}; // their derivatives times the other's factor (entry 0 unused)
      int id = lo0;
      if constexpr (D > 1) {
        const double n1 = a[1 % D].n[i1], d1 = a[1 % D].d[i1];
        const double n2 = D > 2 ? a[2 % D].n[i2] : 1.0, d2 = D > 2 ? a[2 % D].d[i2] : 0.0;
        w = n1 * n2;
        g[1 % D] = d1 * n2;
        if constexpr (D > 2) g[2 % D] = n1 * d2;
        id += (a[1 % D].lo + i1) * axes.stride[1 % D];
        if constexpr (D > 2) id += (a[2 % D].lo + i2) * axes.stride[2 % D];
      }
      int* __restrict row_node = node + q;
      double* __restrict row_N = N + q;
      double* __restrict row_dN = dN + static_cast<std::ptrdiff_t>(q) * D;
      for (int i0 = 0; i0 < m0; ++i0) {
        row_node[i0] = id + i0;
        row_N[i0] = n0[i0] * w;
        row_dN[i0 * D] = d0[i0] * w;
        for (int k = 1; k < D; ++k) row_dN[i0 * D + k] = n0[i0] * g[k];
      }
    }
  }
}

/// write_box with the row length of the common supports fixed (gamma_lme
/// about 1.5 - 6 at the default tolerance: 3 - 7 lines per axis).
template <int D>
void write_box(const LatticeAxes<D>& axes, const BoxAxis (&a)[D], int* node, double* N, double* dN) {
  switch (a[0].m) {
  case 3:
    return write_box<D, 3>(axes, a, node, N, dN);
  case 4:
    return write_box<D, 4>(axes, a, node, N, dN);
  case 5:
    return write_box<D, 5>(axes, a, node, N, dN);
  case 6:
    return write_box<D, 6>(axes, a, node, N, dN);
  case 7:
    return write_box<D, 7>(axes, a, node, N, dN);
  default:
    return write_box<D, 0>(axes, a, node, N, dN);
  }
}

} // namespace

template <int D>
bool box_table_stencil(const LatticeAxes<D>& axes, const BoxTables<D>& tables, const Vec<D>& x,
                       RowTarget<D>& out, Vec<D>& lambda) {
  if (tables.empty()) return false;
  BoxAxis a[D];
  int n = 1;
  for (int k = 0; k < D; ++k) {
    if (!box_axis<D>(axes, *tables.axis[k], k, x[k], a[k].lo, a[k].m, a[k].n, a[k].d, lambda[k]))
      return false;
    n *= a[k].m;
  }
  int* node;
  double* N;
  Vec<D>* dN;
  out.place(n, node, N, dN);
  static_assert(sizeof(Vec<D>) == D * sizeof(double)); // the rows' gradients as D doubles each
  write_box<D>(axes, a, node, N, dN[0].data());
  return true;
}

namespace {
/// The factors of point x (box_table_factor_rows); false when x is not in a
/// cell with a table on every axis.
template <int D>
[[gnu::always_inline]] inline bool box_factors(const LatticeAxes<D>& axes, const BoxTables<D>& tables,
                                               const Vec<D>& x, int lanes, int& base, std::array<int, D>& m,
                                               double* f, Vec<D>& lambda) {
  Vec<D> L;
  int b = 0;
  for (int k = 0; k < D; ++k) {
    int lo;
    if (!box_axis<D>(axes, *tables.axis[k], k, x[k], lo, m[k], f + 2 * k * lanes, f + (2 * k + 1) * lanes,
                     L[k]))
      return false;
    b += lo * axes.stride[k];
  }
  base = b;
  lambda = L;
  return true;
}
} // namespace

template <int D>
int box_table_factor_rows(const LatticeAxes<D>& axes, const BoxTables<D>& tables,
                          const AlignedVector<Vec<D>>& x, int p0, int p1, ProductRows<D>& rows,
                          AlignedVector<Vec<D>>& lambda) {
  if (tables.empty()) return p0;
  for (int p = p0; p < p1; ++p) {
    const auto i = static_cast<std::size_t>(p);
    if (!box_factors<D>(axes, tables, x[i], rows.lanes, rows.base[i], rows.m[i], rows.factors(p), lambda[i]))
      return p;
  }
  return p1;
}

template struct BoxTables<1>;
template struct BoxTables<2>;
template struct BoxTables<3>;
template bool box_table_stencil<1>(const LatticeAxes<1>&, const BoxTables<1>&, const Vec<1>&, RowTarget<1>&,
                                   Vec<1>&);
template bool box_table_stencil<2>(const LatticeAxes<2>&, const BoxTables<2>&, const Vec<2>&, RowTarget<2>&,
                                   Vec<2>&);
template int box_table_factor_rows<1>(const LatticeAxes<1>&, const BoxTables<1>&,
                                      const AlignedVector<Vec<1>>&, int, int, ProductRows<1>&,
                                      AlignedVector<Vec<1>>&);
template int box_table_factor_rows<2>(const LatticeAxes<2>&, const BoxTables<2>&,
                                      const AlignedVector<Vec<2>>&, int, int, ProductRows<2>&,
                                      AlignedVector<Vec<2>>&);
template int box_table_factor_rows<3>(const LatticeAxes<3>&, const BoxTables<3>&,
                                      const AlignedVector<Vec<3>>&, int, int, ProductRows<3>&,
                                      AlignedVector<Vec<3>>&);
template bool box_table_stencil<3>(const LatticeAxes<3>&, const BoxTables<3>&, const Vec<3>&, RowTarget<3>&,
                                   Vec<3>&);

} // namespace otmpm::maxent
