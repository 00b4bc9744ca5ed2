/// \file particles.cpp
/// Particle storage (particles.hpp) and the particle patterns of a cell.
#include "otmpm/particles/particles.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace otmpm {

template <int D> void Particles<D>::resize(int n) {
  require<std::invalid_argument>(n >= 0, "Particles::resize: n must be >= 0, got ", n);
  x.assign(n, Vec<D>::Zero());
  X = v = length0 = x;
  m.assign(n, 0.0);
  V = V0 = rho = m;
  eps.assign(n, Mat<D>::Zero());
  sigma = eps;
  material.assign(n, 0);
  body.assign(n, 0);
  a.clear(), F.clear(), x_prev.clear(), state.clear();
}

template <int D> void Particles<D>::allocate_optional(bool with_a, bool with_F) {
  const auto n = static_cast<std::size_t>(size());
  if (with_a) a.assign(n, Vec<D>::Zero());
  if (with_F) F.assign(n, Mat<D>::Identity());
}

template <int D> StateField& Particles<D>::add_state(const std::string& name, int width, const double* initial) {
  require<std::invalid_argument>(width >= 1, "Particles::add_state: '", name, "' needs width >= 1, got ", width);
  if (StateField* f = find_state(name)) {
    require<std::invalid_argument>(f->width == width, "Particles::add_state: '", name, "' exists with width ",
                                   f->width, ", asked for ", width);
    return *f;
  }
  StateField f{name, width, std::vector<double>(static_cast<std::size_t>(size()) * width)};
  for (int p = 0; p < size(); ++p) std::copy(initial, initial + width, f.row(p));
  state.push_back(std::move(f));
  return state.back();
}

template <int D> StateField* Particles<D>::find_state(std::string_view name) {
  const auto it = std::find_if(state.begin(), state.end(), [&](const StateField& f) { return f.name == name; });
  return it == state.end() ? nullptr : &*it;
}

template <int D> const StateField* Particles<D>::find_state(std::string_view name) const {
  return const_cast<Particles*>(this)->find_state(name);
}

void gauss_legendre(int n, std::vector<double>& points, std::vector<double>& weights) {
  if (n < 1) throw InputError("gauss_legendre: order must be >= 1, got " + std::to_string(n));
  constexpr int max_newton = 100;
  constexpr double newton_tol = 1e-15;
  points.assign(n, 0.0);
  weights.assign(n, 0.0);
  for (int i = 0; i < n; ++i) {
    // Chebyshev-like initial guess for the i-th root of P_n, refined by Newton.
    double z = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));
    double dp = 1.0;
    for (int it = 0; it < max_newton; ++it) {
      double p0 = 1.0, p1 = z;
      for (int k = 2; k <= n; ++k) {
        const double pk = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = pk;
      }
      if (n == 1) p0 = 1.0;
      dp = n * (z * p1 - p0) / (z * z - 1.0);
      const double dz = p1 / dp;
      z -= dz;
      if (std::abs(dz) < newton_tol) break;
    }
    points[n - 1 - i] = z;
    weights[n - 1 - i] = 2.0 / ((1.0 - z * z) * dp * dp);
  }
}

void cell_pattern(std::string_view placement, int n, std::vector<double>& s, std::vector<double>& w) {
  if (placement == "gauss") {
    gauss_legendre(n, s, w);
    for (int i = 0; i < n; ++i) {
      s[i] = 0.5 * (s[i] + 1.0);
      w[i] *= 0.5;
    }
    return;
  }
  s.resize(n);
  w.assign(n, 1.0 / n);
  for (int i = 0; i < n; ++i) s[i] = (i + 0.5) / n;
}

template struct Particles<1>;
template struct Particles<2>;
template struct Particles<3>;

} // namespace otmpm
