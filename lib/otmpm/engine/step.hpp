#pragma once
/// \file step.hpp
/// What the engine hands an integrator's step function (integrators/): the
/// clock, the integrator's parameters and the particle and nodal fields.
#include "otmpm/core.hpp"

namespace otmpm {

template <int D> class Engine;
template <int D> struct Particles;
template <int D> struct NodalFields;

/// The parameters of the integrators that have any (scene keys under [simulation]).
struct IntegratorParameters {
  double gamma = 0.5; ///< Newmark parameter of npc (molinos et al. Algorithm 1)
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
