/// \file volumetric.cpp
/// The F-bar patch average (volumetric.hpp).
#include "otmpm/engine/volumetric.hpp"

#include "otmpm/engine/distribution.hpp"
#include "otmpm/parallel.hpp"

#include <array>
#include <cmath>

namespace otmpm {

template <int D>
void PatchAverage<D>::apply(const std::vector<long long>& patch, long long patches, const double* V, Mat<D>* H,
                            int n) {
  if constexpr (D == 1) {
    return; // one axis: dFbar = dF (the patch volume change is the particle's own)
  } else {
    reserve(patches);
    dJ_.resize(static_cast<std::size_t>(n));
    parallel_for(n, [&](long long p) { dJ_[p] = (Mat<D>::Identity() + H[p]).determinant(); });
    for (int p = 0; p < n; ++p) { // in particle order: the sums do not depend on the threads
      if (!(dJ_[p] > 0.0)) continue;
      weighted_[patch[p]] += V[p] * dJ_[p];
      weight_[patch[p]] += V[p];
      ++count_[patch[p]];
    }
    parallel_for(n, [&](long long p) {
      if (!(dJ_[p] > 0.0) || count_[patch[p]] < 2) return; // a patch of one: its own dF
      const double ratio = weighted_[patch[p]] / weight_[patch[p]] / dJ_[p];
      const double s = D == 2 ? std::sqrt(ratio) : std::cbrt(ratio);
      // s (I + H) - I without forming I + H: exact for s = 1, no cancellation for small H.
      H[p] = s * H[p];
      H[p].diagonal().array() += s - 1.0;
    });
    clear(patch, n);
  }
}

template <int D>
void PatchAverage<D>::shift_mean_stress(const std::vector<long long>& patch, long long patches, const double* V,
                                        const Mat<D>* sigma, double* shift, int n) {
  reserve(patches);
  for (int p = 0; p < n; ++p) { // in particle order: the sums do not depend on the threads
    weighted_[patch[p]] += V[p] * sigma[p].trace();
    weight_[patch[p]] += V[p];
    ++count_[patch[p]];
  }
  parallel_for(n, [&](long long p) {
    const long long c = patch[p];
    shift[p] = count_[c] < 2 ? 0.0 : (weighted_[c] / weight_[c] - sigma[p].trace()) / D;
  });
  clear(patch, n);
}

template <int D> void PatchAverage<D>::reserve(long long patches) {
  if (static_cast<long long>(weight_.size()) >= patches) return;
  weight_.assign(static_cast<std::size_t>(patches), 0.0);
  weighted_.assign(static_cast<std::size_t>(patches), 0.0);
  count_.assign(static_cast<std::size_t>(patches), 0);
}

template <int D> void PatchAverage<D>::clear(const std::vector<long long>& patch, int n) {
  for (int p = 0; p < n; ++p) {
    weighted_[patch[p]] = weight_[patch[p]] = 0.0;
    count_[patch[p]] = 0;
  }
}

template <int D>
template <class Use>
void NodalAverage<D>::smooth(const BasisTable<D>& table, int nodes, const double* V, double* value, int n,
                             Use&& use) {
  weighted_.assign(static_cast<std::size_t>(nodes), 0.0);
  weight_.assign(static_cast<std::size_t>(nodes), 0.0);
  for (int p = 0; p < n; ++p) { // in particle order: the sums do not depend on the threads
    if (!use(p)) continue;
    for (int e = table.begin(p); e < table.end(p); ++e) {
      const double w = table.N[e] * V[p];
      weighted_[table.node[e]] += w * value[p];
      weight_[table.node[e]] += w;
    }
  }
  if (ranks_)
    ranks_->sum_nodal(
        std::array<NodalArray, 2>{NodalArray{weighted_.data(), 1}, NodalArray{weight_.data(), 1}});
  parallel_for(n, [&](long long p) {
    double sum = 0.0, norm = 0.0;
    for (int e = table.begin(static_cast<int>(p)); e < table.end(static_cast<int>(p)); ++e) {
      const int I = table.node[e];
      if (!(weight_[I] > 0.0)) continue;
      sum += table.N[e] * weighted_[I] / weight_[I];
      norm += table.N[e];
    }
    if (norm > 0.0) value[p] = sum / norm;
  });
}

template <int D>
void NodalAverage<D>::apply(const BasisTable<D>& table, int nodes, const double* V, Mat<D>* H, int n) {
  if constexpr (D == 1) {
    return; // one axis: dFbar = dF, as the cell patches
  } else {
    value_.resize(static_cast<std::size_t>(n));
    parallel_for(n, [&](long long p) { value_[p] = (Mat<D>::Identity() + H[p]).determinant(); });
    dJ_ = value_; // smooth replaces value_ by dJbar
    const std::vector<double>& dJ = dJ_;
    smooth(table, nodes, V, value_.data(), n, [&](int p) { return dJ[p] > 0.0; });
    parallel_for(n, [&](long long p) {
      if (!(dJ[p] > 0.0)) return;
      const double ratio = value_[p] / dJ[p];
      const double s = D == 2 ? std::sqrt(ratio) : std::cbrt(ratio);
      H[p] = s * H[p]; // s (I + H) - I, as PatchAverage::apply
      H[p].diagonal().array() += s - 1.0;
    });
  }
}

template <int D>
void NodalAverage<D>::shift_mean_stress(const BasisTable<D>& table, int nodes, const double* V,
                                        const Mat<D>* sigma, double* shift, int n) {
  value_.resize(static_cast<std::size_t>(n));
  parallel_for(n, [&](long long p) { value_[p] = sigma[p].trace(); });
  smooth(table, nodes, V, value_.data(), n, [](int) { return true; });
  parallel_for(n, [&](long long p) { shift[p] = (value_[p] - sigma[p].trace()) / D; });
}

template <int D>
void NodalAverage<D>::average(const BasisTable<D>& table, int nodes, const double* V, double* value, int n) {
  smooth(table, nodes, V, value, n, [](int) { return true; });
}

template <int D>
const double* FbarState<D>::nodal_mean_stress_shift(const Particles<D>& P, const BasisTable<D>& table,
                                                    int nodes) {
  if (D == 1) return nullptr;
  shift.resize(static_cast<std::size_t>(P.size()));
  nodal.shift_mean_stress(table, nodes, P.V.data(), P.sigma.data(), shift.data(), P.size());
  return shift.data();
}

template <int D> const double* FbarState<D>::mean_stress_shift(const Particles<D>& P) {
  if (D == 1) return nullptr; // one axis: dFbar = dF, and the forces take sigma_p
  require<std::logic_error>(patch.size() == static_cast<std::size_t>(P.size()),
                            "FbarState::mean_stress_shift: the patches are not those of the particles");
  shift.resize(patch.size());
  average.shift_mean_stress(patch, patches, P.V.data(), P.sigma.data(), shift.data(), P.size());
  return shift.data();
}

template class PatchAverage<1>;
template class PatchAverage<2>;
template class PatchAverage<3>;
template class NodalAverage<1>;
template class NodalAverage<2>;
template class NodalAverage<3>;
template struct FbarState<1>;
template struct FbarState<2>;
template struct FbarState<3>;

} // namespace otmpm
