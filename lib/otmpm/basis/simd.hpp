#pragma once
/// \file simd.hpp
/// Short double vectors for the max-ent kernels (the LME Newton solve spends
/// its time in loops over the 10-60 support nodes of a point). The loops of
/// the polynomials are unrolled by pragma (the same operations in the same
/// order; at -O2 they stayed loops with a broadcast per coefficient). Written with
/// the GCC/Clang `vector_size` extension: two lanes (one SSE2 register) with
/// the portable default flags, four lanes (one AVX register) when the build
/// enables AVX (OTMPM_NATIVE on a machine that has it). Every operation is an
/// IEEE operation per lane (no FMA contraction: the build passes
/// -ffp-contract=off, CMakeLists.txt) and horizontal
/// sums add the lanes in a fixed order, so the results do not depend on the
/// thread count; they can differ in the last bits between builds with two and
/// with four lanes (the grouping of the sums differs).
#include <bit>
#include <cstring>
#include <limits>

namespace otmpm::simd {

/// Lanes per vector; arrays handed to the kernels are padded to a multiple.
#if defined(__AVX__)
constexpr int lanes = 4;
#else
constexpr int lanes = 2;
#endif
/// `lanes` doubles.
using vd = double __attribute__((vector_size(lanes * sizeof(double))));
/// `lanes` 64-bit integers (comparison masks: all ones or all zeros per lane).
using vl = long long __attribute__((vector_size(lanes * sizeof(long long))));

/// n rounded up to a multiple of `lanes`.
constexpr int padded(int n) { return (n + lanes - 1) / lanes * lanes; }

inline vd broadcast(double x) { return vd{} + x; }
/// Unaligned load / store of `lanes` doubles.
inline vd load(const double* p) {
  vd v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store(double* p, vd v) { std::memcpy(p, &v, sizeof v); }

/// Lane-wise a < b as a mask (false where either is NaN).
inline vl less(vd a, vd b) { return (vl)(a < b); }
/// Lane-wise mask ? a : b (mask lanes all ones or all zeros).
inline vd select(vl mask, vd a, vd b) { return (vd)((mask & (vl)a) | (~mask & (vl)b)); }
/// Lane-wise maximum; a lane where b is NaN keeps a.
inline vd max(vd a, vd b) { return select(less(a, b), b, a); }

/// 1 / k! for k = 0 .. 13 (each the double nearest to it).
constexpr double inv_factorial[14] = {1.0,
                                      1.0,
                                      0.5,
                                      1.0 / 6.0,
                                      1.0 / 24.0,
                                      1.0 / 120.0,
                                      1.0 / 720.0,
                                      1.0 / 5040.0,
                                      1.0 / 40320.0,
                                      1.0 / 362880.0,
                                      1.0 / 3628800.0,
                                      1.0 / 39916800.0,
                                      1.0 / 479001600.0,
                                      1.0 / 6227020800.0};

/// Sum of the lanes, pairwise: v0 + v1, or (v0 + v2) + (v1 + v3).
inline double sum(vd v) {
  double a[lanes];
  std::memcpy(a, &v, sizeof v);
  for (int w = lanes / 2; w >= 1; w /= 2)
    for (int i = 0; i < w; ++i) a[i] += a[i + w];
  return a[0];
}
/// Largest lane (NaN lanes ignored unless all are NaN).
inline double max_lane(vd v) {
  double m = v[0];
  for (int i = 1; i < lanes; ++i) m = v[i] > m ? v[i] : m;
  return m;
}

/// Lowest exponent evaluated by the polynomial; below it e^x < 3.3e-308 is
/// returned as 0 (a basis value that small is dropped from the stencil).
constexpr double exp_lowest = -708.0;

/// e^x lane by lane for x <= 0 (the shifted exponents of the max-ent dual
/// function): bit for bit maxent::exp_shifted(x) for x >= -708 (Cody-Waite
/// reduction x = k ln 2 + r, degree-13 Taylor polynomial of e^r - its tail
/// by Estrin's scheme, short dependency chains -, 2^k built in the exponent
/// bits; within 2 ulp of e^x, below 1.2 ulp measured), 0 below -708 and for -inf,
/// NaN for NaN. Branch-free.
inline vd exp_shifted(vd x) {
  constexpr double log2e = 1.4426950408889634074;
  constexpr double ln2_hi = 6.93147180369123816490e-01;
  constexpr double ln2_lo = 1.90821492927058770002e-10;
  constexpr double round_shift = 6755399441055744.0; // 1.5 * 2^52
  const vl below = less(x, broadcast(exp_lowest));
  const vd xc = select(below, broadcast(exp_lowest), x); // NaN stays NaN
  const vd t = xc * log2e + round_shift;                 // k in the low mantissa bits
  const vd kd = t - round_shift;
  const vd r = (xc - kd * ln2_hi) - kd * ln2_lo;
  // The tail c_4 + c_5 r + ... + c_13 r^9 by Estrin's scheme (its rounding
  // is scaled by r^4 / 24 <= 6e-4), the first four terms by Horner's (whose
  // last steps set the accuracy): 15 dependent operations instead of 26
  const vd r2 = r * r, r4 = r2 * r2;
  vd q[5];
#pragma GCC unroll 5
  for (int i = 0; i < 5; ++i) q[i] = inv_factorial[4 + 2 * i] + r * inv_factorial[5 + 2 * i];
  const vd tail = (q[0] + r2 * q[1]) + r4 * ((q[2] + r2 * q[3]) + r4 * q[4]);
  const vd poly = 1.0 + r * (1.0 + r * (inv_factorial[2] + r * (inv_factorial[3] + r * tail)));
  const vl k = (vl)t - (vl)broadcast(round_shift);
  const vd scale = (vd)((k + 1023) << 52);
  return select(below, broadcast(0.0), poly * scale);
}

/// e^u for small |u| by its Taylor polynomial of the given degree (Horner,
/// coefficients 1/k!). Degree 5 is within 1 ulp for |u| <= 2^-8, degree 8 for
/// |u| <= 2^-4 (truncation below 2^-54 relative).
template <int Degree> inline vd exp_small(vd u) {
  static_assert(Degree >= 1 && Degree <= 13);
  vd poly = broadcast(inv_factorial[Degree]);
#pragma GCC unroll 13
  for (int k = Degree - 1; k >= 0; --k) poly = poly * u + inv_factorial[k];
  return poly;
}

} // namespace otmpm::simd
