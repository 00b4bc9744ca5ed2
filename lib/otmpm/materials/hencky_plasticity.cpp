/// \file hencky_plasticity.cpp
/// The point updates of hencky_plasticity.hpp. Structure of a step:
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
#include <numbers>
#include <stdexcept>

namespace otmpm::plasticity {

// ---------------------------------------------------------------- parameters

ElasticModuli ElasticModuli::from_young_poisson(double young, double poisson) {
  require(finite_positive(young), "young must be finite and > 0, got ", young);
  require(std::isfinite(poisson) && poisson > -1.0 && poisson < 0.5, "poisson must be in (-1, 0.5), got ", poisson);
  return {young / (3.0 * (1.0 - 2.0 * poisson)), young / (2.0 * (1.0 + poisson))};
}

void ElasticModuli::validate() const {
  require(finite_positive(bulk), "bulk (modulus) must be finite and > 0, got ", bulk);
  require(finite_positive(shear), "shear (modulus) must be finite and > 0, got ", shear);
}

void JohnsonCook::validate() const {
  require(std::isfinite(B) && B >= 0.0, "johnson_cook.B must be finite and >= 0, got ", B);
  require(finite_positive(n), "johnson_cook.n must be finite and > 0, got ", n);
  require(std::isfinite(C) && C >= 0.0, "johnson_cook.C must be finite and >= 0, got ", C);
  require(finite_positive(reference_strain_rate), "johnson_cook.reference_strain_rate must be finite and > 0, got ",
          reference_strain_rate);
}

void J2Parameters::validate() const {
  elastic.validate();
  require(finite_positive(yield_stress), "yield_stress must be finite and > 0, got ", yield_stress);
  require(std::isfinite(hardening_modulus) && hardening_modulus >= 0.0,
          "hardening_modulus must be finite and >= 0, got ", hardening_modulus);
  if (johnson_cook) johnson_cook->validate();
}

namespace {

/// Static part of the J2 yield stress, sigma_y0 + H eps + B eps^n, and its
/// derivative with respect to eps (0^n = 0; the derivative at eps = 0 is
/// taken as H, which only matters as a Newton slope).
struct Hardening {
  double value, slope;
};
Hardening static_flow_stress(const J2Parameters& p, double eps) {
  Hardening h{p.yield_stress + p.hardening_modulus * eps, p.hardening_modulus};
  if (p.johnson_cook && p.johnson_cook->B > 0.0 && eps > 0.0) {
    const double pw = std::pow(eps, p.johnson_cook->n);
    h.value += p.johnson_cook->B * pw;
    h.slope += p.johnson_cook->B * p.johnson_cook->n * pw / eps;
  }
  return h;
}

} // namespace

double J2Parameters::flow_stress(double eps_p, double rate) const {
  double s = static_flow_stress(*this, eps_p).value;
  if (johnson_cook && johnson_cook->C > 0.0 && rate > johnson_cook->reference_strain_rate)
    s *= 1.0 + johnson_cook->C * std::log(rate / johnson_cook->reference_strain_rate);
  return s;
}

namespace {
/// 3 tan(a) / sqrt(9 + 12 tan^2 a) and 3 / sqrt(9 + 12 tan^2 a) for a in degrees.
void cone_coefficients(double angle_deg, double& eta, double& xi) {
  const double t = std::tan(angle_deg * std::numbers::pi / 180.0);
  const double d = std::sqrt(9.0 + 12.0 * t * t);
  eta = 3.0 * t / d;
  xi = 3.0 / d;
}

/// xi c / eta, +infinity for phi = 0.
double cone_apex(double friction_angle, double cohesion) {
  double eta, xi;
  cone_coefficients(friction_angle, eta, xi);
  return eta > 0.0 ? xi * cohesion / eta : std::numeric_limits<double>::infinity();
}
} // namespace

void DruckerPragerParameters::validate() const {
  elastic.validate();
  require(std::isfinite(friction_angle) && friction_angle >= 0.0 && friction_angle < 90.0,
          "friction_angle must be in [0, 90) degrees, got ", friction_angle);
  require(std::isfinite(dilation_angle) && dilation_angle >= 0.0 && dilation_angle <= friction_angle,
          "dilation_angle must be in [0, friction_angle = ", friction_angle, "] degrees, got ", dilation_angle);
  require(std::isfinite(cohesion) && cohesion >= 0.0, "cohesion must be finite and >= 0, got ", cohesion);
  require(cohesion > 0.0 || friction_angle > 0.0,
          "cohesion must be > 0 when friction_angle = 0 (the material would have no strength)");
  require(std::isfinite(tension_cutoff) && tension_cutoff >= 0.0, "tension_cutoff must be finite and >= 0, got ",
          tension_cutoff);
  const double apex = cone_apex(friction_angle, cohesion);
  // A cutoff typed as the apex in decimal may exceed it in the last digit.
  require(tension_cutoff <= apex * (1.0 + 1e-12), "tension_cutoff = ", tension_cutoff,
          " exceeds the apex of the cone, xi cohesion / eta = ", apex,
          " (the largest mean stress the cone allows); use at most that value");
}

DruckerPrager::DruckerPrager(const DruckerPragerParameters& p) : p_(p) {
  p.validate();
  cone_coefficients(p.friction_angle, eta_, xi_);
  double xi_bar = 0.0;
  cone_coefficients(p.dilation_angle, eta_bar_, xi_bar);
  apex_ = cone_apex(p.friction_angle, p.cohesion);
  cutoff_ = std::min(p.tension_cutoff, apex_);
}

double DruckerPrager::yield_function(const Mat3& tau) const {
  const double p = tau.trace() / 3.0;
  const Mat3 s = tau - p * Mat3::Identity();
  return std::sqrt(0.5 * s.squaredNorm()) + eta_ * p - xi_ * p_.cohesion;
}

// ------------------------------------------------------- symmetric eigen 3x3

namespace {

/// One Jacobi rotation annihilating a(p, q) of the symmetric matrix held in
/// `a` (upper triangle used), accumulated into the columns p, q of Q
/// (Numerical Recipes sect. 11.1 conventions).
inline void jacobi_rotate(double a[3][3], Mat3& Q, int p, int q) {
  const double apq = a[p][q];
  if (apq == 0.0) return;
  const int r = 3 - p - q;
  const double theta = (a[q][q] - a[p][p]) / (2.0 * apq);
  // t = tan of the rotation angle, the smaller root of t^2 + 2 theta t - 1 = 0.
  const double t = std::abs(theta) > 1e150 ? 0.5 / theta
                                          : std::copysign(1.0, theta) / (std::abs(theta) + std::sqrt(theta * theta + 1.0));
  const double c = 1.0 / std::sqrt(t * t + 1.0), s = t * c;
  a[p][p] -= t * apq;
  a[q][q] += t * apq;
  a[p][q] = 0.0;
  // Entries (r, p) and (r, q), stored in the upper triangle.
  double& arp = r < p ? a[r][p] : a[p][r];
  double& arq = r < q ? a[r][q] : a[q][r];
  const double xp = arp, xq = arq;
  arp = c * xp - s * xq;
  arq = s * xp + c * xq;
  for (int k = 0; k < 3; ++k) {
    const double qp = Q(k, p), qq = Q(k, q);
    Q(k, p) = c * qp - s * qq;
    Q(k, q) = s * qp + c * qq;
  }
}

} // namespace

void symmetric_eigen(const Mat3& A, Eigen::Vector3d& w, Mat3& Q) {
  // Work on the deviator: round-off of the rotations is then relative to the
  // spread of the eigenvalues, not to their mean (b_e is close to m I).
  const double m = (A(0, 0) + A(1, 1) + A(2, 2)) / 3.0;
  double a[3][3] = {{A(0, 0) - m, A(0, 1), A(0, 2)}, {0.0, A(1, 1) - m, A(1, 2)}, {0.0, 0.0, A(2, 2) - m}};
  Q.setIdentity();
  const double norm2 = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2] +
                       2.0 * (a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2]);
  // Cyclic sweeps converge quadratically; 12 is a safety bound.
  for (int sweep = 0; sweep < 12; ++sweep) {
    const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    // Off-diagonal entries below 1e-15 |A - m I| are round-off (they move the
    // eigenvalues by their square and b_e by their size): done.
    if (!(off > 1e-30 * norm2)) break; // also ends on NaN
    jacobi_rotate(a, Q, 0, 1);
    jacobi_rotate(a, Q, 0, 2);
    jacobi_rotate(a, Q, 1, 2);
  }
  w << a[0][0] + m, a[1][1] + m, a[2][2] + m;
}

// ------------------------------------------------------------ return maps

namespace {

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
/// for x = delta eps_p in [0, q / (3 G)] (r decreasing, r(0) > 0 > r(q/3G))
/// by Newton steps kept inside a shrinking bracket (bisection when a step
/// leaves it or stalls). Converged when |r| <= kNewtonTol sigma_y.
double johnson_cook_return(const J2Parameters& p, double q, double eps_n, double dt, int& iterations) {
  const JohnsonCook& jc = *p.johnson_cook;
  const bool rate_dependent = jc.C > 0.0;
  if (rate_dependent && !(dt > 0.0 && std::isfinite(dt)))
    throw std::invalid_argument("j2_update: Johnson-Cook rate hardening needs a finite time step dt > 0, got " +
                                format_number(dt));
  const double G3 = 3.0 * p.elastic.shear;
  double lo = 0.0, hi = q / G3;
  const Hardening h0 = static_flow_stress(p, eps_n);
  double x = std::clamp((q - h0.value) / (G3 + p.hardening_modulus), 0.0, hi);
  double dx = hi - lo, dx_old = dx; // the last two steps (bisection when Newton stalls)
  double r = 0.0, sigma = 0.0;
  for (int it = 1; it <= kMaxNewton; ++it) {
    const Hardening h = static_flow_stress(p, eps_n + x);
    double factor = 1.0, dfactor = 0.0; // rate factor and its derivative in x
    if (rate_dependent && x > jc.reference_strain_rate * dt) {
      factor = 1.0 + jc.C * std::log(x / (jc.reference_strain_rate * dt));
      dfactor = jc.C / x;
    }
    sigma = h.value * factor;
    r = q - G3 * x - sigma;
    if (std::abs(r) <= kNewtonTol * sigma) {
      iterations = it;
      return x;
    }
    (r > 0.0 ? lo : hi) = x;
    if (hi - lo <= 4.0 * std::numeric_limits<double>::epsilon() * hi) {
      // The bracket is at round-off: accept what double precision allows.
      if (std::abs(r) <= 1e-10 * sigma) {
        iterations = it;
        return x;
      }
      break;
    }
    // Newton (r' = -slope) unless it leaves the bracket or would not halve the
    // step before last (Numerical Recipes' rtsafe rule); bisection then.
    const double slope = G3 + h.slope * factor + h.value * dfactor;
    const double next = x + r / slope;
    dx_old = dx;
    if (!(next > lo && next < hi) || std::abs(2.0 * r) > std::abs(dx_old * slope)) {
      dx = 0.5 * (hi - lo);
      x = lo + dx;
    } else {
      dx = r / slope;
      x = next;
    }
  }
  throw InstabilityError("j2_update: the Johnson-Cook return mapping did not converge in " +
                         std::to_string(kMaxNewton) + " iterations (trial von Mises stress " + format_number(q) +
                         ", eps_p = " + format_number(eps_n) + ", dt = " + format_number(dt) + ", residual " +
                         format_number(r) + " for sigma_y = " + format_number(sigma) + ")");
}

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

/// e^d. A return changes the log strains by little per step, so b_e_new is
/// formed as b_e_trial e^(2 (e_new - e_trial)) in the common eigenbasis with
/// a small argument: Taylor polynomial of degree 7 for |d| <= 1/64
/// (truncation < (1/64)^8 / 8! = 9e-20 relative), std::exp beyond.
inline double exp_small(double d) {
  if (!(std::abs(d) <= 1.0 / 64)) return std::exp(d);
  // Estrin's scheme: three levels of multiplications instead of a chain of seven.
  const double d2 = d * d, d4 = d2 * d2;
  const double lo = (1.0 + d) + d2 * (1.0 / 2 + d * (1.0 / 6));
  const double hi = (1.0 / 24 + d * (1.0 / 120)) + d2 * (1.0 / 720 + d * (1.0 / 5040));
  return lo + d4 * hi;
}

/// cosh(y) and sinh(y)/y from y^2: Taylor series for y^2 <= 1/256
/// (truncation y^10/10! < 3e-19), the library functions beyond.
inline void cosh_shc(double y2, double& ch, double& shc) {
  if (!(y2 <= 1.0 / 256)) {
    const double y = std::sqrt(y2);
    ch = std::cosh(y);
    shc = std::sinh(y) / y;
    return;
  }
  const double y4 = y2 * y2;
  ch = (1.0 + y2 * (1.0 / 2)) + y4 * ((1.0 / 24 + y2 * (1.0 / 720)) + y4 * (1.0 / 40320));
  shc = (1.0 + y2 * (1.0 / 6)) + y4 * ((1.0 / 120 + y2 * (1.0 / 5040)) + y4 * (1.0 / 362880));
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
[[noreturn, gnu::cold, gnu::noinline]] void throw_increment(const char* who, double det) {
  throw InstabilityError(error_message(who, ": det dF = ", det, " is not finite and > 0"));
}
[[noreturn, gnu::cold, gnu::noinline]] void throw_strain(const char* who) {
  throw InstabilityError(
      error_message(who, ": the elastic log strain is not finite (b_e trial not positive definite or overflowed)"));
}
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
Mat3 push_forward(const Mat3& A, const Mat3& M) {
  Mat3 AM;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) AM(i, j) = A(i, 0) * M(0, j) + A(i, 1) * M(1, j) + A(i, 2) * M(2, j);
  Mat3 R;
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) R(i, j) = R(j, i) = AM(i, 0) * A(j, 0) + AM(i, 1) * A(j, 1) + AM(i, 2) * A(j, 2);
  return R;
}

/// Q diag(d) Q^T, exactly symmetric.
Mat3 spectral(const Mat3& Q, const Eigen::Vector3d& d) {
  Mat3 R;
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j)
      R(i, j) = R(j, i) = Q(i, 0) * d[0] * Q(j, 0) + Q(i, 1) * d[1] * Q(j, 1) + Q(i, 2) * d[2] * Q(j, 2);
  return R;
}

/// 3D, b_e_trial far from a multiple of I: Jacobi eigen-decomposition,
/// e_i = 1/2 ln lambda_i, tau and b_e_new assembled in the eigenbasis.
template <class ReturnMap>
PointUpdate update3_eigen(const char* who, const ElasticModuli& el, const Mat3& btr, HenckyState& st, ReturnMap&& ret) {
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
PointUpdate update3_series(const char* who, const ElasticModuli& el, const double z[6], const double y[6], double m,
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
PointUpdate update3(const char* who, const ElasticModuli& el, const Mat3& dF, HenckyState& st, ReturnMap&& ret) {
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
  // Sum of x^(2k) / (2k + 1) by Estrin's scheme.
  const double x4 = x2 * x2;
  if (x2 < 1e-4) return (1.0 + x2 * (1.0 / 3)) + x4 * ((1.0 / 5 + x2 * (1.0 / 7)) + x4 * (1.0 / 9));
  if (x2 < 1e-2) {
    const double x8 = x4 * x4;
    const double lo = (1.0 + x2 * (1.0 / 3)) + x4 * (1.0 / 5 + x2 * (1.0 / 7));
    const double mid = (1.0 / 9 + x2 * (1.0 / 11)) + x4 * (1.0 / 13 + x2 * (1.0 / 15));
    const double hi = 1.0 / 17 + x2 * (1.0 / 19);
    return lo + x8 * (mid + x8 * hi);
  }
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
PointUpdate update2(const char* who, const ElasticModuli& el, const Mat<2>& dF, HenckyState& st, ReturnMap&& ret) {
  check_increment(who, dF(0, 0) * dF(1, 1) - dF(0, 1) * dF(1, 0));
  const double b00 = st.be(0, 0), b01 = st.be(0, 1), b11 = st.be(1, 1), bzz = st.be(2, 2);
  const double m00 = dF(0, 0) * b00 + dF(0, 1) * b01, m01 = dF(0, 0) * b01 + dF(0, 1) * b11;
  const double m10 = dF(1, 0) * b00 + dF(1, 1) * b01, m11 = dF(1, 0) * b01 + dF(1, 1) * b11;
  const double a = m00 * dF(0, 0) + m01 * dF(0, 1);
  const double b = m10 * dF(0, 0) + m11 * dF(0, 1);
  const double c = m10 * dF(1, 0) + m11 * dF(1, 1);
  const double m = 0.5 * (a + c), d1 = 0.5 * (a - c), d2 = b;
  const double r2 = d1 * d1 + d2 * d2;
  const double em = 0.25 * std::log(a * c - b * b), ez = 0.5 * std::log(bzz);
  const double inv_m = 1.0 / m;
  const double x2 = r2 * inv_m * inv_m;
  const double g = atanh_over_x(x2); // h = x g / 2, h / r = g / (2 m)
  const double ev = 2.0 * em + ez, a0 = (em - ez) / 3.0;
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
    const double dv = 2.0 * (r.ev - ev) / 3.0, db = 2.0 * (r.beta - 1.0);
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
PointUpdate update1(const char* who, const ElasticModuli& el, const Mat<1>& dF, HenckyState& st, ReturnMap&& ret) {
  const double f = dF(0, 0);
  check_increment(who, f);
  const double b0 = f * f * st.be(0, 0), b1 = st.be(1, 1), b2 = st.be(2, 2);
  const double e0 = 0.5 * std::log(b0), e1 = 0.5 * std::log(b1), e2 = b2 == b1 ? e1 : 0.5 * std::log(b2);
  const double ev = e0 + e1 + e2;
  const double d0 = e0 - ev / 3.0, d1 = e1 - ev / 3.0, d2 = e2 - ev / 3.0;
  const double dev2 = d0 * d0 + d1 * d1 + d2 * d2;
  check_strain(who, ev, dev2);
  const Return r = ret(ev, dev2);
  PointUpdate out;
  const double K = el.bulk, G2b = 2.0 * el.shear * r.beta;
  out.kirchhoff(0, 0) = K * r.ev + G2b * d0;
  out.kirchhoff(1, 1) = K * r.ev + G2b * d1;
  out.kirchhoff(2, 2) = K * r.ev + G2b * d2;
  if (r.plastic) {
    const double dv = 2.0 * (r.ev - ev) / 3.0, db = 2.0 * (r.beta - 1.0);
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
PointUpdate update(const char* who, const ElasticModuli& el, const Mat<D>& dF, HenckyState& st, ReturnMap&& ret) {
  if constexpr (D == 1) return update1(who, el, dF, st, ret);
  else if constexpr (D == 2) return update2(who, el, dF, st, ret);
  else return update3(who, el, dF, st, ret);
}

/// Spectral form of a general b_e: eigenvalues, eigenvectors, principal strains.
struct Spectral {
  Mat3 Q;
  Eigen::Vector3d e; // 1/2 ln lambda_i
};
Spectral spectral_strain(const Mat3& be) {
  Spectral s;
  Eigen::Vector3d lambda;
  symmetric_eigen(be, lambda, s.Q);
  s.e = 0.5 * lambda.array().log();
  return s;
}

} // namespace

template <int D> PointUpdate j2_update(const J2Parameters& p, const Mat<D>& dF, double dt, HenckyState& state) {
  return update<D>("j2_update", p.elastic, dF, state,
                   [&](double ev, double dev2) { return j2_return(p, ev, dev2, dt, state); });
}

template <int D> PointUpdate drucker_prager_update(const DruckerPrager& m, const Mat<D>& dF, HenckyState& state) {
  return update<D>("drucker_prager_update", m.elastic(), dF, state,
                   [&](double ev, double dev2) { return dp_return(m, ev, dev2, state); });
}

double hencky_energy(const ElasticModuli& m, const Mat3& be) {
  const Eigen::Vector3d e = spectral_strain(be).e;
  const double ev = e.sum();
  return energy(m, ev, (e.array() - ev / 3.0).matrix().squaredNorm());
}

Mat3 hencky_kirchhoff(const ElasticModuli& m, const Mat3& be) {
  const Spectral s = spectral_strain(be);
  const double ev = s.e.sum();
  return spectral(s.Q, (m.bulk * ev + 2.0 * m.shear * (s.e.array() - ev / 3.0)).matrix());
}

Mat3 hencky_strain(const Mat3& be) {
  const Spectral s = spectral_strain(be);
  return spectral(s.Q, s.e);
}

#define OTMPM_INSTANTIATE(D)                                                                             \
  template PointUpdate j2_update<D>(const J2Parameters&, const Mat<D>&, double, HenckyState&);           \
  template PointUpdate drucker_prager_update<D>(const DruckerPrager&, const Mat<D>&, HenckyState&);
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm::plasticity
