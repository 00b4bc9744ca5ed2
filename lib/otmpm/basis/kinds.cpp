/// \file kinds.cpp
/// The table of basis families (kinds.hpp) and make_basis(), which builds a
/// family by its scene name through it.
#include "otmpm/basis/kinds.hpp"

#include "otmpm/basis/families.hpp"

#include <algorithm>
#include <array>
#include <cmath>

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
  for (int k = 0; k < D; ++k) l[k] = opt.particle_half_width[k];
  return make_ugimp_basis<D>(std::move(nodes), l);
}
template <int D, int Degree> std::unique_ptr<Basis<D>> bspline(const BasisOptions& opt, NodeSet<D> nodes) {
  return make_bspline_basis<D>(require_grid(nodes, opt.kind), Degree);
}
template <int D, int Degree>
std::unique_ptr<Basis<D>> bspline_window(const BasisOptions&, const CartesianGrid<D>& grid, const Index<D>& lo,
                                         const Index<D>& hi) {
  return make_bspline_window<D>(grid, Degree, lo, hi);
}
template <int D> std::unique_ptr<Basis<D>> lme(const BasisOptions& opt, NodeSet<D> nodes) {
  return make_lme_basis<D>(std::move(nodes), opt);
}
template <int D> std::unique_ptr<Basis<D>> lme_box(const BasisOptions& opt, NodeSet<D> nodes) {
  return make_lme_box_basis<D>(std::move(nodes), opt);
}
template <int D> std::unique_ptr<Basis<D>> maxent(const BasisOptions& opt, NodeSet<D> nodes) {
  return make_maxent_basis<D>(std::move(nodes), opt);
}

/// Stencil sizes of the tensor-product families: (degree + 1)^dim.
template <int Width> double tensor_stencil(const BasisOptions&, int dim) { return std::pow(Width, dim); }

/// The compact lattice rows of `linear` (LatticeRows): the cell's lowest
/// corner and the place in the cell, 4 + 8 D bytes.
double lattice_row_bytes(const BasisOptions&, int dim) { return 4.0 + 8.0 * dim; }

/// The reaches on the lattice (LatticeReach): the cell's corners (linear),
/// one more cell each side (uGIMP: |x - x_I| < h + l_p), the p + 1 control
/// points c .. c + p of a cell (B-splines of degree p, cells + p per axis),
/// the nodes within the search radius (max-ent families).
LatticeReach corners(double, double, int) { return {}; }
LatticeReach gimp_reach(double, double, int) { return {.below = 1, .above = 2}; }
template <int Degree> LatticeReach spline_reach(double, double, int) {
  return {.points_beyond_cells = Degree, .shift = Degree / 2, .below = 0, .above = Degree};
}
LatticeReach radius_reach(double radius, double h, int) {
  const int r = static_cast<int>(std::ceil(radius / h));
  return {.below = r, .above = r + 1};
}
/// The box support (lme_box): the nodes within R per axis, R = radius /
/// sqrt(dim) (its search radius is the ball around the box) - along an axis
/// the lines the ball of radius R takes, so lme's reach at R. (An R / h
/// that is an integer and that the division leaves an ulp short still
/// reaches its lines: a point in cell c, at c + u with 0 <= u < 1, takes
/// the lines from c - floor(R / h) to at most c + floor(R / h) + 1.)
LatticeReach box_reach(double radius, double h, int dim) {
  return radius_reach(radius / std::sqrt(static_cast<double>(dim)), h, dim);
}

/// The row of a family whose constructor is F<D> for D = 1, 2, 3.
#define OTMPM_FACTORIES(F) .make1 = F<1>, .make2 = F<2>, .make3 = F<3>
#define OTMPM_SPLINE(P) .make1 = bspline<1, P>, .make2 = bspline<2, P>, .make3 = bspline<3, P>, \
    .window1 = bspline_window<1, P>, .window2 = bspline_window<2, P>, .window3 = bspline_window<3, P>
const std::array kKinds{
    BasisKind{.name = "linear",
              .description =
                  "tensor-product hat functions; isoparametric Q4/Q8 on a perturbed or moving lattice; "
                  "a mesh's own elements on its vertices",
              .mesh_elements = true,
              .stencil_nodes = tensor_stencil<2>,
              .compact_row_bytes = lattice_row_bytes,
              .reach = corners,
              OTMPM_FACTORIES(linear)},
    BasisKind{.name = "ugimp",
              .description = "uniform GIMP (Bardenhagen & Kober 2004)",
              .cartesian_only = true,
              .particle_size = true,
              .stencil_nodes = tensor_stencil<3>,
              .reach = gimp_reach,
              OTMPM_FACTORIES(ugimp)},
    BasisKind{.name = "bspline2",
              .description = "quadratic B-splines on open knot vectors",
              .bspline = true,
              .stencil_nodes = tensor_stencil<kQuadraticDegree + 1>,
              .reach = spline_reach<kQuadraticDegree>,
              OTMPM_SPLINE(kQuadraticDegree)},
    BasisKind{.name = "bspline3",
              .description = "cubic B-splines on open knot vectors",
              .bspline = true,
              .stencil_nodes = tensor_stencil<kCubicDegree + 1>,
              .reach = spline_reach<kCubicDegree>,
              OTMPM_SPLINE(kCubicDegree)},
    BasisKind{.name = "lme",
              .description = "local max-ent (Arroyo & Ortiz 2006)",
              .needs_lattice = false,
              .searches_nodes = true,
              .adapts_metric = true,
              .stencil_nodes = lme_stencil_nodes,
              .reach = radius_reach,
              .parameters = lme_parameters(),
              OTMPM_FACTORIES(lme)},
    BasisKind{.name = "lme_box",
              .description = "local max-ent with the box support: 1D LME functions multiplied over the axes, "
                             "read from a table on an untouched lattice",
              .needs_lattice = false,
              .searches_nodes = true,
              .stencil_nodes = lme_box_stencil_nodes,
              .compact_row_bytes = lme_box_row_bytes,
              .reach = box_reach,
              .parameters = lme_parameters(),
              OTMPM_FACTORIES(lme_box)},
    BasisKind{.name = "maxent",
              .description = "max-ent with a cubic-spline prior",
              .needs_lattice = false,
              .searches_nodes = true,
              .stencil_nodes = maxent_stencil_nodes,
              .reach = radius_reach,
              .parameters = maxent_parameters(),
              OTMPM_FACTORIES(maxent)},
};
#undef OTMPM_FACTORIES
#undef OTMPM_SPLINE

constexpr std::array<std::string_view, 3> kMetrics{"isotropic", "deformation", "node_spacing"};

/// "a, b or c" of the names in `list`.
template <class List, class Name> std::string name_list(const List& list, Name name) {
  std::string s;
  for (std::size_t i = 0; i < list.size(); ++i)
    s += std::string(i == 0 ? "" : i + 1 == list.size() ? " or " : ", ") + std::string(name(list[i]));
  return s;
}

} // namespace

std::span<const std::string_view> basis_metrics() { return kMetrics; }

std::string basis_metric_list() {
  return name_list(kMetrics, [](std::string_view m) { return m; });
}

std::span<const BasisKind> basis_kinds() { return kKinds; }

const BasisKind* find_basis_kind(std::string_view name) {
  const auto it = std::find_if(kKinds.begin(), kKinds.end(), [&](const BasisKind& k) { return k.name == name; });
  return it == kKinds.end() ? nullptr : &*it;
}

std::string basis_kind_list() {
  return name_list(kKinds, [](const BasisKind& k) { return k.name; });
}

std::span<const ParameterSpec* const> basis_parameters() {
  static const std::vector<const ParameterSpec*> all = [] {
    std::vector<const ParameterSpec*> out;
    for (const BasisKind& k : kKinds)
      for (const ParameterSpec& p : k.parameters)
        if (std::none_of(out.begin(), out.end(), [&](const ParameterSpec* q) { return q->key == p.key; }))
          out.push_back(&p);
    return out;
  }();
  return all;
}

const ParameterSpec* find_basis_parameter(std::string_view key) {
  for (const ParameterSpec* p : basis_parameters())
    if (p->key == key) return p;
  return nullptr;
}

double BasisOptions::value(std::string_view key) const {
  const ParameterSpec* p = find_basis_parameter(key);
  require<std::invalid_argument>(p != nullptr, "BasisOptions::value: no basis family has a parameter '",
                                 std::string(key), "'");
  return value(*p);
}

const BasisKind& basis_kind(std::string_view name) {
  const BasisKind* k = find_basis_kind(name);
  if (!k) throw InputError("unknown basis kind '" + std::string(name) + "' (expected " + basis_kind_list() + ")");
  return *k;
}

template <int D> std::unique_ptr<Basis<D>> make_basis(const BasisOptions& opt, NodeSet<D> nodes) {
  const BasisKind& k = basis_kind(opt.kind);
  for (const auto& [key, value] : opt.values)
    if (!find_basis_parameter(key)) {
      std::vector<std::string_view> keys;
      for (const ParameterSpec* p : basis_parameters()) keys.push_back(p->key);
      throw InputError(opt.kind + " basis: unknown option '" + key + "' (expected " +
                       name_list(keys, [](std::string_view s) { return s; }) + ")");
    }
  return k.make<D>()(opt, std::move(nodes));
}

template std::unique_ptr<Basis<1>> make_basis<1>(const BasisOptions&, NodeSet<1>);
template std::unique_ptr<Basis<2>> make_basis<2>(const BasisOptions&, NodeSet<2>);
template std::unique_ptr<Basis<3>> make_basis<3>(const BasisOptions&, NodeSet<3>);

} // namespace otmpm
