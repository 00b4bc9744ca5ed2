#pragma once
/// \file particles.hpp
/// Particle (material point) storage: contiguous per-field arrays of
/// fixed-size Eigen types (docs/architecture.md). Fields follow the notation of
/// docs/theory.md: x_p, v_p, a_p, m_p, V_p, V0_p, rho_p, F_p, eps_p, sigma_p.
#include "otmpm/core.hpp"
#include "otmpm/interrupt.hpp"

#include <string>
#include <string_view>
#include <vector>

namespace otmpm {

/// A per-particle internal variable (a material's state, Material::state()):
/// `width` doubles per particle, particle p at values[p * width ...].
struct StateField {
  std::string name;
  int width = 1;
  std::vector<double> values;
  double* row(int p) { return values.data() + static_cast<std::size_t>(p) * static_cast<std::size_t>(width); }
  const double* row(int p) const {
    return values.data() + static_cast<std::size_t>(p) * static_cast<std::size_t>(width);
  }
};

/// All particles of a run. `X` is the initial position (the material
/// coordinate used by exact solutions), `x_prev` the previous position (the
/// OTM velocity), `F` the deformation gradient (finite-strain models, `ul`
/// mode, or asked for as output), `a` the acceleration (NPC). Optional
/// fields are empty when the run does not use them; the assembler allocates
/// what the scene's materials and output need, the engine what the
/// integrator keeps (StepNeeds) and what the materials read. The per-point
/// state of the basis (LME multipliers, cell hints) lives in the basis.
template <int D> struct Particles {
  AlignedVector<Vec<D>> x, X, v, a, x_prev;
  std::vector<double> m, V, V0, rho;
  AlignedVector<Mat<D>> F, eps, sigma;
  /// Initial extent of the particle per axis, V0_p = prod_k l_p[k] (the
  /// share of its cell along each axis): its face normal to axis k has the
  /// area V0_p / l_p[k] (traction areas). Filled by the seeding; the
  /// assembler frees it once the traction areas are taken.
  AlignedVector<Vec<D>> length0;
  std::vector<int> material;
  std::vector<int> body;
  /// Internal variables of the materials, by name (Material::state()).
  std::vector<StateField> state;

  int size() const { return static_cast<int>(x.size()); }
  /// Resizes the fields every run uses to n particles (all zero) and empties
  /// the optional ones (a, F, x_prev, state); std::invalid_argument for n < 0.
  void resize(int n);
  /// Allocates the optional fields a run needs (a = 0, F = I), so that a
  /// scene pays memory only for what it reads.
  void allocate_optional(bool with_a, bool with_F);
  /// The state field `name`, added with `width` values per particle, each
  /// particle's row equal to `initial` (width values), when absent.
  /// std::invalid_argument when it exists with another width.
  StateField& add_state(const std::string& name, int width, const double* initial);
  /// The state field `name`, or null.
  StateField* find_state(std::string_view name);
  const StateField* find_state(std::string_view name) const;

  /// Calls f(name, field) for every per-particle array above except the
  /// state fields, named as its member, so that code handling all fields
  /// (the checkpoint) lists them here only. A field added to Particles must
  /// be added here too.
  template <class F> void for_each_field(F&& f) { visit_fields(*this, f); }
  template <class F> void for_each_field(F&& f) const { visit_fields(*this, f); }

private:
  template <class Self, class F> static void visit_fields(Self& s, F& f) {
    f("x", s.x); f("X", s.X); f("v", s.v); f("a", s.a); f("x_prev", s.x_prev);
    f("m", s.m); f("V", s.V); f("V0", s.V0); f("rho", s.rho);
    f("F", s.F); f("eps", s.eps); f("sigma", s.sigma);
    f("length0", s.length0);
    f("material", s.material); f("body", s.body);
  }
};

/// Gauss-Legendre points (in [-1, 1]) and weights (sum 2) of order n >= 1.
void gauss_legendre(int n, std::vector<double>& points, std::vector<double>& weights);

/// Where particles sit in a cell along one axis and what share of the cell
/// each gets: `s` in [0, 1] (fractions of the cell) and weights `w` summing
/// to 1, for n particles per axis - at the Gauss-Legendre points ("gauss",
/// weights = Gauss weights) or at the centres of n equal sub-cells
/// ("cell_centres", equal weights).
void cell_pattern(std::string_view placement, int n, std::vector<double>& s, std::vector<double>& w);

/// The particles of a box [lower, upper] cut into `cells` cells per axis,
/// n^D particles per cell placed by cell_pattern, cell by cell: cell(c,
/// seed) calls seed(x, V, extent) for the particles of cell c (axis 0
/// fastest): x the position, V = prod of weights x cell volume, extent per
/// axis the particle's share of the cell (weight x cell size; cell size / n
/// for equal shares), so that V = prod extent. A cell alone gives the bits
/// it gives among all of them (a rank of a distributed run seeds only its
/// own cells).
template <int D> class BoxCells {
public:
  BoxCells(const Vec<D>& lower, const Vec<D>& upper, const Index<D>& cells, int n, std::string_view placement)
      : lower_(lower), cells_(cells), n_(n), equal_(placement != "gauss") {
    cell_pattern(placement, n, s_, w_);
    for (int k = 0; k < D; ++k) size_[k] = (upper[k] - lower[k]) / cells[k];
  }
  const Index<D>& cells() const { return cells_; }
  const Vec<D>& size() const { return size_; }
  template <class Seed> void cell(const Index<D>& c, Seed&& seed) const {
    Vec<D> len;
    Index<D> q{};
    while (true) {
      Vec<D> x;
      double V = 1.0;
      for (int k = 0; k < D; ++k) {
        x[k] = lower_[k] + (c[k] + s_[q[k]]) * size_[k];
        V *= w_[q[k]] * size_[k];
        len[k] = equal_ ? size_[k] / n_ : w_[q[k]] * size_[k];
      }
      seed(x, V, len);
      int k = 0;
      while (k < D && ++q[k] == n_) q[k++] = 0;
      if (k == D) break;
    }
  }

private:
  Vec<D> lower_, size_;
  Index<D> cells_;
  int n_;
  bool equal_;
  std::vector<double> s_, w_;
};

/// Calls seed(x, V, extent) for the particles of every cell of a BoxCells
/// (cells in lattice order, axis 0 fastest, then the particles of each cell likewise).
template <int D, class Seed>
void seed_box_cells(const Vec<D>& lower, const Vec<D>& upper, const Index<D>& cells, int n, std::string_view placement,
                    Seed&& seed) {
  const BoxCells<D> box(lower, upper, cells, n, placement);
  Index<D> c{};
  while (true) {
    box.cell(c, seed);
    int k = 0;
    while (k < D && ++c[k] == cells[k]) c[k++] = 0;
    if (k == D) break;
    if (k > 0) interrupt_point("seeding a body"); // once per row of cells
  }
}

extern template struct Particles<1>;
extern template struct Particles<2>;
extern template struct Particles<3>;

} // namespace otmpm
