/// \file pore_fluid.cpp
/// The keys of a saturated material and its pore fluid (pore_fluid.hpp).
#include "otmpm/materials/pore_fluid.hpp"

#include "otmpm/materials/material.hpp"

namespace otmpm {

namespace {

using namespace pore_fluid_keys;
const std::array kKeys{kPorosity, kPermeability, kFluidDensity, kFluidBulkModulus, kFluidViscosity};

} // namespace

std::span<const ParameterSpec> pore_fluid_parameters() { return kKeys; }

std::optional<PoreFluid> pore_fluid(const MaterialParameters& p) {
  int given = 0;
  for (const ParameterSpec& s : kKeys) given += p.has(std::string(s.key));
  if (given == 0) return std::nullopt;
  double values[kKeys.size()];
  for (std::size_t i = 0; i < kKeys.size(); ++i) {
    const std::string key(kKeys[i].key);
    require(p.has(key), "material '", p.name, "': a saturated material (one that gives porosity, permeability, "
            "fluid_density, fluid_bulk_modulus or fluid_viscosity) needs all five; ", key, " is missing");
    values[i] = p.get(key, 0.0);
    const std::string why = kKeys[i].check(values[i]);
    require(why.empty(), "material '", p.name, "': ", key, " ", why);
  }
  return PoreFluid{values[0], values[1], values[2], values[3], values[4]};
}

} // namespace otmpm
