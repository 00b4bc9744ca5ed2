#pragma once
/// \file energy_series.hpp
/// The energy series of a run (internal to run/).
#include "otmpm/engine/engine.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/run/output_time.hpp"
#include "otmpm/run/run.hpp"

#include <array>
#include <string>
#include <vector>

namespace otmpm {

// A member added to EnergySummary must be saved and restored here.
static_assert(sizeof(EnergySummary) == 4 * sizeof(double), "EnergySummary changed: update the checkpoint");

/// Records the energy balance of docs/theory.md sect. 11: at every output
/// time the series /energy - E's kinetic and strain parts, W_ext, W_R (eq.
/// 11.1), W_p as "dissipated" when a material has internal variables, W_f
/// and W_i as "friction" and "impact" with friction (walls, contact), W_d and
/// W_a as "darcy" and "pressure_average" with a pore liquid, W_v as
/// "relaxation" with a PIC relaxation time - and after
/// every step the run's EnergySummary (max_energy_ratio and energy_drift,
/// eq. 11.2; the impact energy W_i).
template <int D> class EnergySeries {
public:
  explicit EnergySeries(const Engine<D>& e) : e_(e) {}

  /// Adds the engine's current energy balance to the EnergySummary (every step).
  void sample_summary() {
    const EnergyBalance& E = e_.energy();
    summary_.initial = E.initial;
    summary_.sample(E.total() + E.spent(), E.work(), E.balance_error()); // W_p, W_f, W_i, W_d and W_a count as spent energy
  }

  /// The columns of /energy now, in the order the file holds them.
  SeriesSample sample() const {
    const EnergyBalance& E = e_.energy();
    SeriesSample s{{"kinetic", E.kinetic}, {"strain", E.strain}, {"external_work", E.external_work},
                   {"reaction_work", E.reaction_work}};
    if (dissipative()) s.emplace_back("dissipated", E.dissipated);
    if (e_.has_friction()) s.emplace_back("friction", E.friction), s.emplace_back("impact", E.impact);
    if (e_.settings().two_phase) s.emplace_back("darcy", E.darcy), s.emplace_back("pressure_average", E.pressure_average);
    if (relaxes()) s.emplace_back("relaxation", E.relaxation);
    return s;
  }

  /// The history /energy (its columns: those of sample()).
  void layout(std::vector<HistoryLayout>& h) const {
    std::vector<std::string> columns;
    for (const auto& column : sample()) columns.push_back(column.first);
    // Result files written before friction and impacts were booked lack their columns.
    h.push_back({.name = "energy", .probe = false, .fields = columns, .zero_if_absent = {"friction", "impact"}});
  }

  void save(StateGroup& g) const { g.put_reals(fields(summary_)); }
  void restore(const StateGroup& g) { g.get_reals(fields(summary_)); }

  /// The run's EnergySummary and impact energy.
  void summarize(RunSummary& s) const {
    s.energy = summary_;
    s.impact = e_.energy().impact;
  }

private:
  /// True when a material of the run has internal variables (and so may
  /// dissipate energy): the energy series then has a "dissipated" column.
  bool dissipative() const {
    for (int i = 0; i < e_.material_count(); ++i)
      if (!e_.material(i).state().empty()) return true;
    return false;
  }
  /// True when the integrator relaxes the particle velocities (pic_relaxation_time > 0).
  bool relaxes() const {
    const auto& values = e_.settings().parameters.values;
    const auto it = values.find("pic_relaxation_time");
    return it != values.end() && it->second > 0.0;
  }

  /// The members of an EnergySummary (const or not) by checkpoint name.
  template <class S> static auto fields(S& s) {
    return std::array{std::pair{"energy_initial", &s.initial}, std::pair{"max_energy", &s.max_energy},
                      std::pair{"max_work", &s.max_work}, std::pair{"max_balance_error", &s.max_balance_error}};
  }

  const Engine<D>& e_;
  EnergySummary summary_;
};

} // namespace otmpm
