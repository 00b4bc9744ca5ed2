#pragma once
/// \file parameters.hpp
/// A named numeric parameter that a closed set declares for its members
/// (material models, integrators): its key, meaning, default and range, so
/// that the scene reader, the validator and the docs take them from one list.
#include <optional>
#include <string>
#include <string_view>

namespace otmpm {

/// A bound of ParameterSpec that bounds nothing (lower = -kUnbounded,
/// upper = kUnbounded: no check at that end).
inline constexpr double kUnbounded = 1e300;

/// One parameter: `fallback` is the default (nullopt: required); the value
/// must be finite and lie in [lower, upper] (an open end excludes its bound),
/// and be a whole number when `integer` (a count).
/// The one range check of every number that enters a run by a scene key
/// or a particle file's column of the same quantity.
struct ParameterSpec {
  std::string_view key;
  std::string_view description;
  std::optional<double> fallback; ///< nullopt: required
  double lower = 0.0;             ///< smallest allowed value (-kUnbounded: none)
  bool lower_open = false;        ///< lower itself excluded
  double upper = kUnbounded;      ///< largest allowed value (kUnbounded: none)
  bool upper_open = false;
  bool integer = false;           ///< a count: whole numbers only
  /// "" when `value` is allowed, else the reason: "must be >= 0 (got -1)",
  /// "must be in (-1, 0.5) (got 0.5)" when both ends bound it, "must be a
  /// whole number (got 2.5)".
  std::string check(double value) const;
};

} // namespace otmpm
