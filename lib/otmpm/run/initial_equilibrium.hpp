#pragma once
/// \file initial_equilibrium.hpp
/// The gravity-loading phase of `simulation.initial_equilibrium`
/// (docs/theory.md sect. 15, "Initial equilibrium"): before t = 0 the
/// bodies are stepped under the scene's loads at t = 0 with Cundall's local
/// non-viscous damping (eq. 15.15) until the residuals (eq. 15.16) have
/// stayed below the tolerance over the window of eq. 15.17 or the phase's
/// time has run; the run then starts from that state.
#include "otmpm/engine/engine.hpp"
#include "otmpm/scene/scene.hpp"

#include <functional>
#include <string>

namespace otmpm {

/// How a gravity-loading phase ended: converged (both residuals below the
/// tolerance at every step over the last window W, eq. 15.17) or out of
/// time, after `steps` steps and `time` seconds, with the last step's
/// residuals: the unbalanced force R_f and the velocity R_v of eq. 15.16.
struct EquilibriumReport {
  bool converged = false;
  long steps = 0;
  double time = 0.0;
  double force_residual = 0.0, velocity_residual = 0.0;
  double window = 0.0; ///< W of eq. 15.17 at the last step: twice the bodies' extent over the wave speed [s]
  double held = 0.0;   ///< how long both residuals had been below the tolerance at the last step [s]
  /// Not converged: the fastest particle at the end, "particle P (body 'NAME') at (x, y): |v| = V".
  std::string fastest;
  /// "converged after N steps (T s): R_f = ..., R_v = ... (tolerance ..., held for W s)" or
  /// "not converged in N steps (T s): ...; what the state was and what to try".
  std::string describe(double tolerance) const;
};

/// The scene the phase steps: `scene` with t_end = the phase's time and its
/// loads held at their values at t = 0 (a ramp's load, rise or plate force
/// absent, the prescribed boundary and wall velocities zero, no initial
/// velocity).
Scene equilibrium_scene(const Scene& scene);

/// Runs the phase of scene.simulation.initial_equilibrium on an engine of
/// equilibrium_scene(scene) and moves its state into `e`, a fresh engine of
/// `scene` (serial): the particles' positions, stresses, pore pressures,
/// deformation gradients and material state (the plastic strain kept, the
/// plastic work zeroed), with the displacements (X_p = x_p), the energy
/// series and the clock starting at zero and the velocities e's initial
/// ones. InstabilityError when the phase becomes unstable; InterruptedError
/// (interrupt_point) when the polled interrupt flag is set during it.
/// `each_step`, when given, sees the report after every step of the phase.
template <int D>
EquilibriumReport settle(const Scene& scene, Engine<D>& e,
                         const std::function<void(const EquilibriumReport&)>& each_step = {});

} // namespace otmpm
