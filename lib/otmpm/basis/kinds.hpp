#pragma once
/// \file kinds.hpp
/// The closed set of basis families, listed once: the scene reader takes its
/// choice list from it, the scene validator and the assembler the rules that
/// depend on the family, and make_basis() its constructor. Adding a family
/// means a file with the family, its constructor in families.hpp and one row
/// here (docs/architecture.md, "Adding a part").
#include "otmpm/basis/basis.hpp"

#include <span>
#include <string>
#include <string_view>

namespace otmpm {

/// Constructor of a family in D dimensions (families.hpp).
template <int D> using BasisFactory = std::unique_ptr<Basis<D>> (*)(const BasisOptions&, NodeSet<D>);

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
  /// Uses the size of the particles (uGIMP: half-width l_p = h / (2 n_ppc) per axis).
  bool particle_size = false;
  /// Searches the nodes within a radius (Verlet lists) and keeps a Lagrange
  /// multiplier per particle (the max-ent families).
  bool searches_nodes = false;
  /// Expected nodes in one particle's stencil on a uniform lattice (for the
  /// memory estimate of `otmpm run --check`).
  double (*stencil_nodes)(const BasisOptions&, int dim) = nullptr;
  BasisFactory<1> make1 = nullptr;
  BasisFactory<2> make2 = nullptr;
  BasisFactory<3> make3 = nullptr;
};

/// Every family, in the order the docs list them.
std::span<const BasisKind> basis_kinds();
/// The family named `name`, or null.
const BasisKind* find_basis_kind(std::string_view name);
/// The family named `name`; InputError listing the families otherwise.
const BasisKind& basis_kind(std::string_view name);
/// "linear, ugimp, bspline2, bspline3, lme or maxent", for messages.
std::string basis_kind_list();

} // namespace otmpm
