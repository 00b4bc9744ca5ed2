#pragma once
/// \file solutions.hpp
/// The concrete exact solutions of the benchmark scenes (docs/benchmarks.md):
/// the Dyka bar (molinos appendix A), the fixed-end vibrating bar (wobbes
/// sect. 8.1), the bar with a dynamic traction (wobbes sect. 8.2, eq. 103) and
/// the plate with an axis-aligned manufactured displacement (wobbes sect. 8.3,
/// eqs. 104-106). Every field is a function of the material (initial)
/// position X and the time t. make_exact_solution() (exact.hpp) builds them
/// from a scene; tests and drivers may also construct them directly.
#include "otmpm/reference/exact.hpp"

namespace otmpm {

/// Axial displacement u_x, velocity v_x and Cauchy stress sigma_xx of a
/// uniaxial bar at one material point and time.
struct BarState {
  double u = 0.0;
  double v = 0.0;
  double sigma = 0.0;
};

/// A bar along the x axis in D dimensions: only the x components of u and v
/// and sigma_xx are non-zero (uniaxial motion with lateral components zero,
/// exact for nu = 0 in 2D/3D). Concrete bars implement state().
template <int D> class UniaxialBar : public ExactSolution<D> {
public:
  /// u_x, v_x, sigma_xx at material x-coordinate X (scene coordinates) and time t.
  virtual BarState state(double X, double t) const = 0;

  Vec<D> displacement(const Vec<D>& X, double t) const override { return along_x(state(X[0], t).u); }
  Vec<D> velocity(const Vec<D>& X, double t) const override { return along_x(state(X[0], t).v); }
  Mat<D> stress(const Vec<D>& X, double t) const override {
    Mat<D> s = Mat<D>::Zero();
    s(0, 0) = state(X[0], t).sigma;
    return s;
  }

protected:
  static Vec<D> along_x(double a) {
    Vec<D> r = Vec<D>::Zero();
    r[0] = a;
    return r;
  }
};

/// Parameters of the Dyka bar. The bar occupies [x_free, x_free + length];
/// the end x_free is traction-free, the end x_free + length is fixed (v = 0).
/// Initial stress zero; initial velocity `region_velocity` for X - x_free in
/// the closed interval [region_begin, region_end] and `rest_velocity` elsewhere.
struct DykaParameters {
  double length = 0.0;          ///< L [m]
  double young = 0.0;           ///< E [Pa]
  double density = 0.0;         ///< rho [kg/m^3]
  double region_velocity = 0.0; ///< V0 [m/s] (-5 in the benchmark)
  double region_begin = 0.0;    ///< start of the V0 region, from the free end [m]
  double region_end = 0.0;      ///< end of the V0 region, from the free end (L/4) [m]
  double rest_velocity = 0.0;   ///< initial velocity outside the region [m/s]
  double x_free = 0.0;          ///< x-coordinate of the free end
};

/// Dyka bar (molinos sect. 3.1 and appendix A), small-strain linear elastic,
/// solved by characteristics. With c = sqrt(E/rho) and V the initial velocity
/// extended evenly about the free end X = 0 and oddly about the fixed end X = L
/// (period 4L):
///   v(X,t)     = (V(X - ct) + V(X + ct)) / 2,
///   sigma(X,t) = rho c (V(X + ct) - V(X - ct)) / 2     (tension positive),
///   u(X,t)     = (W(X + ct) - W(X - ct)) / (2c),         W' = V, W(0) = 0,
/// which satisfy rho v_t = sigma_X, sigma_t = E v_X, sigma = E u_X, v = u_t,
/// sigma(0,t) = 0 (even V) and v(L,t) = 0 (odd V). X is measured from the free
/// end. At a jump of V the region is closed (V(region_end) = V0).
template <int D> class DykaBar final : public UniaxialBar<D> {
public:
  /// Bar [0, L] with V0 on [0, region_end], zero elsewhere. Throws InputError
  /// for non-positive L, E, rho or a region outside [0, L].
  DykaBar(double length, double young, double density, double region_velocity, double region_end);
  explicit DykaBar(const DykaParameters& p);

  std::string name() const override { return "dyka"; }
  BarState state(double X, double t) const override;

  double wave_speed() const { return c_; }
  /// V: the initial velocity extended to the whole line (even about 0, odd about L).
  double extended_velocity(double xi) const;
  /// W: the antiderivative of V with W(0) = 0 (periodic, since V has zero mean over 4L).
  double extended_antiderivative(double xi) const;

private:
  double base_velocity(double s) const;  ///< V on [0, L]
  double base_integral(double s) const;  ///< integral of V over [0, s], s in [0, L]
  DykaParameters p_;
  double c_;
};

/// Parameters of the fixed-end vibrating bar: bar [x_left, x_left + length],
/// both ends fixed, initial velocity amplitude * sin(pi (X - x_left) / L).
struct FixedBarParameters {
  double length = 0.0;    ///< L [m]
  double young = 0.0;     ///< E [Pa]
  double density = 0.0;   ///< rho [kg/m^3]
  double amplitude = 0.0; ///< v_max^0 of wobbes eq. 101 (0.6 m/s) [m/s]
  double x_left = 0.0;
};

/// Fixed-end vibrating bar (wobbes sect. 8.1, eq. 101), small-strain linear
/// elasticity: with w = pi sqrt(E/rho) / L and xi = X - x_left,
///   u = (v0 / w) sin(w t) sin(pi xi / L),  v = v0 cos(w t) sin(pi xi / L),
///   sigma = E u_X = (v0 E / c) sin(w t) cos(pi xi / L)   (small strain).
template <int D> class FixedBar final : public UniaxialBar<D> {
public:
  explicit FixedBar(const FixedBarParameters& p);
  std::string name() const override { return "fixed_bar"; }
  BarState state(double X, double t) const override;
  double angular_frequency() const { return omega_; }

private:
  FixedBarParameters p_;
  double c_, omega_;
};

/// Parameters of the bar with a dynamic traction: bar [x_fixed, x_fixed + length],
/// u = 0 at x_fixed, traction at the free end x_fixed + length.
struct TractionBarParameters {
  double length = 0.0;    ///< l [m]
  double young = 0.0;     ///< E [Pa] (small-strain modulus)
  double density = 0.0;   ///< rho [kg/m^3]
  double amplitude = 1.0; ///< tau_0 [Pa]: wobbes eq. 103 has unit amplitude
  double x_fixed = 0.0;
};

/// Bar with a dynamic traction (wobbes sect. 8.2, eq. 103). With
/// c = sqrt(E/rho), omega = pi / l, s = c t (mod 4l; the paper has c = 1 m/s,
/// so s = t there) and xi = X - x_fixed in [0, l], the stress is eq. 103
/// times tau_0:
///   0                                       s in [0, l - xi)
///   sin(omega(s + xi))                      s in [l - xi, l + xi)
///   sin(omega(s + xi)) + sin(omega(s - xi)) s in [l + xi, 3l - xi)
///   sin(omega(s - xi))                      s in [3l - xi, 3l + xi)
///   0                                       s in [3l + xi, 4l),
/// and, integrating sigma = E u_X from u(0,t) = 0 with u continuous
/// (alpha = tau_0 / (E omega)), the displacement is 0, -alpha (1 + cos(omega(s+xi))),
/// alpha (cos(omega(s-xi)) - cos(omega(s+xi))), alpha (1 + cos(omega(s-xi))), 0
/// on the same intervals; v = c du/ds. This is the linear (small-strain) wave
/// solution the paper compares its neo-Hookean runs with: with E = 100 Pa and
/// tau_0 = 1 Pa the strain stays below 2%, where the neo-Hookean stress differs
/// from E u_X by about half the strain (relative). The state at s = 4l is at rest,
/// so the solution repeats with period 4l/c under the traction below.
template <int D> class TractionBar final : public UniaxialBar<D> {
public:
  explicit TractionBar(const TractionBarParameters& p);
  std::string name() const override { return "traction_bar"; }
  BarState state(double X, double t) const override;

  /// The traction applied at the free end X = l: x-component of the force per
  /// unit reference area, tau(t) = sigma(l, t) = -tau_0 sin(pi c t / l) (tension
  /// positive, outward normal +x). In uniaxial motion the cross-section does not
  /// change, so nominal and Cauchy traction coincide.
  double traction(double t) const;
  double wave_speed() const { return c_; }

private:
  TractionBarParameters p_;
  double c_, omega_;
};

/// Parameters of the manufactured plate: the square [lower, lower + length]^2.
struct MmsPlateParameters {
  double length = 1.0;    ///< l [m]
  double young = 0.0;     ///< E [Pa]
  double poisson = 0.0;   ///< nu
  double density = 0.0;   ///< rho0 [kg/m^3]
  double amplitude = 0.0; ///< A [m] (0.005 in wobbes sect. 8.3)
  double lower[2] = {0.0, 0.0};
};

/// Plate with an axis-aligned manufactured displacement (wobbes sect. 8.3,
/// eqs. 104-106), plane-strain neo-Hookean (wobbes eq. 11), 2D only. With
/// c = sqrt(E/rho0) (eq. 106), xi_k = (X_k - lower_k) / l and
/// s(t) = sin(c pi t / l):
///   u_1 = A sin(2 pi xi_1) s(t),   u_2 = A sin(2 pi xi_2) sin(c pi t / l + pi) = -u_1(xi_2).
/// The body force per unit mass that drives it is b = u_tt - Div P / rho0
/// (derivation in exact.cpp); the stress is the neo-Hookean Cauchy stress.
class MmsPlate final : public ExactSolution<2> {
public:
  explicit MmsPlate(const MmsPlateParameters& p);
  std::string name() const override { return "mms_plate"; }
  Vec<2> displacement(const Vec<2>& X, double t) const override;
  Vec<2> velocity(const Vec<2>& X, double t) const override;
  Mat<2> stress(const Vec<2>& X, double t) const override;
  Vec<2> body_force(const Vec<2>& X, double t) const override;
  bool has_body_force() const override { return true; }

  /// The first Piola-Kirchhoff stress P = mu (F - F^-T) + lambda ln J F^-T.
  Mat<2> first_piola(const Vec<2>& X, double t) const;
  /// Deformation gradient F = I + du/dX (diagonal).
  Mat<2> deformation_gradient(const Vec<2>& X, double t) const;
  double lambda() const { return lambda_; }
  double mu() const { return mu_; }

private:
  double spatial(const Vec<2>& X, int k) const; ///< 2 pi xi_k
  double temporal(double t, int k) const;       ///< sin(c pi t / l + k pi)
  MmsPlateParameters p_;
  double c_, lambda_, mu_, kx_, kt_;
};

extern template class UniaxialBar<1>;
extern template class UniaxialBar<2>;
extern template class UniaxialBar<3>;
extern template class DykaBar<1>;
extern template class DykaBar<2>;
extern template class DykaBar<3>;
extern template class FixedBar<1>;
extern template class FixedBar<2>;
extern template class FixedBar<3>;
extern template class TractionBar<1>;
extern template class TractionBar<2>;
extern template class TractionBar<3>;

} // namespace otmpm
