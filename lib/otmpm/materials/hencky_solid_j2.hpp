#pragma once
/// \file hencky_solid_j2.hpp
/// The 3D J2 step with linear hardening - update3's series branch with
/// j2_return (hencky_point.hpp) - written once for a number type T: T =
/// double updates one particle, T = Lanes2 two particles in one SSE2
/// register, T = Lanes4 four in one AVX register (where the processor has
/// AVX2). Each lane does the IEEE operations of update3 in its order (ISO
/// C++, no contraction; ln m by the library's log, lane by lane; each lane
/// takes as many series terms as update3 gives it), so a particle gets the
/// bits of the general path whichever way it is updated, and results do not
/// depend on how the particles fall into pairs or quads (thread chunks).
///
/// A lane that update3 would not take through its series branch and the
/// polynomial exponentials (det dF <= 0 or not finite, b_e_trial farther
/// from a multiple of I than kSeriesRadius, a non-finite strain, a return
/// whose exponent exceeds 1/64) reports "not covered" and is updated by the
/// general scalar path (update3 with its eigen-decomposition, library
/// functions and error checks). Internal to materials/.
#include "otmpm/materials/hencky_plane_j2.hpp"

#include <limits>

#if defined(__x86_64__) && defined(__GNUC__)
#define OTMPM_WIDE_LANES 1
#endif

namespace otmpm::plasticity::point {

#ifdef OTMPM_WIDE_LANES
/// Four doubles (one AVX register): the 3D J2 step of four particles,
/// inlined into a function compiled for AVX2 (`[[gnu::target("avx2")]]`;
/// no FMA, and the build does not contract: the lanes keep the IEEE
/// operations of the one-particle form) and chosen at run time where the
/// processor has AVX2 (wide_lanes()). The operations below are generic
/// vector code, always inlined: they take the instructions of their caller.
using Lanes4 = double __attribute__((vector_size(32)));
/// Lane masks of Lanes4 comparisons: all ones or all zeros per lane.
using Mask4 = long long __attribute__((vector_size(32)));

template <> struct LaneOps<Lanes4> {
  using Mask = Mask4;
  [[gnu::always_inline]] static inline Lanes4 splat(double x) { return Lanes4{x, x, x, x}; }
  [[gnu::always_inline]] static inline Lanes4 sqrt(Lanes4 x) {
    return Lanes4{std::sqrt(x[0]), std::sqrt(x[1]), std::sqrt(x[2]), std::sqrt(x[3])};
  }
  /// The library's log lane by lane (the bits of the one-particle form).
  [[gnu::always_inline]] static inline Lanes4 log(Lanes4 x) {
    return Lanes4{std::log(x[0]), std::log(x[1]), std::log(x[2]), std::log(x[3])};
  }
  [[gnu::always_inline]] static inline Lanes4 abs(Lanes4 x) { return (Lanes4)((Mask4)x & ~(1LL << 63)); }
  [[gnu::always_inline]] static inline Lanes4 select(Mask4 m, Lanes4 a, Lanes4 b) {
    return (Lanes4)((m & (Mask4)a) | (~m & (Mask4)b));
  }
  /// a where m, +0 elsewhere (one AND).
  [[gnu::always_inline]] static inline Lanes4 keep(Mask4 m, Lanes4 a) { return (Lanes4)(m & (Mask4)a); }
  [[gnu::always_inline]] static inline bool any(Mask4 m) { return ((m[0] | m[1]) | (m[2] | m[3])) != 0; }
  template <class... M> [[gnu::always_inline]] static inline Mask4 all(M... m) { return ((Mask4)m & ...); }
};
#endif

/// The four-lane (AVX2) forms are used - the 3D J2 step, and
/// linear_elastic's straight-path energy weights (elastic.cpp): the
/// processor has AVX2 and set_wide_lanes(false) was not called (j2.cpp).
bool wide_lanes();
/// Allows (true, the default) or forbids the four-lane forms (tests compare
/// the two paths' bits).
void set_wide_lanes(bool allowed);

/// Input and output of a 3D J2 step, one lane per particle. Symmetric
/// tensors as (xx, yy, zz, xy, yz, xz), the order of the b_e state rows.
template <class T> struct SolidJ2 {
  T f[3][3]; ///< in: the increment dF (row, column)
  T b[6];    ///< in: b_e of the last step
  T eps_p;   ///< in: equivalent plastic strain
  T tau[6];  ///< out: Kirchhoff stress
  T be[6];   ///< out: the new b_e
  T eps_p_new; ///< out: the new equivalent plastic strain
  T energy;    ///< out: psi(b_e) per unit reference volume
  T work;      ///< out: plastic dissipation of the step per unit reference volume
  typename LaneOps<T>::Mask plastic; ///< out: the lanes in plastic flow
};

/// det A of a 3x3 matrix (first-row cofactors, Eigen's order).
template <class T> [[gnu::always_inline]] inline T det3(const T (&a)[3][3]) {
  return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
         a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
}

/// c = a b of 3x3 matrices, each entry (a_i0 b_0j + a_i1 b_1j) + a_i2 b_2j:
/// one order for every lane width and build (that of Eigen's product
/// depends on its vectorisation), so the 3D Hencky models advance F with
/// the same bits on any path (HenckyMaterial::advanced_F and the lanes).
template <class T> [[gnu::always_inline]] inline void mul3(const T (&a)[3][3], const T (&b)[3][3], T (&c)[3][3]) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) c[i][j] = (a[i][0] * b[0][j] + a[i][1] * b[1][j]) + a[i][2] * b[2][j];
}

/// F = a b of 3x3 matrices by mul3 above (its order of the sums), and its
/// determinant by det3 (J), for the one-particle path and the tests.
inline Mat<3> mul3(const Mat<3>& a, const Mat<3>& b, double& J) {
  double x[3][3], y[3][3], z[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) x[i][j] = a(i, j), y[i][j] = b(i, j);
  mul3(x, y, z);
  Mat<3> c;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) c(i, j) = z[i][j];
  J = det3(z);
  return c;
}

/// The 3D J2 step (update3 -> update3_series with j2_return, linear
/// hardening): b_e_trial = dF b_e dF^T = m (I + Z), the logarithm and the
/// power (I + Z)^beta by their Cayley-Hamilton series, the closed-form
/// radial return. Returns the lanes the form covers (see the file comment);
/// the outputs of the other lanes are meaningless.
template <class T>
[[gnu::always_inline]] inline typename LaneOps<T>::Mask solid_j2(const J2Parameters& p, SolidJ2<T>& x) {
  using O = LaneOps<T>;
  using Mask = typename O::Mask;
  const double G = p.elastic.shear, K = p.elastic.bulk, H = p.hardening_modulus;
  const T det_dF = det3(x.f);
  // push_forward: A M A^T, M = b_e (mirrored), the upper triangle.
  const T M[3][3] = {{x.b[0], x.b[3], x.b[5]}, {x.b[3], x.b[1], x.b[4]}, {x.b[5], x.b[4], x.b[2]}};
  T AM[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) AM[i][j] = x.f[i][0] * M[0][j] + x.f[i][1] * M[1][j] + x.f[i][2] * M[2][j];
  T btr[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) btr[i][j] = AM[i][0] * x.f[j][0] + AM[i][1] * x.f[j][1] + AM[i][2] * x.f[j][2];
  const T m = (btr[0][0] + btr[1][1] + btr[2][2]) / 3.0, inv_m = 1.0 / m;
  // Z = b / m - I with its trace removed exactly; z, y: Z and Z^2 as (00, 11, 22, 01, 02, 12).
  T z[6] = {btr[0][0] * inv_m, btr[1][1] * inv_m, btr[2][2] * inv_m,
            btr[0][1] * inv_m, btr[0][2] * inv_m, btr[1][2] * inv_m};
  const T shift = (z[0] + z[1] + z[2]) / 3.0;
  z[0] -= shift, z[1] -= shift, z[2] -= shift;
  const T y[6] = {z[0] * z[0] + z[3] * z[3] + z[4] * z[4], z[3] * z[3] + z[1] * z[1] + z[5] * z[5],
                  z[4] * z[4] + z[5] * z[5] + z[2] * z[2], z[0] * z[3] + z[3] * z[1] + z[4] * z[5],
                  z[0] * z[4] + z[3] * z[5] + z[4] * z[2], z[3] * z[4] + z[1] * z[5] + z[5] * z[2]};
  const T J2 = 0.5 * (y[0] + y[1] + y[2]);
  const T rho = O::sqrt(4.0 / 3.0 * J2);
  Mask covered = O::all(det_dF > 0.0, det_dF <= std::numeric_limits<double>::max(), rho <= kSeriesRadius, m > 0.0);
  if (!O::any(covered)) return covered;
  const T J3 = z[0] * (z[1] * z[2] - z[5] * z[5]) - z[3] * (z[3] * z[2] - z[5] * z[4]) +
               z[4] * (z[3] * z[5] - z[1] * z[4]);
  // The series (update3_series): term k is taken where rho^k > kSeriesTolerance,
  // elsewhere +0 is added, which leaves a sum that started at +0 or 1 as it
  // is (a rounded sum is -0 only when both terms are).
  T P[kMaxTerms], Q[kMaxTerms], R[kMaxTerms];
  Mask take[kMaxTerms];
  P[0] = O::splat(0.0), Q[0] = O::splat(1.0), R[0] = O::splat(0.0);
  T c0 = O::splat(0.0), c1 = O::splat(1.0), c2 = O::splat(0.0);
  int n = 1;
  for (T t = rho; n < kMaxTerms; ++n, t *= rho) {
    take[n] = t > kSeriesTolerance;
    if (!O::any(take[n])) break;
    const int k = n;
    P[k] = R[k - 1] * J3;
    Q[k] = P[k - 1] + R[k - 1] * J2;
    R[k] = Q[k - 1];
    const double s = k % 2 ? -kInverse[k] : kInverse[k];
    c0 += O::keep(take[k], s * P[k]);
    c1 += O::keep(take[k], s * Q[k]);
    c2 += O::keep(take[k], s * R[k]);
  }
  const T S = 3.0 * c0 + 2.0 * J2 * c2;
  const T ev = 0.5 * (3.0 * O::log(m) + S);
  const T dev2 = 0.25 * (2.0 * J2 * c1 * c1 + 6.0 * J3 * c1 * c2 + (2.0 / 3.0) * J2 * J2 * c2 * c2);
  covered = O::all(covered, O::abs(ev + dev2) <= std::numeric_limits<double>::max());
  // j2_return, linear hardening: the lanes in plastic flow take the return's beta and eps_p.
  const T sy = p.yield_stress + H * x.eps_p;
  const T q2 = 6.0 * G * G * dev2;
  const Mask plastic = q2 > sy * sy;
  T beta = O::splat(1.0);
  x.plastic = plastic, x.eps_p_new = x.eps_p, x.work = O::splat(0.0);
  if (O::any(plastic)) {
    const T q = O::sqrt(q2), inv = 1.0 / ((3.0 * G + H) * q);
    x.eps_p_new = O::select(plastic, x.eps_p + (q - sy) * q * inv, x.eps_p);
    beta = O::select(plastic, (3.0 * G * sy + H * q) * inv, beta);
  }
  // tau = (K e_v - 2/3 G beta c2 J2) I + G beta (c1 Z + c2 Z^2).
  const T Gb = G * beta;
  const T t0 = K * ev - (2.0 / 3.0) * Gb * c2 * J2, t1 = Gb * c1, t2 = Gb * c2;
  x.tau[0] = t0 + t1 * z[0] + t2 * y[0];
  x.tau[1] = t0 + t1 * z[1] + t2 * y[1];
  x.tau[2] = t0 + t1 * z[2] + t2 * y[2];
  x.tau[3] = t1 * z[3] + t2 * y[3];
  x.tau[4] = t1 * z[5] + t2 * y[5];
  x.tau[5] = t1 * z[4] + t2 * y[4];
  x.be[0] = btr[0][0], x.be[1] = btr[1][1], x.be[2] = btr[2][2];
  x.be[3] = btr[0][1], x.be[4] = btr[1][2], x.be[5] = btr[0][2];
  if (O::any(plastic)) {
    // b_e_new = m exp(-(beta - 1) S / 3) (I + Z)^beta, the binomial series on the same terms.
    T d0 = O::splat(1.0), d1 = O::splat(0.0), d2 = O::splat(0.0), binom = O::splat(1.0);
    for (int k = 0; k < n; ++k) {
      binom *= (beta - double(k)) * kInverse[k];
      const T b = k == 0 ? binom : O::keep(take[k], binom);
      d0 += b * P[k], d1 += b * Q[k], d2 += b * R[k];
    }
    // exp_small, its two polynomial tiers: lanes beyond 1/64 are not covered.
    const T d = (2.0 * (ev - ev) - (beta - 1.0) * S) / 3.0;
    const T small = (1.0 + d) + d * d * (1.0 / 2 + d * (1.0 / 6));
    const T scale = m * O::select(O::abs(d) <= 0x1p-17, small, exp_series(d));
    covered = O::all(covered, O::select(plastic, O::abs(d), O::splat(0.0)) <= 1.0 / 64);
    const T b0 = scale * d0, b1 = scale * d1, b2 = scale * d2;
    x.be[0] = O::select(plastic, b0 + b1 * z[0] + b2 * y[0], x.be[0]);
    x.be[1] = O::select(plastic, b0 + b1 * z[1] + b2 * y[1], x.be[1]);
    x.be[2] = O::select(plastic, b0 + b1 * z[2] + b2 * y[2], x.be[2]);
    x.be[3] = O::select(plastic, b1 * z[3] + b2 * y[3], x.be[3]);
    x.be[4] = O::select(plastic, b1 * z[5] + b2 * y[5], x.be[4]);
    x.be[5] = O::select(plastic, b1 * z[4] + b2 * y[4], x.be[5]);
    // fill_energies: K e_v_new (e_v - e_v_new) + 2 G beta (1 - beta) |dev e|^2, clamped at 0.
    const T w = K * ev * (ev - ev) + 2.0 * G * beta * (1.0 - beta) * dev2;
    x.work = O::select(plastic, O::select(0.0 < w, w, O::splat(0.0)), x.work);
  }
  x.energy = 0.5 * K * ev * ev + G * (beta * beta * dev2);
  return covered;
}

} // namespace otmpm::plasticity::point
