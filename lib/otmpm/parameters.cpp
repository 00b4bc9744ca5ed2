/// \file parameters.cpp
#include "otmpm/parameters.hpp"

#include "otmpm/core.hpp"

#include <cmath>

namespace otmpm {

std::string ParameterSpec::check(double value) const {
  if (!std::isfinite(value)) return "must be a finite number (got " + format_number(value) + ")";
  if (lower_open ? !(value > lower) : !(value >= lower))
    return std::string("must be ") + (lower_open ? "> " : ">= ") + format_number(lower) + " (got " +
           format_number(value) + ")";
  if (upper_open ? !(value < upper) : !(value <= upper))
    return std::string("must be ") + (upper_open ? "< " : "<= ") + format_number(upper) + " (got " +
           format_number(value) + ")";
  return "";
}

} // namespace otmpm
