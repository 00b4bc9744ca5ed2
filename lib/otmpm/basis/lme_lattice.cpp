// LME on an untouched Cartesian lattice, factorised over the axes
// (lme_lattice.hpp, docs/theory.md sect. 4.7).
//
// Choices made here
// -----------------
// * The box. Along axis k the lattice lines within R of x_k (so every
//   factor below is bounded as kLatticeMaxExponent says): at most
//   kLatticeMaxSpan lines, else the general path.
// * The support: node I kept when |x - x_I| <= R, row by row: along a row
//   of axis 0 the kept nodes are the interval dx_0^2 <= R^2 - (the other
//   axes' dx^2), counted by comparisons of the box's squared offsets, with
//   no square root and no branch whose outcome varies from row to row. Only
//   a node at the cut-off itself (weight tol) can be decided otherwise than
//   by the general gather, by the rounding of the sum of squares.
// * Exponents per axis: f_k(i) = -beta dx_k(i)^2 + lambda_k dx_k(i), by
//   the recurrence of axis_factors (two exponentials per axis). They are
//   not shifted: see kLatticeMaxExponent for the bounds that keep every
//   weight, Z and N_I positive and finite.
// * Sums about a centre c: Z, m = sum p (dx - c), S = sum p (dx - c)(dx -
//   c)^T; over a row of axis 0 (factor w of the other axes, offsets t_l =
//   dx_l - c_l there) sum p = w sum e_0, sum p t_0 = w sum e_0 t_0, sum p t_0^2
//   = w sum e_0 t_0^2, and every other moment is one of these times t_l or
//   t_l t_m. c = 0 first; J = S / Z - (m / Z)(m / Z)^T is kept under the
//   general solver's kShiftedMomentLimit, else the sums are taken again about
//   c = r (the centred form).
// * Newton: full steps while |s| R <= kSafeExponentChange (the Armijo
//   condition then holds, as in the general solver); anything that needs
//   the line search, a shifted exponent or a diagnosis goes to the general
//   path, which starts again from the same warm start.
#include "otmpm/basis/lme_lattice.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

namespace otmpm::maxent {

template <int D> LatticeAxes<D> LatticeAxes<D>::from(const NodeSet<D>& nodes, double beta) {
  LatticeAxes axes;
  if (!nodes.on_lattice() || !nodes.grid() || nodes.has_absent()) return axes;
  const CartesianGrid<D>& grid = *nodes.grid();
  const Index<D> n = grid.nodes_per_axis();
  const Vec<D> h = grid.h();
  int stride = 1;
  for (int k = 0; k < D; ++k) {
    axes.stride[k] = stride;
    axes.h[k] = h[k];
    axes.inv_h[k] = 1.0 / h[k];
    axes.kappa[k] = std::exp(-2.0 * beta * h[k] * h[k]);
    axes.coord[k].resize(static_cast<std::size_t>(n[k]));
    for (int i = 0; i < n[k]; ++i) axes.coord[k][static_cast<std::size_t>(i)] = nodes.position(i * stride)[k];
    stride *= n[k];
  }
  return axes;
}

namespace {

/// One axis of a point's lattice box: lines lo .. lo + m - 1, offsets dx =
/// x_k - X_k(i), their squares, and the factors e = exp(-beta dx^2 +
/// lambda_k dx).
struct AxisBox {
  int lo, m;
  int mw; ///< m rounded up to a multiple of 4; sq[m .. mw) = NaN (no node: no comparison keeps it)
  double dx[kLatticeMaxSpan];
  double sq[kLatticeMaxSpan];
  double e[kLatticeMaxSpan];
};

/// A row of the support: box indices a .. b along axis 0, at box index o[l]
/// along axis l + 1.
template <int D> struct Row {
  int a, b;
  int o[D > 1 ? D - 1 : 1];
};

template <int D> constexpr int kMaxRows = D == 1 ? 1 : D == 2 ? kLatticeMaxSpan : kLatticeMaxSpan * kLatticeMaxSpan;

/// The box of one point and the rows of its support (n nodes).
template <int D> struct Box {
  AxisBox axis[D];
  Row<D> row[kMaxRows<D>];
  int rows;
  int n;
};

/// Sets up axis k of the box of coordinate xk (false: the general path).
template <int D> bool axis_box(const LatticeAxes<D>& axes, int k, double xk, double R, AxisBox& a) {
  const std::vector<double>& X = axes.coord[k];
  if (!(xk >= X.front() && xk <= X.back())) return false; // outside the lattice, or NaN
  const double u = (xk - X.front()) * axes.inv_h[k], reach = R * axes.inv_h[k];
  if (!(reach < kLatticeMaxSpan)) return false;
  const int last = static_cast<int>(X.size()) - 1;
  // the lines within reach of u, ceil(u - reach) .. floor(u + reach) (both
  // >= 0: truncation is floor), so that every factor of the box obeys the
  // bounds of kLatticeMaxExponent; a node exactly at distance R may fall
  // outside by the rounding of u, as it may by that of |dx|^2 in the
  // general gather
  const double first = std::max(u - reach, 0.0);
  const int c = static_cast<int>(first);
  a.lo = c + (c < first ? 1 : 0);
  const int hi = std::min(last, static_cast<int>(u + reach));
  a.m = hi - a.lo + 1;
  if (a.m < 1 || a.m > kLatticeMaxSpan) return false;
  for (int i = 0; i < a.m; ++i) {
    a.dx[i] = xk - X[static_cast<std::size_t>(a.lo + i)];
    a.sq[i] = a.dx[i] * a.dx[i];
  }
  a.mw = (a.m + 3) & ~3;
  for (int i = a.m; i < a.mw; ++i) a.sq[i] = std::numeric_limits<double>::quiet_NaN(); // never kept
  return true;
}

/// The box indices i in [0, m) with sq[i] <= rest (a node of the row kept
/// when its squared offset along the row's axis fits in what the other axes
/// leave of R^2), as [a, a + len); len = 0 when none. The squared offsets of
/// a box fall and then rise along the axis (the stored lattice coordinates
/// increase, and rounding keeps x - X and its square monotone), so the kept
/// indices are an interval, read off a bit mask of the comparisons (sq
/// padded with NaN to mw, a multiple of 4): no square root, no branch
/// (the row lengths of neighbouring points differ in no pattern a
/// predictor could learn).
inline int row_interval(const double* sq, int mw, double rest, int& a) {
  static_assert(kLatticeMaxSpan % 4 == 0 && kLatticeMaxSpan < 32, "the mask: whole groups of 4 in 32 bits");
  unsigned mask = 0;
  for (int i = 0; i < mw; i += 4) {
    const unsigned four = (sq[i] <= rest ? 1u : 0u) | (sq[i + 1] <= rest ? 2u : 0u) | (sq[i + 2] <= rest ? 4u : 0u) |
                          (sq[i + 3] <= rest ? 8u : 0u);
    mask |= four << i;
  }
  a = std::countr_zero(mask | (1u << kLatticeMaxSpan)); // kLatticeMaxSpan when none
  return std::countr_one(mask >> a);
}

/// Appends the row at box indices o (axes 1 and 2) whose nodes are kept
/// while dx_0^2 <= rest (R^2 less the other axes' squares); an empty row is
/// written and not counted.
template <int D> void add_row(Box<D>& box, double rest, int o1, int o2) {
  Row<D>& r = box.row[box.rows];
  const int len = row_interval(box.axis[0].sq, box.axis[0].mw, rest, r.a);
  r.b = r.a + len - 1;
  if constexpr (D > 1) r.o[0] = o1;
  if constexpr (D > 2) r.o[1] = o2;
  box.n += len;
  box.rows += len > 0 ? 1 : 0;
}

/// The rows of the support of x (whose box is set up): node I kept when
/// |x - x_I|^2 <= R^2, tested as dx_0^2 <= R^2 - (dx_1^2 + dx_2^2) (which
/// node lies at the cut-off can differ from the general gather's by the
/// rounding of that sum, a node of weight ~tol). In 3D each plane of axis 2
/// visits only the rows of axis 1 within its disc.
template <int D> void gather_rows(Box<D>& box, double R2) {
  box.rows = 0;
  box.n = 0;
  if constexpr (D == 1) {
    add_row<D>(box, R2, 0, 0);
  } else if constexpr (D == 2) {
    for (int j = 0; j < box.axis[1].m; ++j) add_row<D>(box, R2 - box.axis[1].sq[j], j, 0);
  } else {
    const AxisBox &a1 = box.axis[1], &a2 = box.axis[2];
    for (int l = 0; l < a2.m; ++l) {
      const double rest = R2 - a2.sq[l];
      int j0 = 0;
      const int rows = row_interval(a1.sq, a1.mw, rest, j0);
      for (int j = j0; j < j0 + rows; ++j) add_row<D>(box, R2 - (a1.sq[j] + a2.sq[l]), j, l);
    }
  }
}

/// The factors e_k(i) = exp(f_k(i)), f_k(i) = -beta dx_k(i)^2 + lambda_k
/// dx_k(i), of every axis, by the recurrence of a quadratic on the lattice:
/// e_k(i + 1) = e_k(i) g_i with g_i = exp(f_k(i + 1) - f_k(i)) and g_{i+1} =
/// g_i kappa_k (the second difference of f_k is -2 beta h_k^2), so two
/// exponentials per axis. The lattice's own spacing h_k stands for the
/// differences of the stored coordinates (equal to round-off): the weights
/// move by a relative ~1e-16 |X| / h, while r and J are summed with the
/// stored offsets, so the constraint sum N_I (x - x_I) = r holds as solved.
template <int D> void axis_factors(Box<D>& box, const LatticeAxes<D>& axes, const Vec<D>& lambda, double beta) {
  double e0[D], g[D];
#pragma GCC unroll 3
  for (int k = 0; k < D; ++k) {
    const AxisBox& a = box.axis[k];
    const double h = axes.h[k], d = a.dx[0];
    e0[k] = -beta * a.sq[0] + lambda[k] * d;
    g[k] = beta * h * (2.0 * d - h) - lambda[k] * h;
  }
#pragma GCC unroll 3
  for (int k = 0; k < D; ++k) {
    e0[k] = std::exp(e0[k]);
    g[k] = std::exp(g[k]);
  }
#pragma GCC unroll 3
  for (int k = 0; k < D; ++k) {
    AxisBox& a = box.axis[k];
    double e = e0[k], gk = g[k];
    const double kappa = axes.kappa[k];
    a.e[0] = e;
    for (int i = 1; i < a.m; ++i) {
      e *= gk;
      gk *= kappa;
      a.e[i] = e;
    }
  }
}

/// The row's factor of the axes other than 0 and its offsets t_l = dx_l - c_l there.
template <int D> double row_factor(const Box<D>& box, const Row<D>& r, const Vec<D>& c, double t[D]) {
  double w = 1.0;
#pragma GCC unroll 2
  for (int l = 1; l < D; ++l) {
    const AxisBox& a = box.axis[l];
    w *= a.e[r.o[l - 1]];
    t[l] = a.dx[r.o[l - 1]] - c[l];
  }
  return w;
}

/// The row sums of moments() in 3D, plane by plane of axis 2 (gather_rows
/// lists the rows so): each plane's rows are summed with the factor and
/// offset of axis 1 only, and the plane's factor and offset of axis 2 are
/// applied once to the plane's six sums (S lower triangle, added to Z, m, S).
template <int D>
void plane_moments(const Box<D>& box, const Vec<D>& c, const double* P0, const double* P1, const double* P2, double& Z,
                   Vec<D>& m, Mat<D>& S) {
  const AxisBox &a1 = box.axis[1], &a2 = box.axis[2];
  int q = 0;
  while (q < box.rows) {
    const int l = box.row[q].o[1];
    double pz = 0.0, pm0 = 0.0, pm1 = 0.0, ps00 = 0.0, ps10 = 0.0, ps11 = 0.0;
    for (; q < box.rows && box.row[q].o[1] == l; ++q) {
      const Row<D>& r = box.row[q];
      const double z0 = P0[r.b + 1] - P0[r.a], z1 = P1[r.b + 1] - P1[r.a], z2 = P2[r.b + 1] - P2[r.a];
      const double w = a1.e[r.o[0]], t1 = a1.dx[r.o[0]] - c[1];
      const double w0 = w * z0, w1 = w * z1;
      pz += w0;
      pm0 += w1;
      ps00 += w * z2;
      pm1 += w0 * t1;
      ps10 += w1 * t1;
      ps11 += w0 * t1 * t1;
    }
    const double e2 = a2.e[l], t2 = a2.dx[l] - c[2], e2t = e2 * t2;
    Z += e2 * pz;
    m[0] += e2 * pm0;
    m[1] += e2 * pm1;
    m[2] += e2t * pz;
    S(0, 0) += e2 * ps00;
    S(1, 0) += e2 * ps10;
    S(1, 1) += e2 * ps11;
    S(2, 0) += e2t * pm0;
    S(2, 1) += e2t * pm1;
    S(2, 2) += e2t * t2 * pz;
  }
}

/// Z = sum p_I, m = sum p_I (dx_I - c), S = sum p_I (dx_I - c)(dx_I - c)^T
/// (lower triangle), row by row (see the file comment); a row's sums along
/// axis 0 are differences of prefix sums (no loop whose length varies from
/// row to row).
template <int D> void moments(const Box<D>& box, const Vec<D>& c, double& Z, Vec<D>& m, Mat<D>& S) {
  const AxisBox& a0 = box.axis[0];
  double P0[kLatticeMaxSpan + 1], P1[kLatticeMaxSpan + 1], P2[kLatticeMaxSpan + 1]; // prefix sums of e, e t, e t^2
  P0[0] = P1[0] = P2[0] = 0.0;
  for (int i = 0; i < a0.m; ++i) {
    const double t = a0.dx[i] - c[0], et = a0.e[i] * t;
    P0[i + 1] = P0[i] + a0.e[i];
    P1[i + 1] = P1[i] + et;
    P2[i + 1] = P2[i] + et * t;
  }
  Z = 0.0;
  m.setZero();
  S.setZero();
  if constexpr (D == 3) {
    plane_moments(box, c, P0, P1, P2, Z, m, S);
    return;
  }
  for (int q = 0; q < box.rows; ++q) {
    const Row<D>& r = box.row[q];
    const double z0 = P0[r.b + 1] - P0[r.a], z1 = P1[r.b + 1] - P1[r.a], z2 = P2[r.b + 1] - P2[r.a];
    double t[D];
    const double w = row_factor<D>(box, r, c, t);
    const double w0 = w * z0, w1 = w * z1;
    Z += w0;
    m[0] += w1;
    S(0, 0) += w * z2;
#pragma GCC unroll 2
    for (int l = 1; l < D; ++l) {
      m[l] += w0 * t[l];
      S(l, 0) += w1 * t[l];
#pragma GCC unroll 2
      for (int k = 1; k <= l; ++k) S(l, k) += w0 * t[l] * t[k];
    }
  }
}

/// Z, r and J at the current factors (molinos eqs. 38-40); false when not
/// finite.
template <int D> bool dual_sums(const Box<D>& box, double& Z, Vec<D>& r, Mat<D>& J) {
  Vec<D> m;
  Mat<D> S;
  moments<D>(box, Vec<D>::Zero(), Z, m, S);
  if (!(Z > 0.0 && std::isfinite(Z))) return false;
  const double inv_Z = 1.0 / Z;
  r = m * inv_Z;
  bool small = true;
  for (int k = 0; k < D; ++k) {
    for (int l = 0; l <= k; ++l) J(k, l) = J(l, k) = S(k, l) * inv_Z - r[k] * r[l];
    small = small && r[k] * r[k] <= kShiftedMomentLimit * J(k, k);
  }
  if (!small) { // the centred form: sums about c = r
    double Zc;
    Vec<D> mc;
    moments<D>(box, r, Zc, mc, S);
    const Vec<D> mean = mc / Zc;
    for (int k = 0; k < D; ++k)
      for (int l = 0; l <= k; ++l) J(k, l) = J(l, k) = S(k, l) / Zc - mean[k] * mean[l];
  }
  return r.allFinite() && J.allFinite();
}

/// Writes the stencil of the converged state (N_I = p_I / Z, grad N_I =
/// -N_I J^{-1} (dx_I - r)). Every N_I is positive and finite by the bounds
/// of lattice_solve (no test per node).
template <int D>
void write_stencil(const LatticeAxes<D>& axes, const Box<D>& box, double Z, const Vec<D>& r, const Mat<D>& J_inv,
                   RowTarget<D>& out) {
  int* node;
  double* N;
  Vec<D>* dN;
  out.place(box.n, node, N, dN);
  const AxisBox& a0 = box.axis[0];
  const double inv_Z = 1.0 / Z;
  double N0[kLatticeMaxSpan];
  Vec<D> g0[kLatticeMaxSpan]; // J^{-1} e_0 (dx_0 - r_0)
  for (int i = 0; i < a0.m; ++i) {
    N0[i] = a0.e[i] * inv_Z;
    g0[i] = J_inv.col(0) * (a0.dx[i] - r[0]);
  }
  for (int q = 0; q < box.rows; ++q) {
    const Row<D>& row = box.row[q];
    double t[D];
    const double w = row_factor<D>(box, row, r, t);
    Vec<D> g = Vec<D>::Zero(); // J^{-1} (dx - r) of the axes other than 0
    int id = a0.lo;
#pragma GCC unroll 2
    for (int l = 1; l < D; ++l) {
      g += J_inv.col(l) * t[l];
      id += (box.axis[l].lo + row.o[l - 1]) * axes.stride[l];
    }
    const int len = row.b - row.a + 1;
    const double* n0 = N0 + row.a;
    const Vec<D>* gr = g0 + row.a;
    for (int i = 0; i < len; ++i) {
      const double Ni = n0[i] * w;
      node[i] = id + row.a + i;
      N[i] = Ni;
      dN[i] = -Ni * (gr[i] + g);
    }
    node += len;
    N += len;
    dN += len;
  }
}

} // namespace

template <int D>
bool lattice_solve(const LatticeAxes<D>& axes, const GaussianPrior<D>& prior, const NewtonSettings& set,
                   const Vec<D>& x, const Vec<D>& lambda0, RowTarget<D>& out, LatticeSolve<D>& res) {
  const double R = set.support_radius;
  if (!(prior.max_exponent <= kLatticeMaxExponent2)) return false;
  Box<D> box; // filled below (no value-initialisation of the arrays)
  for (int k = 0; k < D; ++k)
    if (!axis_box<D>(axes, k, x[k], R, box.axis[k])) return false;
  gather_rows<D>(box, R * R);
  if (box.n < D + 1) return false;
  Vec<D> lambda = lambda0;
  ScaledInverse<D> inv;
  for (int it = 0;; ++it) {
    // the bounds that keep every weight and N_I positive and finite (see
    // kLatticeMaxExponent; |lambda| R compared squared, without a root)
    const double l2 = lambda.squaredNorm();
    if (!(l2 * (R * R) <= kLatticeMaxExponent * kLatticeMaxExponent && l2 <= 4.0 * kLatticeMaxExponent2 * prior.beta))
      return false;
    axis_factors<D>(box, axes, lambda, prior.beta);
    double Z;
    Vec<D> r;
    Mat<D> J;
    if (!dual_sums<D>(box, Z, r, J)) return false;
    inv.compute(J);
    if (!(inv.lambda_min > kSingularHessian)) return false;
    if (r.norm() <= set.residual_tolerance) {
      res.lambda = lambda;
      res.J_inv = inv.inverse();
      res.r = r;
      res.iterations = it;
      write_stencil<D>(axes, box, Z, r, res.J_inv, out);
      return true;
    }
    if (it >= set.max_iterations) return false;
    const Vec<D> step = -inv.solve(r);
    if (!(step.norm() * R <= kSafeExponentChange)) return false;
    lambda += step;
  }
}

template struct LatticeAxes<1>;
template struct LatticeAxes<2>;
template struct LatticeAxes<3>;
template bool lattice_solve<1>(const LatticeAxes<1>&, const GaussianPrior<1>&, const NewtonSettings&, const Vec<1>&,
                               const Vec<1>&, RowTarget<1>&, LatticeSolve<1>&);
template bool lattice_solve<2>(const LatticeAxes<2>&, const GaussianPrior<2>&, const NewtonSettings&, const Vec<2>&,
                               const Vec<2>&, RowTarget<2>&, LatticeSolve<2>&);
template bool lattice_solve<3>(const LatticeAxes<3>&, const GaussianPrior<3>&, const NewtonSettings&, const Vec<3>&,
                               const Vec<3>&, RowTarget<3>&, LatticeSolve<3>&);

} // namespace otmpm::maxent
