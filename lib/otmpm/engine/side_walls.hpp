#pragma once
/// \file side_walls.hpp
/// A plane-strain body between two side walls (a channel's, normal to the
/// out-of-plane axis z): each wall presses on the body with its normal
/// stress -sigma_zz and resists its in-plane motion by Coulomb friction
/// (docs/theory.md sect. 6.3). Over the channel's width W the two walls
/// give particle p the force
///   f_p = -min(2 mu_w max(-sigmabar_zz,p, 0) V_p / W, m_p |v_p| / dt) v_p / |v_p|   (eq. 6.7)
/// - the wall traction mu_w |sigma_zz| on each face of its slice V_p / W,
/// capped at what stops the particle within the step (a Coulomb force
/// cannot reverse the motion it resists). The walls press with the body's
/// stress, not a material point's: sigmabar_zz,p is sigma_zz averaged at the
/// nodes of p's basis and interpolated back (as the nodal F-bar mean,
/// eq. 9.11). A point's own sigma_zz carries the sub-cell oscillations the
/// grid's forces do not see; eq. 6.7 would turn them into forces (an
/// elastic block sliding between the walls with musl and the linear basis
/// stopped within 0.2 s, 3.4 or more times as fast as the static pressure
/// makes it; 1.97 times with the nodal mean; sect. 6.3 says why). The
/// engine adds f_p to the particle's external force and books its work,
/// -f_p . (x_p^{n+1} - x_p^n), as friction (eq. 6.8).
#include "otmpm/core.hpp"
#include "otmpm/engine/volumetric.hpp"
#include "otmpm/parallel.hpp"
#include "otmpm/particles/particles.hpp"

#include <algorithm>
#include <cmath>

namespace otmpm {

/// The side walls of a channel: distance `width` W [m] between them and
/// their Coulomb friction mu_w with the material.
struct SideWalls {
  double width = 0.0;
  double friction = 0.0;

  /// Eq. 6.7 for one particle: mass m, volume V, velocity v, out-of-plane
  /// stress sigma_zz, step dt.
  template <int D> Vec<D> force(double m, double V, const Vec<D>& v, double sigma_zz, double dt) const {
    const double speed = v.norm();
    if (!(speed > 0.0)) return Vec<D>::Zero();
    const double slide = 2.0 * friction * std::max(-sigma_zz, 0.0) * V / width;
    return (-std::min(slide, m * speed / dt) / speed) * v;
  }
};

/// The side walls of a run (eq. 6.7, 6.8): each force pass computes every
/// particle's f_p, which the pass adds to its external force; the step's
/// loss is their work on the particles' motion since the step began.
template <int D> class ChannelWalls {
public:
  explicit ChannelWalls(const SideWalls& walls) : walls_(walls) {}
  /// f_p of particles 0 .. n-1 at step dt: `zz(p0, p1, out)` writes the
  /// out-of-plane stress of particles p0 .. p1-1, all of one material, and
  /// the nodal average over `table`'s rows gives sigmabar_zz.
  template <class OutOfPlane>
  void compute(const Particles<D>& P, const BasisTable<D>& table, int nodes, double dt, OutOfPlane&& zz) {
    const int n = P.size();
    zz_.resize(static_cast<std::size_t>(n));
    force_.resize(static_cast<std::size_t>(n));
    parallel_chunks(n, [&](long long c0, long long c1) {
      for (auto p0 = static_cast<int>(c0); p0 < c1;) { // the chunk's runs of one material
        int p1 = p0 + 1;
        while (p1 < c1 && P.material[p1] == P.material[p0]) ++p1;
        zz(p0, p1, zz_.data() + p0);
        p0 = p1;
      }
    });
    average_.average(table, nodes, P.V.data(), zz_.data(), n);
    parallel_for(n, [&](long long p) { force_[p] = walls_.force<D>(P.m[p], P.V[p], P.v[p], zz_[p], dt); });
  }
  /// The forces of the last pass (null before the first, or when the particles changed since).
  const Vec<D>* force(int n) const { return static_cast<int>(force_.size()) == n ? force_.data() : nullptr; }
  /// Keeps the particles' positions at the start of a step.
  void start(const Particles<D>& P) { start_.assign(P.x.begin(), P.x.end()); }
  /// Eq. 6.8: the energy the walls took over the step, -sum_p f_p . (x_p -
  /// x_p at the start), summed in blocks of particles (the same bits on any
  /// number of threads).
  double loss(const Particles<D>& P) const {
    if (!force(P.size()) || static_cast<int>(start_.size()) != P.size()) return 0.0;
    return blocked_reduce_ranges<double>(P.size(), [&](long long p0, long long p1, double& acc) {
      for (auto p = p0; p < p1; ++p) acc -= force_[p].dot(P.x[p] - start_[p]);
    });
  }

private:
  SideWalls walls_;
  std::vector<double> zz_; ///< sigma_zz, then sigmabar_zz, of the last pass
  NodalAverage<D> average_;
  AlignedVector<Vec<D>> force_, start_;
};

} // namespace otmpm
