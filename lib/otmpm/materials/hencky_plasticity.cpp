/// \file hencky_plasticity.cpp
/// Parameters and derived constants of the Hencky elastoplastic models, the
/// Jacobi eigen-solver, the Johnson-Cook Newton return and the point updates
/// of hencky_plasticity.hpp (instances of the inline templates of
/// hencky_point.hpp).
#include "otmpm/materials/hencky_plane_j2.hpp"

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

double J2Parameters::flow_stress(double eps_p, double rate) const {
  double s = point::static_flow_stress(*this, eps_p).value;
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

namespace point {

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

[[noreturn, gnu::cold, gnu::noinline]] void throw_increment(const char* who, double det) {
  throw InstabilityError(error_message(who, ": det dF = ", det, " is not finite and > 0"));
}
[[noreturn, gnu::cold, gnu::noinline]] void throw_strain(const char* who) {
  throw InstabilityError(
      error_message(who, ": the elastic log strain is not finite (b_e trial not positive definite or overflowed)"));
}

} // namespace point

namespace {

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
  return point::j2<D>(p, dF, dt, state);
}

template <int D> PointUpdate drucker_prager_update(const DruckerPrager& m, const Mat<D>& dF, HenckyState& state) {
  return point::drucker_prager<D>(m, dF, state);
}

double hencky_energy(const ElasticModuli& m, const Mat3& be) {
  const Eigen::Vector3d e = spectral_strain(be).e;
  const double ev = e.sum();
  return point::energy(m, ev, (e.array() - ev / 3.0).matrix().squaredNorm());
}

Mat3 hencky_kirchhoff(const ElasticModuli& m, const Mat3& be) {
  const Spectral s = spectral_strain(be);
  const double ev = s.e.sum();
  return point::spectral(s.Q, (m.bulk * ev + 2.0 * m.shear * (s.e.array() - ev / 3.0)).matrix());
}

Mat3 hencky_strain(const Mat3& be) {
  const Spectral s = spectral_strain(be);
  return point::spectral(s.Q, s.e);
}

Mat3 hencky_left_cauchy_green(const ElasticModuli& m, const Mat3& tau) {
  Eigen::Vector3d t;
  Mat3 Q;
  symmetric_eigen(tau, t, Q);
  const double mean = t.sum() / 3.0;
  const Eigen::Vector3d e = (mean / (3.0 * m.bulk) + (t.array() - mean) / (2.0 * m.shear)).matrix();
  return point::spectral(Q, (2.0 * e).array().exp().matrix());
}

#define OTMPM_INSTANTIATE(D)                                                                             \
  template PointUpdate j2_update<D>(const J2Parameters&, const Mat<D>&, double, HenckyState&);           \
  template PointUpdate drucker_prager_update<D>(const DruckerPrager&, const Mat<D>&, HenckyState&);
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm::plasticity