#pragma once
/// \file families.hpp
/// Constructors of the individual basis families; make_basis() dispatches to
/// these by name. Each returns a Basis bound to (and owning) its node set.
#include "otmpm/basis/basis.hpp"

namespace otmpm {

/// Tensor-product hat functions on a Cartesian lattice; isoparametric
/// bilinear/trilinear (Q4/Q8) elements on a perturbed or moved lattice
/// (inverse map by Newton). Requires nodes.grid() (InputError otherwise).
template <int D> std::unique_ptr<Basis<D>> make_linear_basis(NodeSet<D> nodes);

/// Uniform GIMP (Bardenhagen & Kober 2004) with particle half-width
/// `half_width` per axis. Requires an untouched Cartesian lattice and
/// 0 < half_width[k] <= h_k / 2 (InputError otherwise).
template <int D>
std::unique_ptr<Basis<D>> make_ugimp_basis(NodeSet<D> nodes, const Vec<D>& half_width);

/// B-splines of degree 2 or 3 by Cox-de Boor on open knot vectors built from
/// the lattice `grid` (knots at the lattice vertices); the degrees of freedom
/// are the control points at the Greville abscissae. Knot vectors are
/// advected in nodes_moved() (unified approach, wobbes Algorithm 3). InputError
/// for an invalid grid or a degree outside [kMinBsplineDegree, kMaxBsplineDegree].
template <int D>
std::unique_ptr<Basis<D>> make_bspline_basis(const CartesianGrid<D>& grid, int degree);
/// The B-splines of `grid` whose degrees of freedom are only the control
/// points with lattice index in [lo, hi) (a distributed run's window).
template <int D>
std::unique_ptr<Basis<D>> make_bspline_window(const CartesianGrid<D>& grid, int degree, const Index<D>& lo,
                                              const Index<D>& hi);

/// Local max-ent (Arroyo & Ortiz 2006, molinos sect. 2.3), beta = gamma_lme / h^2.
/// InputError unless gamma_lme is finite and > 0, 0 < tolerance < 1, and the
/// Newton options are valid (MaxEntBasis).
template <int D> std::unique_ptr<Basis<D>> make_lme_basis(NodeSet<D> nodes, const BasisOptions& opt);

/// Local max-ent with the box support (lme_box.hpp): the tensor product of
/// 1D LME functions on a lattice, read from a table on an untouched uniform
/// lattice; the same options as make_lme_basis, isotropic metric only.
template <int D> std::unique_ptr<Basis<D>> make_lme_box_basis(NodeSet<D> nodes, const BasisOptions& opt);

/// Max-ent with a cubic-spline prior of radius d_max * h (wobbes sect. 6.3).
/// InputError unless d_max is finite and > 0 and the Newton options are valid.
template <int D> std::unique_ptr<Basis<D>> make_maxent_basis(NodeSet<D> nodes, const BasisOptions& opt);

/// The parameters of lme (gamma_lme, tolerance and the Newton options) and
/// of maxent (d_max and the Newton options): scene keys under [basis].
std::span<const ParameterSpec> lme_parameters();
std::span<const ParameterSpec> maxent_parameters();
/// The nodes of an lme / maxent stencil on a uniform lattice: those in the
/// ball of the support radius (LME: exp(-gamma_lme r^2) >= tolerance;
/// max-ent: d_max), at least 2^dim.
double lme_stencil_nodes(const BasisOptions& o, int dim);
/// The mean support of lme_box on a lattice: (2 R / h)^dim.
double lme_box_stencil_nodes(const BasisOptions& o, int dim);
/// The bytes per particle of lme_box's product rows on a lattice (ProductRows:
/// D (4 + 16 M) + 8, M the lanes of its widest axis box) and its multiplier
/// (D doubles); 0 when it fills a table (a metric other than isotropic, or a
/// support wider than its 1D tables take).
double lme_box_row_bytes(const BasisOptions& o, int dim);
double maxent_stencil_nodes(const BasisOptions& o, int dim);

} // namespace otmpm
