/// \file table.cpp
/// The table of integrators (integrator.hpp). A new integrator declares its
/// step function below and adds one row.
#include "otmpm/integrators/integrator.hpp"

#include <algorithm>
#include <array>
#include <vector>

namespace otmpm {

// The step functions, each in its own file.
template <int D> void step_fe(Engine<D>&, const StepContext<D>&);
template <int D> void step_musl(Engine<D>&, const StepContext<D>&);
template <int D> void step_npc(Engine<D>&, const StepContext<D>&);
template <int D> void step_otm(Engine<D>&, const StepContext<D>&);
template <int D> void step_unified(Engine<D>&, const StepContext<D>&);
template <int D> void step_central_difference(Engine<D>&, const StepContext<D>&);
template <int D> void step_explicit_alpha(Engine<D>&, const StepContext<D>&);

namespace {

const ParameterSpec kGamma{"gamma", "Newmark parameter of npc (molinos et al. Algorithm 1)", 0.5, 0.0, true, 1.0};
const ParameterSpec kRhoInf{"rho_inf", "spectral radius at the bifurcation limit of explicit_alpha (Hulbert & Chung rho_b)",
                            0.5, 0.0, false, 1.0};
const ParameterSpec kPicTime{"pic_relaxation_time",
                             "relaxation time tau [s] of the particle velocities toward the grid's: each step v_p += "
                             "min(1, dt / tau) (sum_I N_Ip v_I - v_p), the kinetic energy it removes booked as "
                             "`relaxation`; 0: none (FLIP)",
                             0.0, 0.0};
const std::array kNpcParameters{kGamma, kPicTime};
const std::array kAlphaParameters{kRhoInf, kPicTime};
const std::array kPicParameters{kPicTime};
const std::array kAllParameters{&kGamma, &kRhoInf, &kPicTime};

#define OTMPM_STEPS(F) .step1 = F<1>, .step2 = F<2>, .step3 = F<3>
const std::array kIntegrators{
    IntegratorKind{.name = "fe", .description = "forward Euler, stress updated last (USL)", .two_phase = true,
                   .parameters = kPicParameters, OTMPM_STEPS(step_fe)},
    IntegratorKind{.name = "musl", .description = "forward Euler with the modified update-stress-last",
                   .two_phase = true, .parameters = kPicParameters, OTMPM_STEPS(step_musl)},
    IntegratorKind{.name = "npc",
                   .description = "explicit Newmark predictor-corrector (molinos et al. Algorithm 1)",
                   .needs_acceleration = true,
                   .parameters = kNpcParameters,
                   OTMPM_STEPS(step_npc)},
    IntegratorKind{.name = "otm",
                   .description = "optimal transportation meshfree update (wobbes et al. Algorithm 2)",
                   .needs_ul = true,
                   .consistent_by_default = true,
                   .needs_previous_position = true,
                   OTMPM_STEPS(step_otm)},
    IntegratorKind{.name = "unified",
                   .description = "B-splines on advected knots (wobbes et al. Algorithm 3)",
                   .needs_ul = true,
                   .needs_bspline = true,
                   .consistent_by_default = true,
                   .needs_consistent_mass = true,
                   OTMPM_STEPS(step_unified)},
    IntegratorKind{.name = "central_difference",
                   .description = "central difference in velocity-Verlet form (kick, drift, kick)",
                   .parameters = kPicParameters,
                   OTMPM_STEPS(step_central_difference)},
    IntegratorKind{.name = "explicit_alpha",
                   .description = "explicit generalised-alpha (Hulbert & Chung 1996)",
                   .needs_acceleration = true,
                   .carries_constraints = true,
                   .parameters = kAlphaParameters,
                   OTMPM_STEPS(step_explicit_alpha)},
};
#undef OTMPM_STEPS

} // namespace

std::span<const IntegratorKind> integrator_kinds() { return kIntegrators; }

const IntegratorKind* find_integrator(std::string_view name) {
  const auto it =
      std::find_if(kIntegrators.begin(), kIntegrators.end(), [&](const IntegratorKind& k) { return k.name == name; });
  return it == kIntegrators.end() ? nullptr : &*it;
}

std::span<const ParameterSpec* const> integrator_parameters() { return kAllParameters; }

StepNeeds IntegratorKind::needs() const {
  return {.acceleration = needs_acceleration,
          .previous_position = needs_previous_position,
          .advected_nodes = needs_ul,
          .bspline = needs_bspline,
          .consistent_mass = needs_consistent_mass,
          .carries_constraints = carries_constraints,
          .parameters = parameters};
}

IntegratorParameters IntegratorKind::default_parameters() const {
  IntegratorParameters out;
  for (const ParameterSpec& p : parameters) out.values[std::string(p.key)] = p.fallback.value_or(0.0);
  return out;
}

bool IntegratorKind::takes(std::string_view key) const {
  return std::any_of(parameters.begin(), parameters.end(), [&](const ParameterSpec& p) { return p.key == key; });
}

std::string integrator_list(std::string_view parameter) {
  std::vector<std::string_view> names;
  for (const IntegratorKind& k : kIntegrators)
    if (parameter.empty() || k.takes(parameter)) names.push_back(k.name);
  std::string s;
  for (std::size_t i = 0; i < names.size(); ++i)
    s += std::string(i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + std::string(names[i]);
  return s;
}

const IntegratorKind& integrator_kind(std::string_view name) {
  const IntegratorKind* k = find_integrator(name);
  if (!k) throw InputError("unknown integrator '" + std::string(name) + "' (expected " + integrator_list() + ")");
  return *k;
}

} // namespace otmpm
