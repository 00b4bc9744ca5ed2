#pragma once
/// \file volumetric.hpp
/// The F-bar treatment of volumetric locking (docs/theory.md sect. 9.8):
/// the volume change of each particle's step is replaced by the volume
/// change of its patch, so that isochoric (plastic) flow is not resisted by
/// the many volume constraints of a patch's material points.
///
/// In incremental form (the materials advance F_{n+1} = dF F_n with dF = I + H):
///   dJ_p = det dF_p,   dJbar_c = sum_{p in c} V_p dJ_p / sum_{p in c} V_p,
///   dFbar_p = (dJbar_c / dJ_p)^{1/D} dF_p,
/// so det dFbar_p = dJbar_c (the patch's volume ratio V_c^{n+1} / V_c^n) and
/// the isochoric part of dF_p is kept (de Souza Neto et al. 1996, "Design of
/// simple low order finite elements for large strain analysis of nearly
/// incompressible solids"; for material points: Coombs et al. 2018,
/// "Overcoming volumetric locking in material point methods"). A patch c is a
/// cell of the node lattice and a body: on the fixed grid the cell that holds
/// the particle when the basis is evaluated, with advected nodes the cell of
/// the initial lattice that held it at t = 0, or of the last node reset's
/// lattice that held it then (a Lagrangian patch).
///
/// The internal forces are the work conjugate of the averaged rate: they use
/// each particle's deviatoric stress with its patch's mean stress,
///   sigma_eff,p = sigma_p + (mbar_c - m_p) I,   m_p = tr sigma_p / D,
///   mbar_c = sum_{q in c} V_q m_q / sum_{q in c} V_q,
/// so that sum_p V_p sigma_eff,p : L_p = sum_p V_p sigma_p : Lbar_p, the rate
/// of the energy the materials store (docs/theory.md eq. 9.10).
///
/// The nodal variant (`fbar_nodal`, docs/theory.md eq. 9.11) takes the patch
/// through the basis instead of a cell: the volume ratios are averaged at the
/// nodes and interpolated back,
///   dJ_I = sum_p N_Ip V_p dJ_p / sum_p N_Ip V_p,   dJbar_p = sum_I N_Ip dJ_I,
/// and the forces' mean stress likewise, mbar_p = sum_I N_Ip m_I with
/// m_I = sum_q N_Iq V_q m_q / sum_q N_Iq V_q (the same symmetric operator, so
/// the forces stay the work conjugate of the averaged rate). In a distributed
/// run the nodal sums of each rank's particles are added over the ranks
/// before they are interpolated back (the nodes of a rank's window hold the
/// totals, as the mass does). Internal to the engine.
#include "otmpm/basis/basis.hpp"
#include "otmpm/core.hpp"
#include "otmpm/particles/particles.hpp"

#include <vector>

namespace otmpm {

template <int D> class Distribution;

/// How the engine treats the volumetric part of the deformation.
enum class Volumetric {
  none,       ///< every particle's own dF (full integration of the volume change)
  fbar,       ///< dF's volume change averaged over the particle's cell (F-bar)
  fbar_nodal, ///< dF's volume change averaged at the nodes and interpolated back (nodal F-bar)
};

/// The nodal sums of the nodal F-bar average (docs/theory.md eq. 9.11): each
/// particle's dJ_p (or mean stress) averaged at the nodes of its basis row
/// with the weights N_Ip V_p and interpolated back with N_Ip; reused step
/// after step.
template <int D> class NodalAverage {
public:
  /// Replaces H_p by (dJbar_p / dJ_p)^{1/D} (I + H_p) - I for particles [0, n)
  /// on the rows of `table` over `nodes` nodes; V[p] is the particle's volume at
  /// the start of the step. The sums run in particle order (the same bits for
  /// any thread count). A particle whose dJ_p is not positive keeps H_p and adds
  /// nothing to its nodes; dJbar_p is normalised by the weights N_Ip of the
  /// nodes that received a sum.
  void apply(const BasisTable<D>& table, int nodes, const double* V, Mat<D>* H, int n);
  /// shift[p] = mbar_p - m_p, m_p = tr sigma_p / D, for particles [0, n).
  void shift_mean_stress(const BasisTable<D>& table, int nodes, const double* V, const Mat<D>* sigma,
                         double* shift, int n);
  /// value[p] replaced by its nodal average sum_I N_Ip a_I / sum_I N_Ip,
  /// a_I = sum_q N_Iq V_q value[q] / sum_q N_Iq V_q, for particles [0, n).
  void average(const BasisTable<D>& table, int nodes, const double* V, double* value, int n);
  /// The ranks of a distributed run (null: one process): every call then
  /// adds the nodal sums over the ranks before interpolating them back, so
  /// every rank must make the same calls (each force pass does).
  void distribute(Distribution<D>* ranks) { ranks_ = ranks; }

private:
  /// value[p] replaced by sum_I N_Ip a_I / sum_I N_Ip (over nodes with a sum),
  /// a_I = sum_q N_Iq V_q value[q] / sum_q N_Iq V_q over the q with use(q).
  template <class Use>
  void smooth(const BasisTable<D>& table, int nodes, const double* V, double* value, int n, Use&& use);
  std::vector<double> weighted_, weight_; ///< sum N V value and sum N V per node
  std::vector<double> value_;             ///< dJ_p or tr sigma_p of the current call, then its average
  std::vector<double> dJ_;                ///< dJ_p of the current apply
  Distribution<D>* ranks_ = nullptr;      ///< distribute()
};

/// The patch sums of the F-bar average; reused step after step.
template <int D> class PatchAverage {
public:
  /// Replaces H_p by Hbar_p = (dJbar / dJ_p)^{1/D} (I + H_p) - I for particles
  /// [0, n): patch[p] in [0, patches) is particle p's patch, V[p] its volume at
  /// the start of the step. The sums run in particle order (the same bits for
  /// any thread count). A patch of one particle keeps its H_p. A particle whose dJ_p is not positive keeps H_p (its
  /// material then reports det F <= 0), and adds nothing to its patch.
  void apply(const std::vector<long long>& patch, long long patches, const double* V, Mat<D>* H, int n);
  /// shift[p] = mbar_c - m_p (the file's head) for particles [0, n), with the
  /// patches and volume weights of apply(); 0 in a patch of one. The sums run
  /// in particle order.
  void shift_mean_stress(const std::vector<long long>& patch, long long patches, const double* V,
                         const Mat<D>* sigma, double* shift, int n);

private:
  void reserve(long long patches);
  void clear(const std::vector<long long>& patch, int n); ///< zero the sums patch[0 .. n) touched
  std::vector<double> weighted_, weight_; ///< sum V dJ (or V tr sigma) and sum V per patch (zero between calls)
  std::vector<int> count_;                ///< particles per patch (zero between calls)
  std::vector<double> dJ_;                ///< dJ_p of the current call
};

/// The engine's F-bar state: each particle's patch (docs/theory.md sect.
/// 9.8) and the averaged H_p of the current pass.
template <int D> struct FbarState {
  std::vector<long long> patch; ///< each particle's patch
  long long patches = 0;
  PatchAverage<D> average;
  AlignedVector<Mat<D>> H; ///< the averaged H_p of the current pass
  bool ready = false;      ///< the current pass reads H
  std::vector<double> shift; ///< mbar_c - m_p of the particles' stresses (shift_mean_stress)
  NodalAverage<D> nodal;     ///< the sums of Volumetric::fbar_nodal

  /// The internal forces' mean-stress shifts (PatchAverage::shift_mean_stress)
  /// of the stresses and volumes in P, on the patches of this step; null in 1D.
  const double* mean_stress_shift(const Particles<D>& P);
  /// The same for Volumetric::fbar_nodal (NodalAverage::shift_mean_stress) on
  /// the rows of `table` over `nodes` nodes; null in 1D.
  const double* nodal_mean_stress_shift(const Particles<D>& P, const BasisTable<D>& table, int nodes);
};

extern template class PatchAverage<1>;
extern template class PatchAverage<2>;
extern template class PatchAverage<3>;
extern template class NodalAverage<1>;
extern template class NodalAverage<2>;
extern template class NodalAverage<3>;
extern template struct FbarState<1>;
extern template struct FbarState<2>;
extern template struct FbarState<3>;

} // namespace otmpm
