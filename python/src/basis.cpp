/// \file basis.cpp
/// The basis families from Python (otmpm.basis): a family built on a
/// Cartesian grid (possibly perturbed) or a node cloud, evaluated at points
/// into padded arrays of node ids, N_I and grad N_I.
#include "bindings.hpp"

#include "otmpm/basis/basis.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/scene/resources.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <variant>

namespace otmpm::python {

namespace {

using Points = py::array_t<double, py::array::c_style | py::array::forcecast>;

/// The options of otmpm.basis.Basis (docs/python.md); ppc sets the uGIMP
/// half-width h / (2 ppc) per axis.
struct FamilyOptions {
  BasisOptions basis;
  double ppc = 2.0;
};

/// The (m, D) rows of `a` as Vec<D> (a 1D array is one coordinate per row when D = 1).
template <int D> AlignedVector<Vec<D>> rows_of(const Points& a, const char* what) {
  const bool flat = a.ndim() == 1 && D == 1;
  if (!flat && (a.ndim() != 2 || a.shape(1) != D))
    throw InputError(std::string(what) + ": expected an array of shape (n, " + std::to_string(D) + ")");
  AlignedVector<Vec<D>> x(static_cast<std::size_t>(a.shape(0)));
  const double* p = a.data();
  for (std::size_t i = 0; i < x.size(); ++i)
    for (int k = 0; k < D; ++k) x[i][k] = p[i * D + static_cast<std::size_t>(k)];
  return x;
}

/// A basis family of dimension 1, 2 or 3 with the evaluation into padded arrays.
class PyBasis {
public:
  template <int D> explicit PyBasis(std::unique_ptr<Basis<D>> b) : basis_(std::move(b)) {}

  int dimension() const { return static_cast<int>(basis_.index()) + 1; }

  template <class F> auto visit(F&& f) const {
    return std::visit([&](const auto& b) { return f(*b); }, basis_);
  }

  /// (ids, N, gradN) at the points: (n, k) int64, (n, k), (n, k, D) with k the
  /// largest stencil; a row with fewer nodes is padded with id -1 and zeros.
  py::tuple evaluate(const Points& points) const {
    return visit([&](const auto& b) { return evaluate_on(b, points); });
  }

private:
  template <int D> static py::tuple evaluate_on(const Basis<D>& b, const Points& points) {
    const AlignedVector<Vec<D>> x = rows_of<D>(points, "points");
    std::vector<Stencil<D>> st(x.size());
    {
      py::gil_scoped_release nogil;
      for (std::size_t i = 0; i < x.size(); ++i) {
        PointQuery<D> q;
        q.x = x[i];
        q.id = static_cast<int>(i);
        b.evaluate(q, st[i]);
      }
    }
    py::ssize_t k = 0;
    for (const Stencil<D>& s : st) k = std::max<py::ssize_t>(k, s.size());
    const auto n = static_cast<py::ssize_t>(x.size());
    py::array_t<std::int64_t> ids({n, k});
    py::array_t<double> N({n, k}), dN({n, k, static_cast<py::ssize_t>(D)});
    auto id = ids.mutable_unchecked<2>();
    auto Nv = N.mutable_unchecked<2>();
    auto dNv = dN.mutable_unchecked<3>();
    for (py::ssize_t i = 0; i < n; ++i)
      for (py::ssize_t e = 0; e < k; ++e) {
        const Stencil<D>& s = st[static_cast<std::size_t>(i)];
        const bool in = e < s.size();
        id(i, e) = in ? s.node[static_cast<std::size_t>(e)] : -1;
        Nv(i, e) = in ? s.N[static_cast<std::size_t>(e)] : 0.0;
        for (int d = 0; d < D; ++d) dNv(i, e, d) = in ? s.dN[static_cast<std::size_t>(e)][d] : 0.0;
      }
    return py::make_tuple(ids, N, dN);
  }

  std::variant<std::unique_ptr<Basis<1>>, std::unique_ptr<Basis<2>>, std::unique_ptr<Basis<3>>> basis_;
};

/// The options of a family: `values` by key (BasisKind::parameters; make_basis
/// refuses a key no family has, the family a value out of its range).
FamilyOptions family_options(const std::string& kind, const std::map<std::string, double>& values, double ppc) {
  FamilyOptions o;
  o.basis.kind = kind;
  o.basis.values.insert(values.begin(), values.end());
  require(ppc > 0 && std::isfinite(ppc), "ppc must be finite and > 0, got ", ppc);
  o.ppc = ppc;
  return o;
}

template <int D>
PyBasis on_grid(const FamilyOptions& o, const std::vector<double>& lower, const std::vector<double>& upper,
                const std::vector<int>& cells, double perturbation, unsigned seed) {
  CartesianGrid<D> grid;
  for (int k = 0; k < D; ++k) {
    grid.lower[k] = lower[static_cast<std::size_t>(k)];
    grid.upper[k] = upper[static_cast<std::size_t>(k)];
    grid.cells[static_cast<std::size_t>(k)] = cells[static_cast<std::size_t>(k)];
  }
  grid.validate();
  double count = 1;
  std::string given;
  for (int k = 0; k < D; ++k) {
    count *= grid.cells[k] + 1.0;
    given += (k ? ", " : "") + std::to_string(grid.cells[k]);
  }
  check_node_count(count, "Grid(cells = [" + given + "])");
  BasisOptions opt = o.basis;
  for (int k = 0; k < D; ++k) opt.particle_half_width[k] = grid.h()[k] / (2.0 * o.ppc);
  // NaN or a negative fraction is refused by perturbed(), never taken as 0.
  NodeSet<D> nodes =
      perturbation != 0.0 ? NodeSet<D>::perturbed(grid, perturbation, seed) : NodeSet<D>::cartesian(grid);
  return PyBasis(make_basis<D>(opt, std::move(nodes)));
}

template <int D> PyBasis on_cloud(const FamilyOptions& o, const Points& positions, double spacing) {
  check_node_count(static_cast<double>(positions.shape(0)),
                   "a cloud of " + std::to_string(positions.shape(0)) + " nodes");
  return PyBasis(make_basis<D>(o.basis, NodeSet<D>::cloud(rows_of<D>(positions, "nodes"), spacing)));
}

/// The dimension of a grid given by lower, upper and cells.
int grid_dimension(const std::vector<double>& lower, const std::vector<double>& upper, const std::vector<int>& cells) {
  const std::size_t d = lower.size();
  if (d < 1 || d > 3 || upper.size() != d || cells.size() != d)
    throw InputError("lower, upper and cells must have the same length 1, 2 or 3");
  return static_cast<int>(d);
}

} // namespace

void register_basis(py::module_& m) {
  m.def(
      "basis_kinds",
      [] {
        std::vector<std::string> names;
        for (const BasisKind& k : basis_kinds()) names.emplace_back(k.name);
        return names;
      },
      "The basis families, in the order of the table (basis_kinds()).");
  m.def(
      "basis_parameters",
      [] {
        py::list rows;
        for (const ParameterSpec* p : basis_parameters())
          rows.append(py::dict(py::arg("key") = std::string(p->key), py::arg("default") = p->fallback.value_or(0.0),
                               py::arg("description") = std::string(p->description),
                               py::arg("integer") = p->integer));
        return rows;
      },
      "The parameters of every basis family (scene keys under [basis]): key, default, description, integer.");
  py::class_<PyBasis>(m, "Basis", "A basis family on nodes; see otmpm.basis.Basis.")
      .def_static(
          "on_grid",
          [](const std::string& kind, const std::vector<double>& lower, const std::vector<double>& upper,
             const std::vector<int>& cells, double perturbation, unsigned seed,
             const std::map<std::string, double>& options, double ppc) {
            const FamilyOptions o = family_options(kind, options, ppc);
            switch (grid_dimension(lower, upper, cells)) {
            case 1: return on_grid<1>(o, lower, upper, cells, perturbation, seed);
            case 2: return on_grid<2>(o, lower, upper, cells, perturbation, seed);
            default: return on_grid<3>(o, lower, upper, cells, perturbation, seed);
            }
          },
          py::arg("kind"), py::arg("lower"), py::arg("upper"), py::arg("cells"), py::arg("perturbation"),
          py::arg("seed"), py::arg("options"), py::arg("ppc"))
      .def_static(
          "on_cloud",
          [](const std::string& kind, const Points& positions, double spacing,
             const std::map<std::string, double>& options, double ppc) {
            const FamilyOptions o = family_options(kind, options, ppc);
            const py::ssize_t d = positions.ndim() == 1 ? 1 : positions.ndim() == 2 ? positions.shape(1) : 0;
            switch (d) {
            case 1: return on_cloud<1>(o, positions, spacing);
            case 2: return on_cloud<2>(o, positions, spacing);
            case 3: return on_cloud<3>(o, positions, spacing);
            default: throw InputError("nodes: expected an array of shape (m, D) with D = 1, 2 or 3");
            }
          },
          py::arg("kind"), py::arg("positions"), py::arg("spacing"), py::arg("options"), py::arg("ppc"))
      .def("evaluate", &PyBasis::evaluate, py::arg("points"))
      .def_property_readonly("dimension", &PyBasis::dimension)
      .def_property_readonly("kind", [](const PyBasis& b) { return b.visit([](const auto& f) { return std::string(f.kind()); }); })
      .def_property_readonly("linearly_complete", [](const PyBasis& b) { return b.visit([](const auto& f) { return f.linearly_complete(); }); })
      .def_property_readonly("spacing", [](const PyBasis& b) { return b.visit([](const auto& f) { return f.nodes().spacing(); }); })
      .def_property_readonly("nodes", [](const PyBasis& b) {
        return b.visit([](const auto& f) {
          const auto& x = f.nodes().positions();
          constexpr int D = std::remove_cvref_t<decltype(x[0])>::RowsAtCompileTime;
          py::array_t<double> a({static_cast<py::ssize_t>(x.size()), static_cast<py::ssize_t>(D)});
          auto v = a.mutable_unchecked<2>();
          for (std::size_t i = 0; i < x.size(); ++i)
            for (int k = 0; k < D; ++k) v(static_cast<py::ssize_t>(i), k) = x[i][k];
          return a;
        });
      });
}

} // namespace otmpm::python
