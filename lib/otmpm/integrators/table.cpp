/// \file table.cpp
/// The table of integrators (integrator.hpp). A new integrator declares its
/// step function below and adds one row.
#include "otmpm/integrators/integrator.hpp"

#include <algorithm>
#include <array>

namespace otmpm {

// The step functions, each in its own file.
template <int D> void step_fe(Engine<D>&, const StepContext<D>&);
template <int D> void step_musl(Engine<D>&, const StepContext<D>&);
template <int D> void step_npc(Engine<D>&, const StepContext<D>&);
template <int D> void step_otm(Engine<D>&, const StepContext<D>&);
template <int D> void step_unified(Engine<D>&, const StepContext<D>&);

namespace {

#define OTMPM_STEPS(F) F<1>, F<2>, F<3>
// name, description, needs_ul, needs_bspline, consistent_by_default, needs_consistent_mass,
// needs_acceleration, needs_previous_position, step functions
const std::array kIntegrators{
    IntegratorKind{"fe", "forward Euler, stress updated last (USL)", false, false, false, false, false, false,
                   OTMPM_STEPS(step_fe)},
    IntegratorKind{"musl", "forward Euler with the modified update-stress-last", false, false, false, false, false,
                   false, OTMPM_STEPS(step_musl)},
    IntegratorKind{"npc", "explicit Newmark predictor-corrector (molinos et al. Algorithm 1)", false, false, false,
                   false, true, false, OTMPM_STEPS(step_npc)},
    IntegratorKind{"otm", "optimal transportation meshfree update (wobbes et al. Algorithm 2)", true, false, true,
                   false, false, true, OTMPM_STEPS(step_otm)},
    IntegratorKind{"unified", "B-splines on advected knots (wobbes et al. Algorithm 3)", true, true, true, true,
                   false, false, OTMPM_STEPS(step_unified)},
};
#undef OTMPM_STEPS

} // namespace

std::span<const IntegratorKind> integrator_kinds() { return kIntegrators; }

const IntegratorKind* find_integrator(std::string_view name) {
  const auto it =
      std::find_if(kIntegrators.begin(), kIntegrators.end(), [&](const IntegratorKind& k) { return k.name == name; });
  return it == kIntegrators.end() ? nullptr : &*it;
}

std::string integrator_list() {
  std::string s;
  for (std::size_t i = 0; i < kIntegrators.size(); ++i)
    s += std::string(i == 0 ? "" : i + 1 == kIntegrators.size() ? " or " : ", ") + std::string(kIntegrators[i].name);
  return s;
}

const IntegratorKind& integrator_kind(std::string_view name) {
  const IntegratorKind* k = find_integrator(name);
  if (!k) throw InputError("unknown integrator '" + std::string(name) + "' (expected " + integrator_list() + ")");
  return *k;
}

} // namespace otmpm
