/// \file elasticity.cpp
/// The elastic stress laws of elasticity.hpp and the checks of the constants.
#include "otmpm/materials/elasticity.hpp"

#include <algorithm>
#include <cmath>

namespace otmpm {

void ElasticConstants::validate(const std::string& name) const {
  for (const auto& [spec, value] : {std::pair{&kDensity, density}, {&kYoung, young}, {&kPoisson, poisson}}) {
    const std::string why = spec->check(value);
    require(why.empty(), "material '", name, "': ", spec->key, " ", why);
  }
}

namespace {
/// det F, checked finite and > 0 (the finite-strain laws divide by it and take its log).
template <int D> double checked_det(const Mat<D>& F, const char* law) {
  const double J = F.determinant();
  require<InstabilityError>(std::isfinite(J) && J > 0.0, law, ": det F = ", J, " is not finite and > 0");
  return J;
}
/// Lame parameters of a finite-strain law; 1D: uniaxial modulus lambda + 2 mu -> E.
double lame_lambda(const ElasticConstants& c, int D) { return D == 1 ? 0.0 : c.lambda(); }
double lame_mu(const ElasticConstants& c, int D) { return D == 1 ? 0.5 * c.young : c.mu(); }
} // namespace

template <int D> Mat<D> linear_elastic_finite_stress(const ElasticConstants& c, const Mat<D>& F) {
  const double J = checked_det<D>(F, "linear_elastic_finite");
  const Mat<D> Es = 0.5 * (F + F.transpose()) - Mat<D>::Identity();
  return (lame_lambda(c, D) / J) * Es.trace() * F + (2.0 * lame_mu(c, D) / J) * F * Es;
}

template <int D> Mat<D> neo_hookean_stress(const ElasticConstants& c, const Mat<D>& F) {
  const double J = checked_det<D>(F, "neo_hookean");
  const Mat<D> I = Mat<D>::Identity();
  return (lame_lambda(c, D) * std::log(J) / J) * I + (lame_mu(c, D) / J) * (F * F.transpose() - I);
}

namespace {
/// The largest row sum of |F F^T|: an upper bound of its largest eigenvalue,
/// exact for a diagonal F F^T.
template <int D> double largest_stretch2(const Mat<D>& F) {
  const Mat<D> b = F * F.transpose();
  return b.cwiseAbs().rowwise().sum().maxCoeff();
}
} // namespace

template <int D> double linear_elastic_finite_wave_modulus(const ElasticConstants& c, const Mat<D>& F) {
  return (lame_lambda(c, D) + 2.0 * lame_mu(c, D)) * largest_stretch2<D>(F);
}

template <int D> double neo_hookean_wave_modulus(const ElasticConstants& c, const Mat<D>& F) {
  const double J = checked_det<D>(F, "neo_hookean");
  return std::max(0.0, lame_lambda(c, D) * (1.0 - std::log(J)) + lame_mu(c, D) * (largest_stretch2<D>(F) + 1.0));
}

template <int D> double neo_hookean_energy(const ElasticConstants& c, const Mat<D>& F) {
  checked_det<D>(F, "neo_hookean");
  // In H = F - I, without the cancellations of tr(F F^T) - D and ln J near
  // F = I: J - 1 = j = tr H + I2(H) + I3(H), tr(F F^T) - D - 2 ln J = |H|^2
  // - 2 (I2 + I3) + 2 (j - ln(1 + j)).
  const Mat<D> H = F - Mat<D>::Identity();
  const double tr = H.trace();
  const double i2 = D >= 2 ? 0.5 * (tr * tr - (H * H).trace()) : 0.0;
  const double i3 = D == 3 ? H.determinant() : 0.0;
  const double j = tr + i2 + i3, lnJ = std::log1p(j);
  // j - ln(1 + j) = j^2 (1/2 - j/3 + j^2/4 - ...): the series to j^9 below |j| = 0.01.
  double rest = j - lnJ;
  if (std::abs(j) < 1e-2) {
    rest = 0.0;
    for (int k = 9; k >= 2; --k) rest = 1.0 / k - j * rest;
    rest *= j * j;
  }
  return 0.5 * lame_lambda(c, D) * lnJ * lnJ + 0.5 * lame_mu(c, D) * (H.squaredNorm() - 2.0 * (i2 + i3) + 2.0 * rest);
}

double linear_elastic_finite_out_of_plane(const ElasticConstants& c, const Mat<2>& F) {
  const double J = checked_det<2>(F, "linear_elastic_finite");
  return (c.lambda() / J) * ((F(0, 0) - 1.0) + (F(1, 1) - 1.0));
}

double neo_hookean_out_of_plane(const ElasticConstants& c, const Mat<2>& F) {
  const double J = checked_det<2>(F, "neo_hookean");
  return c.lambda() * std::log(J) / J;
}

#define OTMPM_INSTANTIATE(D)                                                                 \
  template Mat<D> linear_elastic_finite_stress<D>(const ElasticConstants&, const Mat<D>&);  \
  template Mat<D> neo_hookean_stress<D>(const ElasticConstants&, const Mat<D>&);                  \
  template double linear_elastic_finite_wave_modulus<D>(const ElasticConstants&, const Mat<D>&);  \
  template double neo_hookean_wave_modulus<D>(const ElasticConstants&, const Mat<D>&);             \
  template double neo_hookean_energy<D>(const ElasticConstants&, const Mat<D>&);
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm
