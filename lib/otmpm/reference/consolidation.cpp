/// \file consolidation.cpp
/// Terzaghi's column and Mandel's slab (consolidation.hpp).
#include "otmpm/reference/consolidation.hpp"


#include <cmath>
#include <numbers>

namespace otmpm {

namespace {

constexpr double pi = std::numbers::pi;

/// Terms of a series below this share of its scale end it (after a few in a row).
constexpr double kSeriesTolerance = 1e-15;
/// The most terms of Terzaghi's series, and the roots of Mandel's.
constexpr int kTerzaghiTerms = 20000;
constexpr int kMandelRoots = 4000;

/// Adds term(i) for i = 0, 1, ... until three terms in a row fall below
/// kSeriesTolerance x scale, or `limit` terms.
template <class Term> double sum_series(int limit, double scale, Term&& term) {
  double sum = 0.0;
  int small = 0;
  for (int i = 0; i < limit && small < 3; ++i) {
    const double x = term(i);
    sum += x;
    small = std::abs(x) < kSeriesTolerance * scale ? small + 1 : 0;
  }
  return sum;
}

} // namespace

LoadHistory::LoadHistory(TimeFunction g) : g_(std::move(g)) {
  require(g_.kind == "constant" || (g_.kind == "ramp" && finite_positive(g_.period)),
          "LoadHistory: the time function must be constant or a ramp with a period > 0");
}

double LoadHistory::rate(double t) const {
  if (g_.kind != "ramp" || t <= 0.0 || t >= 0.5 * g_.period) return 0.0;
  return pi / g_.period * std::sin(2.0 * pi * t / g_.period);
}

double LoadHistory::memory(double lambda, double t) const {
  if (t < 0.0 || !(lambda < kUnbounded)) return 0.0; // an infinitely fast mode has decayed
  if (g_.kind != "ramp") return std::exp(-lambda * t);
  // int_0^s (pi / T) sin(w r) exp(-lambda (t - r)) dr, s = min(t, T / 2), w = 2 pi / T
  const double T = g_.period, w = 2.0 * pi / T, s = std::min(t, 0.5 * T);
  return pi / T *
         (std::exp(-lambda * (t - s)) * (lambda * std::sin(w * s) - w * std::cos(w * s)) + w * std::exp(-lambda * t)) /
         (lambda * lambda + w * w);
}

// ---------------------------------------------------------------------------
// Terzaghi

template <int D>
Terzaghi<D>::Terzaghi(const TerzaghiParameters& p) : p_(p), cv_(0.0), beta_(0.0), history_(p.time) {
  for (double v : {p.height, p.modulus, p.porosity, p.mobility, p.fluid_bulk_modulus})
    require(finite_positive(v), "Terzaghi: height, modulus, porosity, mobility and fluid bulk modulus must be "
            "finite and > 0 (got ", v, ")");
  require(p.porosity < 1.0 && std::isfinite(p.load) && std::isfinite(p.lateral) && p.axis >= 0 && p.axis < D &&
              std::abs(p.direction) == 1.0,
          "Terzaghi: porosity in (0, 1), a finite load, an axis of the run and a direction of +-1");
  const double storage = 1.0 / p.modulus + p.porosity / p.fluid_bulk_modulus;
  cv_ = p.mobility / storage;
  beta_ = 1.0 / (p.modulus * storage);
}

template <int D> double Terzaghi<D>::along(const Vec<D>& X) const {
  return std::clamp(p_.direction * (X[p_.axis] - p_.base), 0.0, p_.height);
}

template <int D> double Terzaghi<D>::series(double xi, double t, bool integral, bool rate) const {
  const double H = p_.height, z = H - xi, scale = beta_ * std::abs(p_.load) * (integral ? H : 1.0);
  if (t <= 0.0) return rate ? 0.0 : beta_ * p_.load * history_.value(0.0) * (integral ? xi : 1.0);
  return sum_series(kTerzaghiTerms, scale, [&](int m) {
    const double M = (2 * m + 1) * pi / 2, lambda = M * M * cv_ / (H * H);
    const double J = rate ? history_.memory_rate(lambda, t) : history_.memory(lambda, t);
    return integral ? 2.0 * beta_ * p_.load * H / (M * M) * std::cos(M * z / H) * J
                    : 2.0 * beta_ * p_.load / M * std::sin(M * z / H) * J;
  });
}

template <int D> double Terzaghi<D>::pore_pressure(const Vec<D>& X, double t) const {
  return series(along(X), t, false, false);
}

template <int D> Vec<D> Terzaghi<D>::displacement(const Vec<D>& X, double t) const {
  const double xi = along(X);
  Vec<D> u = Vec<D>::Zero();
  u[p_.axis] = p_.direction * (series(xi, t, true, false) - p_.load * history_.value(t) * xi) / p_.modulus;
  return u;
}

template <int D> Vec<D> Terzaghi<D>::velocity(const Vec<D>& X, double t) const {
  const double xi = along(X);
  Vec<D> v = Vec<D>::Zero();
  v[p_.axis] = p_.direction * (series(xi, t, true, true) - p_.load * history_.rate(t) * xi) / p_.modulus;
  return v;
}

template <int D> Mat<D> Terzaghi<D>::stress(const Vec<D>& X, double t) const {
  const double axial = pore_pressure(X, t) - p_.load * history_.value(t); // sigma' = M eps = p - q g
  Mat<D> s = Mat<D>::Identity() * (p_.lateral * axial);
  s(p_.axis, p_.axis) = axial;
  return s;
}

template <int D> double Terzaghi<D>::degree(double t) const {
  const double load = p_.load * history_.value(t) * p_.height;
  return load == 0.0 ? 0.0 : 1.0 - series(p_.height, t, true, false) / load;
}

// ---------------------------------------------------------------------------
// Mandel

Mandel::Mandel(const MandelParameters& p) : p_(p), history_(p.time) {
  for (double v : {p.width, p.height, p.young, p.porosity, p.mobility, p.fluid_bulk_modulus})
    require(finite_positive(v), "Mandel: width, height, Young's modulus, porosity, mobility and fluid bulk modulus "
            "must be finite and > 0 (got ", v, ")");
  require(p.porosity < 1.0 && p.poisson > -1.0 && p.poisson < 0.5 && std::isfinite(p.stress),
          "Mandel: porosity in (0, 1), Poisson's ratio in (-1, 0.5) and a finite stress");
  nu_ = p.poisson;
  G_ = p.young / (2.0 * (1.0 + nu_));
  const double K = p.young / (3.0 * (1.0 - 2.0 * nu_)), M = p.fluid_bulk_modulus / p.porosity, Ku = K + M;
  nu_u_ = (3.0 * Ku - 2.0 * G_) / (2.0 * (3.0 * Ku + G_));
  B_ = M / Ku;
  c_ = p.mobility * M * (3.0 * K + 4.0 * G_) / (3.0 * Ku + 4.0 * G_);
  // f(alpha) = sin(alpha) - C alpha cos(alpha) changes sign once in each bracket.
  const double C = (1.0 - nu_) / (nu_u_ - nu_);
  auto f = [C](double a) { return std::sin(a) - C * a * std::cos(a); };
  for (int i = 0; i < kMandelRoots; ++i) {
    double lo = i == 0 ? 1e-9 : i * pi, hi = i * pi + pi / 2;
    const double f_lo = f(lo);
    for (int it = 0; it < 200 && hi - lo > 4e-16 * hi; ++it) {
      const double mid = 0.5 * (lo + hi);
      (f(mid) * f_lo > 0.0 ? lo : hi) = mid;
    }
    alpha_.push_back(0.5 * (lo + hi));
  }
}

template <class Term> double Mandel::series(double t, bool rate, Term&& term) const {
  const double a = p_.width;
  return sum_series(static_cast<int>(alpha_.size()), std::abs(p_.stress), [&](int i) {
    const double al = alpha_[static_cast<std::size_t>(i)], lambda = al * al * c_ / (a * a);
    const double J = rate ? history_.memory_rate(lambda, t) : history_.memory(lambda, t);
    return term(al, std::sin(al), std::cos(al), al - std::sin(al) * std::cos(al)) * J;
  });
}

double Mandel::pore_pressure(const Vec<2>& X, double t) const {
  const double a = p_.width, x = X[0] - p_.lower[0], F = p_.stress * a;
  if (t <= 0.0) return F * B_ * (1.0 + nu_u_) / (3.0 * a) * history_.value(0.0);
  return 2.0 * F * B_ * (1.0 + nu_u_) / (3.0 * a) *
         series(t, false, [&](double al, double s, double c, double d) { return s / d * (std::cos(al * x / a) - c); });
}

Vec<2> Mandel::displacement_at(const Vec<2>& X, double t, bool rate) const {
  const double a = p_.width, x = X[0] - p_.lower[0], y = X[1] - p_.lower[1], F = p_.stress * a;
  const double g = rate ? history_.rate(t) : history_.value(t);
  const double A = series(t, rate, [](double, double s, double c, double d) { return s * c / d; });
  const double Bx = series(t, rate, [&](double al, double, double c, double d) { return c / d * std::sin(al * x / a); });
  // The load presses down (-y): u_x grows outwards, u_y shortens the slab.
  return {(F * nu_ / (2.0 * G_ * a) * g - F * nu_u_ / (G_ * a) * A) * x + F / G_ * Bx,
          (-F * (1.0 - nu_) / (2.0 * G_ * a) * g + F * (1.0 - nu_u_) / (G_ * a) * A) * y};
}

Vec<2> Mandel::displacement(const Vec<2>& X, double t) const { return displacement_at(X, t, false); }
Vec<2> Mandel::velocity(const Vec<2>& X, double t) const { return displacement_at(X, t, true); }

Mat<2> Mandel::stress(const Vec<2>& X, double t) const {
  const double a = p_.width, x = X[0] - p_.lower[0], F = p_.stress * a;
  const double A = series(t, false, [](double, double s, double c, double d) { return s * c / d; });
  const double S = series(t, false, [&](double al, double s, double, double d) { return s / d * std::cos(al * x / a); });
  const double syy = -F / a * history_.value(t) - 2.0 * F * (nu_u_ - nu_) / (a * (1.0 - nu_)) * S + 2.0 * F / a * A;
  const double p = pore_pressure(X, t);
  Mat<2> s;
  s << p, 0.0, 0.0, syy + p; // sigma' = sigma + p I; the total sigma_xx and sigma_xy vanish
  return s;
}

template class Terzaghi<1>;
template class Terzaghi<2>;
template class Terzaghi<3>;

} // namespace otmpm
