#pragma once
/// \file lme_lattice.hpp
/// LME on an untouched Cartesian lattice, factorised over the axes
/// (docs/theory.md sect. 4.7). With the isotropic Gaussian prior the weight
/// of node I = (i_0, ..., i_{D-1}) is a product of one factor per axis,
///
///     p_I = w_I exp(lambda . (x - x_I)) = prod_k exp(-beta dx_k^2 + lambda_k dx_k),
///     dx_k = x_k - X_k(i_k),
///
/// so a Newton evaluation takes the exponentials of the few lattice lines
/// around x (about 5 per axis) instead of one per support node (13 in 2D,
/// 41 in 3D at gamma_lme = 3), and the sums Z, r and J of molinos eqs. 38-40
/// are taken row by row: the support, a ball, cuts every lattice row along
/// axis 0 in one interval, whose sums of p, p dx_0 and p dx_0^2 carry the
/// row's factor of the other axes once. The same nodes (up to the rounding
/// of a node at the cut-off), the same Newton criterion and the same
/// closed-form gradient as the general solver (lme.cpp); the weights differ
/// by rounding: a product of D exponentials instead of the exponential of
/// a sum, and a recurrence that takes the lattice spacing for the
/// differences of the stored coordinates (relative ~1e-16 |X| / h).
/// Internal to the max-ent basis and its tests.
#include "otmpm/basis/lme.hpp"

#include <vector>

namespace otmpm::maxent {

/// Widest box of lattice lines per axis that the factorised path takes:
/// the lines within R of the point, at most 2 R / h + 1 (gamma_lme = 3 at
/// tolerance 1e-6: 4 or 5; 16 lines reach down to gamma_lme ~ 0.25).
inline constexpr int kLatticeMaxSpan = 16;
/// The factorised path takes a point while |lambda| R <= kLatticeMaxExponent,
/// |lambda|^2 / (4 beta) <= kLatticeMaxExponent2 and ln(1/tol) <=
/// kLatticeMaxExponent2. Every line of the box lies within R of x on its
/// axis, so a factor e_k(i) lies between exp(-ln(1/tol) - |lambda_k| R) >=
/// e^-330 and exp(lambda_k^2 / 4 beta) (the maximum over dx of -beta dx^2 +
/// lambda_k dx) <= e^300 over all axes together; a weight p_I (one factor
/// per axis, D <= 3, and in the support beta |dx|^2 <= ln(1/tol)) is at
/// least exp(-ln(1/tol) - |lambda| R) >= e^-330, Z at most 4096 e^300, so
/// N_I = p_I / Z >= e^-639 > 0 and nothing overflows: no test per node.
/// The recurrence's ratios g_i are ratios of two such factors, within
/// e^(+-630); kappa = exp(-2 beta h_k^2) enters only where a box has 3
/// lines or more, i.e. R >= h_k, beta h_k^2 <= ln(1/tol) <= 300. (The sums
/// of p dx^2 also assume lengths in ordinary units: |dx| <= R far below
/// 1e8.)
/// Interior points have |lambda| R of a few units; beyond, the general
/// solver (shifted exponents) takes them.
inline constexpr double kLatticeMaxExponent = 30.0;
inline constexpr double kLatticeMaxExponent2 = 300.0;

/// The converged multiplier of lattice_solve and what the caller needs of it.
template <int D> struct LatticeSolve {
  Vec<D> lambda = Vec<D>::Zero();
  Mat<D> J_inv = Mat<D>::Zero(); ///< J^{-1} at lambda (grad N_I and the multiplier's slope)
  Vec<D> r = Vec<D>::Zero();     ///< the residual at lambda (|r| <= set.residual_tolerance)
  int iterations = 0;            ///< Newton steps taken
};

/// Where lattice_solve writes the stencil: straight to node/N/dN when they
/// are set and the support fits in their `room` entries (a table row), else
/// into `stencil` (sized to the support). On return `size` is the support's
/// size and `in_place` says which was written.
template <int D> struct RowTarget {
  Stencil<D>* stencil = nullptr;
  int* node = nullptr;
  double* N = nullptr;
  Vec<D>* dN = nullptr;
  int room = 0;
  int size = 0;
  bool in_place = false;
  /// Sets size = n and in_place (a row is set and n fits in its room) and
  /// points node, N, dN at where the n entries go: the row, or *stencil
  /// sized to n.
  void place(int n, int*& node_out, double*& N_out, Vec<D>*& dN_out) {
    in_place = node && n <= room;
    size = n;
    node_out = node, N_out = N, dN_out = dN;
    if (in_place) return;
    const auto count = static_cast<std::size_t>(n);
    if (stencil->node.size() != count) stencil->node.resize(count);
    if (stencil->N.size() != count) stencil->N.resize(count);
    if (stencil->dN.size() != count) stencil->dN.resize(count);
    node_out = stencil->node.data(), N_out = stencil->N.data(), dN_out = stencil->dN.data();
  }
};

/// LME with the isotropic Gaussian prior `prior` (support radius R =
/// set.support_radius) at x on the lattice `axes`, warm-started at lambda0:
/// gathers the support (node I kept when |x - x_I| <= R, the general
/// path's test up to the rounding of a node at the cut-off), takes full
/// Newton steps s = -J^{-1} r while |s| R <= kSafeExponentChange (no exponent
/// changes by more, so the Armijo condition holds without a line search)
/// until |r| <= set.residual_tolerance, and writes the stencil to `out`
/// (node ids ascending; grad N_I = -N_I J^{-1} (xbar - x_I)). Returns false,
/// with `res` unspecified and nothing written, when the point needs the
/// general solver: x outside the lattice's box, a support wider than
/// kLatticeMaxSpan nodes on an axis or of fewer than D + 1 nodes, lambda
/// or tol beyond the bounds of kLatticeMaxExponent, a step that would need
/// the line search, a singular J (as kSingularHessian) or
/// set.max_iterations reached.
template <int D>
bool lattice_solve(const LatticeAxes<D>& axes, const GaussianPrior<D>& prior, const NewtonSettings& set,
                   const Vec<D>& x, const Vec<D>& lambda0, RowTarget<D>& out, LatticeSolve<D>& res);

/// lattice_solve into a Stencil (its node, N and dN sized to the support).
template <int D>
bool lattice_solve(const LatticeAxes<D>& axes, const GaussianPrior<D>& prior, const NewtonSettings& set,
                   const Vec<D>& x, const Vec<D>& lambda0, Stencil<D>& out, LatticeSolve<D>& res) {
  RowTarget<D> target;
  target.stencil = &out;
  return lattice_solve<D>(axes, prior, set, x, lambda0, target, res);
}

} // namespace otmpm::maxent
