#pragma once
/// \file step.hpp
/// What the engine hands an integrator's step function (integrators/): the
/// clock, the integrator's parameters and the particle and nodal fields.
#include "otmpm/core.hpp"
#include "otmpm/parameters.hpp"

#include <map>
#include <span>
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

/// What an integrator needs of a run beyond the engine's own state, as its
/// row in the integrator table declares it (IntegratorKind). The engine
/// allocates the particle fields it keeps, at their values at t = 0, when the
/// parts lack them, and refuses to be built without the rest
/// (std::invalid_argument naming the integrator and what is missing), so a
/// run built in code cannot step a different scheme than the one it names.
struct StepNeeds {
  bool acceleration = false;        ///< keeps a_p from step to step (Particles::a; 0 at t = 0)
  bool previous_position = false;   ///< keeps x_p^{s-1} (Particles::x_prev; x_p at t = 0)
  bool advected_nodes = false;      ///< runs only with nodes that move (NodeMode::advected)
  bool bspline = false;             ///< runs only on a B-spline basis (BasisKind::bspline)
  bool consistent_mass = false;     ///< runs only with the consistent mass (StepSettings::consistent_mass)
  bool carries_constraints = false; ///< carries its constraints' momentum on the nodes between steps
  std::span<const ParameterSpec> parameters{}; ///< reads these keys of StepContext::parameters
};

/// An integrator as an engine runs it: its name (for messages), its step
/// function in D dimensions and what it needs (IntegratorKind::step<D>()).
template <int D> struct IntegratorStep {
  std::string_view name;
  StepFunction<D> function = nullptr;
  StepNeeds needs;
};

} // namespace otmpm
