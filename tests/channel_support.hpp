#pragma once
// The scene of the channel tests (test_channel.cpp, test_scenes_channel.cpp):
// an elastic block sliding between a channel's side walls, and what they
// measure of it.
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/particles/particles.hpp"

#include <string>

namespace otmpm::test {

inline constexpr double kG = 9.81, kNu = 0.3, kH = 0.1, kWidth = 0.1, kMu = 0.5;

/// An elastic block 0.5 m x H (rho 1000, E 2e7, nu 0.3) at 1 m/s on a
/// frictionless floor under gravity, between side walls W apart with
/// friction mu_w, run with integrator k (ul and B-splines where it needs
/// them) on a grid of spacing h. Laterally free, the block carries sigma_xx
/// = 0 and sigma_yy = -rho g (H - y), so plane strain's sigma_zz = nu
/// sigma_yy: the walls take 2 mu_w nu rho g H / 2 per unit area of the
/// block, a deceleration mu_w nu g H / W.
inline std::string sliding_block(const IntegratorKind& k, double h, double length = 0.5,
                                 std::string basis = "") {
  const std::string mode = k.needs_ul ? "ul" : "mpm";
  if (basis.empty()) basis = k.needs_bspline ? "bspline2" : "linear";
  return "[simulation]\ndimension = 2\nmode = \"" + mode + "\"\nintegrator = \"" + std::string(k.name) +
         "\"\nt_end = 0.3\ncfl = 0.2\n[basis]\nkind = \"" + basis + "\"\n[grid]\nlower = [-0.1, -0.1]\n" +
         "upper = [" + std::to_string(length + 0.6) + ", 0.3]\nh = " + std::to_string(h) + "\n" +
         "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1000.0\nyoung = 2.0e7\npoisson = "
         "0.3\n"
         "[[body]]\nname = \"block\"\nmaterial = \"m\"\nlower = [0.0, 0.0]\nupper = [" +
         std::to_string(length) +
         ", 0.1]\nvelocity = [1.0, 0.0]\n"
         "[[wall]]\nname = \"floor\"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\n"
         "[body_force]\nvalue = [0.0, -9.81]\n[channel]\nwidth = 0.1\nfriction = 0.5\n";
}

/// The block's mean horizontal velocity.
inline double mean_vx(const Particles<2>& P) {
  double q = 0.0, m = 0.0;
  for (int p = 0; p < P.size(); ++p) q += P.m[p] * P.v[p][0], m += P.m[p];
  return q / m;
}

} // namespace otmpm::test
