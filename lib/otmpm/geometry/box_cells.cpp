/// \file box_cells.cpp
/// The particle patterns of a cell (box_cells.hpp).
#include "otmpm/geometry/box_cells.hpp"

#include <cmath>
#include <numbers>
#include <string>

namespace otmpm {

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

} // namespace otmpm
