// Exact solutions of the benchmark scenes (docs/benchmarks.md) and the RMS
// error of docs/theory.md sect. 12 (assembly/exact_solutions.cpp builds them from a scene).
#include "otmpm/reference/exact.hpp"

#include "otmpm/reference/solutions.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace otmpm {

namespace {

constexpr double pi = std::numbers::pi;

void require_finite_positive(double value, const char* what) {
  require(finite_positive(value), what, " must be finite and positive (got ", value, ")");
}

/// x - period * floor(x / period), in [0, period].
double wrap(double x, double period) { return x - period * std::floor(x / period); }

} // namespace

// ---------------------------------------------------------------------------
// Dyka bar

template <int D>
DykaBar<D>::DykaBar(double length, double young, double density, double region_velocity, double region_end)
    : DykaBar(DykaParameters{length, young, density, region_velocity, 0.0, region_end, 0.0, 0.0}) {}

template <int D> DykaBar<D>::DykaBar(const DykaParameters& p) : p_(p), c_(0.0) {
  require_finite_positive(p.length, "DykaBar: length");
  require_finite_positive(p.young, "DykaBar: Young's modulus");
  require_finite_positive(p.density, "DykaBar: density");
  require(std::isfinite(p.region_velocity) && std::isfinite(p.rest_velocity) && std::isfinite(p.x_free),
          "DykaBar: velocities and position must be finite");
  require(p.region_begin >= 0.0 && p.region_begin <= p.region_end && p.region_end <= p.length,
          "DykaBar: the initial-velocity region [" + std::to_string(p.region_begin) + ", " +
              std::to_string(p.region_end) + "] must lie inside the bar [0, " + std::to_string(p.length) + "]");
  c_ = std::sqrt(p.young / p.density);
}

template <int D> double DykaBar<D>::base_velocity(double s) const {
  return (s >= p_.region_begin && s <= p_.region_end) ? p_.region_velocity : p_.rest_velocity;
}

template <int D> double DykaBar<D>::base_integral(double s) const {
  const double in_region = std::clamp(s, p_.region_begin, p_.region_end) - p_.region_begin;
  return p_.rest_velocity * s + (p_.region_velocity - p_.rest_velocity) * in_region;
}

// V has period 4L; it is even about 0 (so also about 2L) and odd about L:
// fold xi into [0, 2L] by evenness, then [L, 2L] onto [0, L] with a sign flip.
template <int D> double DykaBar<D>::extended_velocity(double xi) const {
  const double L = p_.length;
  double z = wrap(xi, 4.0 * L);
  if (z > 2.0 * L) z = 4.0 * L - z;
  return z > L ? -base_velocity(2.0 * L - z) : base_velocity(z);
}

// W is odd about 0 (antiderivative of an even V with W(0) = 0) and even about
// L (V odd about L); its period is 4L because V integrates to zero over 4L
// (V(xi + 2L) = -V(xi)).
template <int D> double DykaBar<D>::extended_antiderivative(double xi) const {
  const double L = p_.length;
  double z = wrap(xi, 4.0 * L);
  double sign = 1.0;
  if (z > 2.0 * L) {
    z = 4.0 * L - z;
    sign = -1.0;
  }
  if (z > L) z = 2.0 * L - z;
  return sign * base_integral(z);
}

template <int D> BarState DykaBar<D>::state(double X, double t) const {
  const double xi = X - p_.x_free;
  const double s = c_ * t;
  const double behind = extended_velocity(xi - s), ahead = extended_velocity(xi + s);
  BarState r;
  r.v = 0.5 * (behind + ahead);
  r.sigma = 0.5 * p_.density * c_ * (ahead - behind);
  r.u = (extended_antiderivative(xi + s) - extended_antiderivative(xi - s)) / (2.0 * c_);
  return r;
}

// ---------------------------------------------------------------------------
// Fixed-end vibrating bar

template <int D> FixedBar<D>::FixedBar(const FixedBarParameters& p) : p_(p), c_(0.0), omega_(0.0) {
  require_finite_positive(p.length, "FixedBar: length");
  require_finite_positive(p.young, "FixedBar: Young's modulus");
  require_finite_positive(p.density, "FixedBar: density");
  require(std::isfinite(p.amplitude) && std::isfinite(p.x_left), "FixedBar: amplitude and position must be finite");
  c_ = std::sqrt(p.young / p.density);
  omega_ = pi * c_ / p.length;
}

template <int D> BarState FixedBar<D>::state(double X, double t) const {
  const double k = pi / p_.length;
  const double phase = k * (X - p_.x_left);
  BarState r;
  r.u = p_.amplitude / omega_ * std::sin(omega_ * t) * std::sin(phase);
  r.v = p_.amplitude * std::cos(omega_ * t) * std::sin(phase);
  r.sigma = p_.young * p_.amplitude / c_ * std::sin(omega_ * t) * std::cos(phase); // E u_X, k / omega = 1 / c
  return r;
}

// ---------------------------------------------------------------------------
// Bar with a dynamic traction

template <int D> TractionBar<D>::TractionBar(const TractionBarParameters& p) : p_(p), c_(0.0), omega_(0.0) {
  require_finite_positive(p.length, "TractionBar: length");
  require_finite_positive(p.young, "TractionBar: Young's modulus");
  require_finite_positive(p.density, "TractionBar: density");
  require(std::isfinite(p.amplitude) && std::isfinite(p.x_fixed), "TractionBar: amplitude and position must be finite");
  c_ = std::sqrt(p.young / p.density);
  omega_ = pi / p.length;
}

template <int D> BarState TractionBar<D>::state(double X, double t) const {
  const double l = p_.length;
  const double xi = X - p_.x_fixed;
  const double s = wrap(c_ * t, 4.0 * l);
  const double alpha = p_.amplitude / (p_.young * omega_); // displacement scale
  const double vel = c_ * p_.amplitude / p_.young;          // velocity scale c tau_0 / E
  const double a = omega_ * (s + xi), b = omega_ * (s - xi);
  BarState r;
  if (s < l - xi || s >= 3.0 * l + xi) return r; // wave not arrived / gone
  if (s < l + xi) {                              // incoming wave only
    r.sigma = p_.amplitude * std::sin(a);
    r.u = -alpha * (1.0 + std::cos(a));
    r.v = vel * std::sin(a);
  } else if (s < 3.0 * l - xi) { // incoming + reflected from the fixed end
    r.sigma = p_.amplitude * (std::sin(a) + std::sin(b));
    r.u = alpha * (std::cos(b) - std::cos(a));
    r.v = vel * (std::sin(a) - std::sin(b));
  } else { // reflected wave only
    r.sigma = p_.amplitude * std::sin(b);
    r.u = alpha * (1.0 + std::cos(b));
    r.v = -vel * std::sin(b);
  }
  return r;
}

template <int D> double TractionBar<D>::traction(double t) const {
  return -p_.amplitude * std::sin(omega_ * c_ * t);
}

// ---------------------------------------------------------------------------
// Manufactured plate
//
// Derivation of the body force (reference configuration, wobbes eq. 11).
// u_k depends on X_k only, so F = I + grad_X u is diagonal:
//   F_kk = 1 + A kx cos(kx xi_k) T_k(t),  kx = 2 pi / l,  T_k = sin(kt t + k pi),
//   kt = c pi / l,   J = F_11 F_22.
// The Cauchy stress of eq. 11, sigma = lambda ln J / J I + mu / J (F F^T - I),
// pulled back, P = J sigma F^-T, gives
//   P = mu (F - F^-T) + lambda ln J F^-T,  P_kk = mu (F_kk - 1/F_kk) + lambda ln J / F_kk,
// and P is diagonal too. Hence (Div P)_k = dP_kk/dX_k, and since
// d(ln J)/dF_kk = 1/F_kk,
//   dP_kk/dF_kk = mu (1 + 1/F_kk^2) + lambda (1 - ln J) / F_kk^2,
//   (Div P)_k = dP_kk/dF_kk * dF_kk/dX_k,   dF_kk/dX_k = -A kx^2 sin(kx xi_k) T_k.
// Momentum balance in the reference configuration, rho0 u_tt = Div P + rho0 b, gives
//   b = u_tt - Div P / rho0,   u_tt = -kt^2 u.
// The Cauchy stress is sigma = P F^T / J (diagonal).

MmsPlate::MmsPlate(const MmsPlateParameters& p) : p_(p), c_(0.0), lambda_(0.0), mu_(0.0), kx_(0.0), kt_(0.0) {
  require_finite_positive(p.length, "MmsPlate: length");
  require_finite_positive(p.young, "MmsPlate: Young's modulus");
  require_finite_positive(p.density, "MmsPlate: density");
  require(std::isfinite(p.poisson) && p.poisson > -1.0 && p.poisson < 0.5,
          "MmsPlate: Poisson's ratio must lie in (-1, 0.5) (got " + std::to_string(p.poisson) + ")");
  require(std::isfinite(p.amplitude) && std::isfinite(p.lower[0]) && std::isfinite(p.lower[1]),
          "MmsPlate: amplitude and position must be finite");
  c_ = std::sqrt(p.young / p.density);
  mu_ = p.young / (2.0 * (1.0 + p.poisson));
  lambda_ = p.young * p.poisson / ((1.0 + p.poisson) * (1.0 - 2.0 * p.poisson));
  kx_ = 2.0 * pi / p.length;
  kt_ = c_ * pi / p.length;
  // F_kk >= 1 - |A| kx must stay positive, or the motion is not admissible.
  require(std::abs(p.amplitude) * kx_ < 1.0,
          "MmsPlate: amplitude " + std::to_string(p.amplitude) + " gives det F <= 0 (need |A| 2 pi / l < 1)");
}

double MmsPlate::spatial(const Vec<2>& X, int k) const { return kx_ * (X[k] - p_.lower[k]); }

// sin(kt t + k pi) written as +-sin(kt t), which is exact.
double MmsPlate::temporal(double t, int k) const { return (k == 0 ? 1.0 : -1.0) * std::sin(kt_ * t); }

Vec<2> MmsPlate::displacement(const Vec<2>& X, double t) const {
  Vec<2> u;
  for (int k = 0; k < 2; ++k) u[k] = p_.amplitude * std::sin(spatial(X, k)) * temporal(t, k);
  return u;
}

Vec<2> MmsPlate::velocity(const Vec<2>& X, double t) const {
  Vec<2> v;
  for (int k = 0; k < 2; ++k)
    v[k] = p_.amplitude * std::sin(spatial(X, k)) * kt_ * (k == 0 ? 1.0 : -1.0) * std::cos(kt_ * t);
  return v;
}

Mat<2> MmsPlate::deformation_gradient(const Vec<2>& X, double t) const {
  Mat<2> F = Mat<2>::Identity();
  for (int k = 0; k < 2; ++k) F(k, k) += p_.amplitude * kx_ * std::cos(spatial(X, k)) * temporal(t, k);
  return F;
}

Mat<2> MmsPlate::first_piola(const Vec<2>& X, double t) const {
  const Mat<2> F = deformation_gradient(X, t);
  const double lnJ = std::log(F(0, 0) * F(1, 1));
  Mat<2> P = Mat<2>::Zero();
  for (int k = 0; k < 2; ++k) P(k, k) = mu_ * (F(k, k) - 1.0 / F(k, k)) + lambda_ * lnJ / F(k, k);
  return P;
}

Mat<2> MmsPlate::stress(const Vec<2>& X, double t) const {
  const Mat<2> F = deformation_gradient(X, t);
  return first_piola(X, t) * F.transpose() / (F(0, 0) * F(1, 1)); // J of the diagonal F
}

Vec<2> MmsPlate::body_force(const Vec<2>& X, double t) const {
  const Mat<2> F = deformation_gradient(X, t);
  const double lnJ = std::log(F(0, 0) * F(1, 1));
  const Vec<2> u = displacement(X, t);
  Vec<2> b;
  for (int k = 0; k < 2; ++k) {
    const double Fk = F(k, k);
    const double dP_dF = mu_ * (1.0 + 1.0 / (Fk * Fk)) + lambda_ * (1.0 - lnJ) / (Fk * Fk);
    const double dF_dX = -p_.amplitude * kx_ * kx_ * std::sin(spatial(X, k)) * temporal(t, k);
    b[k] = -kt_ * kt_ * u[k] - dP_dF * dF_dX / p_.density;
  }
  return b;
}

double rms_error(const std::vector<double>& squared_errors) {
  if (squared_errors.empty()) throw InputError("rms_error: no samples");
  double sum = 0.0;
  for (double e : squared_errors) {
    if (!std::isfinite(e) || e < 0.0)
      throw InputError("rms_error: squared error " + std::to_string(e) + " is negative or not finite");
    sum += e;
  }
  return std::sqrt(sum / static_cast<double>(squared_errors.size()));
}

template class UniaxialBar<1>;
template class UniaxialBar<2>;
template class UniaxialBar<3>;
template class DykaBar<1>;
template class DykaBar<2>;
template class DykaBar<3>;
template class FixedBar<1>;
template class FixedBar<2>;
template class FixedBar<3>;
template class TractionBar<1>;
template class TractionBar<2>;
template class TractionBar<3>;

} // namespace otmpm
