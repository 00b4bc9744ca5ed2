#pragma once
/// \file consolidation.hpp
/// Exact solutions of the consolidation benchmarks of saturated bodies
/// (docs/theory.md sect. 15.8, docs/benchmarks.md): Terzaghi's column and
/// Mandel's slab, for a pore liquid of finite bulk modulus K_w and
/// incompressible grains (Biot coefficient 1, Biot modulus K_w / n), under a
/// load F g(t) whose time function is the scene's (constant: a sudden load;
/// ramp: sin^2, by Duhamel's integral). Small strain, quasi-static: the
/// inertia of the run is what its error against them measures, with the
/// discretisation's. Every field is a function of the initial position X and
/// the time t; the stress is the effective stress the particles carry
/// (sigma' = sigma + p I, tension positive; p compression positive).
#include "otmpm/parameters.hpp"
#include "otmpm/reference/exact.hpp"
#include "otmpm/time_function.hpp"

#include <vector>

namespace otmpm {

/// A load's time function g(t) and, for a mode that decays at the rate
/// lambda, its memory J(lambda, t) = int_0^t g'(s) exp(-lambda (t - s)) ds
/// (a sudden load: exp(-lambda t)), with dJ/dt = g'(t) - lambda J.
class LoadHistory {
public:
  explicit LoadHistory(TimeFunction g);
  double value(double t) const { return time_function(g_, t); }
  double rate(double t) const; ///< g'(t) for t > 0 (0 for a sudden load)
  double memory(double lambda, double t) const;
  /// dJ/dt; 0 for an infinite lambda (J follows the load: lambda J -> g'(t)).
  double memory_rate(double lambda, double t) const {
    return lambda < kUnbounded ? rate(t) - lambda * memory(lambda, t) : 0.0;
  }

private:
  TimeFunction g_;
};

/// Terzaghi's column: a saturated layer of height H on an impermeable base,
/// loaded on its drained top by the total stress -q g(t) along `axis`,
/// confined laterally (oedometric modulus M = E in 1D, lambda + 2 mu in 2D
/// and 3D). With the mobility k = kappa / mu_w, the storage
/// S = 1 / M + n / K_w, c_v = k / S and the undrained share beta = 1 / (M S),
/// z the distance from the drained end and M_m = (2m + 1) pi / 2:
///   p = sum_m (2 beta q / M_m) sin(M_m z / H) J(M_m^2 c_v / H^2, t).
struct TerzaghiParameters {
  double height = 0.0;           ///< H [m]
  double base = 0.0;             ///< coordinate of the impermeable base along the axis
  double direction = 1.0;        ///< +1: the drained top is at base + H, -1: at base - H
  int axis = 0;
  double modulus = 0.0;          ///< oedometric modulus M [Pa]
  double lateral = 0.0;          ///< lambda / (lambda + 2 mu): the lateral effective stress per axial one
  double porosity = 0.0;
  double mobility = 0.0;         ///< kappa / mu_w [m^2 / (Pa s)]
  double fluid_bulk_modulus = 0.0;
  double load = 0.0;             ///< q [Pa], compression positive
  TimeFunction time;
};

template <int D> class Terzaghi final : public ExactSolution<D> {
public:
  explicit Terzaghi(const TerzaghiParameters& p);
  std::string name() const override { return "terzaghi"; }
  Vec<D> displacement(const Vec<D>& X, double t) const override;
  Vec<D> velocity(const Vec<D>& X, double t) const override;
  Mat<D> stress(const Vec<D>& X, double t) const override;
  double pore_pressure(const Vec<D>& X, double t) const override;
  bool has_pore_pressure() const override { return true; }
  double consolidation_coefficient() const { return cv_; }
  /// The undrained share beta of the load the pore liquid takes at once.
  double undrained_share() const { return beta_; }
  /// T_v = c_v t / H^2.
  double time_factor(double t) const { return cv_ * t / (p_.height * p_.height); }
  /// The degree of consolidation: the settlement over the final one under the load of time t.
  double degree(double t) const;

private:
  /// The sums of p and of its integral from the base (ints = true), or their rates (rates = true).
  double series(double xi, double t, bool integral, bool rate) const;
  double along(const Vec<D>& X) const; ///< xi: the distance from the base
  TerzaghiParameters p_;
  double cv_, beta_;
  LoadHistory history_;
};

/// Mandel's slab, plane strain: the quarter [x0, x0 + a] x [y0, y0 + b] of a
/// slab pressed by rigid, frictionless, impermeable plates with the force
/// 2 F g(t) per unit length (F = the stress sigma_0 times a on the quarter),
/// drained at x = x0 + a, rollers on the symmetry lines x = x0 and y = y0.
/// With the drained G, K, nu, the Biot modulus M = K_w / n, K_u = K + M,
/// nu_u = (3 K_u - 2 G) / (2 (3 K_u + G)), B = M / K_u, c = k M (3 K + 4 G) /
/// (3 K_u + 4 G) and the roots alpha_i of tan(alpha) = (1 - nu) / (nu_u - nu)
/// alpha:
///   p = 2 F B (1 + nu_u) / (3 a) sum_i sin(alpha_i) / (alpha_i - sin(alpha_i) cos(alpha_i))
///       (cos(alpha_i x / a) - cos(alpha_i)) J(alpha_i^2 c / a^2, t)
/// (Cheng & Detournay 1988; Abousleiman et al. 1996), with the displacement
/// and sigma_yy of the same references.
struct MandelParameters {
  double width = 0.0;  ///< a [m]
  double height = 0.0; ///< b [m]
  double lower[2] = {0.0, 0.0};
  double young = 0.0, poisson = 0.0;
  double porosity = 0.0;
  double mobility = 0.0; ///< kappa / mu_w
  double fluid_bulk_modulus = 0.0;
  double stress = 0.0;   ///< sigma_0 = F / a [Pa], compression positive
  TimeFunction time;
};

class Mandel final : public ExactSolution<2> {
public:
  explicit Mandel(const MandelParameters& p);
  std::string name() const override { return "mandel"; }
  Vec<2> displacement(const Vec<2>& X, double t) const override;
  Vec<2> velocity(const Vec<2>& X, double t) const override;
  Mat<2> stress(const Vec<2>& X, double t) const override;
  double pore_pressure(const Vec<2>& X, double t) const override;
  bool has_pore_pressure() const override { return true; }
  double consolidation_coefficient() const { return c_; }
  double skempton() const { return B_; }
  double undrained_poisson() const { return nu_u_; }
  /// The roots alpha_i of tan(alpha) = (1 - nu) / (nu_u - nu) alpha in ((i-1) pi, (i-1/2) pi).
  const std::vector<double>& roots() const { return alpha_; }

private:
  /// Sums over the roots of coefficient(i) times J (or dJ/dt with rate).
  template <class Term> double series(double t, bool rate, Term&& term) const;
  Vec<2> displacement_at(const Vec<2>& X, double t, bool rate) const;
  MandelParameters p_;
  double G_, nu_, nu_u_, B_, c_;
  std::vector<double> alpha_;
  LoadHistory history_;
};

extern template class Terzaghi<1>;
extern template class Terzaghi<2>;
extern template class Terzaghi<3>;

} // namespace otmpm
