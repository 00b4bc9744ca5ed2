#pragma once
/// \file exact_solutions.hpp
/// The exact solution of a scene ([reference]): the solutions of reference/
/// built with the scene's parameters.
#include "otmpm/reference/exact.hpp"
#include "otmpm/scene/scene.hpp"

#include <memory>

namespace otmpm {

/// The exact solution named by scene.reference.solution, with its
/// parameters (material, bar length, initial velocity) taken from the scene.
/// Returns null when the scene has none; throws InputError (naming the key)
/// when the scene does not fit the solution (e.g. "dyka" in a scene with two
/// materials, "mms_plate" in 1D).
template <int D> std::unique_ptr<ExactSolution<D>> make_exact_solution(const Scene& scene);

} // namespace otmpm
