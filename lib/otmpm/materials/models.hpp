#pragma once
/// \file models.hpp
/// The descriptors of the material models, one function per model (each
/// defined in the model's own file) and the table of materials/models.cpp
/// that lists them. Internal to materials/: users go through material.hpp.
#include "otmpm/materials/material.hpp"

namespace otmpm {

const MaterialModel& linear_elastic_model();
const MaterialModel& linear_elastic_finite_model();
const MaterialModel& neo_hookean_model();
const MaterialModel& j2_model();
const MaterialModel& drucker_prager_model();
const MaterialModel& mu_i_model();

} // namespace otmpm
