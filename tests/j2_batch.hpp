#pragma once
// Shared by the tests of the j2 lane forms (test_plane_j2.cpp,
// test_solid_j2.cpp): their material, a batch of particles with it bound to
// them, and the check that a particle gets the same bits whether the batch
// update takes it in a pair, in the other pairing or alone.
#include "otmpm/materials/hencky_plasticity.hpp"
#include "otmpm/materials/material.hpp"

#include <doctest/doctest.h>

#include <bit>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace otmpm::test {

inline std::uint64_t bits(double x) { return std::bit_cast<std::uint64_t>(x); }

/// The material of the tests: E = 10 MPa, nu = 0.3, yield stress 2 kPa,
/// linear hardening 100 kPa.
constexpr double kYoung = 1.0e7, kPoisson = 0.3, kYield = 2.0e3, kHardening = 1.0e5;
inline plasticity::J2Parameters parameters() {
  plasticity::J2Parameters p;
  p.elastic = plasticity::ElasticModuli::from_young_poisson(kYoung, kPoisson);
  p.yield_stress = kYield;
  p.hardening_modulus = kHardening;
  return p;
}

/// n particles of the tests' j2 material with the state arrays bound, and
/// their increments H (to be filled by the caller).
template <int D> struct J2Batch {
  std::unique_ptr<Material<D>> material;
  Particles<D> P;
  std::vector<Mat<D>, Eigen::aligned_allocator<Mat<D>>> H;
};
template <int D> J2Batch<D> j2_batch(int n) {
  J2Batch<D> b;
  b.material = make_material<D>({.name = "steel",
                                 .model = "j2",
                                 .density = 1000.0,
                                 .young = kYoung,
                                 .poisson = kPoisson,
                                 .extra = {{"yield_stress", kYield}, {"hardening_modulus", kHardening}}});
  b.P.resize(n);
  b.P.allocate_optional(false, true);
  for (const StateSpec& s : b.material->state()) b.P.add_state(std::string(s.name), s.width, s.initial.data());
  b.material->bind(b.P);
  b.H.resize(static_cast<std::size_t>(n));
  for (int p = 0; p < n; ++p) {
    b.P.V[p] = b.P.V0[p] = 1e-4;
    b.P.m[p] = b.P.rho[p] = 1000.0 * 1e-4;
  }
  return b;
}

/// Every per-particle field of a and b is bitwise equal.
template <int D> bool same_particles(const Particles<D>& a, const Particles<D>& b) {
  for (int p = 0; p < a.size(); ++p) {
    const bool same = a.F[p] == b.F[p] && a.sigma[p] == b.sigma[p] && a.eps[p] == b.eps[p] &&
                      bits(a.V[p]) == bits(b.V[p]) && bits(a.rho[p]) == bits(b.rho[p]);
    if (!same) return false;
  }
  for (std::size_t f = 0; f < a.state.size(); ++f)
    for (std::size_t i = 0; i < a.state[f].values.size(); ++i)
      if (bits(a.state[f].values[i]) != bits(b.state[f].values[i])) return false;
  return true;
}

/// Batches of make(n) updated whole (pairs (0,1), (2,3), ...), in the other
/// pairing ((1,2), (3,4), ...) and one particle at a time give the same
/// bits, every stress finite; returns how many particles' plastic strain grew.
template <int D> int check_pairings(const std::function<J2Batch<D>(int)>& make, int n) {
  J2Batch<D> whole = make(n), shifted = make(n), single = make(n);
  whole.material->update(whole.P, 0, n, whole.H.data(), 1e-3);
  shifted.material->update(shifted.P, 0, 1, shifted.H.data(), 1e-3);
  shifted.material->update(shifted.P, 1, n, shifted.H.data() + 1, 1e-3);
  for (int p = 0; p < n; ++p) single.material->update(single.P, p, p + 1, single.H.data() + p, 1e-3);
  CHECK(same_particles(whole.P, shifted.P));
  CHECK(same_particles(whole.P, single.P));
  const std::vector<double>& eps_p = whole.P.find_state("plastic_strain")->values;
  const J2Batch<D> before = make(n);
  const std::vector<double>& eps_p0 = before.P.find_state("plastic_strain")->values;
  int grown = 0;
  for (int p = 0; p < n; ++p) {
    grown += eps_p[static_cast<std::size_t>(p)] > eps_p0[static_cast<std::size_t>(p)];
    CHECK(whole.P.sigma[p].allFinite());
  }
  return grown;
}

} // namespace otmpm::test
