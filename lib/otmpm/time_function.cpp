/// \file time_function.cpp
#include "otmpm/time_function.hpp"

#include <cmath>
#include <numbers>

namespace otmpm {

double time_function(const TimeFunction& g, double t) {
  if (g.kind != "ramp") return 1.0;
  // molinos eq. 45: g(t) = 0.5 (sin(2 pi t / T - pi / 2) + 1) up to T/2, then 1:
  // a smooth ramp from 0 (zero slope) to 1 (zero slope) at T/2.
  if (t >= 0.5 * g.period) return 1.0;
  return 0.5 * (std::sin(2.0 * std::numbers::pi * t / g.period - 0.5 * std::numbers::pi) + 1.0);
}

} // namespace otmpm
