#pragma once
/// \file kinds.hpp
/// The closed set of basis families, listed once: the scene reader takes its
/// choice list and the family's parameters (scene keys under [basis]) from
/// it, the scene writer, `otmpm basis` and the Python package its
/// parameters, the scene validator and the assembler the rules that depend
/// on the family, a distributed run how far a stencil reaches, and
/// make_basis() its constructor. Adding a family means its source, its
/// header (constructor, parameters) and one row in kinds.cpp
/// (docs/architecture.md, "Adding a part").
#include "otmpm/basis/basis.hpp"

#include <span>
#include <string>
#include <string_view>

namespace otmpm {

/// Constructor of a family in D dimensions (families.hpp).
template <int D> using BasisFactory = std::unique_ptr<Basis<D>> (*)(const BasisOptions&, NodeSet<D>);

/// Constructor of a family on a window of a lattice whose points are not
/// the lattice's nodes (B-splines: the control points with lattice index in
/// [lo, hi) on the whole lattice's knot vectors; a distributed run).
template <int D>
using WindowFactory = std::unique_ptr<Basis<D>> (*)(const BasisOptions&, const CartesianGrid<D>& lattice,
                                                    const Index<D>& lo, const Index<D>& hi);

/// Where a family's points sit on a lattice of cells and which of them the
/// stencil of a point in cell c reaches along one axis: the points from
/// c minus `below` to c plus `above`, of (cells + `points_beyond_cells`) per
/// axis, the point of cell c being c plus `shift` (distributed runs: a
/// rank's window of points).
struct LatticeReach {
  int points_beyond_cells = 1; ///< 1: the lattice vertices; B-splines of degree p: p control points
  int shift = 0;
  int below = 0;
  int above = 1;
};

/// The parts of a run that read a basis table in some pass of the step: where
/// none does, a family with compact rows (BasisKind::compact_row_bytes: the
/// lattice rows of `linear`, the product rows of `lme_box`) keeps those
/// instead. One rule for the run (Engine::evaluate_basis) and for the memory
/// estimate made from the scene before it (scene/resources.cpp).
struct TableReaders {
  bool nodes_move = false;      ///< `ul`: the nodes move with the particles
  bool ranks = false;           ///< more than one process: the halo's support check
  bool contact = false;         ///< body contact: each body's own rows
  bool two_phase = false;       ///< saturated bodies
  bool fbar = false;            ///< a volumetric treatment (F-bar, either form): cell patches
  bool consistent_mass = false; ///< the consistent mass matrix and its solve
  bool side_walls = false;      ///< the channel's side walls ([channel])
  /// True when no pass of the step reads a table.
  bool none() const {
    return !(nodes_move || ranks || contact || two_phase || fbar || consistent_mass || side_walls);
  }
};

/// One basis family as the scene names it (`basis.kind`) and the facts about
/// it that the rest of otmpm needs.
struct BasisKind {
  std::string_view name;
  std::string_view description;
  /// Needs a structured node set (a lattice: cartesian or perturbed grid).
  bool needs_lattice = true;
  /// Needs an untouched Cartesian lattice: no perturbation, no node motion (uGIMP).
  bool cartesian_only = false;
  /// A B-spline family (the unified integrator needs one).
  bool bspline = false;
  /// On a mesh's vertices (a body with nodes = "mesh") it takes the mesh's
  /// own elements as its shape functions (linear: make_element_basis).
  bool mesh_elements = false;
  /// Uses the size of the particles (uGIMP: half-width l_p = h / (2 n_ppc) per axis).
  bool particle_size = false;
  /// Searches the nodes within a radius (Verlet lists) and keeps a Lagrange
  /// multiplier per particle (the max-ent families).
  bool searches_nodes = false;
  /// Adapts the locality of its prior to the deformation or the node
  /// spacing (`basis.metric` other than "isotropic"; LME).
  bool adapts_metric = false;
  /// Expected nodes in one particle's stencil on a uniform lattice (for the
  /// memory estimate of `otmpm run --check`).
  double (*stencil_nodes)(const BasisOptions&, int dim) = nullptr;
  /// Bytes per particle of the rows the family keeps instead of a basis
  /// table on an untouched lattice, in a run whose every pass takes them
  /// (TableReaders::none()), for the memory estimate; null, or 0 for the
  /// given options: the family fills a table.
  double (*compact_row_bytes)(const BasisOptions&, int dim) = nullptr;
  /// Its reach along an axis of spacing h in `dim` dimensions, `radius` its
  /// search radius (Basis::search_radius(); 0 for the families that do not search).
  LatticeReach (*reach)(double radius, double h, int dim) = nullptr;
  /// Its parameters (scene keys under [basis], `otmpm basis` options,
  /// Python keywords), with their defaults and ranges.
  std::span<const ParameterSpec> parameters{};
  BasisFactory<1> make1 = nullptr;
  BasisFactory<2> make2 = nullptr;
  BasisFactory<3> make3 = nullptr;
  /// On a window of the lattice, for the families whose points are not the
  /// lattice's nodes (null: the family on the window's nodes).
  WindowFactory<1> window1 = nullptr;
  WindowFactory<2> window2 = nullptr;
  WindowFactory<3> window3 = nullptr;

  /// The constructor for D dimensions.
  template <int D> BasisFactory<D> make() const {
    if constexpr (D == 1) return make1;
    else if constexpr (D == 2) return make2;
    else return make3;
  }
  /// The window constructor for D dimensions (null: the lattice's nodes).
  template <int D> WindowFactory<D> window() const {
    if constexpr (D == 1) return window1;
    else if constexpr (D == 2) return window2;
    else return window3;
  }
};

/// Every family, in the order the docs list them.
std::span<const BasisKind> basis_kinds();
/// The family named `name`, or null.
const BasisKind* find_basis_kind(std::string_view name);
/// The family named `name`; InputError listing the families otherwise.
const BasisKind& basis_kind(std::string_view name);
/// "linear, ugimp, bspline2, bspline3, lme, lme_box or maxent", for messages.
std::string basis_kind_list();
/// The parameters of every family, each key once (the scene accepts each of
/// them whatever the family, so that switching families with --set works).
std::span<const ParameterSpec* const> basis_parameters();
/// The parameter `key` of some family, or null.
const ParameterSpec* find_basis_parameter(std::string_view key);

/// The values of `basis.metric` (BasisOptions::metric), "isotropic" first.
std::span<const std::string_view> basis_metrics();
/// "isotropic, deformation or node_spacing", for messages.
std::string basis_metric_list();

} // namespace otmpm
