#pragma once
/// \file integrator.hpp
/// The closed set of time integrators, listed once (IntegratorKind): the
/// scene reader takes its choice list and pairing rules from it, the
/// validator its checks, the assembler which particle fields and mass matrix
/// to prepare and which step function the engine calls. Each integrator is
/// one function, in its own file, that reads like its algorithm listing
/// (docs/theory.md sect. 8) and drives the engine through its
/// public stages. Adding one (docs/architecture.md, "Adding a part"): its
/// file and one row in integrators/table.cpp.
#include "otmpm/engine/step.hpp"
#include "otmpm/parameters.hpp"

#include <span>
#include <string>
#include <string_view>

namespace otmpm {

/// One integrator as the scene names it (`simulation.integrator`) and what it needs.
struct IntegratorKind {
  std::string_view name;
  std::string_view description;
  /// Runs only with advected nodes (`mode = "ul"`).
  bool needs_ul = false;
  /// Needs a B-spline basis (BasisKind::bspline).
  bool needs_bspline = false;
  /// The mass matrix of its algorithm listing: consistent (true) or lumped.
  bool consistent_by_default = false;
  /// Refuses `mass = "lumped"` (its algorithm is defined with the consistent mass).
  bool needs_consistent_mass = false;
  /// Keeps the particle acceleration a_p from step to step.
  bool needs_acceleration = false;
  /// Keeps the previous particle position x_p^{s-1}.
  bool needs_previous_position = false;
  /// Carries the momentum its constraints give from step to step, on the
  /// nodes (Constraints::book_carried): a distributed run is not rebalanced.
  bool carries_constraints = false;
  /// Steps saturated bodies: drives the liquid phase (engine/two_phase.hpp).
  bool two_phase = false;
  /// Its parameters (scene keys under [simulation]).
  std::span<const ParameterSpec> parameters{};
  /// Its parameters at their defaults (what a run built in code starts from).
  IntegratorParameters default_parameters() const;
  /// True when `key` is one of its parameters.
  bool takes(std::string_view key) const;
  StepFunction<1> step1 = nullptr;
  StepFunction<2> step2 = nullptr;
  StepFunction<3> step3 = nullptr;

  /// What the engine must provide (from the flags and parameters above).
  StepNeeds needs() const;
  /// The integrator as an engine runs it in D dimensions (StepSettings::step).
  template <int D> IntegratorStep<D> step() const {
    if constexpr (D == 1) return {name, step1, needs()};
    else if constexpr (D == 2) return {name, step2, needs()};
    else return {name, step3, needs()};
  }
};

/// Every integrator, in the order the docs list them.
std::span<const IntegratorKind> integrator_kinds();
/// The integrator named `name`, or null.
const IntegratorKind* find_integrator(std::string_view name);
/// The integrator named `name`; InputError listing the integrators otherwise.
const IntegratorKind& integrator_kind(std::string_view name);
/// "fe, musl, npc, otm, unified, central_difference or explicit_alpha", for
/// messages; with `parameter`, only the integrators that take it.
std::string integrator_list(std::string_view parameter = {});
/// The parameter keys of every integrator (the scene accepts each of them
/// whatever the integrator, so that switching integrators with --set works).
std::span<const ParameterSpec* const> integrator_parameters();

} // namespace otmpm
