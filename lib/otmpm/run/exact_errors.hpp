#pragma once
/// \file exact_errors.hpp
/// A run's errors against its exact solution at t_end (internal to run/).
#include "otmpm/distributed/global_view.hpp"
#include "otmpm/engine/engine.hpp"
#include "otmpm/engine/two_phase.hpp"
#include "otmpm/reference/exact.hpp"
#include "otmpm/run/run_common.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace otmpm {

/// Records the errors of a finished run against its [reference] solution:
/// rms_velocity_error, rms_displacement_error and rms_stress_error (docs/theory.md
/// eq. 12.1 over all particles) and, for saturated bodies, the pore pressure's.
template <int D> class ExactErrors {
public:
  ExactErrors(const Engine<D>& e, const distributed::GlobalView<D>& view, const ExactSolution<D>& exact)
      : e_(e), view_(view), exact_(exact) {}

  /// The errors into s.errors; a state whose error overflows ends the run as unstable instead.
  void summarize(RunSummary& s) const {
    std::vector<double> ev, eu, es;
    squared_errors(ev, eu, es);
    // A finite state that overflows against the exact solution (a value near 1e300 written by hand through
    // a view after the last step, which checked the state) has no error: it ends the run as unstable.
    bool overflow = false;
    for (const std::vector<double>* e : {&ev, &eu, &es})
      overflow = overflow || !std::all_of(e->begin(), e->end(), [](double x) { return std::isfinite(x); });
    if (view_.max(overflow ? 1.0 : 0.0) > 0.0) {
      s.status = "unstable: " + diagnosis("the state is too far from the exact solution for its error to be a "
                                          "finite number",
                                          e_.steps(), e_.time());
      s.exit_code = 1;
      return;
    }
    s.errors["rms_velocity_error"] = view_.rms(ev);
    s.errors["rms_displacement_error"] = view_.rms(eu);
    s.errors["rms_stress_error"] = view_.rms(es);
    pore_pressure_errors(s);
  }

private:
  /// |q_p - q_exact(X_p, t)|^2 of the velocity, displacement and stress of every particle.
  void squared_errors(std::vector<double>& ev, std::vector<double>& eu, std::vector<double>& es) const {
    const Particles<D>& P = e_.particles();
    const double t = e_.time();
    for (int p = 0; p < P.size(); ++p) {
      ev.push_back((P.v[p] - exact_.velocity(P.X[p], t)).squaredNorm());
      eu.push_back((P.x[p] - P.X[p] - exact_.displacement(P.X[p], t)).squaredNorm());
      es.push_back((P.sigma[p] - exact_.stress(P.X[p], t)).squaredNorm());
    }
  }

  /// A saturated body against an exact pore pressure: rms_pore_pressure_error
  /// (eq. 12.1 over the saturated particles) and max_pore_pressure_error, the
  /// largest |p_p - p(X_p, t)|.
  void pore_pressure_errors(RunSummary& s) const {
    const TwoPhase<D>* liquid = e_.settings().two_phase.get();
    if (!liquid || !exact_.has_pore_pressure()) return;
    const Particles<D>& P = e_.particles();
    const StateField& pressure = *P.find_state(kPorePressureField);
    std::vector<double> ep;
    double largest = 0.0;
    for (int p = 0; p < P.size(); ++p) {
      if (!liquid->fluid(P.material[p])) continue;
      const double d = pressure.values[static_cast<std::size_t>(p)] - exact_.pore_pressure(P.X[p], e_.time());
      ep.push_back(d * d);
      largest = std::max(largest, std::abs(d));
    }
    if (ep.empty()) return;
    s.errors["rms_pore_pressure_error"] = view_.rms(ep);
    s.errors["max_pore_pressure_error"] = view_.max(largest);
  }

  const Engine<D>& e_;
  const distributed::GlobalView<D>& view_;
  const ExactSolution<D>& exact_;
};

} // namespace otmpm
