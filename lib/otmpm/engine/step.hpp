#pragma once
/// \file step.hpp
/// What the engine hands an integrator's step function (integrators/): the
/// clock, the integrator's parameters and the particle and nodal fields.
#include "otmpm/core.hpp"

#include <map>
#include <string>
#include <string_view>

namespace otmpm {

template <int D> class Engine;
template <int D> struct Particles;
template <int D> struct NodalFields;

/// The parameters of the integrator by key (scene keys under [simulation],
/// declared by each integrator: IntegratorKind::parameters), with their
/// defaults filled in.
struct IntegratorParameters {
  std::map<std::string, double, std::less<>> values;
  /// The parameter `key`; std::invalid_argument when the integrator has none.
  double get(std::string_view key) const;
};

/// What a step function is given: the clock, the parameters, and the
/// particle and nodal fields it updates (the same objects the engine holds).
template <int D> struct StepContext {
  double t = 0.0;       ///< time at the start of the step
  double dt = 0.0;      ///< this step's size
  double dt_prev = 0.0; ///< the previous step's size (dt in the first step)
  long step = 0;        ///< steps taken before this one
  const IntegratorParameters& parameters;
  Particles<D>& particles;
  NodalFields<D>& nodes;
};

/// One step of an integrator in D dimensions.
template <int D> using StepFunction = void (*)(Engine<D>&, const StepContext<D>&);

} // namespace otmpm
