/// \file models.cpp
/// The table of material models and the construction of a material from
/// its parameters (material.hpp). A new model adds one line to kModels.
#include "otmpm/materials/models.hpp"
#include "otmpm/materials/pore_fluid.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace otmpm {

namespace {

const std::array<const MaterialModel*, 6> kModels{&linear_elastic_model(), &linear_elastic_finite_model(),
                                                  &neo_hookean_model(), &j2_model(), &drucker_prager_model(),
                                                  &mu_i_model()};

/// The sub-table of a parameter key "table.key" ("" for a top-level key).
std::string_view table_of(std::string_view key) {
  const auto dot = key.find('.');
  return dot == std::string_view::npos ? std::string_view() : key.substr(0, dot);
}

/// True when the scene gave some key of sub-table `table`.
bool gives_table(const MaterialParameters& p, std::string_view table) {
  return std::any_of(p.extra.begin(), p.extra.end(),
                     [&](const auto& kv) { return table_of(kv.first) == table; });
}

const MaterialModel& model_of(const MaterialParameters& p) {
  const MaterialModel* m = find_material_model(p.model);
  require(m != nullptr, "material '", p.name, "': unknown model '", p.model, "' (expected ", material_model_list(),
          ")");
  return *m;
}

} // namespace

double MaterialParameters::get(const std::string& key, double fallback) const {
  const auto it = extra.find(key);
  return it == extra.end() ? fallback : it->second;
}

std::span<const MaterialModel* const> material_models() { return kModels; }

const MaterialModel* find_material_model(std::string_view name) {
  const auto it = std::find_if(kModels.begin(), kModels.end(), [&](const MaterialModel* m) { return m->name == name; });
  return it == kModels.end() ? nullptr : *it;
}

std::string material_model_list() {
  std::string s;
  for (std::size_t i = 0; i < kModels.size(); ++i)
    s += std::string(i == 0 ? "" : i + 1 == kModels.size() ? " or " : ", ") + std::string(kModels[i]->name);
  return s;
}

void validate_material(const MaterialParameters& p) {
  p.elastic().validate(p.name);
  const MaterialModel& model = model_of(p);
  for (const auto& entry : p.extra) {
    const std::string& key = entry.first; // named, not a structured binding: lambdas capture it (clang)
    const double value = entry.second;
    const auto fluid = pore_fluid_parameters();
    if (std::any_of(fluid.begin(), fluid.end(), [&](const ParameterSpec& s) { return s.key == key; }))
      continue; // a saturated material's key, whatever the model (pore_fluid below)
    const auto spec = std::find_if(model.parameters.begin(), model.parameters.end(),
                                   [&](const ParameterSpec& s) { return s.key == key; });
    require(spec != model.parameters.end(), "material '", p.name, "': model '", p.model, "' has no parameter '", key,
            "'");
    const std::string why = spec->check(value);
    require(why.empty(), "material '", p.name, "': ", key, " ", why);
  }
  for (const ParameterSpec& s : model.parameters) {
    const std::string_view table = table_of(s.key);
    const bool expected = !s.fallback && (table.empty() || gives_table(p, table));
    require(!expected || p.has(std::string(s.key)), "material '", p.name, "': model '", p.model, "' needs ",
            std::string(s.key));
  }
  (void)pore_fluid(p);  // all five keys of a saturated material, or none
  (void)model.make3(p); // the model's own checks across its parameters
}

template <int D> std::unique_ptr<Material<D>> make_material(const MaterialParameters& p) {
  validate_material(p);
  const MaterialModel& m = model_of(p);
  if constexpr (D == 1) return m.make1(p);
  else if constexpr (D == 2) return m.make2(p);
  else return m.make3(p);
}

template std::unique_ptr<Material<1>> make_material<1>(const MaterialParameters&);
template std::unique_ptr<Material<2>> make_material<2>(const MaterialParameters&);
template std::unique_ptr<Material<3>> make_material<3>(const MaterialParameters&);

} // namespace otmpm
