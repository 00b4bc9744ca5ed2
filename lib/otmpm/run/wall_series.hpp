#pragma once
/// \file wall_series.hpp
/// The walls' series of a run (internal to run/).
#include "otmpm/engine/engine.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/run/output_time.hpp"

#include <string>
#include <vector>

namespace otmpm {

/// Records /walls/NAME at every output time: the impulse J the wall gave
/// the body since t = 0 (J += sum_I m_I dv_I, docs/theory.md sect. 6.1) and
/// the mean force (J - J_prev) / (t - t_prev) since the previous sample
/// (zero at the first).
template <int D> class WallSeries {
public:
  explicit WallSeries(const Engine<D>& e) : e_(e) {}

  Samples sample(double t) {
    const auto& walls = e_.walls();
    Samples out;
    last_.resize(walls.size(), Vec<D>::Zero());
    for (std::size_t w = 0; w < walls.size(); ++w) {
      const Vec<D>& J = e_.wall_impulse()[w];
      const Vec<D> F = t > time_ ? Vec<D>((J - last_[w]) / (t - time_)) : Vec<D>::Zero();
      out.push_back({walls[w].name,
                     {{"force", std::vector<double>(F.data(), F.data() + D)},
                      {"impulse", std::vector<double>(J.data(), J.data() + D)}}});
      last_[w] = J;
    }
    time_ = t;
    return out;
  }

  void layout(std::vector<HistoryLayout>& h) const {
    for (const Wall<D>& w : e_.walls()) h.push_back({w.name, true, {"force", "impulse"}, "walls"});
  }

  void save(StateGroup& g) const {
    g.reals["wall_time"] = time_;
    StateArray<double>& walls = g.real_arrays["wall_last_impulse"];
    walls.cols = D;
    for (const Vec<D>& J : last_) walls.values.insert(walls.values.end(), J.data(), J.data() + D);
  }

  void restore(const StateGroup& g) {
    time_ = g.real("wall_time");
    const auto& walls = g.real_array("wall_last_impulse", e_.walls().size(), D).values;
    last_.assign(e_.walls().size(), Vec<D>::Zero());
    for (std::size_t w = 0; w < last_.size(); ++w)
      for (int k = 0; k < D; ++k) last_[w][k] = walls[w * D + static_cast<std::size_t>(k)];
  }

private:
  const Engine<D>& e_;
  AlignedVector<Vec<D>> last_; ///< wall impulses at the previous sample
  double time_ = 0.0;          ///< time of the previous sample
};

} // namespace otmpm
