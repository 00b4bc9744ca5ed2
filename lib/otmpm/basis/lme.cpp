// Local max-ent (LME) and max-ent with a cubic-spline prior (docs/theory.md
// sect. 4; molinos sect. 2.3; wobbes sect. 6.3).
//
// Choices made here (the papers leave them open)
// ----------------------------------------------
// * One formula, two priors, one solver. N_I = w_I exp(lambda.(x - x_I)) / Z
//   with w_I = exp(-beta |x - x_I|^2) (LME, beta = gamma_lme / h^2, h = the
//   initial spacing NodeSet::spacing(), also for moved nodes) or the cubic
//   spline of wobbes eq. 89 at r = |x - x_I| / (d_max h). The paper's
//   d_I = d_max zeta_I (zeta_I = distance from node I to its nearest node) is
//   replaced by d_max h with the same h for every node, so that the support
//   radius is one number known in advance (neighbour search by
//   NodeSet::within) and does not change when nodes are advected; on a
//   Cartesian grid the two are the same. The Newton solver only sees
//   the priors, so both families share it (MaxEntBasis<D, Prior>): log w_I
//   for the Gaussian (its exponent, free), w_I itself for the cubic spline,
//   whose weights are p_I = w_I exp(lambda . (x - x_I)) with no logarithm
//   per node (log w_I is formed only on the rare paths that need it: the
//   shifted exponents beyond kUnshiftedExponent and the round-off bound of
//   the line search). While |lambda| R <= kTaylorSmall (the spline prior
//   of d_max = 2 is the cubic B-spline of spacing h and reproduces x by
//   itself, so lambda stays near 0 on nearly even nodes) exp(lambda . (x -
//   x_I)) is taken by its degree-5 Taylor polynomial (within an ulp).
// * Support: LME keeps node I when beta |x - x_I|^2 <= -ln(tol), i.e.
//   exp(-beta r^2) >= tol, radius R = h sqrt(-ln(tol) / gamma_lme); max-ent
//   keeps nodes with |x - x_I| < d_max h (w_I > 0).
// * Newton on the convex dual log Z(lambda): r = sum N_I (x - x_I),
//   J = sum N_I (x - x_I)(x - x_I)^T - r r^T, accumulated in the centred form
//   sum N_I (x - x_I - r)(x - x_I - r)^T (sum of non-negative terms, no
//   cancellation next to the hull boundary). Exponents are shifted by their
//   maximum before exp(). Step s = -J^{-1} r through the closed-form inverse of
//   the diagonally scaled J (see below). Converged when |r| <= newton_tolerance h.
// * Line search: Armijo backtracking on log Z, accept t s when
//   log Z(lambda + t s) - log Z(lambda) <= kArmijo t r.s (kArmijo = 1e-4),
//   otherwise halve t (kBacktrack = 0.5), at most kMaxBacktracks = 40 times
//   ("stalled"). The change of log Z is computed directly as
//   log sum_I N_I exp(t s.(x - x_I)) in the log1p/expm1 form (shifted-exp form
//   if an exponent change exceeds 500), not as the difference of two log Z
//   values, so that decreases of order r^T J^{-1} r far below the round-off of
//   log Z stay resolvable (needed next to the hull boundary, where J is tiny).
//   When every exponent changes by at most kSafeExponentChange = 0.25 the
//   Armijo condition provably holds (see the constant) and log Z is not
//   evaluated: the quadratic phase costs no extra exp() pass.
// * Cost. The support is held in structure-of-arrays form (one
//   array per axis of x - x_I, log w_I or w_I, N_I), padded to whole short vectors
//   (simd.hpp: two lanes with SSE2, four with AVX), and every pass over the
//   nodes - exponents, exp(), the sums for r and J, the exponent changes of
//   the line search - runs on those vectors; exp() is a branch-free vector
//   kernel equal to exp_shifted bit for bit. After the first evaluation of a
//   solve, an accepted step whose exponent changes u_I = t s.(x - x_I) are
//   all below kTaylorLarge updates N_I <- N_I e^u_I / sum_J N_J e^u_J with a
//   short Taylor polynomial for e^u (1 ulp) instead of an exponential per
//   node; from a warm start that is every step (|u_I| ~ 1e-3). log Z is
//   only formed when the line search compares two values of it.
//   The candidates of the neighbour search come from the particle's Verlet
//   list (nodes/neighbour_lists.hpp) when the engine passes one: the same
//   nodes in the same order as NodeSet::within, without searching.
// * Warm start from *q.lambda, or from its prediction (the slope or the
//   history below); if the solve fails for any reason it is repeated from
//   *q.lambda when the prediction was another point, then from lambda = 0
//   (a stale multiplier from a far-away previous position must not turn
//   into an error). The iteration count reported is the total of the
//   solves (not counting the steps of a factorised attempt on the lattice,
//   lme_lattice.cpp, that handed the point over); lambda is written back
//   only on success.
// * Taylor-predicted warm start (q.slope, kept while the nodes are fixed):
//   differentiating r(x, lambda(x)) = 0 gives d lambda / d x = -J^{-1} (I + A)
//   (A as for the gradients below; 2 B - J^{-1} for a Gaussian prior with
//   one metric B over the support), stored with the position x0 of the
//   solve, and the next solve starts from lambda + G (x - x0). Its residual
//   is second order in the displacement (|x - x0| ~ 1e-4 h per step in the
//   benchmarks), so one Newton step less is needed to reach the same
//   tolerance; the converged lambda is the same to that tolerance, not bit
//   for bit.
// * Singular J. Js = S J S, S = diag(J_kk^{-1/2}) (unit diagonal); J is
//   singular when not positive definite or when 1 / tr(Js^{-1}) (within a
//   factor D of the smallest eigenvalue of Js) <= kSingularHessian = 1e-13.
//   This is deliberately not a bound on J relative to h^2: J's entries are sums
//   of non-negative terms, accurate to ~n eps even when tiny, so a J that is
//   small along an axis (a point on or next to a face of a box, interior nodes
//   clustered near it) is inverted accurately and must not be rejected; what
//   cannot be inverted is a near-singular Js (degenerate nodes).
// * Convex hull detection. Inside the hull of the support log Z has a unique
//   minimiser; outside it log Z is unbounded below, the iterates run off to
//   infinity and J collapses along the normal of the nearest face of the hull.
//   Caught, cheapest first, by:
//     - fewer than D + 1 support nodes;
//     - x beyond the bounding box of its support nodes by more than
//       newton_tolerance h (no Newton needed);
//     - singular J: Js becomes singular for a slanted face; for an axis-aligned
//       face the normal variance underflows to exactly zero a few
//       (exponentially growing) steps later, so this always triggers outside.
//       Reported as a degenerate support when it happens at lambda = 0 (every
//       support node then has N_I > 0, so the nodes do not span D dimensions),
//       as "outside the convex hull" when |r| > kHullResidual h = 1e-8 h
//       (|r| >= the distance to the hull), else as "on or just outside the
//       boundary of the convex hull";
//     - non-finite exponents (lambda diverged);
//     - the line search stalling, or max_newton_iterations reached.
//   Every one of these is a BasisError naming the point (and q.id). lambda
//   itself is not bounded: where nodes cluster at a distance g << h the
//   converged |lambda| is of order ln(g / distance to the node) / g,
//   legitimately large. A point exactly on the hull boundary is accepted:
//   there lambda -> infinity but |r| falls by a constant factor per Newton step
//   and the iteration stops at |r| <= newton_tolerance h (about 25-30
//   iterations from a cold start), the limit of N_I from inside to within the
//   tolerance.
// * Gradients at the converged lambda, with x - x_I replaced by xbar - x_I,
//   xbar = sum N_I x_I = x - r (identical at r = 0):
//     LME:     grad N_I = -N_I J^{-1} (xbar - x_I)
//     max-ent: grad N_I = N_I ( g_I - gbar - (I + A^T) J^{-1} (xbar - x_I) ),
//              g_I = grad log w_I, gbar = sum N_J g_J,
//              A = sum N_J (xbar - x_J)(g_J - gbar)^T,
//   the latter from differentiating log N_I and the constraint
//   r(x, lambda(x)) = 0 implicitly (dlambda/dx = -J^{-1} (I + A)); it reduces
//   to the LME form for the Gaussian prior (g_I = -2 beta (x - x_I),
//   A = -2 beta J). wobbes eq. 84 as printed does not reduce to the LME
//   gradient for a Gaussian prior (its signs differ); this expression is
//   checked against finite differences in tests/test_maxent.cpp.
//   With xbar, sum grad N_I = 0 and sum x_I (x) grad N_I = I hold to round-off
//   even though |r| is only below the tolerance.
// * Nodes whose N_I underflows to 0 are dropped from the stencil (their
//   gradient is N_I times a finite vector, hence 0 too).
// * max_stencil(): on an untouched Cartesian lattice the smaller of the box
//   count prod_k (floor(2R/h_k) + 1) and the volume bound
//   |B(R + |h|/2)| / prod h_k; otherwise the maximum, over the cells of a
//   bucket grid of side R/2, of the nodes in all cells that a ball of radius R
//   centred in that cell can reach. Computed lazily, cached, invalidated by
//   nodes_moved().
#include "otmpm/basis/lme.hpp"
#include "otmpm/basis/lme_box.hpp"
#include "otmpm/basis/lme_lattice.hpp"

#include "otmpm/basis/families.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/parallel.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace otmpm::maxent {
namespace {

// ---- Newton / line search constants (see the file comment) -----------------
constexpr double kArmijo = 1e-4;           ///< sufficient-decrease factor of the line search
constexpr double kBacktrack = 0.5;         ///< step reduction per backtracking step
constexpr int kMaxBacktracks = 40;         ///< then the line search has stalled
constexpr double kHullResidual = 1e-8;     ///< |r| / h above which a singular J means "outside the hull"
/// Largest exponent for which the expm1 form of the log Z change is used.
constexpr double kPreciseFormMaxExponent = 500.0;
/// Relative round-off of log Z = max_I f_I + log sum_I exp(f_I - max f), per
/// unit of max_I |f_I| (a few eps).
constexpr double kLogZRoundoff = 8.0 * std::numeric_limits<double>::epsilon();
/// The line search compares two log Z values only when the Armijo decrease
/// exceeds this multiple of their round-off; below, it uses the expm1 form.
constexpr double kResolvableFactor = 1e4;

// ---- adapted locality (Metric) ----------------------------------------------
/// Relative slack on the radius within which the ellipse of a deformed
/// point's prior is searched (the exact test dx^T B dx <= -ln(tol) decides;
/// this only covers the round-off of the eigenvalues of F F^T).
constexpr double kMetricRadiusSlack = 1e-6;
/// Metric::node_spacing: the search radius is max_I R_I rounded up to a
/// multiple of R / kRadiusSteps (R the isotropic radius), so that the Verlet
/// lists of moving nodes are rebuilt only when it crosses a step.
constexpr double kRadiusSteps = 8.0;

// ---- stencil bound ---------------------------------------------------------
constexpr double kBucketsPerRadius = 2.0;    ///< bucket side R / 2
constexpr double kMaxBucketsPerNode = 16.0;  ///< coarsen buckets beyond this many per node
constexpr double kMinBuckets = 4096.0;
constexpr double kBucketSafety = 1e-9;       ///< relative slack on the bucket distance test

/// Largest |u_I| = |s . (x - x_I)| of an accepted Newton step for which the
/// new weights are computed from the current ones, p_I exp(u_I), with exp by
/// a Taylor polynomial (simd::exp_small) instead of a full exponential per
/// node: degree 5 up to 2^-8, degree 8 up to 2^-4 (both within 1 ulp);
/// beyond, the exponents are evaluated afresh. In the quadratic phase of a
/// warm-started solve |u_I| is ~1e-3, so every step after the first
/// evaluation costs a few multiplications per node. |u_I| <= |s| R (R bounds
/// |x - x_I| on the support) decides it before any pass over the nodes; a
/// step with |s| R <= kTaylorLarge < kSafeExponentChange also satisfies the
/// Armijo condition, so it is taken without a line search. The first pass
/// of the cubic-spline prior takes degree 5 too while |lambda| R <=
/// kTaylorSmall (dual_state_impl).
constexpr double kTaylorSmall = 0x1p-8;
constexpr double kTaylorLarge = 0x1p-4;
/// While |lambda| R <= this, every exponent f_I = log w_I + lambda . dx_I lies
/// in [-ln(1/tol) - 300, 300] and exp(f_I) is taken unshifted (no pass for
/// the maximum); beyond, the exponents are shifted by their maximum.
constexpr double kUnshiftedExponent = 300.0;
/// The second-order term of the warm start (eq. 4.7b) is added when the
/// displacement d since the last solve is alpha e, e the displacement before
/// it: within an angle of 0.01 rad (|d - alpha e|^2 <= kCurvatureAngle2
/// |d|^2), and |alpha| <= kCurvatureMaxRatio (an extrapolation over a few
/// past steps; beyond, the difference G - G_prev, which carries the Newton
/// tolerance of both solves, would be amplified by alpha).
constexpr double kCurvatureAngle2 = 1e-4;
constexpr double kCurvatureMaxRatio = 4.0;

/// The start of eq. 4.7c from the last solve's lambda and the history of
/// the solves before: quadratic over the last three solves, linear over
/// two, else lambda itself (also when the extrapolation is not finite).
template <int D> Vec<D> extrapolated_start(const Vec<D>& lambda, const MultiplierHistory<D>& h) {
  Vec<D> start = lambda;
  if (h.solves >= 3)
    start = 3.0 * (lambda - h.previous) + h.before;
  else if (h.solves == 2)
    start = 2.0 * lambda - h.previous;
  return start.allFinite() ? start : lambda;
}

/// The multiplier a point keeps after a solve converged at lambda with
/// residual r: with a history (eq. 4.7c) polished by the Newton step of the
/// final state, lambda - J^{-1} r (free: J^{-1} and r are at hand), so that
/// the extrapolation, which multiplies the kept values by up to 7, is not
/// dominated by the solves' own residuals; else lambda itself.
template <int D>
Vec<D> kept_multiplier(const PointQuery<D>& q, const Vec<D>& lambda, const Mat<D>& J_inv, const Vec<D>& r) {
  return q.history ? Vec<D>(lambda - J_inv * r) : lambda;
}

/// The plain warm start: the last solve's lambda (zero when absent or not finite).
template <int D> Vec<D> plain_start(const PointQuery<D>& q) {
  return q.lambda && q.lambda->allFinite() ? *q.lambda : Vec<D>::Zero();
}

/// The components of a D-vector, each broadcast to all lanes once (outside
/// the loops over the nodes): a * v with a scalar a broadcasts it anyway, so
/// the products are the same bits.
template <int D> struct Broadcast {
  simd::vd v[D];
  explicit Broadcast(const Vec<D>& a) {
#pragma GCC unroll 3
    for (int k = 0; k < D; ++k) v[k] = simd::broadcast(a[k]);
  }
};

/// u_i = step . dx_i for the lanes from i.
template <int D> simd::vd exponent_increment(const Broadcast<D>& step, const Support<D>& s, int i) {
  simd::vd u = step.v[0] * simd::load(s.dx[0] + i);
#pragma GCC unroll 3
  for (int k = 1; k < D; ++k) u += step.v[k] * simd::load(s.dx[k] + i);
  return u;
}

/// Sums of the weights p_I about a centre c: Z = sum p_I, m = sum p_I (dx_I
/// - c), S = sum p_I (dx_I - c)(dx_I - c)^T, accumulated lane by lane in the
/// same pass that computes the weights (add(), then finish()).
template <int D> struct Moments {
  simd::vd z = simd::broadcast(0.0), m[D] = {}, S[D][D] = {};
  Vec<D> c;
  Broadcast<D> c_lanes; ///< c broadcast

  explicit Moments(const Vec<D>& centre) : c(centre), c_lanes(centre) {}
  void add(const Support<D>& s, int i, simd::vd p) {
    z += p;
    simd::vd d[D];
#pragma GCC unroll 3
    for (int k = 0; k < D; ++k) d[k] = simd::load(s.dx[k] + i) - c_lanes.v[k];
#pragma GCC unroll 3
    for (int k = 0; k < D; ++k) {
      const simd::vd pd = p * d[k];
      m[k] += pd;
#pragma GCC unroll 3
      for (int l = 0; l <= k; ++l) S[k][l] += pd * d[l];
    }
  }
  /// Z, r = c + m / Z and J = S / Z - (m / Z)(m / Z)^T into st; J in the
  /// centred form (one more pass) when the correction is not small.
  bool finish(const Support<D>& s, const double* p, NewtonState<D>& st) const {
    st.Z = simd::sum(z);
    const double inv_Z = 1.0 / st.Z;
    Vec<D> mean;
#pragma GCC unroll 3
    for (int k = 0; k < D; ++k) mean[k] = simd::sum(m[k]) * inv_Z;
    st.r = c + mean;
    bool small = true;
#pragma GCC unroll 3
    for (int k = 0; k < D; ++k)
#pragma GCC unroll 3
      for (int l = 0; l <= k; ++l) {
        st.J(k, l) = st.J(l, k) = simd::sum(S[k][l]) * inv_Z - mean[k] * mean[l];
        if (k == l) small = small && mean[k] * mean[k] <= kShiftedMomentLimit * st.J(k, k);
      }
    if (!small) centred_J(s, p, inv_Z, st);
    return st.r.allFinite() && st.J.allFinite() && st.Z > 0.0 && std::isfinite(st.Z);
  }
  /// J = sum N_I (dx_I - r)(dx_I - r)^T: sums of non-negative terms, no
  /// cancellation next to the hull boundary.
  static void centred_J(const Support<D>& s, const double* p, double inv_Z, NewtonState<D>& st) {
    Moments<D> centred(st.r);
    for (int i = 0; i < s.n_pad; i += simd::lanes) centred.add(s, i, simd::load(p + i) * inv_Z);
    for (int k = 0; k < D; ++k)
      for (int l = 0; l <= k; ++l) st.J(k, l) = st.J(l, k) = simd::sum(centred.S[k][l]);
  }
};

/// The weights p_I = exp(f_I - log_base) (into p), f_I = log w_I + lambda .
/// dx_I (formed as w_I exp(lambda . dx_I - log_base) when kWeights), and the state at lambda (molinos eqs. 36-40): Z = sum p_I, N_I =
/// p_I / Z, r, J, log Z = log_base + log(Z). log_base = 0 while |lambda| R <=
/// kUnshiftedExponent, else the largest f_I. Moments about c (the caller's
/// best guess of r). Returns false when not finite. kWeights: the priors
/// are held as w_I (Support::w), else as log w_I; with kWeights and |lambda|
/// R <= kTaylorSmall exp(lambda . dx_I) is its degree-5 Taylor polynomial.
template <int D, bool kWeights>
bool dual_state_impl(const Vec<D>& lambda, const Support<D>& s, double* p, const Vec<D>& c, NewtonState<D>& st) {
  using simd::vd;
  st.log_base = 0.0;
  if (!(lambda.norm() * s.radius <= kUnshiftedExponent)) {
    if constexpr (!kWeights) {
      vd fmax = simd::broadcast(-std::numeric_limits<double>::infinity());
      const Broadcast<D> lambda_lanes(lambda);
      for (int i = 0; i < s.n_pad; i += simd::lanes)
        fmax = simd::max(fmax, simd::load(s.log_w + i) + exponent_increment<D>(lambda_lanes, s, i));
      st.log_base = simd::max_lane(fmax);
    } else { // w_I held directly: log w_I only here (|lambda| R > kUnshiftedExponent is rare)
      st.log_base = -std::numeric_limits<double>::infinity();
      for (int i = 0; i < s.n; ++i) st.log_base = std::max(st.log_base, std::log(s.w[i]) + lambda.dot(s.offset(i)));
    }
    if (!std::isfinite(st.log_base)) return false;
  }
  Moments<D> mo(c);
  const Broadcast<D> lambda_lanes(lambda);
  if constexpr (!kWeights) {
    for (int i = 0; i < s.n_pad; i += simd::lanes) {
      const vd f = simd::load(s.log_w + i) + exponent_increment<D>(lambda_lanes, s, i);
      const vd e = simd::exp_shifted(f - st.log_base);
      simd::store(p + i, e);
      mo.add(s, i, e);
    }
  } else if (lambda.norm() * s.radius <= kTaylorSmall) {
    // every |lambda . dx_I| <= |lambda| R <= 2^-8 (and log_base = 0):
    // e^u by its degree-5 Taylor polynomial, within an ulp and 10 dependent
    // operations instead of the 15 and the reduction of exp_shifted (the
    // cubic-spline prior of d_max = 2 reproduces x by itself on evenly
    // spaced nodes, so lambda stays near 0 where they are nearly even)
    for (int i = 0; i < s.n_pad; i += simd::lanes) {
      const vd e = simd::load(s.w + i) * simd::exp_small<5>(exponent_increment<D>(lambda_lanes, s, i));
      simd::store(p + i, e);
      mo.add(s, i, e);
    }
  } else { // p_I = w_I exp(lambda . dx_I - log_base): no logarithm per node
    for (int i = 0; i < s.n_pad; i += simd::lanes) {
      const vd e = simd::load(s.w + i) * simd::exp_shifted(exponent_increment<D>(lambda_lanes, s, i) - st.log_base);
      simd::store(p + i, e);
      mo.add(s, i, e);
    }
  }
  return mo.finish(s, p, st);
}

/// dual_state_impl for priors held as w_I, compiled on its own: inlined
/// next to the log-prior pass, the moments of both passes went to memory.
template <int D>
[[gnu::noinline]] bool dual_state_weights(const Vec<D>& lambda, const Support<D>& s, double* p, const Vec<D>& c,
                                          NewtonState<D>& st) {
  return dual_state_impl<D, true>(lambda, s, p, c, st);
}

/// dual_state_impl for the priors `s` holds.
template <int D>
bool dual_state(const Vec<D>& lambda, const Support<D>& s, double* p, const Vec<D>& c, NewtonState<D>& st) {
  return s.w ? dual_state_weights<D>(lambda, s, p, c, st) : dual_state_impl<D, false>(lambda, s, p, c, st);
}

/// The state at lambda + step from the state `st` at lambda (weights in p,
/// updated in place): p_I exp(u_I), u_I = step . dx_I, with |u_I| <= u_max
/// <= kTaylorLarge (exp by its Taylor polynomial); log_base is kept.
template <int D>
bool shifted_state(const Vec<D>& step, const Support<D>& s, double* p, double u_max, NewtonState<D>& st) {
  Moments<D> mo(st.r);
  const Broadcast<D> step_lanes(step);
  const bool small = u_max <= kTaylorSmall;
  for (int i = 0; i < s.n_pad; i += simd::lanes) {
    const simd::vd u = exponent_increment<D>(step_lanes, s, i);
    const simd::vd e = simd::load(p + i) * (small ? simd::exp_small<5>(u) : simd::exp_small<8>(u));
    simd::store(p + i, e);
    mo.add(s, i, e);
  }
  return mo.finish(s, p, st);
}

/// Bound on the round-off of log Z at lambda: kLogZRoundoff (1 + max_I |f_I|).
template <int D> double log_Z_error(const Vec<D>& lambda, const Support<D>& s) {
  double fabs_max = 0.0;
  for (int i = 0; i < s.n; ++i) {
    const double log_w = s.log_w ? s.log_w[i] : std::log(s.w[i]);
    fabs_max = std::max(fabs_max, std::abs(log_w + lambda.dot(s.offset(i))));
  }
  return kLogZRoundoff * (1.0 + fabs_max);
}

/// Largest and largest absolute change u_I = step . dx_I of the exponents.
struct ExponentChange {
  double max = 0.0;
  double max_abs = 0.0;
};

template <int D> ExponentChange exponent_change(const Vec<D>& step, const Support<D>& s) {
  simd::vd hi = simd::broadcast(-std::numeric_limits<double>::infinity()), neg = hi; // max u, max -u
  const Broadcast<D> step_lanes(step);
  for (int i = 0; i < s.n_pad; i += simd::lanes) { // padding has u = 0: harmless
    const simd::vd u = exponent_increment<D>(step_lanes, s, i);
    hi = simd::max(hi, u);
    neg = simd::max(neg, -u);
  }
  ExponentChange c;
  c.max = simd::max_lane(hi);
  c.max_abs = std::max(c.max, simd::max_lane(neg));
  return c;
}

/// log Z(lambda + step) - log Z(lambda) = log sum_I N_I exp(step . dx_I) from
/// the current weights p_I (N_I = p_I / Z), in the log1p/expm1 form while the
/// exponents are moderate: resolves decreases far below the round-off of
/// log Z itself. umax = max_I step . dx_I shifts the exponents in the other form.
template <int D>
double log_partition_change(const Vec<D>& step, const Support<D>& s, double Z, double umax) {
  double sum = 0.0;
  if (umax <= kPreciseFormMaxExponent) {
    for (int i = 0; i < s.n; ++i) sum += s.p[i] * std::expm1(step.dot(s.offset(i)));
    return std::log1p(sum / Z);
  }
  for (int i = 0; i < s.n; ++i) sum += s.p[i] * std::exp(step.dot(s.offset(i)) - umax);
  return umax + std::log(sum / Z);
}

/// Outcome of one backtracking line search.
enum class LineSearch { accepted, accepted_evaluated, stalled };

/// Armijo backtracking along `step` from the state `st` (see the file
/// comment). On `accepted_evaluated` the new state (with N_I in s.trial) is
/// already in `next`; on `accepted` it still has to be computed, and u_max
/// holds max_I |t step . dx_I| of the accepted step.
template <int D>
LineSearch line_search(const Support<D>& s, const Vec<D>& lambda, const Vec<D>& step, const NewtonState<D>& st,
                       double& t, double& u_max, NewtonState<D>& next) {
  const double slope = st.r.dot(step); // = -r^T J^{-1} r < 0
  double roundoff = -1.0;              // log Z round-off, computed when first needed
  t = 1.0;
  for (int k = 0; k <= kMaxBacktracks; ++k, t *= kBacktrack) {
    const ExponentChange u = exponent_change<D>(t * step, s);
    u_max = u.max_abs;
    if (u.max_abs <= kSafeExponentChange) return LineSearch::accepted; // Armijo holds
    const double wanted = kArmijo * t * slope;
    if (roundoff < 0.0) roundoff = log_Z_error<D>(lambda, s);
    if (-wanted > kResolvableFactor * roundoff) {
      // the decrease is far above the round-off of log Z: compare two log Z
      // values, and keep the trial state when it is accepted
      if (dual_state<D>(lambda + t * step, s, s.trial, st.r, next) && next.log_Z() - st.log_Z() <= wanted)
        return LineSearch::accepted_evaluated;
    } else if (log_partition_change<D>(t * step, s, st.Z, u.max) <= wanted) {
      return LineSearch::accepted;
    }
  }
  return LineSearch::stalled;
}

/// The state after an accepted step (the new lambda and the step taken)
/// that the line search did not evaluate: by shifted_state when every
/// exponent changes by at most u_max <= kTaylorLarge, else afresh. False when
/// not finite.
template <int D>
bool advance_state(const Vec<D>& lambda, const Vec<D>& step, double u_max, Support<D>& s, NewtonState<D>& st) {
  if (u_max <= kTaylorLarge) return shifted_state<D>(step, s, s.p, u_max, st);
  return dual_state<D>(lambda, s, s.p, st.r, st);
}

/// One Newton step from `st` along `step` (updates lambda, s and st): taken
/// whole without a line search when |step| R <= kTaylorLarge (then every
/// |u_I| is that small, Armijo holds and the Taylor update applies), else
/// after line_search. False when the line search stalled or the new state is
/// not finite (st.status says which).
template <int D>
bool newton_step(const Vec<D>& step, Support<D>& s, Vec<D>& lambda, NewtonState<D>& st, NewtonState<D>& next) {
  const int iterations = st.iterations + 1;
  bool finite;
  if (const double bound = step.norm() * s.radius; bound <= kTaylorLarge) {
    lambda += step;
    finite = shifted_state<D>(step, s, s.p, bound, st);
  } else {
    double t = 1.0, u_max = 0.0;
    const LineSearch ls = line_search<D>(s, lambda, step, st, t, u_max, next);
    if (ls == LineSearch::stalled) {
      st.status = NewtonStatus::stalled;
      return false;
    }
    lambda += t * step;
    finite = true;
    if (ls == LineSearch::accepted_evaluated) {
      std::swap(s.p, s.trial);
      st = next;
    } else {
      finite = advance_state<D>(lambda, Vec<D>(t * step), u_max, s, st);
    }
  }
  st.iterations = iterations;
  if (!finite) st.status = NewtonStatus::diverged;
  return finite;
}

/// The shared Newton solver for lambda = argmin log Z (docs/theory.md
/// sect. 4): Newton steps on r with an Armijo backtracking line search on
/// log Z. On return s.p holds the weights p_I at the final lambda (N_I =
/// p_I / Z; the buffers s.p and s.trial may have been swapped) and the state
/// its Z, r, J and, when converged, J^{-1} (in J_inv).
template <int D>
NewtonState<D> solve_lambda(const NewtonSettings& set, Support<D>& s, Vec<D>& lambda) {
  NewtonState<D> st, next;
  if (!dual_state(lambda, s, s.p, Vec<D>::Zero().eval(), st)) {
    st.status = NewtonStatus::diverged;
    return st;
  }
  ScaledInverse<D> inv;
  for (;;) {
    inv.compute(st.J);
    st.lambda_min = inv.lambda_min;
    const bool regular = st.lambda_min > kSingularHessian;
    if (st.r.norm() <= set.residual_tolerance) {
      st.status = regular ? NewtonStatus::converged : NewtonStatus::singular;
      if (regular) st.J_inv = inv.inverse();
      return st;
    }
    if (!regular) {
      st.status = NewtonStatus::singular;
      return st;
    }
    if (st.iterations >= set.max_iterations) {
      st.status = NewtonStatus::max_iterations;
      return st;
    }
    if (!newton_step<D>(-inv.solve(st.r), s, lambda, st, next)) return st;
  }
}

/// Distance from node I to its nearest other node (the nodes within a
/// radius doubled from h until one is found; `near` is scratch).
template <int D> double nearest_distance(const NodeSet<D>& nodes, int I, double h, std::vector<int>& near) {
  const Vec<D> x = nodes.position(I);
  for (double r = h;; r *= 2.0) {
    near.clear();
    nodes.within(x, r, near);
    double d2 = std::numeric_limits<double>::infinity();
    for (const int J : near)
      if (J != I) d2 = std::min(d2, (nodes.position(J) - x).squaredNorm());
    if (d2 <= r * r || !std::isfinite(r)) return std::sqrt(d2);
  }
}

/// beta_I of the node_spacing metric for a node whose nearest node is h_I
/// away: beta (h / h_I)^2 (beta itself at h_I = h).
double spacing_beta(double beta, double h, double h_I) { return h_I != h ? beta * (h / h_I) * (h / h_I) : beta; }

/// The search radius (Verlet lists) of the node_spacing metric for the
/// largest support radius R_max: R_max rounded up to a multiple of
/// radius0 / kRadiusSteps, so that the lists are rebuilt only when the
/// largest R_I crosses a step.
double stepped_radius(double radius0, double R_max) {
  return radius0 * std::ceil(kRadiusSteps * R_max / radius0) / kRadiusSteps;
}

/// The parameters of the two families (scene keys under [basis]).
constexpr ParameterSpec kGammaLme{"gamma_lme", "LME locality: beta = gamma_lme / h^2", 4.0, 0.0, true};
constexpr ParameterSpec kTolerance{"tolerance", "LME support cut-off: exp(-beta r^2) >= tolerance", 1e-6, 0.0, true,
                                   1.0, true};
constexpr ParameterSpec kNewtonTolerance{"newton_tolerance",
                                         "Newton solve converged when |r| <= newton_tolerance h (LME, max-ent)",
                                         1e-12, 0.0, true, 1.0, true};
constexpr ParameterSpec kMaxNewtonIterations{
    "max_newton_iterations", "Newton iterations at most (LME, max-ent)", 100.0, 1.0, false, 2147483647.0, false, true};
constexpr ParameterSpec kDMax{"d_max", "max-ent support radius d_max h of the cubic-spline prior", 2.0, 0.0, true};
constexpr std::array kLmeParameters{kGammaLme, kTolerance, kNewtonTolerance, kMaxNewtonIterations};
constexpr std::array kMaxentParameters{kDMax, kNewtonTolerance, kMaxNewtonIterations};

/// The Gaussian prior of an lme basis with options `opt` on nodes of spacing h.
template <int D> GaussianPrior<D> lme_prior(const BasisOptions& opt, double h) {
  GaussianPrior<D> prior;
  prior.beta = opt.value(kGammaLme) / (h * h);
  prior.max_exponent = -std::log(opt.value(kTolerance));
  return prior;
}

std::string format_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

/// Explains a failed solve. `st` is the last solve, which started from
/// lambda = 0; `total` counts the iterations of all solves; `h` scales r.
template <int D>
std::string describe_failure(const NewtonState<D>& st, int total, double h, double tol, int n) {
  const std::string rh = format_number(st.r.norm() / h);
  const std::string support = " of its " + std::to_string(n) + " support nodes";
  const std::string after = " after " + std::to_string(total) + " Newton iterations";
  const std::string eig = format_number(st.lambda_min);
  switch (st.status) {
  case NewtonStatus::singular:
    if (st.iterations == 0) // at lambda = 0 every support node has N_I > 0
      return "singular Hessian J at lambda = 0 (scaled smallest eigenvalue ~" + eig + "): the " + std::to_string(n) +
             " support nodes do not span " + std::to_string(D) + " dimensions around the point";
    if (st.r.norm() > kHullResidual * h)
      return "outside the convex hull" + support + " (Newton drives lambda to infinity: |r| = " + rh +
             " h, scaled smallest eigenvalue of J ~" + eig + after + ")";
    return "on or just outside the boundary of the convex hull" + support + " (singular Hessian J, scaled smallest eigenvalue ~" +
           eig + " <= " + format_number(kSingularHessian) + ", |r| = " + rh + " h" + after + ")";
  case NewtonStatus::diverged:
    return "outside the convex hull" + support + " (lambda diverged, |r| = " + rh + " h" + after + ")";
  case NewtonStatus::stalled:
    return "Newton did not converge: the line search found no decrease of log Z at |r| = " + rh +
           " h > " + format_number(tol) + " h" + after + " (outside or on the boundary of the convex hull" +
           support + "?)";
  case NewtonStatus::max_iterations:
    return "Newton did not converge" + after + " (|r| = " + rh + " h > " + format_number(tol) +
           " h; outside or on the boundary of the convex hull" + support + "?)";
  case NewtonStatus::converged: break;
  }
  return "internal error: describe_failure on a converged solve";
}

} // namespace

// ---- priors ------------------------------------------------------------------

Metric parse_metric(const std::string& name, std::string_view kind) {
  if (name == "isotropic") return Metric::isotropic;
  if (name == "deformation") return Metric::deformation;
  if (name == "node_spacing") return Metric::node_spacing;
  throw InputError(std::string(kind) + " basis: unknown metric '" + name + "' (expected " + basis_metric_list() + ")");
}

template <int D> double GaussianPrior<D>::support_radius() const {
  return std::sqrt(max_exponent / beta) * (box ? std::sqrt(static_cast<double>(D)) : 1.0);
}

// ---- stencil bound -------------------------------------------------------------

namespace {

/// Bound for an untouched Cartesian lattice (see file comment).
template <int D> int lattice_bound(const CartesianGrid<D>& grid, double R) {
  const Vec<D> h = grid.h();
  const Index<D> n = grid.nodes_per_axis();
  double box = 1.0, cell_volume = 1.0;
  for (int k = 0; k < D; ++k) {
    box *= std::min<double>(n[k], std::floor(2.0 * R / h[k]) + 1.0);
    cell_volume *= h[k];
  }
  const double rho = R + 0.5 * h.norm();
  const double ball = std::pow(std::numbers::pi, 0.5 * D) / std::tgamma(0.5 * D + 1.0) * std::pow(rho, D);
  return static_cast<int>(std::min(box, std::floor(ball / cell_volume)));
}

/// A uniform bucket grid over the bounding box of a node set.
template <int D> struct BucketGrid {
  Vec<D> lo = Vec<D>::Zero();
  double side = 1.0;
  Index<D> n{};
  std::int64_t total = 1;

  /// Buckets of side >= `side` over [lo, hi], coarsened until there are at most `limit`.
  BucketGrid(const Vec<D>& lower, const Vec<D>& hi, double wanted_side, double limit) : lo(lower), side(wanted_side) {
    for (;;) {
      double cells = 1.0;
      for (int k = 0; k < D; ++k) cells *= std::floor((hi[k] - lo[k]) / side) + 1.0;
      if (cells <= limit) break;
      side *= std::pow(cells / limit, 1.0 / D) * (1.0 + kBucketSafety);
    }
    for (int k = 0; k < D; ++k) {
      n[k] = static_cast<int>(std::floor((hi[k] - lo[k]) / side)) + 1;
      total *= n[k];
    }
  }
  Index<D> index_of(const Vec<D>& p) const {
    Index<D> ijk{};
    for (int k = 0; k < D; ++k) ijk[k] = std::clamp(static_cast<int>(std::floor((p[k] - lo[k]) / side)), 0, n[k] - 1);
    return ijk;
  }
  /// Flat id of ijk, or -1 outside the grid.
  std::int64_t id(const Index<D>& ijk) const {
    std::int64_t id = 0;
    for (int k = D - 1; k >= 0; --k) {
      if (ijk[k] < 0 || ijk[k] >= n[k]) return -1;
      id = id * n[k] + ijk[k];
    }
    return id;
  }
};

/// Bucket offsets o that can hold a node within R of a point of bucket 0: the
/// gap between the buckets, side * sqrt(sum_k max(0, |o_k| - 1)^2), is <= R.
template <int D> std::vector<Index<D>> reachable_offsets(double R, double side) {
  const int reach = static_cast<int>(std::ceil(R / side)) + 1;
  const double reach2 = (R / side) * (R / side) * (1.0 + kBucketSafety);
  std::vector<Index<D>> offsets;
  Index<D> o{};
  o.fill(-reach);
  for (;;) {
    double gap2 = 0.0;
    for (int k = 0; k < D; ++k) {
      const double g = std::max(0, std::abs(o[k]) - 1);
      gap2 += g * g;
    }
    if (gap2 <= reach2) offsets.push_back(o);
    int k = 0;
    while (k < D && ++o[k] > reach) o[k++] = -reach;
    if (k == D) return offsets;
  }
}

/// Bucket-grid bound for any node set (see file comment): every bucket adds
/// its node count to all buckets it can be reached from; the bound is the
/// largest total. A query point outside the box counts no more nodes than its
/// projection onto the box, so the buckets of the box suffice.
template <int D> int bucket_bound(const NodeSet<D>& nodes, double R) {
  const auto& x = nodes.positions();
  Vec<D> lo = x.front(), hi = x.front();
  for (const auto& p : x) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const BucketGrid<D> grid(lo, hi, R / kBucketsPerRadius,
                           kMaxBucketsPerNode * static_cast<double>(x.size()) + kMinBuckets);
  std::vector<int> count(static_cast<std::size_t>(grid.total), 0);
  for (const auto& p : x) ++count[static_cast<std::size_t>(grid.id(grid.index_of(p)))];
  const std::vector<Index<D>> offsets = reachable_offsets<D>(R, grid.side);
  std::vector<int> reached(static_cast<std::size_t>(grid.total), 0);
  for (const auto& p : x) {
    const Index<D> b = grid.index_of(p);
    for (const auto& o : offsets) {
      Index<D> c = b;
      for (int k = 0; k < D; ++k) c[k] += o[k];
      const std::int64_t id = grid.id(c);
      if (id >= 0) ++reached[static_cast<std::size_t>(id)];
    }
  }
  return *std::max_element(reached.begin(), reached.end());
}

} // namespace

template <int D> int max_nodes_within(const NodeSet<D>& nodes, double R) {
  require<std::invalid_argument>(finite_positive(R), "max_nodes_within: radius R must be finite and > 0, got ", R);
  if (nodes.size() == 0) return 0;
  int bound = nodes.size();
  if (nodes.on_lattice() && nodes.grid()) bound = std::min(bound, lattice_bound(*nodes.grid(), R));
  else bound = std::min(bound, bucket_bound(nodes, R));
  return bound;
}

// ---- the basis ---------------------------------------------------------------

template <int D, class Prior>
MaxEntBasis<D, Prior>::MaxEntBasis(NodeSet<D> nodes, const BasisOptions& opt, const Prior& prior,
                                   std::string_view kind, Metric metric)
    : nodes_(std::move(nodes)), prior_(prior), kind_(kind), metric_(metric) {
  const std::string name(kind);
  if (nodes_.size() < D + 1)
    throw InputError(name + " basis needs at least " + std::to_string(D + 1) + " nodes, got " +
                     std::to_string(nodes_.size()));
  require_options(opt, std::array{kNewtonTolerance, kMaxNewtonIterations});
  require(finite_positive(prior_.support_radius()), name, " basis: the prior's support radius must be finite and > 0, got ",
          prior_.support_radius());
  settings_.h = nodes_.spacing();
  settings_.residual_tolerance = opt.value(kNewtonTolerance) * settings_.h;
  settings_.max_iterations = static_cast<int>(opt.value(kMaxNewtonIterations));
  settings_.support_radius = prior_.support_radius();
  radius0_ = settings_.support_radius;
  require(Prior::kGaussian || metric_ == Metric::isotropic, name, " basis: only the Gaussian prior adapts its metric");
  nodes_.prepare_search();
  if (metric_ == Metric::node_spacing) update_node_spacing();
  read_lattice();
}

template <int D, class Prior> void MaxEntBasis<D, Prior>::read_lattice() {
  if constexpr (Prior::kGaussian) {
    lattice_ = LatticeAxes<D>::from(nodes_, prior_.beta);
    if (prior_.box && !box_ && !lattice_.empty())
      box_ = std::make_shared<const BoxTables<D>>(
          BoxTables<D>::from(lattice_, prior_.beta, prior_.max_exponent));
  }
}

template <int D, class Prior> void MaxEntBasis<D, Prior>::nodes_moved(const AlignedVector<Vec<D>>&) {
  // NodeSet marked itself moved; rebuild its search index now so that
  // evaluate() may run from several threads. The stencil bound is stale.
  nodes_.prepare_search();
  if (metric_ == Metric::node_spacing) update_node_spacing();
  read_lattice();
  std::lock_guard lock(bound_mutex_);
  bound_ = -1;
}

template <int D, class Prior> int MaxEntBasis<D, Prior>::max_stencil() const {
  std::lock_guard lock(bound_mutex_);
  if (bound_ < 0)
    bound_ = box_support() && !lattice_.empty() && nodes_.on_lattice()
                 ? box_lattice_bound()
                 : max_nodes_within(nodes_, settings_.support_radius);
  return bound_;
}

template <int D, class Prior> int MaxEntBasis<D, Prior>::box_lattice_bound() const {
  int n = 1;
  if constexpr (Prior::kGaussian) {
    const double R = std::sqrt(prior_.max_exponent / prior_.beta);
    for (int k = 0; k < D; ++k) n *= static_cast<int>(std::floor(2.0 * R * lattice_.inv_h[k])) + 1;
  }
  return n;
}

template <int D, class Prior> void MaxEntBasis<D, Prior>::fail(const PointQuery<D>& q, const std::string& why) const {
  std::ostringstream msg;
  msg << kind_ << " basis: point ";
  if (q.id >= 0) msg << q.id << " at ";
  msg << format_point<D>(q.x) << ": " << why;
  throw BasisError(msg.str());
}

template <int D, class Prior>
template <class PriorValue>
int MaxEntBasis<D, Prior>::gather_support(const PointQuery<D>& q, double R, const PriorValue& prior_value,
                                          Stencil<D>& out, Vec<D>& lo, Vec<D>& hi) const {
  // Candidates: the point's Verlet list (a superset within the search
  // radius) or the nodes within R; the same distance test as
  // NodeSet::within keeps exactly its answer.
  const double R2 = R * R;
  std::span<const int> candidates;
  if (q.neighbours && R <= settings_.support_radius) {
    candidates = q.neighbours->candidates(nodes_, q.id, q.x, out.scratch_ids);
  } else {
    out.scratch_ids.clear();
    nodes_.within(q.x, R, out.scratch_ids);
    candidates = out.scratch_ids;
  }
  const int count = static_cast<int>(candidates.size());
  const int stride = simd::padded(count);
  // The scratch arrays only grow (their contents are meaningless between
  // calls): no value-initialisation when the candidate count changes.
  if (const auto size = static_cast<std::size_t>(kScratchArrays) * static_cast<std::size_t>(stride);
      out.scratch_w.size() < size)
    out.scratch_w.resize(size);
  // The kept ids go to scratch_ids: compacted in place when the candidates
  // are held there (kept index <= candidate index), else copied into it.
  const int* cand = candidates.data();
  if (cand != out.scratch_ids.data() && out.scratch_ids.size() < candidates.size())
    out.scratch_ids.resize(candidates.size());
  int* ids = out.scratch_ids.data();
  double* dx = out.scratch_w.data();
  double* value = dx + D * stride; // log w_I (Gaussian prior) or w_I
  double* grad_factor = value + stride;
  int n = 0;
  double low[D], high[D]; // locals: not aliased by the stores below
  for (int k = 0; k < D; ++k) low[k] = std::numeric_limits<double>::infinity(), high[k] = -low[k];
  const Vec<D> x = q.x;
  const Vec<D>* pos = nodes_.positions().data();
  for (int i = 0; i < count; ++i) {
    const int I = cand[i];
    const Vec<D> d = x - pos[I];
    double v, c;
    if (!(d.squaredNorm() <= R2) || !prior_value(I, d, v, c)) continue;
    ids[n] = I;
    value[n] = v;
    if constexpr (!Prior::kGaussian) grad_factor[n] = c;
#pragma GCC unroll 3
    for (int k = 0; k < D; ++k) {
      dx[k * stride + n] = d[k];
      low[k] = std::min(low[k], d[k]);
      high[k] = std::max(high[k], d[k]);
    }
    ++n;
  }
  if (out.node.size() != static_cast<std::size_t>(n)) out.node.resize(static_cast<std::size_t>(n));
  std::copy(ids, ids + n, out.node.data());
  for (int k = 0; k < D; ++k) lo[k] = low[k], hi[k] = high[k];
  for (int i = n; i < simd::padded(n); ++i) { // padding: N = 0
    for (int k = 0; k < D; ++k) dx[k * stride + i] = 0.0;
    value[i] = Prior::kGaussian ? -std::numeric_limits<double>::infinity() : 0.0;
  }
  return stride;
}

template <int D, class Prior>
int MaxEntBasis<D, Prior>::gather_metric_support(const PointQuery<D>& q, const PointMetric<D>& pm, Stencil<D>& out,
                                                 Vec<D>& lo, Vec<D>& hi, double widen) const {
  const double R = settings_.support_radius * widen;
  if constexpr (Prior::kGaussian) {
    // the cut-off exponent -ln(tol) scales with the square of the radius
    const double max_exponent = prior_.max_exponent * (widen * widen);
    if (metric_ == Metric::node_spacing) {
      // node I kept while beta_I |dx|^2 <= -ln(tol), i.e. within R_I = h_I sqrt(-ln(tol) / gamma_lme)
      const auto weight = [&](int I, const Vec<D>& d, double& w, double&) {
        const double e = node_beta_[static_cast<std::size_t>(I)] * d.squaredNorm();
        w = -e;
        return e <= max_exponent;
      };
      return gather_support(q, R, weight, out, lo, hi);
    }
    if (!pm.isotropic) {
      const Mat<D> B = pm.B;
      const auto weight = [&](int, const Vec<D>& d, double& w, double&) {
        const double e = d.dot(B * d);
        w = -e;
        return e <= max_exponent;
      };
      return gather_support(q, pm.radius * widen, weight, out, lo, hi);
    }
    if (widen != 1.0) {
      const auto weight = [&](int, const Vec<D>& d, double& w, double&) {
        return prior_.log_weight(d, w, max_exponent);
      };
      return gather_support(q, R, weight, out, lo, hi);
    }
  }
  const auto weight = [this](int, const Vec<D>& d, double& w, double& c) {
    if constexpr (Prior::kGaussian) {
      (void)c;
      return prior_.log_weight(d, w);
    } else {
      return prior_.weight(d, w, c); // the cubic spline's support is its own (not widened)
    }
  };
  return gather_support(q, R, weight, out, lo, hi);
}

template <int D, class Prior>
PointMetric<D> MaxEntBasis<D, Prior>::point_metric(const PointQuery<D>& q, const Mat<D>& F) const {
  PointMetric<D> pm;
  pm.radius = settings_.support_radius;
  if constexpr (D > 1 && Prior::kGaussian) {
    // M = (F F^T)^-1 det(F F^T)^(1/D) (det M = 1); the ellipse dx^T beta M dx
    // <= -ln(tol) reaches R sqrt(lambda_max(M^-1)) from the point.
    const Mat<D> b = F * F.transpose();
    const double det_b = b.determinant();
    if (!(det_b > 0.0) || !std::isfinite(det_b) || !b.allFinite())
      fail(q, "metric 'deformation': F F^T is not positive definite (det F F^T = " + format_number(det_b) + ")");
    const double scale = std::pow(det_b, 1.0 / D);
    const Mat<D> M = b.inverse() * scale;
    if (M == Mat<D>::Identity()) return pm; // F orthogonal: the isotropic prior, bit for bit
    Eigen::SelfAdjointEigenSolver<Mat<D>> eig;
    eig.computeDirect(b, Eigen::EigenvaluesOnly);
    const double stretch2 = eig.eigenvalues()[D - 1] / scale; // lambda_max(M^-1) >= 1
    if (!(stretch2 > 0.0) || !std::isfinite(stretch2))
      fail(q, "metric 'deformation': the eigenvalues of F F^T are not finite and positive");
    pm.isotropic = false;
    pm.B = prior_.beta * M;
    pm.radius = radius0_ * std::sqrt(std::max(1.0, stretch2)) * (1.0 + kMetricRadiusSlack);
  } else {
    (void)q;
    (void)F;
  }
  return pm;
}

template <int D, class Prior> bool MaxEntBasis<D, Prior>::uniform_beta(const Stencil<D>& out) const {
  if (metric_ != Metric::node_spacing) return true;
  const int n = out.size();
  for (int i = 1; i < n; ++i)
    if (node_beta_[static_cast<std::size_t>(out.node[i])] != node_beta_[static_cast<std::size_t>(out.node[0])])
      return false;
  return true;
}

template <int D, class Prior> void MaxEntBasis<D, Prior>::update_node_spacing() {
  update_beta_by_spacing(); // nothing for a prior without a beta
}

template <int D, class Prior> void MaxEntBasis<D, Prior>::update_beta_by_spacing() {
  // Defined for every prior (clang 14 instantiates constrained members with
  // the class); only the Gaussian (LME) prior has a beta to adapt.
  if constexpr (Prior::kGaussian) {
  const int N = nodes_.size();
  const double h = nodes_.spacing();
  node_beta_.assign(static_cast<std::size_t>(N), prior_.beta);
  double R_max = radius0_;
  if (!nodes_.on_lattice()) {
    nodes_.prepare_search();
    std::vector<double> h_I(static_cast<std::size_t>(N));
    // each node its own entry: the result does not depend on the threads
    parallel_chunks(N, [&](long long begin, long long end) {
      std::vector<int> near;
      for (auto I = static_cast<int>(begin); I < end; ++I)
        h_I[static_cast<std::size_t>(I)] = nearest_distance(nodes_, I, h, near);
    });
    R_max = 0.0;
    for (int I = 0; I < N; ++I) {
      const double hI = h_I[static_cast<std::size_t>(I)];
      const double beta = node_beta_[static_cast<std::size_t>(I)] = spacing_beta(prior_.beta, h, hI);
      R_max = std::max(R_max, std::sqrt(prior_.max_exponent / beta));
    }
  }
  settings_.support_radius = stepped_radius(radius0_, R_max);
  }
}

template <int D, class Prior> Support<D> MaxEntBasis<D, Prior>::support(Stencil<D>& out, int stride) const {
  const int n = out.size();
  double* base = out.scratch_w.data();
  Support<D> s;
  for (int k = 0; k < D; ++k) s.dx[k] = base + k * stride;
  s.log_w = Prior::kGaussian ? base + D * stride : nullptr;
  s.w = Prior::kGaussian ? nullptr : base + D * stride;
  s.grad_factor = base + (D + 1) * stride;
  s.n = n;
  s.n_pad = simd::padded(n);
  s.p = base + (D + 2) * stride;
  s.trial = base + (D + 3) * stride;
  s.radius = settings_.support_radius;
  return s;
}

template <int D, class Prior> void MaxEntBasis<D, Prior>::evaluate(const PointQuery<D>& q, Stencil<D>& out) const {
  RowTarget<D> target;
  target.stencil = &out;
  evaluate_to(q, target);
}

template <int D, class Prior>
int MaxEntBasis<D, Prior>::evaluate_into(const PointQuery<D>& q, int room, int* node, double* N, Vec<D>* dN,
                                         Stencil<D>& st) const {
  RowTarget<D> target;
  target.stencil = &st;
  target.node = node;
  target.N = N;
  target.dN = dN;
  target.room = room;
  return evaluate_to(q, target) && target.in_place ? target.size : -1;
}

template <int D, class Prior>
bool MaxEntBasis<D, Prior>::evaluate_to(const PointQuery<D>& q, RowTarget<D>& target) const {
  Stencil<D>& out = *target.stencil;
  // out is not cleared: gather_support and finish_stencil size its arrays
  // (kept at their size from the last point, no value-initialisation)
  if (!q.x.allFinite()) fail(q, "the position is not finite");
  PointMetric<D> pm;
  pm.radius = settings_.support_radius;
  if (metric_ == Metric::deformation && q.deformation) pm = point_metric(q, *q.deformation);
  if (evaluate_on_table(q, target)) return true;
  const Vec<D> warm = warm_start(q);
  if (evaluate_on_lattice(q, pm, warm, target)) return true;
  // The support within the prior's cut-off; where the point is not inside
  // its hull there (nodes held by a wall, crowded or torn apart), the same
  // prior over a search kWiden times wider (docs/theory.md sect. 4.8).
  NewtonState<D> st;
  Vec<D> lambda;
  Support<D> s;
  int n = 0, iterations = 0;
  for (int attempt = 0;; ++attempt) {
    const double widen = kWiden[attempt];
    const bool last = attempt + 1 == (Prior::kGaussian ? static_cast<int>(kWiden.size()) : 1);
    Vec<D> lo, hi;
    const int stride = gather_metric_support(q, pm, out, lo, hi, widen);
    n = out.size();
    if (n < D + 1) {
      if (!last) continue;
      if (q.moved && Prior::kGaussian && n > 0) return evaluate_moved(q, out, target);
      fail(q, "outside the convex hull of the nodes: only " + std::to_string(n) + " nodes within the support radius " +
                  format_number(pm.radius * widen) + " (at least " + std::to_string(D + 1) + " needed)");
    }
    s = support(out, stride);
    s.radius = pm.radius * widen;
    if (!within_extent(n, lo, hi)) {
      if (!last) continue;
      if (q.moved && Prior::kGaussian) return evaluate_moved(q, out, target);
      check_extent(q, n, lo, hi);
    }
    lambda = warm;
    st = solve_lambda<D>(settings_, s, lambda);
    iterations += st.iterations;
    // a failed solve is repeated from the plain warm start *q.lambda when the
    // prediction was another point, then from zero
    const Vec<D> retries[2] = {plain_start(q), Vec<D>::Zero()};
    Vec<D> tried = warm;
    for (const Vec<D>& start : retries) {
      if (st.status == NewtonStatus::converged) break;
      if (start == tried) continue;
      lambda = tried = start;
      st = solve_lambda<D>(settings_, s, lambda);
      iterations += st.iterations;
    }
    if (st.status == NewtonStatus::converged) {
      if (attempt > 0) widened_.fetch_add(1, std::memory_order_relaxed);
      break;
    }
    if (last) {
      if (q.iterations) *q.iterations = iterations;
      if (q.moved && Prior::kGaussian && n >= D + 1) return evaluate_moved(q, out, target);
      fail(q, describe_failure<D>(st, iterations, settings_.h, settings_.residual_tolerance / settings_.h, n));
    }
  }
  if (q.iterations) *q.iterations = iterations;
  const bool closed_form = Prior::kGaussian && uniform_beta(out);
  const Mat<D> two_B = closed_form && q.slope ? prior_hessian(pm, out) : Mat<D>::Zero();
  const Mat<D> JA = finish_stencil(st, s, closed_form, out);
  store_point_state(q, kept_multiplier(q, lambda, st.J_inv, st.r), iterations, two_B, JA);
  return false;
}

template <int D, class Prior>
bool MaxEntBasis<D, Prior>::evaluate_moved(const PointQuery<D>& q, const Stencil<D>& support, RowTarget<D>& target) const {
  // The centroid c of the widest support tried; the point moves along the
  // segment from c to x, to the farthest position whose solve converges
  // (bisection on the fraction s of x - c kept, to 1 / 2^kMoveBisections).
  Vec<D> c = Vec<D>::Zero();
  for (const int I : support.node) c += nodes_.position(I);
  c /= static_cast<double>(support.size());
  PointQuery<D> trial;
  trial.id = q.id;
  trial.deformation = q.deformation;
  Vec<D> lambda = Vec<D>::Zero();
  trial.lambda = &lambda;
  Stencil<D> scratch;
  const auto converges = [&](double s) {
    trial.x = c + s * (q.x - c);
    lambda.setZero();
    try {
      evaluate(trial, scratch);
      return true;
    } catch (const BasisError&) {
      return false;
    }
  };
  double inside = 0.0, outside = 1.0;
  if (!converges(inside))
    fail(q, "outside the convex hull of every node near it, and the centroid " + format_point<D>(c) +
                " of its " + std::to_string(support.size()) + " nearest nodes is not inside their hull either");
  for (int i = 0; i < kMoveBisections; ++i) {
    const double mid = 0.5 * (inside + outside);
    (converges(mid) ? inside : outside) = mid;
  }
  // The point's own evaluation at the position found, from a cold start:
  // its multiplier history belongs to the position it left.
  PointQuery<D> at = q;
  at.x = c + inside * (q.x - c);
  at.moved = nullptr;
  at.slope = nullptr;
  if (at.lambda) at.lambda->setZero();
  if (at.history) *at.history = MultiplierHistory<D>{};
  const bool lattice = evaluate_to(at, target);
  *q.moved = at.x - q.x;
  moved_.fetch_add(1, std::memory_order_relaxed);
  return lattice;
}

template <int D, class Prior>
bool MaxEntBasis<D, Prior>::evaluate_on_table(const PointQuery<D>& q, RowTarget<D>& out) const {
  if constexpr (Prior::kGaussian) {
    if (!box_ || lattice_.empty() || !nodes_.on_lattice()) return false;
    Vec<D> lambda;
    if (!box_table_stencil<D>(lattice_, *box_, q.x, out, lambda)) return false;
    // lme_box keeps no multiplier slope (point_state_use): the multiplier only
    store_point_state(q, lambda, 0, Mat<D>::Zero(), Mat<D>::Zero());
    return true;
  } else {
    (void)q, (void)out;
    return false;
  }
}

template <int D, class Prior>
bool MaxEntBasis<D, Prior>::evaluate_product_rows(const AlignedVector<Vec<D>>& x, ProductRows<D>& rows) {
  if constexpr (Prior::kGaussian) {
    if (!box_ || lattice_.empty() || !nodes_.on_lattice()) return false;
    PointState<D>& state = this->point_state();
    // lme_box keeps the multiplier alone (point_state_use) while the nodes stay
    if (state.lambda.size() != x.size() || !state.slope.empty() || !state.history.empty()) return false;
    const int n = static_cast<int>(x.size());
    rows.resize(n, box_->max_lanes()); // evaluated in place: the lanes an axis' lookup writes
    for (int k = 0; k < D; ++k) rows.stride[k] = lattice_.stride[k];
    std::atomic<bool> inside{true};
    parallel_chunks(n, [&](long long p0, long long p1) {
      const auto end = static_cast<int>(p1);
      if (box_table_factor_rows<D>(lattice_, *box_, x, static_cast<int>(p0), end, rows, state.lambda) != end)
        inside.store(false, std::memory_order_relaxed);
    });
    return inside.load() && rows.count_entries();
  } else {
    (void)x, (void)rows;
    return false;
  }
}

template <int D, class Prior>
bool MaxEntBasis<D, Prior>::evaluate_on_lattice(const PointQuery<D>& q, const PointMetric<D>& pm,
                                                const Vec<D>& warm, RowTarget<D>& out) const {
  if constexpr (Prior::kGaussian) {
    // on the lattice every beta_I of Metric::node_spacing is the prior's beta;
    // the box support is not lattice_solve's ball
    if (prior_.box || lattice_.empty() || !nodes_.on_lattice() || !pm.isotropic) return false;
    LatticeSolve<D> res;
    if (!lattice_solve<D>(lattice_, prior_, settings_, q.x, warm, out, res)) return false;
    const int first = out.in_place ? out.node[0] : out.stencil->node[0];
    store_point_state(q, kept_multiplier(q, res.lambda, res.J_inv, res.r), res.iterations, prior_hessian(pm, first),
                      res.J_inv);
    return true;
  } else {
    (void)q, (void)pm, (void)warm, (void)out;
    return false;
  }
}

template <int D, class Prior>
void MaxEntBasis<D, Prior>::store_point_state(const PointQuery<D>& q, const Vec<D>& lambda, int iterations,
                                              const Mat<D>& two_B, const Mat<D>& JA) const {
  if (q.iterations) *q.iterations = iterations;
  if (q.lambda && q.history) { // lambda_n becomes lambda_{n-1}
    MultiplierHistory<D>& h = *q.history;
    h.before = h.previous;
    h.previous = *q.lambda;
    h.solves = std::min(h.solves + 1, 3);
  }
  if (q.lambda) *q.lambda = lambda;
  if (q.slope) {
    q.slope->e = q.slope->G.isZero(0.0) ? Vec<D>::Zero().eval() : Vec<D>(q.x - q.slope->x0);
    q.slope->G_prev = q.slope->G;
    q.slope->x0 = q.x;
    q.slope->G = two_B - JA;
  }
}

template <int D, class Prior> Vec<D> MaxEntBasis<D, Prior>::warm_start(const PointQuery<D>& q) const {
  if (!q.lambda || !q.lambda->allFinite()) return Vec<D>::Zero();
  if (q.history) return extrapolated_start<D>(*q.lambda, *q.history);
  if (!q.slope) return *q.lambda;
  const Vec<D> d = q.x - q.slope->x0;
  Vec<D> predicted = *q.lambda + q.slope->G * d;
  // eq. 4.7b: along the last displacement e, (G - G_prev) / |e| is the
  // derivative of G, so 1/2 alpha (G - G_prev) d is the second-order term
  const Vec<D>& e = q.slope->e;
  if (!predicted.allFinite()) return *q.lambda;
  if (const double ee = e.squaredNorm(); ee > 0.0) {
    const double alpha = d.dot(e) / ee;
    if (std::abs(alpha) <= kCurvatureMaxRatio && (d - alpha * e).squaredNorm() <= kCurvatureAngle2 * d.squaredNorm()) {
      const Vec<D> second = (0.5 * alpha) * ((q.slope->G - q.slope->G_prev) * d);
      if (second.allFinite()) predicted += second; // else the first-order start
    }
  }
  return predicted;
}

template <int D, class Prior>
Mat<D> MaxEntBasis<D, Prior>::prior_hessian(const PointMetric<D>& pm, int first) const {
  if constexpr (Prior::kGaussian) {
    if (!pm.isotropic) return 2.0 * pm.B;
    const double beta =
        metric_ == Metric::node_spacing ? node_beta_[static_cast<std::size_t>(first)] : prior_.beta;
    return Mat<D>::Identity() * (2.0 * beta);
  } else {
    (void)pm, (void)first;
    return Mat<D>::Zero();
  }
}

template <int D, class Prior>
bool MaxEntBasis<D, Prior>::within_extent(int n, const Vec<D>& lo, const Vec<D>& hi) const {
  (void)n;
  for (int k = 0; k < D; ++k)
    if (lo[k] > settings_.residual_tolerance || hi[k] < -settings_.residual_tolerance) return false;
  return true;
}

template <int D, class Prior>
void MaxEntBasis<D, Prior>::check_extent(const PointQuery<D>& q, int n, const Vec<D>& lo, const Vec<D>& hi) const {
  for (int k = 0; k < D; ++k)
    // dx = x - x_I: x beyond every support node along axis k.
    if (lo[k] > settings_.residual_tolerance || hi[k] < -settings_.residual_tolerance)
      fail(q, "outside the convex hull of its " + std::to_string(n) + " support nodes (beyond their extent along axis " +
                  std::to_string(k) + ")");
}

template <int D, class Prior>
Mat<D> MaxEntBasis<D, Prior>::finish_stencil(const NewtonState<D>& st, const Support<D>& s, bool closed_form,
                                             Stencil<D>& out) const {
  const int n = s.n;
  Mat<D> JA = st.J_inv;
  const double inv_Z = 1.0 / st.Z;
  if (closed_form) {
    // grad N_I = -N_I J^{-1} (xbar - x_I) = -N_I J^{-1} (dx_I - r), on whole
    // vectors (the padding lanes of the last vector are computed, not stored:
    // growing the stencil to the padded size and back cost a call per point)
    // (sizes kept from the last point when equal: no call)
    if (out.N.size() != static_cast<std::size_t>(n)) out.N.resize(static_cast<std::size_t>(n));
    if (out.dN.size() != static_cast<std::size_t>(n)) out.dN.resize(static_cast<std::size_t>(n));
    double* N_out = out.N.data();
    double* dN = out.dN.data()->data(); // D doubles per entry
    const simd::vd scale = simd::broadcast(inv_Z);
    simd::vl positive = ~simd::vl{}; // all lanes: N_I > 0 so far
    const simd::vd zero = simd::broadcast(0.0);
    bool tail_positive = true;
    const Broadcast<D> r_lanes(st.r);
    simd::vd J_inv[D][D]; // broadcast once, not per vector of nodes
#pragma GCC unroll 3
    for (int k = 0; k < D; ++k)
#pragma GCC unroll 3
      for (int l = 0; l < D; ++l) J_inv[k][l] = simd::broadcast(st.J_inv(k, l));
    const auto entries = [&](int i, int m) { // nodes i .. i + m - 1, m <= lanes
      const simd::vd N = simd::load(s.p + i) * scale;
      simd::vd c[D], g[D];
#pragma GCC unroll 3
      for (int l = 0; l < D; ++l) c[l] = simd::load(s.dx[l] + i) - r_lanes.v[l];
#pragma GCC unroll 3
      for (int k = 0; k < D; ++k) {
        g[k] = J_inv[k][0] * c[0];
#pragma GCC unroll 3
        for (int l = 1; l < D; ++l) g[k] += J_inv[k][l] * c[l];
        g[k] = -N * g[k];
      }
      if (m == simd::lanes) { // a whole vector (m is a constant here once inlined)
        simd::store(N_out + i, N);
        positive &= simd::less(zero, N);
#pragma GCC unroll 4
        for (int j = 0; j < simd::lanes; ++j)
#pragma GCC unroll 3
          for (int k = 0; k < D; ++k) dN[(i + j) * D + k] = g[k][j];
      } else {
        for (int j = 0; j < m; ++j) {
          N_out[i + j] = N[j];
          tail_positive = tail_positive && N[j] > 0.0;
#pragma GCC unroll 3
          for (int k = 0; k < D; ++k) dN[(i + j) * D + k] = g[k][j];
        }
      }
    };
    int i = 0;
    for (; i + simd::lanes <= n; i += simd::lanes) entries(i, simd::lanes);
    if (i < n) entries(i, n - i);
    bool zeros = !tail_positive;
    for (int j = 0; j < simd::lanes; ++j) zeros = zeros || positive[j] == 0;
    if (zeros) drop_zeros(out);
    return JA;
  }
  out.N.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) out.N[i] = s.p[i] * inv_Z;
  if constexpr (Prior::kGaussian) { // beta_I of each node (Metric::node_spacing)
    const auto grad_log = [&](int i) {
      return Vec<D>(-2.0 * node_beta_[static_cast<std::size_t>(out.node[i])] * s.offset(i));
    };
    JA = general_gradient(st, s, grad_log, out);
  } else {
    // c_I from gather_support: c_I dx_I is prior_.grad_log_weight(dx_I), bit for bit
    JA = general_gradient(st, s, [&](int i) { return Vec<D>(s.grad_factor[i] * s.offset(i)); }, out);
  }
  bool positive = true; // no short cut: one test per node
  for (int i = 0; i < n; ++i) positive &= out.N[i] > 0.0;
  const bool zeros = !positive;
  if (zeros) drop_zeros(out);
  return JA;
}

template <int D, class Prior>
template <class GradLog>
Mat<D> MaxEntBasis<D, Prior>::general_gradient(const NewtonState<D>& st, const Support<D>& s, const GradLog& grad_log,
                                             Stencil<D>& out) const {
  const int n = s.n;
  out.dN.resize(static_cast<std::size_t>(n));
  Vec<D> g_bar = Vec<D>::Zero();
  for (int i = 0; i < n; ++i) {
    out.dN[i] = grad_log(i); // g_I, overwritten below
    g_bar += out.N[i] * out.dN[i];
  }
  Mat<D> A = Mat<D>::Zero();
  for (int i = 0; i < n; ++i) A.noalias() += (out.N[i] * (s.offset(i) - st.r)) * (out.dN[i] - g_bar).transpose();
  const Mat<D> M = (Mat<D>::Identity() + A.transpose()) * st.J_inv;
  for (int i = 0; i < n; ++i) out.dN[i] = out.N[i] * (out.dN[i] - g_bar - M * (s.offset(i) - st.r));
  return M.transpose();
}

template <int D, class Prior> void MaxEntBasis<D, Prior>::drop_zeros(Stencil<D>& out) const {
  // Drop nodes whose N_I underflowed to zero (their gradient is zero too).
  const int n = out.size();
  int kept = 0;
  for (int i = 0; i < n; ++i) {
    if (!(out.N[i] > 0.0)) continue;
    out.node[kept] = out.node[i];
    out.N[kept] = out.N[i];
    out.dN[kept] = out.dN[i];
    ++kept;
  }
  out.node.resize(static_cast<std::size_t>(kept));
  out.N.resize(static_cast<std::size_t>(kept));
  out.dN.resize(static_cast<std::size_t>(kept));
}

template <int D> double nearest_node_distance(const NodeSet<D>& nodes, int I, double h) {
  std::vector<int> near;
  return nearest_distance(nodes, I, h, near);
}

double node_spacing_search_radius(const BasisOptions& opt, double h, double nearest_max) {
  // make_lme_basis' prior and update_beta_by_spacing's radius for the node
  // with the largest h_I (R_I = sqrt(max_exponent / beta_I) does not
  // decrease as h_I grows, each rounded operation being monotone).
  const GaussianPrior<1> prior = lme_prior<1>(opt, h);
  const double R_max = std::max(0.0, std::sqrt(prior.max_exponent / spacing_beta(prior.beta, h, nearest_max)));
  return stepped_radius(prior.support_radius(), R_max);
}

template struct GaussianPrior<1>;
template struct GaussianPrior<2>;
template struct GaussianPrior<3>;
template struct CubicSplinePrior<1>;
template struct CubicSplinePrior<2>;
template struct CubicSplinePrior<3>;
template class MaxEntBasis<1, GaussianPrior<1>>;
template class MaxEntBasis<2, GaussianPrior<2>>;
template class MaxEntBasis<3, GaussianPrior<3>>;
template class MaxEntBasis<1, CubicSplinePrior<1>>;
template class MaxEntBasis<2, CubicSplinePrior<2>>;
template class MaxEntBasis<3, CubicSplinePrior<3>>;
template int max_nodes_within<1>(const NodeSet<1>&, double);
template int max_nodes_within<2>(const NodeSet<2>&, double);
template int max_nodes_within<3>(const NodeSet<3>&, double);
template double nearest_node_distance<1>(const NodeSet<1>&, int, double);
template double nearest_node_distance<2>(const NodeSet<2>&, int, double);
template double nearest_node_distance<3>(const NodeSet<3>&, int, double);

} // namespace otmpm::maxent

namespace otmpm {

namespace {

/// The volume of the ball of radius r (in units of h) in dim dimensions:
/// the lattice nodes a max-ent support holds.
double ball_volume(int dim, double r) {
  if (dim == 1) return 2.0 * r;
  if (dim == 2) return std::numbers::pi * r * r;
  return 4.0 / 3.0 * std::numbers::pi * r * r * r;
}

} // namespace

std::span<const ParameterSpec> lme_parameters() { return maxent::kLmeParameters; }
std::span<const ParameterSpec> maxent_parameters() { return maxent::kMaxentParameters; }

namespace {
/// The support radius of lme and lme_box in units of h: exp(-gamma_lme r^2) = tolerance.
double lme_radius(const BasisOptions& o) {
  return std::sqrt(-std::log(o.value(maxent::kTolerance)) / o.value(maxent::kGammaLme));
}
} // namespace

double lme_stencil_nodes(const BasisOptions& o, int dim) {
  const double radius = lme_radius(o);
  return std::max(std::pow(2.0, dim), ball_volume(dim, radius));
}
double lme_box_stencil_nodes(const BasisOptions& o, int dim) {
  // the mean count of lattice lines within R of a point is 2 R / h per axis
  const double radius = lme_radius(o);
  return std::max(std::pow(2.0, dim), std::pow(2.0 * radius, dim));
}
double lme_box_row_bytes(const BasisOptions& o, int dim) {
  if (o.metric != "isotropic") return 0.0; // the metric adapts: a table (evaluate_product_rows)
  const double radius = lme_radius(o);
  if (!maxent::box_support_fits(radius)) return 0.0; // no 1D tables (BoxAxisTable): a table
  // an axis' box: at most floor(2 R / h) + 1 lines (BoxAxisTable's segments)
  const double lanes = maxent::box_lanes(static_cast<int>(std::floor(2.0 * radius)) + 1);
  return dim * (4.0 + 16.0 * lanes) + 8.0 + dim * sizeof(double);
}
double maxent_stencil_nodes(const BasisOptions& o, int dim) {
  return std::max(std::pow(2.0, dim), ball_volume(dim, o.value(maxent::kDMax)));
}

namespace {

/// The nodal spacing of a max-ent family's nodes; InputError naming `kind`
/// unless it is finite and > 0.
template <int D> double checked_spacing(const NodeSet<D>& nodes, std::string_view kind) {
  const double h = nodes.spacing();
  if (!(h > 0.0) || !std::isfinite(h))
    throw InputError(std::string(kind) + " basis: the nodal spacing must be > 0, got " +
                     maxent::format_number(h));
  return h;
}

/// InputError naming `kind` unless opt.metric is "isotropic" (`hint`: what
/// to use instead).
void require_isotropic(const BasisOptions& opt, std::string_view kind, std::string_view hint) {
  if (maxent::parse_metric(opt.metric, kind) != maxent::Metric::isotropic)
    throw InputError(std::string(kind) + " basis: metric '" + opt.metric + "' is not available (" +
                     std::string(hint) + ")");
}

} // namespace

template <int D> std::unique_ptr<Basis<D>> make_lme_basis(NodeSet<D> nodes, const BasisOptions& opt) {
  require_options(opt, maxent::kLmeParameters);
  const double h = checked_spacing(nodes, "lme");
  const maxent::Metric metric = maxent::parse_metric(opt.metric, "lme");
  const maxent::GaussianPrior<D> prior = maxent::lme_prior<D>(opt, h);
  return std::make_unique<maxent::MaxEntBasis<D, maxent::GaussianPrior<D>>>(std::move(nodes), opt, prior, "lme",
                                                                             metric);
}

template <int D> std::unique_ptr<Basis<D>> make_lme_box_basis(NodeSet<D> nodes, const BasisOptions& opt) {
  require_options(opt, maxent::kLmeParameters);
  const double h = checked_spacing(nodes, "lme_box");
  require_isotropic(opt, "lme_box",
                    "the box support is the isotropic prior's; use kind = \"lme\" to adapt the metric");
  maxent::GaussianPrior<D> prior = maxent::lme_prior<D>(opt, h);
  prior.box = true;
  return std::make_unique<maxent::MaxEntBasis<D, maxent::GaussianPrior<D>>>(std::move(nodes), opt, prior,
                                                                            "lme_box");
}

template <int D> std::unique_ptr<Basis<D>> make_maxent_basis(NodeSet<D> nodes, const BasisOptions& opt) {
  require_options(opt, maxent::kMaxentParameters);
  const double h = checked_spacing(nodes, "maxent");
  require_isotropic(opt, "maxent", "only lme adapts its metric; use metric = \"isotropic\"");
  const maxent::CubicSplinePrior<D> prior(opt.value(maxent::kDMax) * h);
  return std::make_unique<maxent::MaxEntBasis<D, maxent::CubicSplinePrior<D>>>(std::move(nodes), opt, prior,
                                                                                "maxent");
}

template std::unique_ptr<Basis<1>> make_lme_basis<1>(NodeSet<1>, const BasisOptions&);
template std::unique_ptr<Basis<2>> make_lme_basis<2>(NodeSet<2>, const BasisOptions&);
template std::unique_ptr<Basis<3>> make_lme_basis<3>(NodeSet<3>, const BasisOptions&);
template std::unique_ptr<Basis<1>> make_lme_box_basis<1>(NodeSet<1>, const BasisOptions&);
template std::unique_ptr<Basis<2>> make_lme_box_basis<2>(NodeSet<2>, const BasisOptions&);
template std::unique_ptr<Basis<3>> make_lme_box_basis<3>(NodeSet<3>, const BasisOptions&);
template std::unique_ptr<Basis<1>> make_maxent_basis<1>(NodeSet<1>, const BasisOptions&);
template std::unique_ptr<Basis<2>> make_maxent_basis<2>(NodeSet<2>, const BasisOptions&);
template std::unique_ptr<Basis<3>> make_maxent_basis<3>(NodeSet<3>, const BasisOptions&);

} // namespace otmpm
