#pragma once
/// \file linear.hpp
/// Internal: the one-dimensional weight functions behind the `linear` and
/// `ugimp` families (families.hpp), exposed for unit tests.
#include "otmpm/core.hpp"

namespace otmpm::detail {

/// A 1D weight S(xi) and its derivative dS/dx at xi = x - x_I.
struct Weight1D {
  double S = 0.0;
  double dS = 0.0;
};

/// Uniform GIMP weight (Bardenhagen & Kober 2004, eq. for the "uGIMP" case):
/// the hat function of node I (width h) averaged over a particle of
/// half-width lp centred at x = x_I + xi,
///   S = 1 - (xi^2 + lp^2) / (2 h lp)       |xi| < lp
///     = 1 - |xi| / h                       lp <= |xi| <= h - lp
///     = (h + lp - |xi|)^2 / (4 h lp)       h - lp < |xi| < h + lp
///     = 0                                  otherwise.
/// S is C1 (the second derivative jumps at |xi| = lp, h - lp, h + lp).
/// Requires 0 < lp <= h / 2.
Weight1D ugimp_weight(double xi, double h, double lp);

} // namespace otmpm::detail
