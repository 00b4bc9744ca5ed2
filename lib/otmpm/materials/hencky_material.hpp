#pragma once
/// \file hencky_material.hpp
/// The Material<D> face of the finite-strain elastoplastic models
/// (hencky_plasticity.hpp; docs/theory.md sect. 9): the per-particle state
/// b_e (6 values: xx, yy, zz, xy, yz, xz), the equivalent and volumetric
/// plastic strains, the stored elastic energy and the accumulated plastic
/// work of each particle (J), and the particle update around a model's point
/// update. Internal to materials/: a model (j2.cpp, drucker_prager.cpp)
/// supplies `Model::update(dF, dt, state)` and its parameters.
#include "otmpm/materials/hencky_plane_j2.hpp"
#include "otmpm/materials/hencky_solid_j2.hpp"
#include "otmpm/materials/material.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace otmpm {

/// The internal variables every Hencky model keeps (StateSpec rows).
inline constexpr std::array<StateSpec, 5> kHenckyState{{
    {"elastic_left_cauchy_green", 6, {1, 1, 1, 0, 0, 0}, "b_e = F_e F_e^T (xx, yy, zz, xy, yz, xz)"},
    {"plastic_strain", 1, {}, "equivalent plastic strain eps_p", 0.0},
    {"volumetric_plastic_strain", 1, {}, "volumetric plastic strain eps_v (dilation > 0)"},
    {"elastic_energy", 1, {}, "stored elastic energy V0 psi(b_e) [J]", 0.0},
    {"plastic_work", 1, {}, "energy dissipated by plastic flow since t = 0 [J]", 0.0},
}};

/// What a model with values of its own per particle (Model::kExtraState,
/// width 1 each) gets besides dF, dt and the Hencky state: det F before and
/// after the step and those values, read before and written after it.
template <std::size_t N> struct ModelPoint {
  double J_n = 1.0, J = 1.0;
  std::array<double, N> values{};
};

/// The state rows of a model: kHenckyState, then Model::kExtraState if it
/// has one.
template <class Model> inline constexpr auto kModelState = [] {
  if constexpr (requires { Model::kExtraState; }) {
    std::array<StateSpec, kHenckyState.size() + Model::kExtraState.size()> all{};
    std::copy(kHenckyState.begin(), kHenckyState.end(), all.begin());
    std::copy(Model::kExtraState.begin(), Model::kExtraState.end(), all.begin() + kHenckyState.size());
    return all;
  } else {
    return kHenckyState;
  }
}();

/// A Hencky elastoplastic material: Model has
///   plasticity::PointUpdate update(const Mat<D>& dF, double dt, plasticity::HenckyState&) const
/// and `elastic()` (the moduli, for the wave speed); a model with values of
/// its own (Model::kExtraState) has instead
///   plasticity::PointUpdate update(const Mat<D>& dF, double dt, plasticity::HenckyState&, ModelPoint<N>&) const.
template <int D, class Model> class HenckyMaterial final : public Material<D> {
  static constexpr auto& kState = kModelState<Model>;
  static constexpr std::size_t kExtra = kState.size() - kHenckyState.size();

public:
  HenckyMaterial(const MaterialParameters& p, Model model) : Material<D>(p), model_(std::move(model)) {}

  /// Uniaxial strain in 1D (K + 4G/3), lambda + 2 mu otherwise: K + 4G/3 in every dimension.
  double p_modulus() const override {
    const plasticity::ElasticModuli& m = model_.elastic();
    return m.bulk + 4.0 / 3.0 * m.shear;
  }
  /// c_p^2 = M / rho0_p, rho0_p = m_p / V0_p: the law is written in the
  /// Kirchhoff stress tau = J sigma with the constant tangent M = K + 4G/3
  /// in the elastic log strain, so the Cauchy tangent is M / J and c_p^2 =
  /// (M / J) / (rho0_p / J) whatever the volume change (plastic dilation
  /// included; docs/theory-plasticity.md, "Wave speed"). Exact at zero
  /// elastic strain; the elastic strains of these models are small.
  void max_wave_speed2(const Particles<D>& P, int p0, int p1, double& c2) const override {
    double largest = 0.0; // the largest 1 / rho0_p
    for (int p = p0; p < p1; ++p) largest = std::max(largest, P.V0[p] / P.m[p]);
    c2 = std::max(c2, p_modulus() * largest);
  }
  bool needs_deformation_gradient() const override { return true; }
  std::span<const StateSpec> state() const override { return kState; }

  void bind(Particles<D>& P) override {
    for (std::size_t i = 0; i < kState.size(); ++i) {
      const StateField* f = P.find_state(kState[i].name);
      require<std::invalid_argument>(f != nullptr, "material '", this->name(), "': the particles have no state '",
                                     std::string(kState[i].name), "'");
      field_[i] = static_cast<int>(f - P.state.data());
    }
  }

  /// b_e = exp(2 e) with tau(e) = sigma0 at J = 1 (Hencky's law inverted),
  /// the stored energy V0_p psi(b_e); no plastic strain.
  void start_from_stress(Particles<D>& P, int p, const Mat<3>& sigma0) const override {
    const plasticity::Mat3 be = plasticity::hencky_left_cauchy_green(model_.elastic(), sigma0);
    double* b = P.find_state(kHenckyState[0].name)->row(p);
    b[0] = be(0, 0), b[1] = be(1, 1), b[2] = be(2, 2), b[3] = be(0, 1), b[4] = be(1, 2), b[5] = be(0, 2);
    P.find_state(kHenckyState[3].name)->row(p)[0] = P.V0[p] * plasticity::hencky_energy(model_.elastic(), be);
  }

  /// The point update of each particle inlined (Model::update), sigma =
  /// tau / J with one division, the state read and written through the
  /// arrays' base pointers. In plane strain and in 3D a model with `lanes()`
  /// (J2) updates two particles at a time where its plane or 3D form covers
  /// both.
  void update(Particles<D>& P, int p0, int p1, const Mat<D>* H, double dt) const override {
    // A local copy: the stores of the loop cannot alias its parameters, so
    // they stay in registers and the derived constants are hoisted.
    const Model model = model_;
    const Rows r = rows(P);
    int p = p0;
    if constexpr (D >= 2 && requires { model.lanes(); })
      if (model.lanes()) {
#ifdef OTMPM_WIDE_LANES
        if constexpr (D == 3)
          if (p1 - p >= 4 && plasticity::point::wide_lanes())
            p = update_solid_quads(P, r, model, p, p1, H + (p - p0), dt);
#endif
        for (; p + 1 < p1; p += 2) {
          if constexpr (D == 2) update_pair(P, r, model, p, H + (p - p0), dt);
          else update_solid_pair(P, r, model, p, H + (p - p0), dt);
        }
      }
    for (; p < p1; ++p) update_one(P, r, model, p, H[p - p0], dt);
  }

  void add_energies(const Particles<D>& P, int p0, int p1, double& stored, double& dissipated) const override {
    const double* e = row(P, 3, 0);
    const double* w = row(P, 4, 0);
    for (int p = p0; p < p1; ++p) {
      stored += e[p];
      dissipated += w[p];
    }
  }

  /// Plane strain: sigma_zz = tau_zz / J with the Hencky law on the stored
  /// b_e (block form, b_xz = b_yz = 0): e_m = 1/4 ln det B of the in-plane
  /// block B, e_z = 1/2 ln b_zz, tau_zz = K (2 e_m + e_z) - 4/3 G (e_m - e_z)
  /// (update2's tau_zz with beta = 1: after a return b_e is the returned
  /// state), J = det F_p.
  void out_of_plane_stress(const Particles<D>& P, int p0, int p1, double* out) const override {
    if constexpr (D != 2) {
      Material<D>::out_of_plane_stress(P, p0, p1, out);
    } else {
      const double K = model_.elastic().bulk, G = model_.elastic().shear;
      const double* be = row(P, 0, 0);
      for (int p = p0; p < p1; ++p) {
        const double* b = be + 6 * static_cast<std::ptrdiff_t>(p);
        const double em = 0.25 * std::log(b[0] * b[1] - b[3] * b[3]), ez = 0.5 * std::log(b[2]);
        const double tau_zz = K * (2.0 * em + ez) - (4.0 / 3.0) * G * (em - ez);
        out[p - p0] = tau_zz / P.F[p].determinant();
      }
    }
  }

private:
  /// Base pointers of the state rows (extra: the model's own, kExtraState).
  struct Rows {
    double *be, *eps_p, *eps_v, *energy, *work;
    std::array<double*, kExtra> extra;
  };
  Rows rows(Particles<D>& P) const {
    Rows r{row(P, 0, 0), row(P, 1, 0), row(P, 2, 0), row(P, 3, 0), row(P, 4, 0), {}};
    for (std::size_t i = 0; i < kExtra; ++i) r.extra[i] = row(P, static_cast<int>(kHenckyState.size() + i), 0);
    return r;
  }

  /// F = dF F_n and J = det F of particle p; ParticleFailure when J <= 0.
  /// In 3D by mul3 and det3, as the lanes (update_solid_lanes).
  static Mat<D> advanced_F(const Particles<D>& P, int p, const Mat<D>& dF, double& J) {
    Mat<D> F;
    if constexpr (D == 3) {
      F = plasticity::point::mul3(dF, P.F[p], J);
    } else {
      F = dF * P.F[p];
      J = F.determinant();
    }
    if (!(J > 0.0)) [[unlikely]]
      fail_det(p, J);
    return F;
  }

  /// The kinematic fields and the stress of particle p after its step.
  static void commit(Particles<D>& P, const Rows& r, int p, const Mat<D>& F, double J, const Mat<D>& tau, double energy,
                     double work) {
    P.F[p] = F;
    P.V[p] = J * P.V0[p];
    P.rho[p] = P.m[p] / P.V[p];
    P.sigma[p] = tau * (1.0 / J);
    P.eps[p] = 0.5 * (F + F.transpose()) - Mat<D>::Identity();
    r.energy[p] = P.V0[p] * energy;
    r.work[p] += P.V0[p] * work;
  }

  /// One particle through Model::update.
  static void update_one(Particles<D>& P, const Rows& r, const Model& model, int p, const Mat<D>& Hp, double dt) {
    const Mat<D> dF = Mat<D>::Identity() + Hp;
    double J;
    const Mat<D> F = advanced_F(P, p, dF, J);
    plasticity::HenckyState s;
    double* const b = r.be + 6 * static_cast<std::ptrdiff_t>(p);
    s.be << b[0], b[3], b[5], b[3], b[1], b[4], b[5], b[4], b[2];
    s.eps_p = r.eps_p[p];
    s.eps_v = r.eps_v[p];
    plasticity::PointUpdate u;
    try {
      if constexpr (kExtra > 0) {
        ModelPoint<kExtra> point{P.F[p].determinant(), J, {}};
        for (std::size_t i = 0; i < kExtra; ++i) point.values[i] = r.extra[i][p];
        u = model.update(dF, dt, s, point);
        for (std::size_t i = 0; i < kExtra; ++i) r.extra[i][p] = point.values[i];
      } else {
        u = model.update(dF, dt, s);
      }
    } catch (const InstabilityError& e) {
      throw ParticleFailure{p, e.what()};
    }
    b[0] = s.be(0, 0), b[1] = s.be(1, 1), b[2] = s.be(2, 2);
    b[3] = s.be(0, 1), b[4] = s.be(1, 2), b[5] = s.be(0, 2);
    r.eps_p[p] = s.eps_p;
    r.eps_v[p] = s.eps_v;
    commit(P, r, p, F, J, u.kirchhoff.template topLeftCorner<D, D>(), u.elastic_energy, u.plastic_work);
  }

  /// Particles p and p + 1 (plane strain) in the two lanes of Model::plane,
  /// the kinematics and the stress of update_one lane by lane with the same
  /// operations (Eigen's 2x2 product, determinant and sums); both by
  /// update_one where the plane form does not cover both or a J <= 0.
  static void update_pair(Particles<D>& P, const Rows& r, const Model& model, int p, const Mat<D>* Hp, double dt)
    requires(D == 2)
  {
    using L = plasticity::point::Lanes2;
    const auto lanes = [](double a, double b) { return L{a, b}; };
    const double* b0 = r.be + 6 * static_cast<std::ptrdiff_t>(p);
    const double* b1 = b0 + 6;
    const Mat<2>&H0 = Hp[0], &H1 = Hp[1];
    plasticity::point::PlaneJ2<L> x{};
    x.f00 = 1.0 + lanes(H0(0, 0), H1(0, 0)), x.f01 = 0.0 + lanes(H0(0, 1), H1(0, 1));
    x.f10 = 0.0 + lanes(H0(1, 0), H1(1, 0)), x.f11 = 1.0 + lanes(H0(1, 1), H1(1, 1));
    x.b00 = lanes(b0[0], b1[0]), x.b01 = lanes(b0[3], b1[3]), x.b11 = lanes(b0[1], b1[1]), x.bzz = lanes(b0[2], b1[2]);
    x.eps_p = lanes(r.eps_p[p], r.eps_p[p + 1]);
    const auto covered = model.plane(x);
    // F = dF F_n and J = det F (Eigen: F00 F11 - F10 F01).
    const Mat<2>&Fa = P.F[p], &Fb = P.F[p + 1];
    const L n00 = lanes(Fa(0, 0), Fb(0, 0)), n01 = lanes(Fa(0, 1), Fb(0, 1));
    const L n10 = lanes(Fa(1, 0), Fb(1, 0)), n11 = lanes(Fa(1, 1), Fb(1, 1));
    const L F00 = x.f00 * n00 + x.f01 * n10, F01 = x.f00 * n01 + x.f01 * n11;
    const L F10 = x.f10 * n00 + x.f11 * n10, F11 = x.f10 * n01 + x.f11 * n11;
    const L J = F00 * F11 - F10 * F01;
    if (!(covered[0] && covered[1] && J[0] > 0.0 && J[1] > 0.0)) {
      update_one(P, r, model, p, Hp[0], dt);
      update_one(P, r, model, p + 1, Hp[1], dt);
      return;
    }
    const L V = J * lanes(P.V0[p], P.V0[p + 1]), rho = lanes(P.m[p], P.m[p + 1]) / V, inv_J = 1.0 / J;
    const L s00 = x.tau00 * inv_J, s01 = x.tau01 * inv_J, s11 = x.tau11 * inv_J;
    const L e00 = 0.5 * (F00 + F00) - 1.0, e01 = 0.5 * (F01 + F10), e11 = 0.5 * (F11 + F11) - 1.0;
    const L energy = lanes(P.V0[p], P.V0[p + 1]) * x.energy, work = lanes(P.V0[p], P.V0[p + 1]) * x.work;
    for (int l = 0; l < 2; ++l) {
      const int q = p + l;
      P.F[q] << F00[l], F01[l], F10[l], F11[l];
      P.V[q] = V[l];
      P.rho[q] = rho[l];
      P.sigma[q] << s00[l], s01[l], s01[l], s11[l];
      P.eps[q] << e00[l], e01[l], e01[l], e11[l];
      double* const b = r.be + 6 * static_cast<std::ptrdiff_t>(q);
      b[0] = x.be00[l], b[1] = x.be11[l], b[2] = x.bezz[l], b[3] = x.be01[l];
      r.eps_p[q] = x.eps_p_new[l];
      r.energy[q] = energy[l];
      r.work[q] += work[l];
    }
  }

  /// Particles p and p + 1 (3D) in the two lanes of Model::solid
  /// (solid_lanes).
  static void update_solid_pair(Particles<D>& P, const Rows& r, const Model& model, int p, const Mat<D>* Hp, double dt)
    requires(D == 3)
  {
    update_solid_lanes<plasticity::point::Lanes2, 2>(P, r, model, p, Hp, dt);
  }

#ifdef OTMPM_WIDE_LANES
  /// Particles p, p + 4, ... below p1 four at a time (AVX2, solid_lanes);
  /// Hp[i] is particle p + i's increment. Returns the first particle not
  /// updated.
  [[gnu::target("avx2"), gnu::noinline]] static int update_solid_quads(Particles<D>& P, const Rows& r,
                                                                     const Model& model, int p, int p1,
                                                                     const Mat<D>* Hp, double dt)
    requires(D == 3)
  {
    int q = p;
    for (; q + 3 < p1; q += 4) update_solid_lanes<plasticity::point::Lanes4, 4>(P, r, model, q, Hp + (q - p), dt);
    return q;
  }
#endif

  /// Particles p .. p + W - 1 (3D) in the W lanes of Model::solid, the
  /// stress and the state of update_one lane by lane with the same
  /// operations (F = dF F_n and det F by mul3 and det3, as advanced_F).
  /// All by update_one where the 3D form does not cover every lane or a
  /// J <= 0.
  template <class L, int W>
  [[gnu::always_inline]] static inline void update_solid_lanes(Particles<D>& P, const Rows& r, const Model& model,
                                                               int p, const Mat<D>* Hp, double dt)
    requires(D == 3)
  {
    Mat<3> dF[W];
    for (int l = 0; l < W; ++l) dF[l] = Mat<3>::Identity() + Hp[l];
    const double* b0 = r.be + 6 * static_cast<std::ptrdiff_t>(p);
    plasticity::point::SolidJ2<L> x;
    L V0, m;
    for (int l = 0; l < W; ++l) {
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) x.f[i][j][l] = dF[l](i, j);
      for (int k = 0; k < 6; ++k) x.b[k][l] = b0[6 * l + k];
      x.eps_p[l] = r.eps_p[p + l];
      V0[l] = P.V0[p + l];
      m[l] = P.m[p + l];
    }
    const auto covered = model.solid(x);
    L Fn[3][3] = {}, Fv[3][3];
    for (int l = 0; l < W; ++l)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) Fn[i][j][l] = P.F[p + l](i, j);
    plasticity::point::mul3(x.f, Fn, Fv);
    const L J = plasticity::point::det3(Fv);
    bool all = true;
    for (int l = 0; l < W; ++l) all = all && covered[l] && J[l] > 0.0;
    if (!all) {
      for (int l = 0; l < W; ++l) update_one(P, r, model, p + l, Hp[l], dt);
      return;
    }
    const L V = J * V0, rho = m / V, inv_J = 1.0 / J;
    const L energy = V0 * x.energy, work = V0 * x.work;
    L s[6];
    for (int k = 0; k < 6; ++k) s[k] = x.tau[k] * inv_J;
    constexpr int kSym[3][3] = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}}; // (xx, yy, zz, xy, yz, xz)
    for (int l = 0; l < W; ++l) {
      const int q = p + l;
      Mat<3> Fq;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) Fq(i, j) = Fv[i][j][l];
      P.F[q] = Fq;
      P.eps[q] = 0.5 * (Fq + Fq.transpose()) - Mat<3>::Identity();
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) P.sigma[q](i, j) = s[kSym[i][j]][l];
      P.V[q] = V[l];
      P.rho[q] = rho[l];
      double* const b = r.be + 6 * static_cast<std::ptrdiff_t>(q);
      for (int k = 0; k < 6; ++k) b[k] = x.be[k][l];
      r.eps_p[q] = x.eps_p_new[l];
      r.energy[q] = energy[l];
      r.work[q] += work[l];
    }
  }

  double* row(Particles<D>& P, int i, int p) const { return P.state[static_cast<std::size_t>(field_[i])].row(p); }
  const double* row(const Particles<D>& P, int i, int p) const {
    return P.state[static_cast<std::size_t>(field_[i])].row(p);
  }
  [[noreturn, gnu::cold, gnu::noinline]] static void fail_det(int p, double J) {
    throw ParticleFailure{p, "det F = " + format_number(J) + " <= 0"};
  }

  Model model_;
  std::array<int, kState.size()> field_{};
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
