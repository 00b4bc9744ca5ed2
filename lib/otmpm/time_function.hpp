#pragma once
/// \file time_function.hpp
/// A time function g(t) that multiplies a load (docs/theory.md sect. 7).
#include <string>

namespace otmpm {

/// Constant 1, or the smooth ramp of molinos et al. eq. 45,
/// g(t) = 0.5 (sin(2 pi t / T - pi/2) + 1) = sin^2(pi t / T) for t <= T/2 and
/// 1 afterwards: it rises from 0 to 1 with zero slope at both ends.
struct TimeFunction {
  std::string kind = "constant"; ///< constant | ramp
  double period = 0.0;           ///< T of molinos eq. 45
};

/// g(t) of `g`.
double time_function(const TimeFunction& g, double t);

} // namespace otmpm
