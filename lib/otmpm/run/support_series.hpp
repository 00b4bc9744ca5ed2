#pragma once
/// \file support_series.hpp
/// The support diagnostics of a run (internal to run/).
#include "otmpm/engine/engine.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/run/output_time.hpp"
#include "otmpm/run/run.hpp"

#include <array>
#include <vector>

namespace otmpm {

/// Records where max-ent supports degenerated in `ul` mode (docs/theory.md
/// sect. 4.8): the evaluations since t = 0 that needed a wider support
/// (widened_supports) and the points moved into their support's hull
/// (moved_points), over every rank and across restarts - the series
/// /diagnostics and the run's summary. Off unless the nodes move and the
/// family searches its support. The summary of a run whose nodes move also
/// gives node_resets: how many times the nodes were laid out anew since
/// t = 0 (docs/theory.md sect. 3; a checkpoint carries the count).
template <int D> class SupportSeries {
public:
  explicit SupportSeries(const Engine<D>& e) : e_(e) {}

  bool active() const { return e_.mode().nodes_move() && e_.basis().search_radius() > 0.0; }

  /// The columns of /diagnostics now (collective; empty when not active()).
  SeriesSample sample() const {
    if (!active()) return {};
    const auto c = counts();
    return {{"widened_supports", c[0]}, {"moved_points", c[1]}};
  }

  void layout(std::vector<HistoryLayout>& h) const {
    if (active()) h.push_back({"diagnostics", false, {"widened_supports", "moved_points"}});
  }

  void save(StateGroup& g) const {
    if (!active()) return;
    const auto c = counts();
    g.reals["widened_supports"] = c[0];
    g.reals["moved_points"] = c[1];
  }

  /// The counts before the checkpoint (this process' basis counts from 0).
  void restore(const StateGroup& g) {
    if (g.reals.count("widened_supports")) before_ = {g.real("widened_supports"), g.real("moved_points")};
  }

  void summarize(RunSummary& s) const {
    const SeriesSample c = sample();
    if (!c.empty()) s.diagnostics = {c.begin(), c.end()};
    if (e_.mode().nodes_move()) s.diagnostics["node_resets"] = static_cast<double>(e_.node_resets());
  }

private:
  std::array<double, 2> counts() const {
    std::array<double, 2> c{static_cast<double>(e_.basis().widened_supports()),
                            static_cast<double>(e_.basis().moved_points())};
    if (Distribution<D>* d = e_.distribution()) d->sum(c);
    return {before_[0] + c[0], before_[1] + c[1]};
  }

  const Engine<D>& e_;
  std::array<double, 2> before_{}; ///< the counts of the run before its checkpoint (a restart)
};

} // namespace otmpm
