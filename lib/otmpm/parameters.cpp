/// \file parameters.cpp
#include "otmpm/parameters.hpp"

#include "otmpm/core.hpp"

#include <cmath>

namespace otmpm {

std::string ParameterSpec::check(double value) const {
  const bool above = lower <= -kUnbounded || (lower_open ? value > lower : value >= lower);
  const bool below = upper >= kUnbounded || (upper_open ? value < upper : value <= upper);
  const bool whole = !integer || value == std::floor(value);
  if (above && below && whole && std::isfinite(value)) return ""; // no message built: checked once per particle-file value
  const std::string got = " (got " + format_number(value) + ")";
  if (!std::isfinite(value)) return "must be a finite number" + got;
  if (above && below) return "must be a whole number" + got;
  if (lower > -kUnbounded && upper < kUnbounded) // both ends bound it: the interval
    return std::string("must be in ") + (lower_open ? "(" : "[") + format_number(lower) + ", " + format_number(upper) +
           (upper_open ? ")" : "]") + got;
  if (!above) return std::string("must be ") + (lower_open ? "> " : ">= ") + format_number(lower) + got;
  return std::string("must be ") + (upper_open ? "< " : "<= ") + format_number(upper) + got;
}

} // namespace otmpm
