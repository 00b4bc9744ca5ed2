#pragma once
/// \file exact.hpp
/// Exact solutions of the benchmark scenes (benchmarks.md) and the error
/// norms of docs/theory.md sect. 12. All fields are functions of the
/// initial (material) position X and time t.
#include "otmpm/core.hpp"

#include <memory>
#include <string>

namespace otmpm {


/// An exact solution u(X, t), v(X, t), sigma(X, t). Scenes with a manufactured
/// solution also provide the body force per unit mass b(X, t) that drives it.
template <int D> class ExactSolution {
public:
  virtual ~ExactSolution() = default;
  virtual std::string name() const = 0;
  virtual Vec<D> displacement(const Vec<D>& X, double t) const = 0;
  virtual Vec<D> velocity(const Vec<D>& X, double t) const = 0;
  /// Cauchy stress.
  virtual Mat<D> stress(const Vec<D>& X, double t) const = 0;
  /// Pore pressure of a saturated body (compression positive; zero for a dry one).
  virtual double pore_pressure(const Vec<D>& /*X*/, double /*t*/) const { return 0.0; }
  virtual bool has_pore_pressure() const { return false; }
  /// Body force per unit mass needed by a manufactured solution (zero otherwise).
  virtual Vec<D> body_force(const Vec<D>& /*X*/, double /*t*/) const { return Vec<D>::Zero(); }
  virtual bool has_body_force() const { return false; }
};

/// RMS over particles (docs/theory.md sect. 12, molinos eq. 44):
/// sqrt((1/N) sum_p |q_p - q_exact(X_p, t)|^2).
double rms_error(const std::vector<double>& squared_errors);

} // namespace otmpm
