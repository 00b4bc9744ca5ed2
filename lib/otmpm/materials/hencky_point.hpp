#pragma once
/// \file hencky_point.hpp
/// The point updates of hencky_plasticity.hpp as inline templates, internal
/// to materials/: hencky_plasticity.cpp instantiates them behind j2_update and
/// drucker_prager_update, and HenckyMaterial (hencky_material.hpp) inlines them
/// into its particle loop (no call, no PointUpdate through memory per particle).
/// Structure of a step:
///  1. kinematics (per dimension): b_e_trial = dF b_e dF^T and its spectral
///     form, reduced to the two invariants the return mappings need,
///     e_v = tr(e) and |dev e|^2 (update1, update2, update3_series / _eigen);
///  2. the return mapping in those invariants (j2_return, dp_return): the new
///     e_v and the factor beta of the deviator, e_new = e_v_new/3 I + beta dev e;
///  3. reconstruction (per dimension): tau and, after a plastic return,
///     b_e_new = exp(2 e_new) in the eigenbasis of b_e_trial.
#include "otmpm/materials/hencky_plasticity.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace otmpm::plasticity::point {


/// Static part of the J2 yield stress, sigma_y0 + H eps + B eps^n, and its
/// derivative with respect to eps (0^n = 0; the derivative at eps = 0 is
/// taken as H, which only matters as a Newton slope).
struct Hardening {
  double value, slope;
};
inline Hardening static_flow_stress(const J2Parameters& p, double eps) {
  Hardening h{p.yield_stress + p.hardening_modulus * eps, p.hardening_modulus};
  if (p.johnson_cook && p.johnson_cook->B > 0.0 && eps > 0.0) {
    const double pw = std::pow(eps, p.johnson_cook->n);
    h.value += p.johnson_cook->B * pw;
    h.slope += p.johnson_cook->B * p.johnson_cook->n * pw / eps;
  }
  return h;
}


/// Outcome of a return mapping in strain invariants: the new volumetric
/// elastic strain e_v and the factor beta in dev e_new = beta dev e_trial.
struct Return {
  double ev = 0.0;
  double beta = 1.0;
  bool plastic = false;
  int iterations = 0;
};

constexpr int kMaxNewton = 100;
/// Johnson-Cook consistency tolerance |f| <= kNewtonTol sigma_y (relative).
constexpr double kNewtonTol = 1e-12;

/// Johnson-Cook return: solves r(x) = q - 3 G x - sigma_y(eps_n + x, x / dt) = 0
/// for x = delta eps_p in [0, q / (3 G)] (hencky_plasticity.cpp).
double johnson_cook_return(const J2Parameters& p, double q, double eps_n, double dt, int& iterations);

/// J2 radial return in invariants (ev, dev2 = |dev e|^2): q = sqrt(6) G |dev e|.
[[gnu::always_inline]] inline Return j2_return(const J2Parameters& p, double ev, double dev2, double dt, HenckyState& s) {
  const double G = p.elastic.shear;
  const double sy = static_flow_stress(p, s.eps_p).value; // rate factor is 1 at delta eps_p = 0
  const double q2 = 6.0 * G * G * dev2;
  if (q2 <= sy * sy) return {ev, 1.0, false, 0};
  const double q = std::sqrt(q2);
  Return r{ev, 1.0, true, 0};
  if (p.johnson_cook) {
    const double dgamma = johnson_cook_return(p, q, s.eps_p, dt, r.iterations);
    r.beta = 1.0 - 3.0 * G * dgamma / q;
    s.eps_p += dgamma;
    return r;
  }
  // Closed form (linear hardening): delta eps_p = (q - sigma_y) / (3 G + H) and
  // beta = q_new / q = (3 G sigma_y + H q) / ((3 G + H) q), with one division.
  const double H = p.hardening_modulus, inv = 1.0 / ((3.0 * G + H) * q);
  s.eps_p += (q - sy) * q * inv;
  r.beta = (3.0 * G * sy + H * q) * inv;
  return r;
}

/// Drucker-Prager return in invariants: p = K ev, sqrt(J2) = sqrt(2) G |dev e|.
/// Regions (T = tension cutoff <= apex): elastic; cap (p -> T, s kept); cone
/// (closed form, p_new <= T); corner (p = T and sqrt(J2) = xi c - eta T; the
/// apex when T = apex).
[[gnu::always_inline]] inline Return dp_return(const DruckerPrager& m, double ev, double dev2, HenckyState& s) {
  const double K = m.elastic().bulk, G = m.elastic().shear;
  const double c = m.parameters().cohesion, T = m.tension_cutoff();
  const double eta = m.eta(), xi = m.xi(), eta_bar = m.eta_bar();
  const double p = K * ev;
  const double limit = xi * c - eta * p; // sqrt(J2) allowed at p
  if (p <= T && limit >= 0.0 && 2.0 * G * G * dev2 <= limit * limit) return {ev, 1.0, false, 0};
  const double dev_norm = std::sqrt(dev2);
  const double sqrt_j2 = std::sqrt(2.0) * G * dev_norm;
  const double limit_T = xi * c - eta * T; // sqrt(J2) at the corner, >= 0
  Return r{ev, 1.0, true, 0};
  if (p > T && sqrt_j2 <= limit_T) {
    r.ev = T / K; // cap: volumetric return only
  } else {
    const double dgamma = (sqrt_j2 + eta * p - xi * c) / (G + K * eta * eta_bar);
    const double ev_cone = ev - eta_bar * dgamma;
    if (K * ev_cone <= T) {
      r.ev = ev_cone;
      r.beta = 1.0 - G * dgamma / sqrt_j2;
    } else {
      r.ev = T / K; // corner (apex when limit_T = 0)
      r.beta = limit_T / sqrt_j2;
    }
  }
  s.eps_v += ev - r.ev;
  s.eps_p += std::sqrt(2.0 / 3.0) * (1.0 - r.beta) * dev_norm;
  return r;
}
// ------------------------------------------------------------ kinematics

// The series of the point updates as templates on the number type: T is
// double (one particle) or Lanes2 (two particles, hencky_plane_j2.hpp), the
// same operations in the same order either way.

/// e^d by its Taylor polynomial of degree 7 for |d| <= 1/64 (truncation
/// < (1/64)^8 / 8! = 9e-20 relative), by Estrin's scheme: three levels of
/// multiplications instead of a chain of seven.
template <class T> [[gnu::always_inline]] inline T exp_series(T d) {
  const T d2 = d * d, d4 = d2 * d2;
  const T lo = (1.0 + d) + d2 * (1.0 / 2 + d * (1.0 / 6));
  const T hi = (1.0 / 24 + d * (1.0 / 120)) + d2 * (1.0 / 720 + d * (1.0 / 5040));
  return lo + d4 * hi;
}

/// ln(1 + u) = u - u^2 (1/2 - u/3 + ... - u^9/11) for |u| <= 1/32
/// (truncation u^11/12 < 3e-18 relative; the leading u is exact, so the
/// error is that of std::log, ~0.5 ulp).
template <class T> inline T log1p_series(T u) {
  const T u2 = u * u, u4 = u2 * u2, u8 = u4 * u4;
  const T a = (1.0 / 2 - u * (1.0 / 3)) + u2 * (1.0 / 4 - u * (1.0 / 5));
  const T b = (1.0 / 6 - u * (1.0 / 7)) + u2 * (1.0 / 8 - u * (1.0 / 9));
  const T c = 1.0 / 10 - u * (1.0 / 11);
  return u - u2 * ((a + u4 * b) + u8 * c);
}

/// atanh(x) / x = sum x^(2k) / (2k + 1) as a function of x2 = x^2 < 1e-2, to
/// x^18 (truncation x^20/21 < 1e-21), by Estrin's scheme.
template <class T> inline T atanh_series(T x2) {
  const T x4 = x2 * x2, x8 = x4 * x4;
  const T lo = (1.0 + x2 * (1.0 / 3)) + x4 * (1.0 / 5 + x2 * (1.0 / 7));
  const T mid = (1.0 / 9 + x2 * (1.0 / 11)) + x4 * (1.0 / 13 + x2 * (1.0 / 15));
  const T hi = 1.0 / 17 + x2 * (1.0 / 19);
  return lo + x8 * (mid + x8 * hi);
}

/// cosh(y) and sinh(y)/y from y2 = y^2 <= 1/256 by their series to y^8
/// (truncation y^10/10! < 3e-19).
template <class T> inline void cosh_shc_series(T y2, T& ch, T& shc) {
  const T y4 = y2 * y2;
  ch = (1.0 + y2 * (1.0 / 2)) + y4 * ((1.0 / 24 + y2 * (1.0 / 720)) + y4 * (1.0 / 40320));
  shc = (1.0 + y2 * (1.0 / 6)) + y4 * ((1.0 / 120 + y2 * (1.0 / 5040)) + y4 * (1.0 / 362880));
}

/// e^d. A return changes the log strains by little per step, so b_e_new is
/// formed as b_e_trial e^(2 (e_new - e_trial)) in the common eigenbasis with
/// a small argument: Taylor polynomial of degree 3 for |d| <= 2^-17 (the
/// usual plastic increment of a step; truncation < d^4 / 4! < 2e-22
/// relative), of degree 7 for |d| <= 1/64 (truncation < (1/64)^8 / 8! =
/// 9e-20), std::exp beyond.
inline double exp_small(double d) {
  if (std::abs(d) <= 0x1p-17) return (1.0 + d) + d * d * (1.0 / 2 + d * (1.0 / 6));
  if (!(std::abs(d) <= 1.0 / 64)) return std::exp(d);
  return exp_series(d);
}

/// ln(x) for x > 0: the series ln(1 + u) = u - u^2 (1/2 - u/3 + ... - u^9/11)
/// for |u| = |x - 1| <= 1/32 (truncation u^11/12 < 3e-18 relative; the
/// leading u is exact, so the error is that of std::log, ~0.5 ulp), std::log
/// beyond. The Hencky strains of an elastic predictor are the logs of
/// numbers near 1 (|e| < 1.5%: metals, soils); the series is shorter on the
/// critical path of a point update than the library call.
inline double log_near1(double x) {
  const double u = x - 1.0;
  if (!(std::abs(u) <= 1.0 / 32)) return std::log(x);
  return log1p_series(u);
}

/// cosh(y) and sinh(y)/y from y^2: Taylor series to y^4 for y^2 <= 2^-20
/// (truncation y^6/6! < 2e-21), to y^8 for y^2 <= 1/256 (truncation
/// y^10/10! < 3e-19), the library functions beyond.
inline void cosh_shc(double y2, double& ch, double& shc) {
  if (y2 <= 0x1p-20) {
    ch = 1.0 + y2 * (1.0 / 2 + y2 * (1.0 / 24));
    shc = 1.0 + y2 * (1.0 / 6 + y2 * (1.0 / 120));
    return;
  }
  if (!(y2 <= 1.0 / 256)) {
    const double y = std::sqrt(y2);
    ch = std::cosh(y);
    shc = std::sinh(y) / y;
    return;
  }
  cosh_shc_series(y2, ch, shc);
}

/// psi(ev, dev2) = K/2 ev^2 + G dev2.
inline double energy(const ElasticModuli& el, double ev, double dev2) {
  return 0.5 * el.bulk * ev * ev + el.shear * dev2;
}

/// The material dissipation of a return, tau_new : delta e_p with
/// delta e_p = e_trial - e_new = (e_v - e_v_new)/3 I + (1 - beta) dev e_trial:
/// K e_v_new (e_v - e_v_new) + 2 G beta (1 - beta) |dev e_trial|^2, >= 0 in
/// exact arithmetic for both models (theory doc), rounding clamped.
inline double dissipated_energy(const ElasticModuli& el, double ev, double dev2, const Return& r) {
  return std::max(0.0, el.bulk * r.ev * (ev - r.ev) + 2.0 * el.shear * r.beta * (1.0 - r.beta) * dev2);
}

/// The algorithmic part of psi(trial) - psi(new), 1/2 delta e_p : C : delta e_p.
inline double return_energy(const ElasticModuli& el, double ev, double dev2, const Return& r) {
  return 0.5 * el.bulk * (ev - r.ev) * (ev - r.ev) + el.shear * (1.0 - r.beta) * (1.0 - r.beta) * dev2;
}

// The checks of every update: one inline comparison; the message is built in
// a cold function, only on failure.
[[noreturn]] void throw_increment(const char* who, double det);
[[noreturn]] void throw_strain(const char* who);
inline void check_increment(const char* who, double det) {
  if (!(det > 0.0 && det <= std::numeric_limits<double>::max())) [[unlikely]]
    throw_increment(who, det);
}
inline void check_strain(const char* who, double ev, double dev2) {
  if (!std::isfinite(ev + dev2)) [[unlikely]]
    throw_strain(who);
}

inline void fill_energies(PointUpdate& out, const ElasticModuli& el, double ev, double dev2, const Return& r) {
  out.elastic_energy = energy(el, r.ev, r.beta * r.beta * dev2);
  out.plastic = r.plastic;
  out.iterations = r.iterations;
  if (!r.plastic) return;
  out.plastic_work = dissipated_energy(el, ev, dev2, r);
  out.return_work = return_energy(el, ev, dev2, r);
}

/// Symmetric A M A^T for symmetric M (upper triangle of the product formed,
/// mirrored: exactly symmetric).
inline Mat3 push_forward(const Mat3& A, const Mat3& M) {
  Mat3 AM;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) AM(i, j) = A(i, 0) * M(0, j) + A(i, 1) * M(1, j) + A(i, 2) * M(2, j);
  Mat3 R;
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) R(i, j) = R(j, i) = AM(i, 0) * A(j, 0) + AM(i, 1) * A(j, 1) + AM(i, 2) * A(j, 2);
  return R;
}

/// Q diag(d) Q^T, exactly symmetric.
inline Mat3 spectral(const Mat3& Q, const Eigen::Vector3d& d) {
  Mat3 R;
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j)
      R(i, j) = R(j, i) = Q(i, 0) * d[0] * Q(j, 0) + Q(i, 1) * d[1] * Q(j, 1) + Q(i, 2) * d[2] * Q(j, 2);
  return R;
}

/// 3D, b_e_trial far from a multiple of I: Jacobi eigen-decomposition,
/// e_i = 1/2 ln lambda_i, tau and b_e_new assembled in the eigenbasis.
template <class ReturnMap>
[[gnu::noinline]] PointUpdate update3_eigen(const char* who, const ElasticModuli& el, const Mat3& btr, HenckyState& st, ReturnMap&& ret) {
  Eigen::Vector3d lambda;
  Mat3 Q;
  symmetric_eigen(btr, lambda, Q);
  Eigen::Vector3d e(0.5 * std::log(lambda[0]), 0.5 * std::log(lambda[1]), 0.5 * std::log(lambda[2]));
  const double ev = e.sum();
  const Eigen::Vector3d dev = e.array() - ev / 3.0;
  const double dev2 = dev.squaredNorm();
  check_strain(who, ev, dev2);
  const Return r = ret(ev, dev2);
  PointUpdate out;
  const double K = el.bulk, G2b = 2.0 * el.shear * r.beta;
  out.kirchhoff = spectral(Q, (K * r.ev + G2b * dev.array()).matrix());
  if (r.plastic) {
    // lambda_i e^(2 (e_new,i - e_i)), e_new - e = (e_v_new - e_v)/3 + (beta - 1) dev e.
    const double dv = 2.0 * (r.ev - ev) / 3.0, db = 2.0 * (r.beta - 1.0);
    st.be = spectral(Q, Eigen::Vector3d(lambda[0] * exp_small(dv + db * dev[0]), lambda[1] * exp_small(dv + db * dev[1]),
                                        lambda[2] * exp_small(dv + db * dev[2])));
  } else {
    st.be = btr;
  }
  fill_energies(out, el, ev, dev2, r);
  return out;
}

/// Spectral radius bound up to which update3_series is used: b_e_trial / m
/// has eigenvalues 1 + z_i with |z_i| <= 0.05 (deviatoric elastic log
/// strains up to ~2.5%, every metal and most soils); 13 terms at most.
constexpr double kSeriesRadius = 0.05;
constexpr int kMaxTerms = 14;
/// 1 / (k + 1), k = 0 .. kMaxTerms - 1 (no division inside the series loops).
constexpr double kInverse[kMaxTerms] = {1.0,       1.0 / 2,  1.0 / 3,  1.0 / 4,  1.0 / 5,  1.0 / 6,  1.0 / 7,
                                        1.0 / 8,   1.0 / 9,  1.0 / 10, 1.0 / 11, 1.0 / 12, 1.0 / 13, 1.0 / 14};
/// 2^-56: truncation of the series below the round-off of Z itself.
constexpr double kSeriesTolerance = 1.3877787807814457e-17;

/// 3D, b_e_trial = m (I + Z) near a multiple of I (Z traceless, |z_i| <=
/// kSeriesRadius): no eigen-decomposition. Every power of Z reduces by
/// Cayley-Hamilton, Z^3 = J2 Z + J3 I (J2 = tr(Z^2)/2, J3 = det Z), to
/// Z^k = p_k I + q_k Z + r_k Z^2 with p_{k+1} = r_k J3, q_{k+1} = p_k + r_k J2,
/// r_{k+1} = q_k, so the series
///   ln(I + Z)  = sum (-1)^(k+1) Z^k / k         = c0 I + c1 Z + c2 Z^2,
///   (I + Z)^beta = I + sum binom(beta, k) Z^k   = d0 I + d1 Z + d2 Z^2
/// cost a few scalar operations per term. Then e = 1/2 (ln m I + ln(I + Z)),
/// S = tr ln(I + Z) = 3 c0 + 2 J2 c2, e_v = 1/2 (3 ln m + S),
/// 2 dev e = c1 Z + c2 (Z^2 - 2 J2/3 I), |2 dev e|^2 = 2 J2 c1^2 + 6 J3 c1 c2 + 2/3 J2^2 c2^2,
/// and b_e_new = exp(2 e_new) = exp(2 e_v_new / 3 - beta S / 3) (I + Z)^beta.
/// The power series of (I + Z)^beta uses the same p_k, q_k, r_k.
template <class ReturnMap>
[[gnu::always_inline]] inline PointUpdate update3_series(const char* who, const ElasticModuli& el, const double z[6], const double y[6], double m,
                           double J2, double J3, double rho, HenckyState& st, ReturnMap&& ret) {
  // z, y: Z and Z^2 as (00, 11, 22, 01, 02, 12).
  int n = 1;
  for (double t = rho; t > kSeriesTolerance && n < kMaxTerms; t *= rho) ++n;
  double p[kMaxTerms], q[kMaxTerms], r[kMaxTerms]; // Z^(k+1) = p[k] I + q[k] Z + r[k] Z^2
  p[0] = 0.0, q[0] = 1.0, r[0] = 0.0;
  double c0 = 0.0, c1 = 1.0, c2 = 0.0;
  for (int k = 1; k < n; ++k) {
    p[k] = r[k - 1] * J3;
    q[k] = p[k - 1] + r[k - 1] * J2;
    r[k] = q[k - 1];
    const double s = k % 2 ? -kInverse[k] : kInverse[k];
    c0 += s * p[k];
    c1 += s * q[k];
    c2 += s * r[k];
  }
  const double S = 3.0 * c0 + 2.0 * J2 * c2;
  const double ev = 0.5 * (3.0 * std::log(m) + S);
  const double dev2 = 0.25 * (2.0 * J2 * c1 * c1 + 6.0 * J3 * c1 * c2 + (2.0 / 3.0) * J2 * J2 * c2 * c2);
  check_strain(who, ev, dev2);
  const Return ret_ = ret(ev, dev2);
  PointUpdate out;
  // tau = K e_v_new I + 2 G beta dev e = (K e_v_new - 2/3 G beta c2 J2) I + G beta (c1 Z + c2 Z^2).
  const double Gb = el.shear * ret_.beta;
  const double t0 = el.bulk * ret_.ev - (2.0 / 3.0) * Gb * c2 * J2, t1 = Gb * c1, t2 = Gb * c2;
  Mat3& tau = out.kirchhoff;
  tau(0, 0) = t0 + t1 * z[0] + t2 * y[0];
  tau(1, 1) = t0 + t1 * z[1] + t2 * y[1];
  tau(2, 2) = t0 + t1 * z[2] + t2 * y[2];
  tau(0, 1) = tau(1, 0) = t1 * z[3] + t2 * y[3];
  tau(0, 2) = tau(2, 0) = t1 * z[4] + t2 * y[4];
  tau(1, 2) = tau(2, 1) = t1 * z[5] + t2 * y[5];
  if (ret_.plastic) {
    double d0 = 1.0, d1 = 0.0, d2 = 0.0, binom = 1.0;
    for (int k = 0; k < n; ++k) {
      binom *= (ret_.beta - k) * kInverse[k];
      d0 += binom * p[k];
      d1 += binom * q[k];
      d2 += binom * r[k];
    }
    // exp((2 e_v_new - beta S) / 3) = m exp((2 (e_v_new - e_v) - (beta - 1) S) / 3), a small argument.
    const double scale = m * exp_small((2.0 * (ret_.ev - ev) - (ret_.beta - 1.0) * S) / 3.0);
    const double b0 = scale * d0, b1 = scale * d1, b2 = scale * d2;
    st.be(0, 0) = b0 + b1 * z[0] + b2 * y[0];
    st.be(1, 1) = b0 + b1 * z[1] + b2 * y[1];
    st.be(2, 2) = b0 + b1 * z[2] + b2 * y[2];
    st.be(0, 1) = st.be(1, 0) = b1 * z[3] + b2 * y[3];
    st.be(0, 2) = st.be(2, 0) = b1 * z[4] + b2 * y[4];
    st.be(1, 2) = st.be(2, 1) = b1 * z[5] + b2 * y[5];
  }
  fill_energies(out, el, ev, dev2, ret_);
  return out;
}

/// General 3D point update around a return mapping `ret(ev, dev2) -> Return`:
/// the series path when b_e_trial is close to a multiple of I, the
/// eigen-decomposition otherwise.
template <class ReturnMap>
[[gnu::always_inline]] inline PointUpdate update3(const char* who, const ElasticModuli& el, const Mat3& dF, HenckyState& st, ReturnMap&& ret) {
  check_increment(who, dF.determinant());
  const Mat3 btr = push_forward(dF, st.be);
  const double m = (btr(0, 0) + btr(1, 1) + btr(2, 2)) / 3.0, inv_m = 1.0 / m;
  // Z = b / m - I with its trace removed exactly.
  double z[6] = {btr(0, 0) * inv_m, btr(1, 1) * inv_m, btr(2, 2) * inv_m,
                 btr(0, 1) * inv_m, btr(0, 2) * inv_m, btr(1, 2) * inv_m};
  const double shift = (z[0] + z[1] + z[2]) / 3.0;
  z[0] -= shift, z[1] -= shift, z[2] -= shift;
  const double y[6] = {z[0] * z[0] + z[3] * z[3] + z[4] * z[4], z[3] * z[3] + z[1] * z[1] + z[5] * z[5],
                       z[4] * z[4] + z[5] * z[5] + z[2] * z[2], z[0] * z[3] + z[3] * z[1] + z[4] * z[5],
                       z[0] * z[4] + z[3] * z[5] + z[4] * z[2], z[3] * z[4] + z[1] * z[5] + z[5] * z[2]};
  const double J2 = 0.5 * (y[0] + y[1] + y[2]);
  // Largest |z_i| <= sqrt(2/3 tr Z^2) = sqrt(4/3 J2).
  const double rho = std::sqrt(4.0 / 3.0 * J2);
  if (!(rho <= kSeriesRadius && m > 0.0)) return update3_eigen(who, el, btr, st, ret);
  const double J3 = z[0] * (z[1] * z[2] - z[5] * z[5]) - z[3] * (z[3] * z[2] - z[5] * z[4]) +
                    z[4] * (z[3] * z[5] - z[1] * z[4]);
  PointUpdate out = update3_series(who, el, z, y, m, J2, J3, rho, st, ret);
  if (!out.plastic) st.be = btr;
  return out;
}

/// atanh(x) / x as a function of x2 = x^2 in [0, 1): series below 1e-2
/// (truncation x^20/21 < 1e-21), the library function above.
inline double atanh_over_x(double x2) {
  if (x2 < 1e-4) {
    // Sum of x^(2k) / (2k + 1) to x^8 (truncation x^10/11 < 1e-21).
    const double x4 = x2 * x2;
    return (1.0 + x2 * (1.0 / 3)) + x4 * ((1.0 / 5 + x2 * (1.0 / 7)) + x4 * (1.0 / 9));
  }
  if (x2 < 1e-2) return atanh_series(x2);
  const double x = std::sqrt(x2);
  return std::atanh(x) / x;
}

/// Plane strain: the in-plane block B = [[a, b], [b, c]] of b_e_trial has
/// mean m, deviator D = [[d1, d2], [d2, -d1]] (eigenvalues +-r, r^2 = d1^2 +
/// d2^2) and eigenvalues m +- r; b_zz is unchanged by dF. With x = r/m the
/// in-plane Hencky strains are e_m +- h, e_m = 1/4 ln det B,
/// h = 1/4 ln((m + r)/(m - r)) = atanh(x)/2, and every isotropic function f of
/// B is (f1 + f2)/2 I + (f1 - f2)/(2 r) D, where for the stress
/// (tau1 - tau2)/(2 r) = 2 G beta h / r = G beta atanh(x)/(x m) has no 0/0 at r = 0.
template <class ReturnMap>
[[gnu::always_inline]] inline PointUpdate update2(const char* who, const ElasticModuli& el, const Mat<2>& dF, HenckyState& st, ReturnMap&& ret) {
  check_increment(who, dF(0, 0) * dF(1, 1) - dF(0, 1) * dF(1, 0));
  const double b00 = st.be(0, 0), b01 = st.be(0, 1), b11 = st.be(1, 1), bzz = st.be(2, 2);
  const double m00 = dF(0, 0) * b00 + dF(0, 1) * b01, m01 = dF(0, 0) * b01 + dF(0, 1) * b11;
  const double m10 = dF(1, 0) * b00 + dF(1, 1) * b01, m11 = dF(1, 0) * b01 + dF(1, 1) * b11;
  const double a = m00 * dF(0, 0) + m01 * dF(0, 1);
  const double b = m10 * dF(0, 0) + m11 * dF(0, 1);
  const double c = m10 * dF(1, 0) + m11 * dF(1, 1);
  const double m = 0.5 * (a + c), d1 = 0.5 * (a - c), d2 = b;
  const double r2 = d1 * d1 + d2 * d2;
  const double em = 0.25 * log_near1(a * c - b * b), ez = 0.5 * log_near1(bzz);
  const double inv_m = 1.0 / m;
  const double x2 = r2 * inv_m * inv_m;
  const double g = atanh_over_x(x2); // h = x g / 2, h / r = g / (2 m)
  const double ev = 2.0 * em + ez, a0 = (1.0 / 3) * (em - ez);
  const double dev2 = 6.0 * a0 * a0 + 0.5 * x2 * g * g; // (a0 + h)^2 + (a0 - h)^2 + (2 a0)^2
  check_strain(who, ev, dev2);
  const Return r = ret(ev, dev2);
  PointUpdate out;
  const double K = el.bulk, G2b = 2.0 * el.shear * r.beta;
  const double tm = K * r.ev + G2b * a0, k = 0.5 * G2b * g * inv_m;
  Mat3& tau = out.kirchhoff;
  tau(0, 0) = tm + k * d1;
  tau(1, 1) = tm - k * d1;
  tau(0, 1) = tau(1, 0) = k * d2;
  tau(2, 2) = K * r.ev - 2.0 * G2b * a0;
  if (r.plastic) {
    // mu_i = lambda_i e^(delta_i), delta_i = 2 (e_new,i - e_i) = c +- y with
    // c = 2 (e_v_new - e_v)/3 + 2 (beta - 1) a0, y = 2 (beta - 1) h, lambda_1,2 = m +- r, r = x m:
    //   (mu1 + mu2)/2      = m e^c (cosh y + x^2 (beta - 1) g shc(y)),  shc(y) = sinh(y)/y,
    //   (mu1 - mu2)/(2 r)  = e^c (cosh y + (beta - 1) g shc(y))          (y / x = (beta - 1) g),
    // with cosh and shc even in y: no square root, no division, no 0/0 at r = 0.
    const double dv = (2.0 / 3) * (r.ev - ev), db = 2.0 * (r.beta - 1.0);
    const double c = dv + db * a0, y2 = 0.25 * db * db * x2 * g * g;
    double ch, shc;
    cosh_shc(y2, ch, shc);
    const double E = exp_small(c), bg = 0.5 * db * g * shc;
    const double mean = m * E * (ch + x2 * bg), coef = E * (ch + bg);
    st.be(0, 0) = mean + coef * d1;
    st.be(1, 1) = mean - coef * d1;
    st.be(0, 1) = st.be(1, 0) = coef * d2;
    st.be(2, 2) = bzz * exp_small(dv - 2.0 * db * a0);
  } else {
    st.be(0, 0) = a;
    st.be(1, 1) = c;
    st.be(0, 1) = st.be(1, 0) = b;
  }
  fill_energies(out, el, ev, dev2, r);
  return out;
}

/// Uniaxial strain: b_e diagonal, b_11 *= dF_11^2; principal strains 1/2 ln b_ii.
template <class ReturnMap>
[[gnu::always_inline]] inline PointUpdate update1(const char* who, const ElasticModuli& el, const Mat<1>& dF, HenckyState& st, ReturnMap&& ret) {
  const double f = dF(0, 0);
  check_increment(who, f);
  const double b0 = f * f * st.be(0, 0), b1 = st.be(1, 1), b2 = st.be(2, 2);
  const double e0 = 0.5 * log_near1(b0), e1 = 0.5 * log_near1(b1), e2 = b2 == b1 ? e1 : 0.5 * log_near1(b2);
  const double ev = e0 + e1 + e2;
  const double em = ev * (1.0 / 3), d0 = e0 - em, d1 = e1 - em, d2 = e2 - em;
  const double dev2 = d0 * d0 + d1 * d1 + d2 * d2;
  check_strain(who, ev, dev2);
  const Return r = ret(ev, dev2);
  PointUpdate out;
  const double K = el.bulk, G2b = 2.0 * el.shear * r.beta;
  out.kirchhoff(0, 0) = K * r.ev + G2b * d0;
  out.kirchhoff(1, 1) = K * r.ev + G2b * d1;
  out.kirchhoff(2, 2) = K * r.ev + G2b * d2;
  if (r.plastic) {
    const double dv = (2.0 / 3) * (r.ev - ev), db = 2.0 * (r.beta - 1.0);
    st.be(0, 0) = b0 * exp_small(dv + db * d0);
    st.be(1, 1) = b1 * exp_small(dv + db * d1);
    st.be(2, 2) = b2 == b1 ? st.be(1, 1) : b2 * exp_small(dv + db * d2);
  } else {
    st.be(0, 0) = b0;
  }
  fill_energies(out, el, ev, dev2, r);
  return out;
}

template <int D, class ReturnMap>
[[gnu::always_inline]] inline PointUpdate update(const char* who, const ElasticModuli& el, const Mat<D>& dF, HenckyState& st, ReturnMap&& ret) {
  if constexpr (D == 1) return update1(who, el, dF, st, ret);
  else if constexpr (D == 2) return update2(who, el, dF, st, ret);
  else return update3(who, el, dF, st, ret);
}

/// One J2 step by the general path (every dimension, Johnson-Cook, any
/// strain); j2 of hencky_plane_j2.hpp takes the plane-strain steps it covers.
template <int D>
[[gnu::always_inline]] inline PointUpdate j2_general(const J2Parameters& p, const Mat<D>& dF, double dt, HenckyState& state) {
  return update<D>("j2_update", p.elastic, dF, state,
                   [&](double ev, double dev2) { return j2_return(p, ev, dev2, dt, state); });
}

/// One Drucker-Prager step (drucker_prager_update of hencky_plasticity.hpp), inlined.
template <int D>
[[gnu::always_inline]] inline PointUpdate drucker_prager(const DruckerPrager& m, const Mat<D>& dF, HenckyState& state) {
  return update<D>("drucker_prager_update", m.elastic(), dF, state,
                   [&](double ev, double dev2) { return dp_return(m, ev, dev2, state); });
}

} // namespace otmpm::plasticity::point
