#pragma once
/// \file pore_fluid.hpp
/// The pore fluid of a saturated material (docs/theory.md sect. 15): a
/// material whose table gives the five keys below is a mixture of its solid
/// grains (`density` is the grains' density) and the liquid that fills its
/// pores. Any solid model (elastic, j2, drucker_prager, ...) gives the
/// effective stress of the skeleton; the engine adds the liquid phase
/// (engine/two_phase.hpp).
#include "otmpm/parameters.hpp"

#include <array>
#include <optional>
#include <span>
#include <string_view>

namespace otmpm {

struct MaterialParameters;

namespace pore_fluid_keys {
inline constexpr ParameterSpec kPorosity{"porosity", "initial porosity n_0 (pore volume / total volume)",
                                         std::nullopt, 0.0, true, 1.0, true};
inline constexpr ParameterSpec kPermeability{"permeability", "intrinsic permeability kappa [m^2]", std::nullopt, 0.0,
                                             true};
inline constexpr ParameterSpec kFluidDensity{"fluid_density", "density of the pore liquid rho_w [kg/m^3]",
                                             std::nullopt, 0.0, true};
inline constexpr ParameterSpec kFluidBulkModulus{"fluid_bulk_modulus", "bulk modulus of the pore liquid K_w [Pa]",
                                                 std::nullopt, 0.0, true};
inline constexpr ParameterSpec kFluidViscosity{"fluid_viscosity", "dynamic viscosity of the pore liquid mu_w [Pa s]",
                                               std::nullopt, 0.0, true};
} // namespace pore_fluid_keys

/// The names of the liquid's particle state arrays (Particles::state) and
/// output fields: the pore pressure p_p [Pa] (one value, compression
/// positive) and the liquid velocity w_p [m/s] (D values).
inline constexpr std::string_view kPorePressureField = "pore_pressure";
inline constexpr std::string_view kLiquidVelocityField = "liquid_velocity";
/// The out-of-plane stress sigma_zz a plane-strain particle starts with (a
/// geostatic start, docs/theory.md eq. 15.12: k0 times the vertical
/// effective stress), added to the material's sigma_zz of its strain.
inline constexpr std::string_view kInitialOutOfPlaneStressField = "initial_stress_zz";

/// The keys of a saturated material, every one required once any is given.
std::span<const ParameterSpec> pore_fluid_parameters();

/// The pore fluid of a saturated material: initial porosity n_0,
/// intrinsic permeability kappa, the liquid's density rho_w, bulk modulus K_w
/// and viscosity mu_w. The grains are incompressible.
struct PoreFluid {
  double porosity = 0.0;
  double permeability = 0.0;
  double density = 0.0;
  double bulk_modulus = 0.0;
  double viscosity = 0.0;
  /// The Darcy drag coefficient per unit mixture volume at porosity n:
  /// n^2 mu_w / kappa (the force on the liquid is -that x (v_w - v_s)).
  double drag(double n) const { return n * n * viscosity / permeability; }
};

/// The pore fluid of `p`, or nullopt for a dry material (none of the keys).
/// InputError naming the material and the missing key when only some are given,
/// or the key and its range when a value is out of range.
std::optional<PoreFluid> pore_fluid(const MaterialParameters& p);

} // namespace otmpm
