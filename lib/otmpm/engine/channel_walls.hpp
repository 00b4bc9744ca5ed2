#pragma once
/// \file channel_walls.hpp
/// The side walls of a channel during a run (internal: needs parallel.hpp):
/// the forces of eq. 6.7 (engine/side_walls.hpp) on every particle of each
/// force pass, and their work over the step, booked as friction (eq. 6.8).
#include "otmpm/engine/side_walls.hpp"
#include "otmpm/engine/volumetric.hpp"
#include "otmpm/parallel.hpp"
#include "otmpm/particles/particles.hpp"

#include <vector>

namespace otmpm {

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
  /// The ranks of a distributed run (null: one process): the nodal mean of
  /// sigma_zz is then summed over them (NodalAverage::distribute).
  void distribute(Distribution<D>* ranks) { average_.distribute(ranks); }
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
