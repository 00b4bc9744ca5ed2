#pragma once
/// \file hencky_material.hpp
/// The Material<D> face of the finite-strain elastoplastic models
/// (hencky_plasticity.hpp; docs/theory.md sect. 9): the per-particle state
/// b_e (6 values: xx, yy, zz, xy, yz, xz), the equivalent and volumetric
/// plastic strains, the stored elastic energy and the accumulated plastic
/// work of each particle (J), and the particle update around a model's point
/// update. Internal to materials/: a model (j2.cpp, drucker_prager.cpp)
/// supplies `Model::update(dF, dt, state)` and its parameters.
#include "otmpm/materials/hencky_plasticity.hpp"
#include "otmpm/materials/material.hpp"

#include <array>

namespace otmpm {

/// The internal variables every Hencky model keeps (StateSpec rows).
inline constexpr std::array<StateSpec, 5> kHenckyState{{
    {"elastic_left_cauchy_green", 6, {1, 1, 1, 0, 0, 0}, "b_e = F_e F_e^T (xx, yy, zz, xy, yz, xz)"},
    {"plastic_strain", 1, {}, "equivalent plastic strain eps_p"},
    {"volumetric_plastic_strain", 1, {}, "volumetric plastic strain eps_v (dilation > 0)"},
    {"elastic_energy", 1, {}, "stored elastic energy V0 psi(b_e) [J]"},
    {"plastic_work", 1, {}, "energy dissipated by plastic flow since t = 0 [J]"},
}};

/// A Hencky elastoplastic material: Model has
///   plasticity::PointUpdate update(const Mat<D>& dF, double dt, plasticity::HenckyState&) const
/// and `elastic()` (the moduli, for the wave speed).
template <int D, class Model> class HenckyMaterial final : public Material<D> {
public:
  HenckyMaterial(const MaterialParameters& p, Model model) : Material<D>(p), model_(std::move(model)) {}

  /// Uniaxial strain in 1D (K + 4G/3), lambda + 2 mu otherwise: K + 4G/3 in every dimension.
  double p_modulus() const override {
    const plasticity::ElasticModuli& m = model_.elastic();
    return m.bulk + 4.0 / 3.0 * m.shear;
  }
  bool needs_deformation_gradient() const override { return true; }
  std::span<const StateSpec> state() const override { return kHenckyState; }

  void bind(Particles<D>& P) override {
    for (std::size_t i = 0; i < kHenckyState.size(); ++i) {
      const StateField* f = P.find_state(kHenckyState[i].name);
      require<std::invalid_argument>(f != nullptr, "material '", this->name(), "': the particles have no state '",
                                     std::string(kHenckyState[i].name), "'");
      field_[i] = static_cast<int>(f - P.state.data());
    }
  }

  void update(Particles<D>& P, int p0, int p1, const Mat<D>* H, double dt) const override {
    for (int p = p0; p < p1; ++p) {
      const Mat<D> dF = Mat<D>::Identity() + H[p - p0];
      const Mat<D> F = dF * P.F[p];
      const double J = F.determinant();
      if (!(J > 0.0)) throw ParticleFailure{p, "det F = " + format_number(J) + " <= 0"};
      plasticity::HenckyState s = load(P, p);
      plasticity::PointUpdate u;
      try {
        u = model_.update(dF, dt, s);
      } catch (const InstabilityError& e) {
        throw ParticleFailure{p, e.what()};
      }
      P.F[p] = F;
      P.V[p] = J * P.V0[p];
      P.rho[p] = P.m[p] / P.V[p];
      P.sigma[p] = u.kirchhoff.template topLeftCorner<D, D>() / J;
      P.eps[p] = 0.5 * (F + F.transpose()) - Mat<D>::Identity();
      store(P, p, s);
      row(P, 3, p)[0] = P.V0[p] * u.elastic_energy;
      row(P, 4, p)[0] += P.V0[p] * u.plastic_work;
    }
  }

  void add_energies(const Particles<D>& P, int p0, int p1, double& stored, double& dissipated) const override {
    const double* e = row(P, 3, 0);
    const double* w = row(P, 4, 0);
    for (int p = p0; p < p1; ++p) {
      stored += e[p];
      dissipated += w[p];
    }
  }

private:
  double* row(Particles<D>& P, int i, int p) const { return P.state[static_cast<std::size_t>(field_[i])].row(p); }
  const double* row(const Particles<D>& P, int i, int p) const {
    return P.state[static_cast<std::size_t>(field_[i])].row(p);
  }
  plasticity::HenckyState load(const Particles<D>& P, int p) const {
    const double* b = row(P, 0, p);
    plasticity::HenckyState s;
    s.be << b[0], b[3], b[5], b[3], b[1], b[4], b[5], b[4], b[2];
    s.eps_p = row(P, 1, p)[0];
    s.eps_v = row(P, 2, p)[0];
    return s;
  }
  void store(Particles<D>& P, int p, const plasticity::HenckyState& s) const {
    double* b = row(P, 0, p);
    b[0] = s.be(0, 0), b[1] = s.be(1, 1), b[2] = s.be(2, 2);
    b[3] = s.be(0, 1), b[4] = s.be(1, 2), b[5] = s.be(0, 2);
    row(P, 1, p)[0] = s.eps_p;
    row(P, 2, p)[0] = s.eps_v;
  }

  Model model_;
  std::array<int, kHenckyState.size()> field_{};
};

/// ElasticModuli of a material's young and poisson, with the InputError
/// naming the material.
inline plasticity::ElasticModuli hencky_moduli(const MaterialParameters& p) {
  try {
    return plasticity::ElasticModuli::from_young_poisson(p.young, p.poisson);
  } catch (const InputError& e) {
    throw InputError("material '" + p.name + "': " + e.what());
  }
}

} // namespace otmpm
