#pragma once
/// \file two_phase_scatter.hpp
/// The liquid's particle-to-node sums (TwoPhase, docs/theory.md sect. 15):
/// on their own (musl's re-projection), or beside the engine's sums in the
/// engine's pass at the start of a step (Engine::to_nodes with
/// ToNodes::liquid), so that both phases take one traversal of the basis
/// table. Each field is summed in the same order either way (BlockedScatter:
/// particle order in a block, then block order): the same bits. Internal to
/// the engine.
#include "otmpm/engine/engine.hpp"
#include "otmpm/engine/scatter.hpp"
#include "otmpm/engine/two_phase.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace otmpm {

/// Per-node partial sums of the liquid: m_w, the drag coefficient Q, the
/// momentum q_w, the liquid's pressure force f_w = sum V n p grad N and the
/// pore pressure's force on the mixture f_p = sum V p grad N (eq. 15.4), and
/// the surface vectors G = sum V grad N, G_n = sum n V grad N (Drain).
template <int D> struct LiquidSums {
  double m = 0.0, drag = 0.0;
  Vec<D> q = Vec<D>::Zero(), fw = Vec<D>::Zero(), fp = Vec<D>::Zero(), g = Vec<D>::Zero(), gn = Vec<D>::Zero();
};

/// Per-node partial sums of both phases in one pass: the engine's (the
/// solid's mass, momentum and force) and the liquid's.
template <int D> struct MixtureSums {
  NodeSums<D> solid;
  LiquidSums<D> liquid;
};

/// The lattice cell of x as one number: the node number of its lower corner
/// (clamped as CartesianGrid::cell_of clamps; a NaN is caught after the step).
template <int D>
inline long long lattice_cell(const Vec<D>& x, const Vec<D>& lower, const Vec<D>& inverse, const Index<D>& cells) {
  long long id = 0;
  for (int k = D - 1; k >= 0; --k) {
    // clamped first, then truncated: floor's cell without a call to floor
    const double c = (x[k] - lower[k]) * inverse[k];
    const double clamped = std::isnan(c) ? 0.0 : std::clamp(c, 0.0, cells[k] - 1.0);
    id = id * (cells[k] + 1LL) + static_cast<long long>(clamped);
  }
  return id;
}

template <int D>
template <bool MomentumOnly, class Sum>
void TwoPhase<D>::with_sums(const Engine<D>& e, Sum&& sum) {
  const Particles<D>& P = e.particles();
  const BasisTable<D>& table = e.table();
  struct Payload {
    double m = 0.0, drag = 0.0, Vp = 0.0, Vnp = 0.0, V = 0.0, nV = 0.0;
    Vec<D> q = Vec<D>::Zero();
  };
  // Plain pointers by value: the sums' stores cannot alias them.
  const int* material = P.material.data();
  const double *V = P.V.data(), *V0 = P.V0.data(), *pressure = P.find_state(kPorePressureField)->values.data();
  const double* velocity = P.find_state(kLiquidVelocityField)->values.data();
  const PoreFluid* const* fluid_of = fluids_.data();
  auto prep = [=](int p) __attribute__((always_inline)) { // inlined in the scatter's loop (as the engine's)
    Payload w;
    const PoreFluid* f = fluid_of[material[p]];
    if (!f) return w;
    const double nV = V[p] - (1.0 - f->porosity) * V0[p]; // the pores' volume n V
    w.m = f->density * nV;
    w.q = w.m * Eigen::Map<const Vec<D>>(velocity + static_cast<std::size_t>(p) * D);
    if constexpr (MomentumOnly) return w;
    w.drag = f->drag(nV / V[p]) * V[p];
    w.Vp = V[p] * pressure[p];
    w.Vnp = nV * pressure[p];
    w.V = V[p], w.nV = nV;
    return w;
  };
  auto add =
      [](LiquidSums<D> & acc, double N, const Vec<D>& dN, const Payload& w) __attribute__((always_inline)) {
    acc.q += N * w.q;
    if constexpr (MomentumOnly) return;
    acc.m += N * w.m;
    acc.drag += N * w.drag;
    acc.fw += w.Vnp * dN;
    acc.fp += w.Vp * dN;
    acc.g += w.V * dN;
    acc.gn += w.nV * dN;
  };
  auto merge = [&](int I, const LiquidSums<D>& acc) {
    qw_[I] += acc.q;
    if constexpr (MomentumOnly) return;
    mw_[I] += acc.m, drag_[I] += acc.drag, fw_[I] += acc.fw, fp_[I] += acc.fp, g_[I] += acc.g, gn_[I] += acc.gn;
  };
  auto clear = [&](int I0, int I1) {
    std::fill(qw_.begin() + I0, qw_.begin() + I1, Vec<D>::Zero());
    if constexpr (MomentumOnly) return;
    std::fill(mw_.begin() + I0, mw_.begin() + I1, 0.0);
    std::fill(drag_.begin() + I0, drag_.begin() + I1, 0.0);
    std::fill(fw_.begin() + I0, fw_.begin() + I1, Vec<D>::Zero());
    std::fill(fp_.begin() + I0, fp_.begin() + I1, Vec<D>::Zero());
    std::fill(g_.begin() + I0, g_.begin() + I1, Vec<D>::Zero());
    std::fill(gn_.begin() + I0, gn_.begin() + I1, Vec<D>::Zero());
  };
  if constexpr (!MomentumOnly) width_ = linear_row_width(table); // the table of this step
  sum(prep, add, merge, clear);
}

template <int D>
template <bool MomentumOnly, class Update>
void TwoPhase<D>::scatter(const Engine<D>& e, Update&& update) {
  with_sums<MomentumOnly>(e, [&](auto& prep, auto& add, auto& merge, auto& clear) {
    scatter_->invalidate(width_);
    scatter_->run(e.table(), static_cast<int>(mw_.size()), update, prep, add, merge, clear);
  });
}

template <int D>
template <class Update, class Prep, class Add, class Merge, class Clear>
void TwoPhase<D>::scatter_with(const Engine<D>& e, Update&& update, Prep&& prep, Add&& add, Merge&& merge,
                               Clear&& clear) {
  with_sums<false>(e, [&](auto& liquid_prep, auto& liquid_add, auto& liquid_merge, auto& liquid_clear) {
    // Copies of the adds' and preps' closures (pointers by value): the sums' stores cannot alias them.
    auto prep_both = [prep, liquid_prep](int p) __attribute__((always_inline)) {
      return std::pair(prep(p), liquid_prep(p));
    };
    auto add_both = [ add, liquid_add ](MixtureSums<D> & acc, double N, const Vec<D>& dN, const auto& w)
        __attribute__((always_inline)) {
      add(acc.solid, N, dN, w.first);
      liquid_add(acc.liquid, N, dN, w.second);
    };
    auto merge_both = [&](int I, const MixtureSums<D>& acc) { merge(I, acc.solid), liquid_merge(I, acc.liquid); };
    auto clear_both = [&](int I0, int I1) { clear(I0, I1), liquid_clear(I0, I1); };
    mixture_->invalidate(width_);
    mixture_->run(e.table(), static_cast<int>(mw_.size()), update, prep_both, add_both, merge_both, clear_both);
  });
  summed_ = true;
}

} // namespace otmpm
