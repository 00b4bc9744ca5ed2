#pragma once
/// \file probe_series.hpp
/// The probes of a run (internal to run/).
#include "otmpm/distributed/global_view.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/reference/exact.hpp"
#include "otmpm/run/output_time.hpp"
#include "otmpm/run/run.hpp"

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace otmpm {

/// Records the probes of output.probes: at every output time the position,
/// velocity and stress of each probe's particle (/probes/NAME), and, with an
/// exact solution, the history error of its velocity (docs/theory.md eq.
/// 12.2, history_error_NAME).
template <int D> class ProbeSeries {
public:
  ProbeSeries(const Scene& scene, const distributed::GlobalView<D>& view, const Particles<D>& P,
              const ExactSolution<D>* exact)
      : view_(view), exact_(exact) {
    for (const ProbeSection& pr : scene.output.probes) probes_.push_back({pr.name, particle(P, pr), 0.0, 0});
  }

  /// Each probe's x, v and stress at time t (on every rank), adding to its history error.
  Samples sample(double t) {
    Samples samples;
    for (Probe& pr : probes_) {
      const auto r = view_.row(pr.particle); // its values on every rank
      if (exact_) {
        pr.sum_sq += (r.v - exact_->velocity(r.X, t)).squaredNorm();
        ++pr.samples;
      }
      std::vector<double> x(r.x.data(), r.x.data() + D), v(r.v.data(), r.v.data() + D);
      std::vector<double> sig(r.sigma.data(), r.sigma.data() + D * D);
      samples.push_back({pr.name, {{"x", x}, {"v", v}, {"stress", sig}}});
    }
    return samples;
  }

  void layout(std::vector<HistoryLayout>& h) const {
    for (const Probe& pr : probes_) h.push_back({pr.name, true, {"x", "v", "stress"}});
  }

  void save(StateGroup& g) const {
    StateArray<double>& sum_sq = g.real_arrays["probe_sum_sq"];
    StateArray<std::int64_t>& samples = g.integer_arrays["probe_samples"];
    for (const Probe& pr : probes_) {
      sum_sq.values.push_back(pr.sum_sq);
      samples.values.push_back(pr.samples);
    }
  }

  void restore(const StateGroup& g) {
    const auto& sum_sq = g.real_array("probe_sum_sq", probes_.size(), 1).values;
    const auto& samples = g.integer_array("probe_samples", probes_.size(), 1).values;
    for (std::size_t i = 0; i < probes_.size(); ++i) {
      probes_[i].sum_sq = sum_sq[i];
      probes_[i].samples = static_cast<int>(samples[i]);
    }
  }

  /// history_error_NAME of each probe that was sampled against an exact solution.
  void summarize(RunSummary& s) const {
    for (const Probe& pr : probes_)
      if (exact_ && pr.samples > 0) s.errors["history_error_" + pr.name] = std::sqrt(pr.sum_sq / pr.samples);
  }

private:
  struct Probe {
    std::string name;
    long long particle; ///< global id
    double sum_sq;
    int samples;
  };

  /// The (global) particle a probe follows: the leftmost/rightmost by initial
  /// position (ties: lowest index) or the one nearest to a point.
  long long particle(const Particles<D>& P, const ProbeSection& probe) const {
    Vec<D> at;
    for (int k = 0; k < D; ++k) at[k] = probe.at[k];
    return view_.best([&](int p) {
      return probe.particle == "leftmost"    ? P.X[p][0]
             : probe.particle == "rightmost" ? -P.X[p][0]
                                             : (P.X[p] - at).norm();
    });
  }

  const distributed::GlobalView<D>& view_;
  const ExactSolution<D>* exact_;
  std::vector<Probe> probes_;
};

} // namespace otmpm
