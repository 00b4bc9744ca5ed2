#pragma once
/// \file hencky_plane_j2.hpp
/// The plane-strain J2 step with linear hardening (update2 and j2_return of
/// hencky_point.hpp) written once for a number type T: T = double updates one
/// particle, T = Lanes2 two particles in one SSE2 register. Each lane does the
/// same IEEE operations in the same order as the scalar form (ISO C++, no
/// contraction), so a particle gets the same bits whichever way it is
/// updated, and results do not depend on how the particles fall into pairs
/// (thread chunks). Internal to materials/.
///
/// The form branches only on whether some lane yields: then the return is
/// evaluated for every lane and the state chosen per lane; the series of
/// hencky_point.hpp are used in the single tier that covers ordinary elastic
/// strains (|det b - 1|, |b_zz - 1| <= 1/32, x^2 < 1e-2, small exponentials
/// <= 1/64). A lane outside that range, or with a non-positive or
/// non-finite det dF, reports "not covered" and is updated by the general
/// scalar path (update2 with library functions and the error checks).
#include "otmpm/materials/hencky_point.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace otmpm::plasticity::point {

/// Two doubles (one SSE2 register; GCC/Clang vector extension).
using Lanes2 = double __attribute__((vector_size(16)));
/// Lane masks of Lanes2 comparisons: all ones or all zeros per lane.
using Mask2 = long long __attribute__((vector_size(16)));

/// The lane operations the J2 forms need (plane here, 3D in
/// hencky_solid_j2.hpp), for one particle (double) and for two (Lanes2).
template <class T> struct LaneOps;

template <> struct LaneOps<double> {
  using Mask = bool;
  static double splat(double x) { return x; }
  static double sqrt(double x) { return std::sqrt(x); }
  static double log(double x) { return std::log(x); }
  static double abs(double x) { return std::abs(x); }
  static double select(bool m, double a, double b) { return m ? a : b; }
  static double keep(bool m, double a) { return m ? a : 0.0; }
  static bool any(bool m) { return m; }
  template <class... M> static bool all(M... m) { return (m && ...); }
};

template <> struct LaneOps<Lanes2> {
  using Mask = Mask2;
  static Lanes2 splat(double x) { return Lanes2{x, x}; }
  static Lanes2 sqrt(Lanes2 x) {
#if defined(__SSE2__)
    return (Lanes2)_mm_sqrt_pd((__m128d)x);
#else
    return Lanes2{std::sqrt(x[0]), std::sqrt(x[1])};
#endif
  }
  /// The library's log lane by lane (the bits of the one-particle form).
  static Lanes2 log(Lanes2 x) { return Lanes2{std::log(x[0]), std::log(x[1])}; }
  static Lanes2 abs(Lanes2 x) { return (Lanes2)((Mask2)x & Mask2{~(1LL << 63), ~(1LL << 63)}); }
  static Lanes2 select(Mask2 m, Lanes2 a, Lanes2 b) { return (Lanes2)((m & (Mask2)a) | (~m & (Mask2)b)); }
  /// a where m, +0 elsewhere (one AND).
  static Lanes2 keep(Mask2 m, Lanes2 a) { return (Lanes2)(m & (Mask2)a); }
  static bool any(Mask2 m) { return (m[0] | m[1]) != 0; }
  template <class... M> static Mask2 all(M... m) { return ((Mask2)m & ...); }
};

/// Input and output of a plane-strain J2 step, one lane per particle.
template <class T> struct PlaneJ2 {
  T f00, f01, f10, f11; ///< in: the increment dF
  T b00, b01, b11, bzz; ///< in: b_e of the last step (in-plane block and zz)
  T eps_p;              ///< in: equivalent plastic strain
  T tau00, tau11, tau01, tau22; ///< out: Kirchhoff stress
  T be00, be11, be01, bezz;     ///< out: the new b_e
  T eps_p_new;                  ///< out: the new equivalent plastic strain
  T energy;                     ///< out: psi(b_e) per unit reference volume
  T work;                       ///< out: plastic dissipation of the step per unit reference volume
  T beta, dev2;                 ///< out: the return's factor and |dev e_trial|^2
  typename LaneOps<T>::Mask plastic; ///< out: the lanes in plastic flow
};

/// The plane J2 step (update2 with j2_return, linear hardening: e_v is
/// unchanged, dev e_new = beta dev e_trial with beta = (3 G sigma_y / q + H)
/// / (3 G + H) when q = sqrt(6) G |dev e| > sigma_y = sigma_y0 + H eps_p).
/// Returns the lanes the form covers (see the file comment); the outputs of
/// the other lanes are meaningless. 1/q is formed as q (1/q^2) so that the
/// square root and the division run side by side.
template <class T>
[[gnu::always_inline]] inline typename LaneOps<T>::Mask plane_j2(const J2Parameters& p, PlaneJ2<T>& x) {
  using O = LaneOps<T>;
  const double G = p.elastic.shear, K = p.elastic.bulk, H = p.hardening_modulus;
  const T det_dF = x.f00 * x.f11 - x.f01 * x.f10;
  const T m00 = x.f00 * x.b00 + x.f01 * x.b01, m01 = x.f00 * x.b01 + x.f01 * x.b11;
  const T m10 = x.f10 * x.b00 + x.f11 * x.b01, m11 = x.f10 * x.b01 + x.f11 * x.b11;
  const T a = m00 * x.f00 + m01 * x.f01, b = m10 * x.f00 + m11 * x.f01, c = m10 * x.f10 + m11 * x.f11;
  const T m = 0.5 * (a + c), d1 = 0.5 * (a - c);
  const T ud = (a * c - b * b) - 1.0, uz = x.bzz - 1.0;
  const T em = 0.25 * log1p_series(ud), ez = 0.5 * log1p_series(uz);
  const T inv_m = 1.0 / m;
  const T x2 = (d1 * d1 + b * b) * inv_m * inv_m;
  const T g = atanh_series(x2);
  const T ev = 2.0 * em + ez, a0 = (1.0 / 3) * (em - ez);
  const T dev2 = 6.0 * a0 * a0 + 0.5 * x2 * g * g;
  // Radial return (closed form); the lanes in plastic flow take the
  // return's beta, eps_p and b_e, the others keep the trial values (beta = 1).
  const T sy = p.yield_stress + H * x.eps_p;
  const T q2 = (6.0 * G * G) * dev2;
  const typename O::Mask plastic = q2 > sy * sy;
  x.plastic = plastic, x.dev2 = dev2;
  x.beta = O::splat(1.0), x.eps_p_new = x.eps_p;
  x.be00 = a, x.be11 = c, x.be01 = b, x.bezz = x.bzz;
  x.work = O::splat(0.0);
  typename O::Mask covered =
      O::all(det_dF > 0.0, m > 0.0, O::abs(ud) <= 1.0 / 32, O::abs(uz) <= 1.0 / 32, x2 < 1e-2);
  if (O::any(plastic)) {
    const T q = O::sqrt(q2), inv_q = q * (1.0 / q2);
    const double inv_h = 1.0 / (3.0 * G + H);
    x.eps_p_new = O::select(plastic, x.eps_p + (q - sy) * inv_h, x.eps_p);
    x.beta = O::select(plastic, ((3.0 * G) * sy * inv_q + H) * inv_h, x.beta);
    // b_e_new = b_e_trial e^(2 (e_new - e_trial)) in its eigenbasis (update2, e_v unchanged).
    const T db = 2.0 * (x.beta - 1.0);
    const T cin = db * a0, czz = -2.0 * cin, y2 = 0.25 * db * db * x2 * g * g;
    T ch, shc;
    cosh_shc_series(y2, ch, shc);
    const T E = exp_series(cin), bg = 0.5 * db * g * shc;
    const T mean = m * E * (ch + x2 * bg), coef = E * (ch + bg);
    x.be00 = O::select(plastic, mean + coef * d1, a);
    x.be11 = O::select(plastic, mean - coef * d1, c);
    x.be01 = O::select(plastic, coef * b, b);
    x.bezz = O::select(plastic, x.bzz * exp_series(czz), x.bzz);
    // Dissipation (fill_energies): 2 G beta (1 - beta) |dev e|^2 (e_v is unchanged).
    const T w = 2.0 * G * x.beta * (1.0 - x.beta) * dev2;
    x.work = O::select(plastic, O::select(w > 0.0, w, x.work), x.work);
    // |czz| = 2 |cin| exactly; elastic lanes have cin = y2 = 0.
    covered = O::all(covered, O::abs(cin) <= 1.0 / 128, y2 <= 1.0 / 256);
  }
  // tau = K e_v I + 2 G beta dev e (update2), psi(e_v, beta^2 |dev e|^2).
  const T G2b = (2.0 * G) * x.beta;
  const T tm = K * ev + G2b * a0, k = 0.5 * G2b * g * inv_m;
  x.tau00 = tm + k * d1;
  x.tau11 = tm - k * d1;
  x.tau01 = k * b;
  x.tau22 = K * ev - 2.0 * G2b * a0;
  x.energy = 0.5 * K * ev * ev + G * (x.beta * x.beta * dev2);
  // A non-finite dF or b_e fails the comparisons on ud or uz (NaN or inf).
  return covered;
}

/// One particle's plane J2 step through plane_j2 when it covers the
/// particle; false (state untouched) otherwise.
inline bool plane_j2_point(const J2Parameters& p, const Mat<2>& dF, HenckyState& st, PointUpdate& out) {
  PlaneJ2<double> x{};
  x.f00 = dF(0, 0), x.f01 = dF(0, 1), x.f10 = dF(1, 0), x.f11 = dF(1, 1);
  x.b00 = st.be(0, 0), x.b01 = st.be(0, 1), x.b11 = st.be(1, 1), x.bzz = st.be(2, 2), x.eps_p = st.eps_p;
  if (!plane_j2(p, x)) return false;
  out.kirchhoff << x.tau00, x.tau01, 0.0, x.tau01, x.tau11, 0.0, 0.0, 0.0, x.tau22;
  out.plastic = x.plastic;
  out.elastic_energy = x.energy;
  out.plastic_work = x.work;
  out.return_work = x.plastic ? p.elastic.shear * (1.0 - x.beta) * (1.0 - x.beta) * x.dev2 : 0.0;
  out.iterations = 0;
  st.be(0, 0) = x.be00, st.be(1, 1) = x.be11, st.be(2, 2) = x.bezz;
  st.be(0, 1) = st.be(1, 0) = x.be01;
  st.eps_p = x.eps_p_new;
  return true;
}

/// One J2 step (j2_update of hencky_plasticity.hpp), inlined: plane_j2 for
/// the plane-strain steps without Johnson-Cook that it covers, j2_general
/// otherwise.
template <int D>
[[gnu::always_inline]] inline PointUpdate j2(const J2Parameters& p, const Mat<D>& dF, double dt, HenckyState& state) {
  if constexpr (D == 2) {
    PointUpdate out;
    if (!p.johnson_cook && plane_j2_point(p, dF, state, out)) return out;
  }
  return j2_general<D>(p, dF, dt, state);
}

} // namespace otmpm::plasticity::point
