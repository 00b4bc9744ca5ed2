/// \file mu_i.cpp
/// `model = "mu_i"`: dense granular flow with the mu(I) rheology (Jop,
/// Forterre & Pouliquen 2006), elastic in the dense state and stress-free
/// below its critical packing (Dunatunga & Kamrin 2015), finite strain on
/// the Hencky framework of hencky_material.hpp (docs/theory-plasticity.md,
/// "mu(I) granular flow"). The return is a closed form: the root of a
/// quadratic in the plastic shear strain of the step.
#include "otmpm/materials/hencky_material.hpp"
#include "otmpm/materials/hencky_point.hpp"
#include "otmpm/materials/models.hpp"

#include <limits>

namespace otmpm {

namespace {

const std::array<ParameterSpec, 6> kParameters{{
    {"mu_s", "static friction coefficient mu_s (sqrt(J2) = mu_s p at the onset of flow)", std::nullopt, 0.0, true},
    {"mu_2", "limiting friction coefficient mu_2 at large I, >= mu_s", std::nullopt, 0.0, true},
    {"I_0", "inertial number I_0 at which mu = (mu_s + mu_2) / 2", std::nullopt, 0.0, true},
    {"grain_diameter", "grain diameter d [m]", std::nullopt, 0.0, true},
    {"grain_density", "grain density rho_s [kg/m3], at least the bulk density", std::nullopt, 0.0, true},
    {"critical_packing",
     "packing fraction phi_c below which the grains lose contact, at most density / grain_density; 0: none (they "
     "lose contact only where the pressure vanishes)",
     0.0, 0.0, false, 1.0},
}};

/// x^(1/D).
template <int D> double root(double x) {
  if constexpr (D == 1) return x;
  else if constexpr (D == 2) return std::sqrt(x);
  else return std::cbrt(x);
}

/// The mu(I) point update: the Hencky kinematics of hencky_point.hpp around
/// mu_i_return, with the critical-packing rule on det F (ModelPoint J_n, J).
struct MuIModel {
  /// The flowing state of the last step, written per particle.
  static constexpr std::array<StateSpec, 2> kExtraState{{
      {"inertial_number", 1, {}, "inertial number I = gamma_dot_p d / sqrt(p / rho_s) of the last step (0: static or stress-free)"},
      {"friction", 1, {}, "mobilised friction sqrt(J2) / p of the last step, mu(I) in flow (0: stress-free)"},
  }};

  plasticity::ElasticModuli moduli;
  double mu_s = 0.0, mu_2 = 0.0, I_0 = 0.0, grain_diameter = 0.0, grain_density = 0.0;
  /// det F at the critical packing, phi0 / phi_c with phi0 = density /
  /// grain_density the packing the material is seeded with (infinite
  /// without a critical packing).
  double J_c = 1.0;

  const plasticity::ElasticModuli& elastic() const { return moduli; }

  /// One step. J > J_c (the packing phi0 / J below phi_c): stress-free.
  /// Else a particle that was stress-free (J_n > J_c) takes the step's
  /// increment scaled by (J_n / J_c)^(1/D), so that its elastic volume
  /// strain is ln(J / J_c), the compaction beyond the critical packing, not
  /// ln(J / J_n).
  template <int D>
  [[gnu::always_inline]] plasticity::PointUpdate update(const Mat<D>& dF, double dt, plasticity::HenckyState& s,
                                                        ModelPoint<2>& point) const {
    const bool loose = point.J > J_c;
    const Mat<D> dF_eff = point.J_n > J_c && !loose ? Mat<D>(dF * root<D>(point.J_n / J_c)) : dF;
    return plasticity::point::update<D>("mu_i_update", moduli, dF_eff, s, [&](double ev, double dev2) {
      return mu_i_return(ev, dev2, dt, loose, point, s);
    });
  }

  /// The return in invariants (p = K e_v, sqrt(J2) = sqrt(2) G |dev e|, P =
  /// -p the Kirchhoff pressure, S = sqrt(J2)): stress-free (loose, or P <= 0
  /// with a shear: e_v = 0, beta = 0), elastic (S <= mu_s P), or flow at the
  /// fixed P (isochoric): S - G x = mu(I) P with x the plastic shear strain of
  /// the step and I = (x / dt) d / sqrt(P_c / rho_s), P_c = P / J the Cauchy
  /// pressure (docs/theory-plasticity.md, eqs. 7.2-7.4).
  [[gnu::always_inline]] plasticity::point::Return mu_i_return(double ev, double dev2, double dt, bool loose,
                                                               ModelPoint<2>& point,
                                                               plasticity::HenckyState& s) const {
    const double K = moduli.bulk, G = moduli.shear;
    const double P = -K * ev, S = std::sqrt(2.0 * dev2) * G;
    double& I = point.values[0];
    double& mu = point.values[1];
    if (!loose && S <= mu_s * P) { // elastic (also the rest state S = P = 0)
      I = 0.0;
      mu = P > 0.0 ? S / P : 0.0;
      return {ev, 1.0, false, 0};
    }
    plasticity::point::Return r{ev, 1.0, true, 0};
    if (loose || !(P > 0.0)) { // stress-free: every strain of the step is plastic
      r.ev = 0.0;
      r.beta = 0.0;
      I = 0.0;
      mu = 0.0;
    } else {
      // The time over which a plastic shear strain x gives I = x / t_I.
      const double t_I = dt * std::sqrt(P / (point.J * grain_density)) / grain_diameter;
      const double x = plastic_shear(S, P, t_I);
      r.beta = 1.0 - G * x / S;
      I = x / t_I;
      mu = r.beta * S / P;
    }
    s.eps_v += ev - r.ev;
    s.eps_p += std::sqrt(2.0 / 3.0) * (1.0 - r.beta) * std::sqrt(dev2);
    return r;
  }

  /// The root x in (0, (S - mu_s P) / G) of S - G x = mu(I) P, I = x / t_I
  /// (t_I = dt sqrt(P_cauchy / rho_s) / d): with S0 = S - mu_s P, B =
  /// (mu_2 - mu_s) P, (S0 - G x)(I_0 t_I + x) = B x, i.e.
  ///   G x^2 + (G I_0 t_I + B - S0) x - S0 I_0 t_I = 0,
  /// one positive root (the product of the roots is negative), taken in the
  /// form without cancellation. mu_2 = mu_s: x = S0 / G (Drucker-Prager).
  double plastic_shear(double S, double P, double t_I) const {
    const double G = moduli.shear, S0 = S - mu_s * P, B = (mu_2 - mu_s) * P;
    if (B == 0.0) return S0 / G;
    const double c = S0 * I_0 * t_I, b = G * I_0 * t_I + B - S0;
    const double r = std::sqrt(b * b + 4.0 * G * c);
    return b >= 0.0 ? 2.0 * c / (b + r) : (r - b) / (2.0 * G);
  }
};

MuIModel mu_i_model(const MaterialParameters& m) {
  MuIModel model;
  model.moduli = hencky_moduli(m);
  model.mu_s = m.get("mu_s", 0.0);
  model.mu_2 = m.get("mu_2", 0.0);
  model.I_0 = m.get("I_0", 0.0);
  model.grain_diameter = m.get("grain_diameter", 0.0);
  model.grain_density = m.get("grain_density", 0.0);
  require(model.mu_2 >= model.mu_s, "material '", m.name, "': mu_2 = ", model.mu_2, " must be at least mu_s = ",
          model.mu_s);
  require(model.grain_density >= m.density, "material '", m.name, "': grain_density = ", model.grain_density,
          " must be at least the bulk density = ", m.density, " (a packing fraction density / grain_density <= 1)");
  const double phi0 = m.density / model.grain_density, phi_c = m.get("critical_packing", 0.0);
  require(phi_c <= phi0, "material '", m.name, "': critical_packing = ", phi_c,
          " must be at most the packing of the seeded material, density / grain_density = ", phi0);
  model.J_c = phi_c > 0.0 ? phi0 / phi_c : std::numeric_limits<double>::infinity();
  return model;
}

template <int D> std::unique_ptr<Material<D>> make_mu_i(const MaterialParameters& m) {
  return std::make_unique<HenckyMaterial<D, MuIModel>>(m, mu_i_model(m));
}

} // namespace

const MaterialModel& mu_i_model() {
  // The glass beads of examples/column_collapse_mu_i.toml.
  static const std::array<ParameterValue, 9> example{{{"density", 1590.0},
                                                      {"young", 10.0e6},
                                                      {"poisson", 0.3},
                                                      {"mu_s", 0.6},
                                                      {"mu_2", 0.86},
                                                      {"I_0", 0.279},
                                                      {"grain_diameter", 0.5e-3},
                                                      {"grain_density", 2650.0},
                                                      {"critical_packing", 0.6}}};
  static const MaterialModel m{"mu_i",
                               "dense granular flow, mu(I) rheology, stress-free below the critical packing, finite strain",
                               kParameters, kModelState<MuIModel>, make_mu_i<1>, make_mu_i<2>, make_mu_i<3>, example,
                               false, true};
  return m;
}

} // namespace otmpm
