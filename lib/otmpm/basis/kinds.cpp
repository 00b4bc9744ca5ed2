/// \file kinds.cpp
/// The table of basis families (kinds.hpp) and make_basis(), which builds a
/// family by its scene name through it.
#include "otmpm/basis/kinds.hpp"

#include "otmpm/basis/families.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

namespace otmpm {

namespace {

constexpr int kQuadraticDegree = 2;
constexpr int kCubicDegree = 3;

template <int D> const CartesianGrid<D>& require_grid(const NodeSet<D>& nodes, std::string_view kind) {
  if (!nodes.grid())
    throw InputError("basis '" + std::string(kind) +
                     "' needs a structured grid (cartesian or perturbed), not a node cloud");
  return *nodes.grid();
}

template <int D> std::unique_ptr<Basis<D>> linear(const BasisOptions&, NodeSet<D> nodes) {
  return make_linear_basis<D>(std::move(nodes));
}
template <int D> std::unique_ptr<Basis<D>> ugimp(const BasisOptions& opt, NodeSet<D> nodes) {
  Vec<D> l;
  for (int k = 0; k < D; ++k) l[k] = opt.ugimp_half_width[k];
  return make_ugimp_basis<D>(std::move(nodes), l);
}
template <int D, int Degree> std::unique_ptr<Basis<D>> bspline(const BasisOptions& opt, NodeSet<D> nodes) {
  return make_bspline_basis<D>(require_grid(nodes, opt.kind), Degree);
}
template <int D> std::unique_ptr<Basis<D>> lme(const BasisOptions& opt, NodeSet<D> nodes) {
  return make_lme_basis<D>(std::move(nodes), opt);
}
template <int D> std::unique_ptr<Basis<D>> maxent(const BasisOptions& opt, NodeSet<D> nodes) {
  return make_maxent_basis<D>(std::move(nodes), opt);
}

/// Stencil sizes: (degree + 1)^dim for the tensor-product families; for
/// the max-ent families the lattice nodes in the ball of the support radius
/// (in units of h): LME's cut-off exp(-gamma_lme r^2) >= tolerance, max-ent's d_max.
double ball_volume(int dim, double r) {
  if (dim == 1) return 2.0 * r;
  if (dim == 2) return std::numbers::pi * r * r;
  return 4.0 / 3.0 * std::numbers::pi * r * r * r;
}
template <int Width> double tensor_stencil(const BasisOptions&, int dim) { return std::pow(Width, dim); }
double lme_stencil(const BasisOptions& o, int dim) {
  return std::max(std::pow(2.0, dim), ball_volume(dim, std::sqrt(-std::log(o.tolerance) / o.gamma_lme)));
}
double maxent_stencil(const BasisOptions& o, int dim) { return std::max(std::pow(2.0, dim), ball_volume(dim, o.d_max)); }

/// The row of a family whose constructor is F<D> for D = 1, 2, 3.
#define OTMPM_FACTORIES(F) .make1 = F<1>, .make2 = F<2>, .make3 = F<3>
const std::array kKinds{
    BasisKind{.name = "linear",
              .description = "tensor-product hat functions; isoparametric Q4/Q8 on a perturbed or moving lattice",
              .stencil_nodes = tensor_stencil<2>,
              OTMPM_FACTORIES(linear)},
    BasisKind{.name = "ugimp",
              .description = "uniform GIMP (Bardenhagen & Kober 2004)",
              .cartesian_only = true,
              .particle_size = true,
              .stencil_nodes = tensor_stencil<3>,
              OTMPM_FACTORIES(ugimp)},
    BasisKind{.name = "bspline2",
              .description = "quadratic B-splines on open knot vectors",
              .bspline = true,
              .stencil_nodes = tensor_stencil<kQuadraticDegree + 1>,
              .make1 = bspline<1, kQuadraticDegree>,
              .make2 = bspline<2, kQuadraticDegree>,
              .make3 = bspline<3, kQuadraticDegree>},
    BasisKind{.name = "bspline3",
              .description = "cubic B-splines on open knot vectors",
              .bspline = true,
              .stencil_nodes = tensor_stencil<kCubicDegree + 1>,
              .make1 = bspline<1, kCubicDegree>,
              .make2 = bspline<2, kCubicDegree>,
              .make3 = bspline<3, kCubicDegree>},
    BasisKind{.name = "lme",
              .description = "local max-ent (Arroyo & Ortiz 2006)",
              .needs_lattice = false,
              .searches_nodes = true,
              .stencil_nodes = lme_stencil,
              OTMPM_FACTORIES(lme)},
    BasisKind{.name = "maxent",
              .description = "max-ent with a cubic-spline prior",
              .needs_lattice = false,
              .searches_nodes = true,
              .stencil_nodes = maxent_stencil,
              OTMPM_FACTORIES(maxent)},
};
#undef OTMPM_FACTORIES

} // namespace

std::span<const BasisKind> basis_kinds() { return kKinds; }

const BasisKind* find_basis_kind(std::string_view name) {
  const auto it = std::find_if(kKinds.begin(), kKinds.end(), [&](const BasisKind& k) { return k.name == name; });
  return it == kKinds.end() ? nullptr : &*it;
}

std::string basis_kind_list() {
  std::string s;
  for (std::size_t i = 0; i < kKinds.size(); ++i)
    s += std::string(i == 0 ? "" : i + 1 == kKinds.size() ? " or " : ", ") + std::string(kKinds[i].name);
  return s;
}

const BasisKind& basis_kind(std::string_view name) {
  const BasisKind* k = find_basis_kind(name);
  if (!k) throw InputError("unknown basis kind '" + std::string(name) + "' (expected " + basis_kind_list() + ")");
  return *k;
}

template <int D> std::unique_ptr<Basis<D>> make_basis(const BasisOptions& opt, NodeSet<D> nodes) {
  const BasisKind& k = basis_kind(opt.kind);
  if constexpr (D == 1) return k.make1(opt, std::move(nodes));
  else if constexpr (D == 2) return k.make2(opt, std::move(nodes));
  else return k.make3(opt, std::move(nodes));
}

template std::unique_ptr<Basis<1>> make_basis<1>(const BasisOptions&, NodeSet<1>);
template std::unique_ptr<Basis<2>> make_basis<2>(const BasisOptions&, NodeSet<2>);
template std::unique_ptr<Basis<3>> make_basis<3>(const BasisOptions&, NodeSet<3>);

} // namespace otmpm
