#pragma once
/// \file parameters.hpp
/// A named numeric parameter that a closed set declares for its members
/// (material models, integrators): its key, meaning, default and range, so
/// that the scene reader, the validator and the docs take them from one list.
#include <optional>
#include <string>
#include <string_view>

namespace otmpm {

/// One parameter: `fallback` is the default (nullopt: required); the value
/// must lie in [lower, upper] (an open end excludes its bound).
struct ParameterSpec {
  std::string_view key;
  std::string_view description;
  std::optional<double> fallback; ///< nullopt: required
  double lower = 0.0;             ///< smallest allowed value
  bool lower_open = false;        ///< lower itself excluded
  double upper = 1e300;           ///< largest allowed value
  bool upper_open = false;
  /// "" when `value` is allowed, else the reason ("must be >= 0 (got -1)").
  std::string check(double value) const;
};

} // namespace otmpm
