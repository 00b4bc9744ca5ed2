#pragma once
/// \file side_walls.hpp
/// A plane-strain body between two side walls (a channel's, normal to the
/// out-of-plane axis z): each wall presses on the body with its normal
/// stress -sigma_zz and resists its in-plane motion by Coulomb friction
/// (docs/theory.md sect. 6.3). Over the channel's width W the two walls
/// give particle p the force
///   f_p = -min(2 mu_w max(-sigmabar_zz,p, 0) V_p / W, m_p |v_p| / dt) v_p / |v_p|   (eq. 6.7)
/// - the wall traction mu_w |sigma_zz| on each face of its slice V_p / W,
/// capped at what stops the particle within the step (a Coulomb force
/// cannot reverse the motion it resists). The walls press with the body's
/// stress, not a material point's: sigmabar_zz,p is sigma_zz averaged at the
/// nodes of p's basis and interpolated back (as the nodal F-bar mean,
/// eq. 9.11). A point's own sigma_zz carries the sub-cell oscillations the
/// grid's forces do not see; eq. 6.7 would turn them into forces (an
/// elastic block sliding between the walls with musl and the linear basis
/// stopped within 0.2 s, 3.4 or more times as fast as the static pressure
/// makes it; 1.97 times with the nodal mean; sect. 6.3 says why). The
/// engine adds f_p to the particle's external force and books its work,
/// -f_p . (x_p^{n+1} - x_p^n), as friction (eq. 6.8; engine/channel_walls.hpp,
/// internal).
#include "otmpm/core.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace otmpm {

/// The side walls of a channel: distance `width` W [m] between them and
/// their Coulomb friction mu_w with the material.
struct SideWalls {
  double width = 0.0;
  double friction = 0.0;

  /// Eq. 6.7 for one particle: mass m, volume V, velocity v, out-of-plane
  /// stress sigma_zz, step dt.
  template <int D> Vec<D> force(double m, double V, const Vec<D>& v, double sigma_zz, double dt) const {
    const double speed = v.norm();
    if (!(speed > 0.0)) return Vec<D>::Zero();
    const double slide = 2.0 * friction * std::max(-sigma_zz, 0.0) * V / width;
    return (-std::min(slide, m * speed / dt) / speed) * v;
  }

  /// Why a channel refuses saturated bodies (the scene check and the engine
  /// say it in the same words).
  static std::string refusal_saturated() {
    return "[channel]: side walls are not available with saturated bodies (the liquid phase's share of the "
           "wall pressure is not modelled)";
  }
};

} // namespace otmpm
