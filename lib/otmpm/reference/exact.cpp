// Exact solutions of the benchmark scenes (docs/benchmarks.md), the factory
// that builds them from a scene, and the RMS error of docs/theory.md sect. 12.
#include "otmpm/reference/exact.hpp"

#include "otmpm/reference/consolidation.hpp"
#include "otmpm/reference/solutions.hpp"
#include "otmpm/scene/scene.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace otmpm {

namespace {

constexpr double pi = std::numbers::pi;

/// Relative tolerance for geometric comparisons of scene boxes (a box edge
/// written with the same decimal literal as the body edge must match).
constexpr double kBoxTolerance = 1e-9;

/// wobbes eq. 103 has a unit traction amplitude [Pa].
constexpr double kWobbesTractionAmplitude = 1.0;

/// Displacement amplitude A of the manufactured plate (wobbes sect. 8.3) [m].
constexpr double kMmsAmplitude = 0.005;

/// Name of the built-in traction history of wobbes eq. 103 in a [[traction]] section.
const char* const kTractionBarFunction = "wobbes_traction_bar";

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

// ---------------------------------------------------------------------------
// Factory

namespace {

/// The single material and body of a bar or plate scene, checked.
struct SceneParts {
  const MaterialSection* material;
  const BodySection* body;
};

template <int D> SceneParts single_body(const Scene& scene, const SourceRef& where, const std::string& name) {
  if (scene.materials.size() != 1 || scene.bodies.size() != 1)
    input_error(where, "exact solution '" + name + "' needs exactly one [[material]] and one [[body]] (the scene has " +
                           std::to_string(scene.materials.size()) + " and " + std::to_string(scene.bodies.size()) + ")");
  const MaterialSection& m = scene.materials[0];
  const BodySection& b = scene.bodies[0];
  if (!b.material.empty() && b.material != m.name)
    input_error(where, "exact solution '" + name + "': body '" + b.name + "' uses material '" + b.material +
                           "', not '" + m.name + "'");
  if (!(m.density > 0.0) || !(m.young > 0.0))
    input_error(where, "exact solution '" + name + "' needs a positive density and Young's modulus in material '" +
                           m.name + "'");
  for (int k = 0; k < D; ++k)
    if (!(b.upper[k] > b.lower[k]))
      input_error(where, "exact solution '" + name + "': body '" + b.name + "' has no extent along axis " +
                             std::to_string(k));
  return {&m, &b};
}

/// The bar's motion must be along x only: no initial velocity across it.
template <int D> void require_axial(const Vec3& velocity, const SourceRef& where, const std::string& what) {
  for (int k = 1; k < D; ++k)
    if (velocity[k] != 0.0)
      input_error(where, what + " has a non-zero component " + std::to_string(k) +
                             "; the exact solution is for motion along x only");
}

bool covers(double box_lower, double box_upper, double lower, double upper) {
  const double tol = kBoxTolerance * std::max(1.0, std::abs(upper - lower));
  return box_lower <= lower + tol && box_upper >= upper - tol;
}

template <int D> std::unique_ptr<ExactSolution<D>> make_dyka(const Scene& scene, const SourceRef& where) {
  const auto [m, b] = single_body<D>(scene, where, "dyka");
  if (scene.initial_velocities.size() != 1)
    input_error(where, "exact solution 'dyka' needs exactly one [[initial_velocity]] box (the scene has " +
                           std::to_string(scene.initial_velocities.size()) + ")");
  if (b->velocity_profile)
    input_error(where, "exact solution 'dyka' needs a uniform body velocity, not velocity_profile = '" +
                           *b->velocity_profile + "'");
  const InitialVelocitySection& iv = scene.initial_velocities[0];
  require_axial<D>(iv.velocity, where, "the [[initial_velocity]] velocity");
  require_axial<D>(b->velocity, where, "the body velocity");
  for (int k = 1; k < D; ++k)
    if (!covers(iv.lower[k], iv.upper[k], b->lower[k], b->upper[k]))
      input_error(where, "exact solution 'dyka': the [[initial_velocity]] box must span the whole bar across axis " +
                             std::to_string(k));
  DykaParameters p;
  p.length = b->upper[0] - b->lower[0];
  p.young = m->young;
  p.density = m->density;
  p.region_velocity = iv.velocity[0];
  p.rest_velocity = b->velocity[0];
  p.x_free = b->lower[0];
  p.region_begin = std::max(iv.lower[0], b->lower[0]) - p.x_free;
  p.region_end = std::min(iv.upper[0], b->upper[0]) - p.x_free;
  if (p.region_end < p.region_begin)
    input_error(where, "exact solution 'dyka': the [[initial_velocity]] box does not overlap the bar");
  return std::make_unique<DykaBar<D>>(p);
}

template <int D> std::unique_ptr<ExactSolution<D>> make_fixed_bar(const Scene& scene, const SourceRef& where) {
  const auto [m, b] = single_body<D>(scene, where, "fixed_bar");
  if (!b->velocity_profile || *b->velocity_profile != "sin_x")
    input_error(where, "exact solution 'fixed_bar' needs body velocity_profile = \"sin_x\"");
  if (!scene.initial_velocities.empty())
    input_error(where, "exact solution 'fixed_bar' does not allow [[initial_velocity]] boxes");
  require_axial<D>(b->velocity, where, "the body velocity");
  FixedBarParameters p;
  p.length = b->upper[0] - b->lower[0];
  p.young = m->young;
  p.density = m->density;
  p.amplitude = b->velocity[0];
  p.x_left = b->lower[0];
  return std::make_unique<FixedBar<D>>(p);
}

template <int D> std::unique_ptr<ExactSolution<D>> make_traction_bar(const Scene& scene, const SourceRef& where) {
  const auto [m, b] = single_body<D>(scene, where, "traction_bar");
  const auto it = std::find_if(scene.tractions.begin(), scene.tractions.end(),
                               [](const TractionSection& t) { return t.function == kTractionBarFunction; });
  if (it == scene.tractions.end())
    input_error(where, std::string("exact solution 'traction_bar' needs a [[traction]] with function = \"") +
                           kTractionBarFunction + "\"");
  if (!scene.initial_velocities.empty() || b->velocity_profile || b->velocity != Vec3{0, 0, 0})
    input_error(where, "exact solution 'traction_bar' starts at rest: no initial velocity allowed");
  TractionBarParameters p;
  p.length = b->upper[0] - b->lower[0];
  p.young = m->young;
  p.density = m->density;
  p.amplitude = it->value[0] != 0.0 ? it->value[0] : kWobbesTractionAmplitude;
  p.x_fixed = b->lower[0];
  return std::make_unique<TractionBar<D>>(p);
}

template <int D> std::unique_ptr<ExactSolution<D>> make_mms_plate(const Scene& scene, const SourceRef& where) {
  if constexpr (D != 2) {
    input_error(where, "exact solution 'mms_plate' is two-dimensional; the run is " + std::to_string(D) + "D");
  } else {
    const auto [m, b] = single_body<D>(scene, where, "mms_plate");
    const double lx = b->upper[0] - b->lower[0], ly = b->upper[1] - b->lower[1];
    if (std::abs(lx - ly) > kBoxTolerance * lx)
      input_error(where, "exact solution 'mms_plate' needs a square body (got " + std::to_string(lx) + " x " +
                             std::to_string(ly) + ")");
    MmsPlateParameters p;
    p.length = lx;
    p.young = m->young;
    p.poisson = m->poisson;
    p.density = m->density;
    p.amplitude = kMmsAmplitude;
    p.lower[0] = b->lower[0];
    p.lower[1] = b->lower[1];
    try {
      return std::make_unique<MmsPlate>(p);
    } catch (const InputError& e) {
      input_error(where, e.what());
    }
  }
}

} // namespace

template <int D> std::unique_ptr<ExactSolution<D>> make_exact_solution(const Scene& scene) {
  const std::string& name = scene.reference.solution;
  if (name.empty()) return nullptr;
  const SourceRef where = scene.locate("reference.solution");
  if (scene.simulation.dimension != D)
    input_error(where, "the scene is " + std::to_string(scene.simulation.dimension) + "D but the run is " +
                           std::to_string(D) + "D");
  if (name == "dyka") return make_dyka<D>(scene, where);
  if (name == "fixed_bar") return make_fixed_bar<D>(scene, where);
  if (name == "traction_bar") return make_traction_bar<D>(scene, where);
  if (name == "mms_plate") return make_mms_plate<D>(scene, where);
  if (auto consolidation = make_consolidation<D>(scene, name)) return consolidation;
  input_error(where, "unknown exact solution '" + name +
                         "' (expected dyka, fixed_bar, traction_bar, mms_plate, terzaghi or mandel)");
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
template std::unique_ptr<ExactSolution<1>> make_exact_solution<1>(const Scene&);
template std::unique_ptr<ExactSolution<2>> make_exact_solution<2>(const Scene&);
template std::unique_ptr<ExactSolution<3>> make_exact_solution<3>(const Scene&);

} // namespace otmpm
