/// \file material.cpp
/// The constitutive models of material.hpp and the checks of their parameters.
#include "otmpm/materials/material.hpp"

#include <cmath>

namespace otmpm {

Material::Model Material::parse_model(const std::string& name) {
  if (name == "linear_elastic") return Model::linear_elastic;
  if (name == "linear_elastic_finite") return Model::linear_elastic_finite;
  if (name == "neo_hookean") return Model::neo_hookean;
  throw InputError("unknown material model '" + name +
                   "' (expected linear_elastic, linear_elastic_finite or neo_hookean)");
}

void Material::validate() const {
  const std::string what = "material '" + name + "': ";
  require(finite_positive(density), what, "density must be finite and > 0, got ", density);
  require(finite_positive(young), what, "young must be finite and > 0, got ", young);
  require(std::isfinite(poisson) && poisson > -1.0 && poisson < 0.5, what, "poisson must be in (-1, 0.5), got ",
          poisson);
}

template <int D> Mat<D> elastic_stress_increment(const Material& mat, const Mat<D>& d_eps) {
  if constexpr (D == 1) {
    return mat.young * d_eps;
  } else {
    return mat.lambda() * d_eps.trace() * Mat<D>::Identity() + 2.0 * mat.mu() * d_eps;
  }
}

template <int D> Mat<D> cauchy_stress(const Material& mat, const Mat<D>& F) {
  const double J = F.determinant();
  require<InstabilityError>(std::isfinite(J) && J > 0.0, "cauchy_stress (material '", mat.name, "'): det F = ", J,
                            " is not finite and > 0");
  const Mat<D> I = Mat<D>::Identity();
  // 1D: uniaxial modulus lambda + 2 mu -> E (see header).
  const double lambda = D == 1 ? 0.0 : mat.lambda();
  const double mu = D == 1 ? 0.5 * mat.young : mat.mu();
  if (mat.model == Material::Model::linear_elastic_finite) {
    const Mat<D> Es = 0.5 * (F + F.transpose()) - I;
    return (lambda / J) * Es.trace() * F + (2.0 * mu / J) * F * Es;
  }
  return (lambda * std::log(J) / J) * I + (mu / J) * (F * F.transpose() - I);
}

template <int D> double strain_energy_density(const Mat<D>& sigma, const Mat<D>& eps) {
  return 0.5 * sigma.cwiseProduct(eps).sum();
}

#define OTMPM_INSTANTIATE(D)                                                             \
  template Mat<D> elastic_stress_increment<D>(const Material&, const Mat<D>&);          \
  template Mat<D> cauchy_stress<D>(const Material&, const Mat<D>&);                     \
  template double strain_energy_density<D>(const Mat<D>&, const Mat<D>&);
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm
