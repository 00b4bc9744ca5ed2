#pragma once
/// \file lme.hpp
/// Internal declarations of the two maximum-entropy families (docs/theory.md
/// sect. 4): local max-ent (LME, Arroyo & Ortiz 2006, molinos
/// sect. 2.3) and max-ent with a cubic-spline prior (wobbes sect. 6.3). Both are
///
///     N_I(x) = w_I(x) exp(lambda . (x - x_I)) / Z(x, lambda),
///     Z = sum_J w_J(x) exp(lambda . (x - x_J)),
///
/// with lambda(x) the minimiser of the convex log Z (molinos eqs. 36-39,
/// wobbes eqs. 80-83); they differ only in the prior w_I. One class template,
/// MaxEntBasis<D, Prior>, and one Newton solver serve both. Use
/// make_lme_basis / make_maxent_basis (families.hpp); this header is for the
/// implementation and its tests.
#include "otmpm/basis/basis.hpp"
#include "otmpm/basis/simd.hpp"

#include <Eigen/LU>

#include <bit>
#include <cmath>
#include <limits>

#include <array>
#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

namespace otmpm::maxent {

/// e^x for the shifted exponents x <= 0 of dual_state, within 2 ulp of the
/// exact value (x >= -708; below, where e^x < 3e-308, libm takes over): one
/// lane of simd::exp_shifted (Cody-Waite reduction x = k ln 2 + r,
/// |r| <= ln 2 / 2, the degree-13 Taylor polynomial of e^r, truncation
/// < 5e-18 relative, then 2^k built in the exponent bits). The solver uses
/// the four-lane kernel directly.
inline double exp_shifted(double x) {
  if (!(x >= simd::exp_lowest)) return std::exp(x);
  return simd::exp_shifted(simd::broadcast(x))[0];
}

/// The LME prior w_I = exp(-beta |x - x_I|^2) (molinos eq. 36), cut off where
/// w_I < tol, i.e. beyond R = sqrt(-ln(tol) / beta) = h sqrt(-ln(tol) / gamma_lme)
/// (molinos sect. 2.3). With this prior the gradient has the closed form
/// grad N_I = -N_I J^{-1} (x - x_I) (Arroyo & Ortiz 2006, molinos eq. 42).
template <int D> struct GaussianPrior {
  /// Marks the prior whose log-gradient is -2 beta (x - x_I), which lets the
  /// gradient use the closed LME form.
  static constexpr bool kGaussian = true;
  double beta = 1.0;       ///< beta = gamma_lme / h^2
  double max_exponent = 1; ///< -ln(tol): node kept while beta |x - x_I|^2 <= -ln(tol)
  /// The box support (lme_box.hpp): node kept while beta dx_k^2 <= -ln(tol)
  /// on every axis k instead of beta |dx|^2 <= -ln(tol).
  bool box = false;

  /// Support radius: R = sqrt(-ln(tol) / beta), sqrt(D) R for the box.
  double support_radius() const;
  /// log w_I for dx = x - x_I; false when the node lies outside the support.
  bool log_weight(const Vec<D>& dx, double& log_w) const { return log_weight(dx, log_w, max_exponent); }
  /// log_weight with the cut-off exponent `cut` in place of -ln(tol) (a
  /// widened support).
  bool log_weight(const Vec<D>& dx, double& log_w, double cut) const;
  /// grad_x log w_I = -2 beta dx.
  Vec<D> grad_log_weight(const Vec<D>& dx) const { return -2.0 * beta * dx; }
};

/// The cubic-spline prior of wobbes eq. 89, w_I = w(|x - x_I| / d) with support
/// radius d = d_max * h (wobbes eqs. 87-88 with zeta_I = h, the initial nodal
/// spacing, for every node).
template <int D> struct CubicSplinePrior {
  static constexpr bool kGaussian = false;

  CubicSplinePrior() = default;
  /// The prior of support radius d = d_max * h.
  explicit CubicSplinePrior(double radius) : d(radius), inv_d(1.0 / radius), inv_d2(1.0 / (radius * radius)) {}
  double support_radius() const { return d; }
  /// r = |dx| / d, formed as |dx| times 1 / d (one rounding more than the
  /// quotient: within 1.5 ulp of |dx| / d; a division per node was a fifth
  /// of the gather), |dx| as |dx_0| in 1D (sqrt(dx_0^2) rounds to it
  /// exactly while dx_0^2 neither underflows nor overflows).
  double normalised_radius(const Vec<D>& dx) const {
    if constexpr (D == 1) return std::abs(dx[0]) * inv_d;
    return dx.norm() * inv_d;
  }
  /// log w_I for dx = x - x_I; false when |dx| >= d (w_I = 0).
  bool log_weight(const Vec<D>& dx, double& log_w) const;
  /// w_I itself (no logarithm) and the factor c_I of grad_x log w_I = c_I dx,
  /// from one r and one w(r): w the bits of cubic_spline(r), c_I dx the bits
  /// of grad_log_weight(dx). False when |dx| >= d (w_I = 0). The basis forms
  /// both while gathering the support.
  bool weight(const Vec<D>& dx, double& w, double& grad_factor) const;
  /// grad_x log w_I = w'(r) / (w(r) r) dx / d^2, r = |dx| / d < 1.
  Vec<D> grad_log_weight(const Vec<D>& dx) const;

private:
  double d = 1.0;      ///< support radius d_max * h
  double inv_d = 1.0;  ///< 1 / d
  double inv_d2 = 1.0; ///< 1 / d^2
};

constexpr double kSplineInner = 0.5;            ///< r where the two cubic pieces meet
constexpr double kSplineCentre = 2.0 / 3.0;     ///< w(0)
constexpr double kSplineOuterFactor = 4.0 / 3.0; ///< w = 4/3 (1 - r)^3 for 1/2 < r < 1

/// The cubic spline of wobbes eq. 89 at normalised radius r >= 0 (zero for r
/// >= 1). Inline, as the prior's functions below: they run once per support
/// node of every evaluation.
inline double cubic_spline(double r) {
  if (r <= kSplineInner) return kSplineCentre - 4.0 * r * r + 4.0 * r * r * r;
  if (r < 1.0) return kSplineOuterFactor * (1.0 - r) * (1.0 - r) * (1.0 - r);
  return 0.0;
}
/// Its derivative dw/dr.
inline double cubic_spline_derivative(double r) {
  if (r <= kSplineInner) return -8.0 * r + 12.0 * r * r;
  if (r < 1.0) return -4.0 * (1.0 - r) * (1.0 - r);
  return 0.0;
}

template <int D> inline bool CubicSplinePrior<D>::log_weight(const Vec<D>& dx, double& log_w) const {
  const double r = normalised_radius(dx);
  if (!(r < 1.0)) return false;
  const double w = cubic_spline(r);
  if (!(w > 0.0)) return false;
  log_w = std::log(w);
  return true;
}

template <int D> inline bool CubicSplinePrior<D>::weight(const Vec<D>& dx, double& w, double& grad_factor) const {
  const double r = normalised_radius(dx);
  if (!(r < 1.0)) return false;
  w = cubic_spline(r);
  if (!(w > 0.0)) return false;
  // as in grad_log_weight, with the w(r) already formed
  const double factor = r <= kSplineInner ? (-8.0 + 12.0 * r) / w : -3.0 / ((1.0 - r) * r);
  grad_factor = factor * inv_d2;
  return true;
}

template <int D> inline Vec<D> CubicSplinePrior<D>::grad_log_weight(const Vec<D>& dx) const {
  const double r = normalised_radius(dx);
  // d log w / dr / r, written so that r -> 0 is regular (w'(r)/r = -8 + 12 r).
  const double factor = r <= kSplineInner ? (-8.0 + 12.0 * r) / cubic_spline(r) : -3.0 / ((1.0 - r) * r);
  return (factor * inv_d2) * dx;
}

template <int D> inline bool GaussianPrior<D>::log_weight(const Vec<D>& dx, double& log_w, double cut) const {
  const double e = beta * dx.squaredNorm();
  if (!(box ? beta * dx.cwiseAbs2().maxCoeff() <= cut : e <= cut)) return false;
  log_w = -e;
  return true;
}

/// J singular when the smallest eigenvalue of the diagonally scaled J (unit
/// diagonal) is below this (~500 eps: round-off of a degenerate J is ~D eps).
inline constexpr double kSingularHessian = 1e-13;
/// A Newton step s with max_I |s.(x - x_I)| <= this satisfies the Armijo
/// condition without evaluating log Z: with u_I = s.(x - x_I), E_N[u] = r.s =
/// -delta^2 and Var_N[u] = s^T J s = delta^2, so by e^v <= 1 + v + v^2 e^|v| / 2
/// (v = u - E u, |v| <= 0.5), log Z change <= -delta^2 + delta^2 e^0.5 / 2
/// = -0.18 delta^2 <= kArmijo r.s (kArmijo = 1e-4). Saves the exp pass in the quadratic phase.
inline constexpr double kSafeExponentChange = 0.25;
/// J = S / Z - m m^T from moments about c (see Moments) is kept when every
/// m_k^2 <= kShiftedMomentLimit J_kk: the subtraction then costs at most
/// kShiftedMomentLimit relative accuracy (well below round-off effects that
/// matter); otherwise J is recomputed in the centred form.
inline constexpr double kShiftedMomentLimit = 1e-3;

/// J^{-1} and the smallest eigenvalue of the symmetric diagonal scaling Js
/// = S J S, S = diag(J_kk^{-1/2}) (unit diagonal): in 2D and 3D from the
/// adjugate of J over det J, without forming Js (compute_2d, compute_3d),
/// else (and for J of extreme size) through the closed-form inverse of Js
/// (compute_scaled). Js is what decides whether J^{-1} can be computed: J's
/// entries are sums of non-negative terms (relative accuracy ~ n eps), so a J
/// that is tiny only along an axis (a point next to a face of a box) is
/// harmless, whereas a small eigenvalue of Js (degenerate nodes, the iterates
/// leaving the hull through a slanted face) is not.
template <int D> struct ScaledInverse {
  /// J^{-1} (valid when lambda_min > 0).
  Mat<D> J_inv = Mat<D>::Identity();
  /// 1 / tr(Js^{-1}), within a factor D of the smallest eigenvalue of Js; 0
  /// when J is not positive definite.
  double lambda_min = 0.0;

  void compute(const Mat<D>& J) {
    lambda_min = 0.0;
    const Vec<D> d = J.diagonal();
    if (!(d.minCoeff() > 0.0) || !d.allFinite()) return;
    if constexpr (D == 1) {
      J_inv(0, 0) = 1.0 / d[0]; // Js = 1
      lambda_min = 1.0;
      return;
    } else if constexpr (D == 2) {
      if (compute_2d(J)) return;
    } else if constexpr (D == 3) {
      if (compute_3d(J)) return;
    }
    compute_scaled(J);
  }
  /// The general form: Js formed with the square roots of the diagonal
  /// (compute takes it where the closed forms below decline; the tests
  /// compare those with it). Call with J_kk > 0 and finite.
  void compute_scaled(const Mat<D>& J) {
    lambda_min = 0.0;
    const Vec<D> s = J.diagonal().cwiseSqrt().cwiseInverse();
    const Mat<D> Js = s.asDiagonal() * J * s.asDiagonal();
    const double det = Js.determinant();
    if (!(det > 0.0)) return;
    if constexpr (D == 3) // Sylvester: the leading 2 x 2 minor must be positive too
      if (!(1.0 - Js(0, 1) * Js(0, 1) > 0.0)) return;
    const Mat<D> Js_inv = Js.inverse();
    const double trace_inv = Js_inv.trace();
    if (!(trace_inv > 0.0 && std::isfinite(trace_inv))) return;
    lambda_min = 1.0 / trace_inv;
    J_inv = s.asDiagonal() * Js_inv * s.asDiagonal();
  }
  /// 2D without square roots: Js = [1 rho; rho 1] with rho^2 = J01^2 /
  /// (J00 J11), det Js = 1 - rho^2, 1 / tr(Js^{-1}) = det Js / 2 and
  /// J^{-1} = adj(J) / (J00 J11 det Js). False (nothing set) when J00 J11 is
  /// not a normal number, where the general path is safer.
  bool compute_2d(const Mat<D>& J) {
    const double ab = J(0, 0) * J(1, 1), c = J(0, 1);
    if (!(ab >= std::numeric_limits<double>::min() * 1e8 && std::isfinite(ab))) return false;
    const double det = 1.0 - c * c / ab;
    if (!(det > 0.0)) return true; // not positive definite: lambda_min stays 0
    lambda_min = 0.5 * det;
    const double f = 1.0 / (ab * det);
    J_inv(0, 0) = J(1, 1) * f;
    J_inv(1, 1) = J(0, 0) * f;
    J_inv(0, 1) = J_inv(1, 0) = -c * f;
    return true;
  }
  /// 3D without square roots, from the cofactors C of J: det Js = det J /
  /// (J00 J11 J22), the leading 2 x 2 minor of Js is C22 / (J00 J11),
  /// (Js^{-1})_kk = J_kk C_kk / det J, so 1 / tr(Js^{-1}) = det J / sum_k
  /// J_kk C_kk, and J^{-1} = C / det J (C symmetric). False (nothing set)
  /// unless every J_kk lies in [1e-90, 1e90], where the scaled form is
  /// safer: within it the products of three diagonal entries are normal with
  /// 38 decades to spare for cancellation. Positive definite (Sylvester):
  /// J00 > 0 (the caller's test), C22 > 0 and det J > 0; det J may come out
  /// +inf (an off-diagonal entry whose products overflow), and then the
  /// test of the trace, finite and > 0, refuses J: a positive trace bounds
  /// every |J_kl| by sqrt(3 J_kk J_ll), within which nothing overflows.
  bool compute_3d(const Mat<D>& J) {
    const double a00 = J(0, 0), a11 = J(1, 1), a22 = J(2, 2), a01 = J(1, 0), a02 = J(2, 0), a12 = J(2, 1);
    constexpr double lo = 1e-90, hi = 1e90;
    if (!(a00 >= lo && a00 <= hi && a11 >= lo && a11 <= hi && a22 >= lo && a22 <= hi)) return false;
    const double c00 = a11 * a22 - a12 * a12, c11 = a00 * a22 - a02 * a02, c22 = a00 * a11 - a01 * a01;
    const double c01 = a02 * a12 - a01 * a22, c02 = a01 * a12 - a02 * a11, c12 = a01 * a02 - a00 * a12;
    const double det = a00 * c00 + a01 * c01 + a02 * c02;
    if (!(det > 0.0 && c22 > 0.0)) return true; // not positive definite: lambda_min stays 0
    const double trace = a00 * c00 + a11 * c11 + a22 * c22; // det J tr(Js^{-1})
    if (!(trace > 0.0 && std::isfinite(trace))) return true;
    lambda_min = det / trace;
    const double f = 1.0 / det;
    J_inv(0, 0) = c00 * f;
    J_inv(1, 1) = c11 * f;
    J_inv(2, 2) = c22 * f;
    J_inv(0, 1) = J_inv(1, 0) = c01 * f;
    J_inv(0, 2) = J_inv(2, 0) = c02 * f;
    J_inv(1, 2) = J_inv(2, 1) = c12 * f;
    return true;
  }
  Vec<D> solve(const Vec<D>& b) const { return J_inv * b; }
  const Mat<D>& inverse() const { return J_inv; }
};

/// The support of one point in structure-of-arrays form (simd kernels):
/// offsets dx[k][i] = (x - x_I)_k and log-priors log_w[i] = log w_I for the n
/// support nodes, padded to n_pad = simd::padded(n) entries with dx = 0 and
/// log_w = -inf (N = 0 there); and two buffers of n_pad values for the
/// weights p_I = Z N_I (the current state and a trial state of the line
/// search; the solver swaps them on acceptance). For a prior other than the
/// Gaussian the priors are held as w[i] = w_I itself (padding 0) and log_w is
/// null: p_I = w_I exp(lambda . dx_I) needs no logarithm per node (formed
/// where the rare shifted or line-search paths need log w_I); and
/// grad_factor[i] = c_I, grad_x log w_I = c_I dx_I (CubicSplinePrior::weight).
template <int D> struct Support {
  const double* dx[D];
  const double* log_w; ///< log w_I (Gaussian prior), else null
  const double* w;     ///< w_I (other priors), else null
  const double* grad_factor;
  int n;
  int n_pad;
  double radius; ///< bound on |x - x_I| over the support (the support radius R)
  double* p;     ///< weights p_I at the current lambda
  double* trial; ///< scratch of the same length
  Vec<D> offset(int i) const {
    Vec<D> d;
    for (int k = 0; k < D; ++k) d[k] = dx[k][i];
    return d;
  }
};

/// Why a Newton solve for lambda stopped.
enum class NewtonStatus {
  converged,      ///< |r| <= newton_tolerance * h
  singular,       ///< J not positive definite, or diag-scaled J with smallest eigenvalue <= 1e-13
  diverged,       ///< lambda or the exponents stopped being finite
  stalled,        ///< the backtracking line search found no decrease of log Z
  max_iterations, ///< not converged within max_newton_iterations
};

/// Settings of the Newton solve for lambda (docs/theory.md sect. 4).
struct NewtonSettings {
  double h = 1.0;                  ///< the nodal spacing h of beta = gamma_lme / h^2
  double residual_tolerance = 0.0; ///< converged when |r| <= residual_tolerance (= tol * h)
  int max_iterations = 100;
  double support_radius = 1.0;     ///< R: nodes farther than R from x are not in the sum
};

/// State of the dual problem at one lambda: gradient r = d log Z / d lambda and
/// Hessian J = d^2 log Z / d lambda^2 (molinos eqs. 38-40).
template <int D> struct NewtonState {
  Vec<D> r = Vec<D>::Zero();
  Mat<D> J = Mat<D>::Zero();
  /// The solver keeps unnormalised weights p_I = N_I Z with Z = sum p_I; log Z
  /// at lambda is log_base + log(Z), log_base the shift of the exponents at
  /// the last full evaluation (formed only when the line search needs it).
  double log_base = 0.0;
  double Z = 1.0;
  /// J^{-1} at a converged lambda (for the gradients).
  Mat<D> J_inv = Mat<D>::Zero();
  /// 1 / tr(Js^{-1}) of the diagonally scaled Js = S J S (unit diagonal), within
  /// a factor D of its smallest eigenvalue; 0 when J is not positive definite.
  double lambda_min = 0.0;
  int iterations = 0;
  NewtonStatus status = NewtonStatus::max_iterations;
  double log_Z() const { return log_base + std::log(Z); }
};

/// How the locality of the LME prior adapts (BasisOptions::metric,
/// docs/theory.md sect. 4.6).
enum class Metric {
  isotropic,    ///< beta = gamma_lme / h^2 for every point and node
  deformation,  ///< beta_p = gamma_lme / h^2 M_p, M_p = (F_p F_p^T)^-1 scaled to det 1
  node_spacing, ///< beta_I = gamma_lme / h_I^2, h_I = distance from node I to its nearest node
};

/// The metric named `name` ("isotropic", "deformation", "node_spacing");
/// InputError naming `kind` and the choices otherwise.
Metric parse_metric(const std::string& name, std::string_view kind);

/// The prior of one point under Metric::deformation: w_I = exp(-dx^T B dx),
/// B = beta M_p, nodes kept while dx^T B dx <= -ln(tol); every such node lies
/// within `radius` of the point. `isotropic` when M_p = I exactly (the
/// isotropic code path, bit for bit).
template <int D> struct PointMetric {
  bool isotropic = true;
  Mat<D> B = Mat<D>::Identity();
  double radius = 0.0;
};

template <int D> struct RowTarget; // lme_lattice.hpp: where the factorised path writes a stencil
template <int D> struct BoxTables; // lme_box.hpp: the tables of the box support's 1D functions

/// The nodes of an untouched Cartesian lattice axis by axis: node
/// (i_0, ..., i_{D-1}) has id sum_k i_k stride[k] and the position
/// (coord[0][i_0], ..., coord[D-1][i_{D-1}]), read from the stored positions
/// bit for bit.
template <int D> struct LatticeAxes {
  std::vector<double> coord[D];
  int stride[D] = {};
  double h[D] = {};     ///< lattice spacing along each axis
  double inv_h[D] = {}; ///< 1 / h
  /// exp(-2 beta h^2): the ratio of two successive ratios of the prior
  /// exp(-beta dx^2) along axis k (the second difference of -beta dx^2 is
  /// -2 beta h^2).
  double kappa[D] = {};
  /// Reads the axes of `nodes` when they sit on their lattice (kappa for
  /// the prior's `beta`); empty (nothing to factorise) otherwise.
  static LatticeAxes from(const NodeSet<D>& nodes, double beta);
  bool empty() const { return coord[0].empty(); }
};

extern template struct LatticeAxes<1>;
extern template struct LatticeAxes<2>;
extern template struct LatticeAxes<3>;

/// A maximum-entropy basis with prior `Prior` bound to a node set (see file
/// comment). evaluate() finds the support by NodeSet::within (or the point's
/// Verlet list), solves for lambda by the shared Newton solver and returns
/// N_I and grad N_I; with the isotropic Gaussian prior on nodes that sit on
/// their lattice it first tries the factorised path (lattice_solve,
/// lme_lattice.hpp). Thread-safe; no allocation per evaluation once the
/// Stencil buffers have grown.
template <int D, class Prior> class MaxEntBasis final : public Basis<D> {
public:
  /// Throws InputError for fewer than D + 1 nodes, newton_tolerance not finite
  /// and > 0, max_newton_iterations < 1 or a prior whose support radius is not
  /// finite and > 0.
  /// A metric other than isotropic needs the Gaussian prior (LME).
  MaxEntBasis(NodeSet<D> nodes, const BasisOptions& opt, const Prior& prior, std::string_view kind,
              Metric metric = Metric::isotropic);

  std::string_view kind() const override { return kind_; }
  const NodeSet<D>& nodes() const override { return nodes_; }
  NodeSet<D>& nodes() override { return nodes_; }
  void nodes_moved(const AlignedVector<Vec<D>>& dx) override;
  void evaluate(const PointQuery<D>& q, Stencil<D>& out) const override;
  /// While the nodes sit on their lattice and the prior is the Gaussian:
  /// the factorised path can write rows in place.
  bool writes_in_place() const override { return Prior::kGaussian && !lattice_.empty() && nodes_.on_lattice(); }
  /// evaluate() with the factorised path writing straight into the table
  /// row when its stencil fits in `room` (see evaluate_on_lattice).
  int evaluate_into(const PointQuery<D>& q, int room, int* node, double* N, Vec<D>* dN,
                    Stencil<D>& st) const override;
  /// lme_box on its untouched lattice: the product rows of the points
  /// (box_table_factor_rows; each point's multiplier stored as evaluate_points
  /// stores it). False when the box has no tables, the points keep more
  /// state than the multiplier, or a point lies where no table reaches.
  bool evaluate_product_rows(const AlignedVector<Vec<D>>& x, ProductRows<D>& rows) override;
  bool linearly_complete() const override { return true; }
  int max_stencil() const override;
  double search_radius() const override { return settings_.support_radius; }
  long long widened_supports() const override { return widened_.load(std::memory_order_relaxed); }
  long long moved_points() const override { return moved_.load(std::memory_order_relaxed); }
  /// The Lagrange multiplier of each point warm-starts its next solve, and
  /// while the nodes stay fixed its slope (MultiplierSlope) turns that into
  /// the Taylor prediction for the point's new position; while they move,
  /// the multipliers of the solves before (MultiplierHistory) into the
  /// extrapolation over the steps; the deformation metric reads the points'
  /// deformation gradients.
  /// The box support (lme_box) keeps no slope: on its lattice the table
  /// needs no start, and the cells next to the lattice's end that the
  /// Newton solve takes start from the multiplier alone.
  PointStateUse point_state_use(bool nodes_move) const override {
    return {.lambda = true,
            .slope = !nodes_move && !box_support(),
            .history = nodes_move,
            .deformation = metric_ == Metric::deformation};
  }
  /// True for the Gaussian prior with the box support (lme_box.hpp).
  bool box_support() const {
    if constexpr (Prior::kGaussian)
      return prior_.box;
    else
      return false;
  }

  /// The start of the solve at q.x: the Taylor prediction *q.lambda + G (x -
  /// x0) (eq. 4.7a), with the second-order term of eq. 4.7b when q.x - x0
  /// continues the slope's last displacement e, when q carries a slope; the
  /// extrapolation of eq. 4.7c when q carries a history; else *q.lambda
  /// (zero when absent or not finite).
  Vec<D> warm_start(const PointQuery<D>& q) const;
  const Prior& prior() const { return prior_; }
  Metric metric() const { return metric_; }
  /// Metric::node_spacing: beta_I of each node (empty otherwise).
  const std::vector<double>& node_beta() const { return node_beta_; }
  /// The prior of the point with deformation gradient F (Metric::deformation);
  /// BasisError naming `q` when F F^T is not finite and positive definite.
  PointMetric<D> point_metric(const PointQuery<D>& q, const Mat<D>& F) const;

protected:
  /// No state of its own: refreshes the search index and stencil bound after
  /// the node positions were restored from a checkpoint.
  void restore_family_state(const StateGroup&) override { nodes_moved({}); }

private:
  /// Gathers the support of x: node ids into out.node, the offsets x - x_I,
  /// log w_I (Gaussian prior) or w_I and the gradient factors c_I (other
  /// priors) into out.scratch_w in the layout of support(), and the per-axis
  /// extent [lo, hi] of the offsets. Returns the stride of the arrays in
  /// out.scratch_w (simd::padded(candidates); the buffer may be longer).
  /// `radius`: every support node lies within it; `prior_value(I, dx, v, c)`
  /// sets v = log w_I (Gaussian) or v = w_I and c = c_I, grad log w_I = c_I
  /// dx (other priors), and says whether node I is in the support.
  template <class PriorValue>
  int gather_support(const PointQuery<D>& q, double radius, const PriorValue& prior_value, Stencil<D>& out,
                      Vec<D>& lo, Vec<D>& hi) const;
  /// gather_support with the prior of the metric (pm: Metric::deformation),
  /// over `widen` times the radius of the prior's cut-off.
  int gather_metric_support(const PointQuery<D>& q, const PointMetric<D>& pm, Stencil<D>& out, Vec<D>& lo,
                             Vec<D>& hi, double widen = 1.0) const;
  /// Metric::node_spacing: h_I, beta_I and the search radius of the current
  /// node positions (on an untouched lattice h_I = h for every node).
  void update_node_spacing();
  /// The Gaussian prior: lattice_ from the current node positions, and the
  /// box support's tables the first time the nodes sit on their lattice.
  void read_lattice();
  /// The Gaussian prior's part of update_node_spacing (nothing for another prior).
  void update_beta_by_spacing();
  /// True when every support node of `out` has the same beta_I (or the
  /// metric does not vary beta by node): the closed-form LME gradient holds.
  bool uniform_beta(const Stencil<D>& out) const;
  /// The Support view of out.scratch_w after gather_support: D arrays of
  /// offsets, log w_I or w_I, the gradient factors c_I, N_I and a trial buffer,
  /// each of `stride` doubles (gather_support's; kScratchArrays in all).
  Support<D> support(Stencil<D>& out, int stride) const;
  /// True when x lies within the bounding box of its n support nodes
  /// (offsets x - x_I within [lo, hi] per axis).
  bool within_extent(int n, const Vec<D>& lo, const Vec<D>& hi) const;
  /// Throws unless within_extent.
  void check_extent(const PointQuery<D>& q, int n, const Vec<D>& lo, const Vec<D>& hi) const;
  /// Fills out.N and out.dN from the converged state (and removes nodes with
  /// N_I = 0); `closed_form`: the Gaussian prior with one beta (matrix) for
  /// the whole support, grad N_I = -N_I J^{-1} (xbar - x_I). Returns
  /// J^{-1} (I + A) (see general_gradient; A = -2 B J in the closed form,
  /// where it is not formed and J^{-1} is returned): the multiplier's slope
  /// is its negative (MultiplierSlope).
  Mat<D> finish_stencil(const NewtonState<D>& st, const Support<D>& s, bool closed_form, Stencil<D>& out) const;
  /// grad N_I = N_I (g_I - gbar - (I + A^T) J^{-1} (xbar - x_I)) with g_I =
  /// grad_log(i) (see the file comment), after out.N was filled. Returns
  /// J^{-1} (I + A) = -d lambda / d x.
  template <class GradLog>
  Mat<D> general_gradient(const NewtonState<D>& st, const Support<D>& s, const GradLog& grad_log,
                          Stencil<D>& out) const;
  /// 2 B, the Hessian of -log w_I of the Gaussian prior on the support of
  /// `out` (B = beta I, pm.B under Metric::deformation, beta_I I under
  /// Metric::node_spacing); call only where the closed form holds.
  Mat<D> prior_hessian(const PointMetric<D>& pm, const Stencil<D>& out) const { return prior_hessian(pm, out.node[0]); }
  /// prior_hessian for a support whose first node is `first` (the beta_I
  /// of Metric::node_spacing).
  Mat<D> prior_hessian(const PointMetric<D>& pm, int first) const;
  /// evaluate() with the factorised path writing to `target`; the general
  /// solver fills *target.stencil. True when the factorised path took the
  /// point.
  bool evaluate_to(const PointQuery<D>& q, RowTarget<D>& target) const;
  /// A point q outside the hull of the nodes of `support` (the widest support
  /// tried): evaluated instead at the farthest point towards q on the segment
  /// from their centroid whose solve converges, into `target`; *q.moved gets
  /// the displacement (docs/theory.md sect. 4.8). BasisError when even the
  /// centroid is not inside. Returns evaluate_to's answer for that point.
  bool evaluate_moved(const PointQuery<D>& q, const Stencil<D>& support, RowTarget<D>& target) const;
  /// The box support's table (lme_box.hpp) for q, when the prior is the
  /// Gaussian with the box support, the nodes sit on their lattice and q
  /// lies in a cell with a table on every axis, off the lattice's end by kBoxHullGap h;
  /// false otherwise (nothing of q's state written).
  bool evaluate_on_table(const PointQuery<D>& q, RowTarget<D>& out) const;
  /// The factorised path (lattice_solve) for q from the warm start `warm`,
  /// when the nodes sit on their lattice, the prior is the isotropic
  /// Gaussian (ball support) at q and lattice_solve takes the point; false
  /// otherwise (nothing of q's state written).
  bool evaluate_on_lattice(const PointQuery<D>& q, const PointMetric<D>& pm, const Vec<D>& warm,
                           RowTarget<D>& out) const;
  /// Writes back q's multiplier, Newton count and slope or history after a
  /// converged solve (lambda: the multiplier to keep, kept_multiplier; JA =
  /// J^{-1} (I + A), two_B: the prior's Hessian 2 B); the history takes the
  /// multiplier q held before.
  void store_point_state(const PointQuery<D>& q, const Vec<D>& lambda, int iterations, const Mat<D>& two_B,
                         const Mat<D>& JA) const;
  /// Removes the nodes whose N_I underflowed to zero (their gradient is zero too).
  void drop_zeros(Stencil<D>& out) const;
  [[noreturn]] void fail(const PointQuery<D>& q, const std::string& why) const;
  int compute_stencil_bound() const;
  /// The box support on the lattice: at most floor(2 R / h_k) + 1 lines per
  /// axis (R = sqrt(-ln(tol) / beta)), their product in all.
  int box_lattice_bound() const;

  /// Arrays of out.scratch_w (see support()).
  static constexpr int kScratchArrays = D + 4;

  NodeSet<D> nodes_;
  Prior prior_;
  NewtonSettings settings_;
  std::string_view kind_;
  Metric metric_ = Metric::isotropic;
  double radius0_ = 0.0;          ///< the isotropic support radius R = h sqrt(-ln(tol) / gamma_lme)
  std::vector<double> node_beta_; ///< Metric::node_spacing: beta_I
  /// The nodes' lattice axis by axis while they sit on it and the prior is
  /// the Gaussian (the factorised path, lme_lattice.hpp); empty otherwise.
  LatticeAxes<D> lattice_;
  /// The box support's tables (prior_.box on an untouched lattice; built
  /// once, kept while the nodes move); null otherwise.
  std::shared_ptr<const BoxTables<D>> box_;
  /// The factors of the support radius tried in turn when a point is not
  /// inside the hull of its support (the first is the prior's cut-off; the
  /// Gaussian prior only: the cubic spline's support is bounded).
  static constexpr std::array<double, 3> kWiden{1.0, 2.0, 4.0};
  /// Evaluations that needed a wider support since construction.
  mutable std::atomic<long long> widened_{0};
  /// Points moved into the hull of their support since construction.
  mutable std::atomic<long long> moved_{0};
  /// Bisection steps of evaluate_moved (the position to 1/2^12 of the way).
  static constexpr int kMoveBisections = 12;
  mutable std::mutex bound_mutex_;
  mutable int bound_ = -1; ///< cached max_stencil(), -1 when stale
};

/// Sound upper bound on the number of nodes within distance R of any point.
/// std::invalid_argument unless R is finite and > 0.
template <int D> int max_nodes_within(const NodeSet<D>& nodes, double R);

/// The distance from node I to its nearest other node (h_I of the
/// node_spacing metric), searched within h, 2h, 4h, ... as the basis does.
template <int D> double nearest_node_distance(const NodeSet<D>& nodes, int I, double h);

/// The search radius of an lme basis with metric node_spacing on nodes of
/// spacing h that are off their lattice (perturbed), whose largest
/// nearest-node distance is `nearest_max`: the basis' own figure (its R_I
/// grows with h_I), so that a distributed run finds it from the largest
/// h_I of each rank's nodes without the whole lattice.
double node_spacing_search_radius(const BasisOptions& opt, double h, double nearest_max);

extern template struct GaussianPrior<1>;
extern template struct GaussianPrior<2>;
extern template struct GaussianPrior<3>;
extern template struct CubicSplinePrior<1>;
extern template struct CubicSplinePrior<2>;
extern template struct CubicSplinePrior<3>;
extern template class MaxEntBasis<1, GaussianPrior<1>>;
extern template class MaxEntBasis<2, GaussianPrior<2>>;
extern template class MaxEntBasis<3, GaussianPrior<3>>;
extern template class MaxEntBasis<1, CubicSplinePrior<1>>;
extern template class MaxEntBasis<2, CubicSplinePrior<2>>;
extern template class MaxEntBasis<3, CubicSplinePrior<3>>;

} // namespace otmpm::maxent
