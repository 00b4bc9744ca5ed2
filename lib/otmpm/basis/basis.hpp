#pragma once
/// \file basis.hpp
/// The one question every basis family answers (docs/theory.md sect. 4,
/// docs/architecture.md): "for this point, which nodes, with what N and grad N?"
/// Families: linear, ugimp, bspline2, bspline3, lme, lme_box, maxent. Every integrator
/// consumes a BasisTable filled once per step, without knowing the family.
#include "otmpm/core.hpp"
#include "otmpm/nodes/neighbour_lists.hpp"
#include "otmpm/nodes/node_set.hpp"
#include "otmpm/parameters.hpp"

#include <array>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <optional>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

namespace otmpm {

struct StateGroup;
template <int D> struct BasisTable;
template <int D> struct LatticeRows;
template <int D> struct ProductRows;

/// The stencil of one point: node ids I with N_I(x) > 0 and grad N_I(x).
/// Also carries scratch arrays that a family may use during evaluation, so
/// that evaluating a point allocates nothing once the buffers have grown.
template <int D> struct Stencil {
  std::vector<int> node;
  std::vector<double> N;
  AlignedVector<Vec<D>> dN;
  // scratch, owned by the caller's thread; contents meaningless between calls
  std::vector<int> scratch_ids;
  std::vector<double> scratch_w;

  void clear() { node.clear(); N.clear(); dN.clear(); }
  int size() const { return static_cast<int>(node.size()); }
  void push(int I, double n, const Vec<D>& g) { node.push_back(I); N.push_back(n); dN.push_back(g); }
};

/// How a point's max-ent Lagrange multiplier changes with its position: the
/// solve of the last evaluation converged at x0, and G = d lambda / d x there
/// (docs/theory.md sect. 4.4, eq. 4.7a: G = 2 beta I - J^{-1} for LME,
/// -J^{-1} (I + A) in general), so the next solve at x starts from the Taylor
/// prediction lambda + G (x - x0) instead of lambda. Kept per particle while
/// the nodes stay fixed (`mpm` mode); G = 0 (the plain warm start) before the
/// first solve. The solve before that one (at x0 - e, slope G_prev) adds the
/// second-order term of eq. 4.7b, 1/2 alpha (G - G_prev)(x - x0), when the
/// point moves on along e (x - x0 = alpha e within a small angle): a particle
/// in steady motion then starts with a third-order residual. e = 0 (no
/// second-order term) until two solves have been made.
template <int D> struct MultiplierSlope {
  Vec<D> x0 = Vec<D>::Zero();
  Mat<D> G = Mat<D>::Zero();
  /// G of the solve before, at x0 - e.
  Mat<D> G_prev = Mat<D>::Zero();
  /// x0 minus the position of the solve before (0: none).
  Vec<D> e = Vec<D>::Zero();
};

/// The multipliers of a point's solves before its last one, for `ul` mode
/// (the nodes move with the material, so the slope of MultiplierSlope, taken
/// with the nodes fixed, does not apply): the next solve starts from the
/// extrapolation over the steps of the last solves (docs/theory.md eq.
/// 4.7c): 3 lambda_n - 3 lambda_{n-1} + lambda_{n-2} after three solves,
/// 2 lambda_n - lambda_{n-1} after two, lambda_n (PointQuery::lambda) after
/// one. `solves` counts the solves made, at most 3.
template <int D> struct MultiplierHistory {
  Vec<D> previous = Vec<D>::Zero(); ///< lambda_{n-1}: the solve before the last (when solves >= 2)
  Vec<D> before = Vec<D>::Zero();   ///< lambda_{n-2} (when solves == 3)
  int solves = 0;
};

/// One evaluation request. `id` names the point in error messages (a particle
/// index, or -1). `lambda` is the LME/max-ent Lagrange multiplier used as a
/// warm start and overwritten with the converged value (with a `history`:
/// polished by the final Newton step) (may be null: cold start from zero). `iterations`, when not null, receives the Newton count.
template <int D> struct PointQuery {
  Vec<D> x = Vec<D>::Zero();
  int id = -1;
  Vec<D>* lambda = nullptr;
  /// The first-order model of *lambda about the position of its last solve
  /// (MultiplierSlope), or null: the solve then starts from *lambda itself.
  /// Read and updated together with `lambda`.
  MultiplierSlope<D>* slope = nullptr;
  /// The multipliers of the solves before (MultiplierHistory, `ul` mode), or
  /// null. Read and updated together with `lambda`.
  MultiplierHistory<D>* history = nullptr;
  int* iterations = nullptr;
  /// Cell hint for structured layouts (lattice index of the containing cell
  /// from the previous step), or null. Updated by families that use it.
  Index<D>* cell_hint = nullptr;
  /// Verlet lists of the points of a table fill, or null: families that
  /// search nodes within search_radius() take the candidates of point `id`
  /// from them (same result as the direct search, less work).
  NeighbourLists<D>* neighbours = nullptr;
  /// Deformation gradient F of the point, for LME with `metric =
  /// "deformation"` (BasisOptions::metric); null: F = I.
  const Mat<D>* deformation = nullptr;
  /// Where a family may move a point that lies outside the hull of every
  /// node near it back into that hull (max-ent families, docs/theory.md
  /// sect. 4.8): it then evaluates the point at x + *moved and stores the
  /// displacement here (left untouched otherwise). Null: such a point fails.
  Vec<D>* moved = nullptr;
};

/// Throws the BasisError of require_finite_query (out of line, so that the
/// check stays two comparisons in the callers' loops).
template <int D> [[noreturn, gnu::cold, gnu::noinline]] void throw_non_finite_query(std::string_view kind, const PointQuery<D>& q) {
  throw BasisError(error_message(kind, " basis: point ", q.id >= 0 ? std::to_string(q.id) + " at " : std::string(),
                                 q.x, ": the position is not finite"));
}
/// Throws BasisError "KIND basis: point ID at (x, y): the position is not
/// finite" unless q.x is finite; the check every family makes first in evaluate().
template <int D> inline void require_finite_query(std::string_view kind, const PointQuery<D>& q) {
  if (!q.x.allFinite()) [[unlikely]]
    throw_non_finite_query(kind, q);
}

/// The options of a basis: its family, its locality metric and the values
/// of the family's parameters by scene key (BasisKind::parameters, e.g.
/// "gamma_lme"; a key not given takes its default: value()).
struct BasisOptions {
  std::string kind = "linear"; ///< the family (basis_kinds())
  /// LME locality (docs/theory.md, "Adapted locality"): "isotropic" (beta =
  /// gamma_lme / h^2), "deformation" (beta_p = gamma_lme / h^2 M_p, M_p =
  /// (F_p F_p^T)^-1 scaled to det 1, F_p from PointQuery::deformation) or
  /// "node_spacing" (beta_I = gamma_lme / h_I^2, h_I the distance from node
  /// I to its nearest node). basis_metrics() lists them.
  std::string metric = "isotropic";
  /// The parameters given, by key; the rest take their defaults.
  std::map<std::string, double, std::less<>> values;
  /// The particles' half-width per axis, for the families that use particle
  /// sizes (BasisKind::particle_size: uGIMP, l_p = h / (2 n_ppc_axis)):
  /// derived from the particles, not a scene key.
  std::array<double, 3> particle_half_width{0.0, 0.0, 0.0};
  /// The value of parameter `p`: values[p.key], or its default.
  double value(const ParameterSpec& p) const;
  /// The value of the parameter of some family named `key` (kinds.hpp,
  /// find_basis_parameter); std::invalid_argument when no family has one.
  double value(std::string_view key) const;
};

/// InputError "KIND basis: KEY must be ... (got ...)" for the first value of
/// `o` for one of `parameters` that its range refuses (ParameterSpec::check;
/// the defaults are in range).
void require_options(const BasisOptions& o, std::span<const ParameterSpec> parameters);

/// Which per-point state a family keeps between evaluations of the same point.
struct PointStateUse {
  bool lambda = false;    ///< max-ent families: the Lagrange multiplier (warm start)
  /// max-ent families with fixed nodes: the slope of the multiplier
  /// (MultiplierSlope, the Taylor-predicted warm start).
  bool slope = false;
  /// max-ent families with moving nodes: the multipliers of the solves
  /// before (MultiplierHistory, the extrapolated warm start).
  bool history = false;
  bool cell_hint = false; ///< element walk / B-splines: the cell of the last evaluation
  /// Reads the points' deformation gradients (LME, metric = "deformation"):
  /// evaluate_points needs them.
  bool deformation = false;
};

/// The per-point state of the points a family evaluates step after step (the
/// particles): what PointStateUse asks for (empty arrays otherwise), and the
/// Verlet lists of the families that search nodes (search_radius() > 0).
/// Owned by the basis (Basis::bind_points); saved in checkpoints.
template <int D> struct PointState {
  AlignedVector<Vec<D>> lambda;
  AlignedVector<MultiplierSlope<D>> slope;
  AlignedVector<MultiplierHistory<D>> history;
  std::vector<Index<D>> cell_hint;
  NeighbourLists<D> neighbours;
};

/// A plane x_axis = at that moves by `by` within a step: a rigid wall whose
/// normal is a coordinate axis (Basis::hold_on_planes).
struct AxisPlane {
  int axis = 0;
  double at = 0.0, by = 0.0;
};

/// A basis family bound to a node set. `evaluate` is const and thread-safe
/// (all scratch lives in the Stencil). Implementations: see make_basis().
template <int D> class Basis {
public:
  virtual ~Basis() = default;
  /// The family name as in the scene file ("lme", "bspline2", ...).
  virtual std::string_view kind() const = 0;
  /// The nodes the family's degrees of freedom live on. For Lagrangian-type
  /// families these are the grid vertices; for B-splines the control points
  /// placed at the Greville abscissae of the knot vectors.
  virtual const NodeSet<D>& nodes() const = 0;
  /// Mutable access for advection in `ul` mode (x_I += dx_I); call
  /// nodes_moved() afterwards.
  virtual NodeSet<D>& nodes() = 0;
  /// Tells the family the nodes moved by dx (already applied to nodes()). The
  /// B-spline family advects its knot vectors here; others refresh indices.
  virtual void nodes_moved(const AlignedVector<Vec<D>>& dx) = 0;
  /// The planes (walls whose normal is a coordinate axis) that hold what lies
  /// on them through the next nodes_moved(): the B-spline family keeps a knot
  /// on such a plane with it (its control points follow the knots, not their
  /// own increments); the families whose nodes move by their own increments
  /// need nothing.
  virtual void hold_on_planes(std::vector<AxisPlane> /*planes*/) {}
  /// Fills `out` with the stencil of q.x (on success it holds exactly that
  /// stencil; after a throw its contents are unspecified). Throws BasisError
  /// naming the point when it cannot, also when q.x is not finite (one check
  /// per call, require_finite_query).
  virtual void evaluate(const PointQuery<D>& q, Stencil<D>& out) const = 0;
  /// True when sum_I N_I x_I = x holds (linear completeness w.r.t. nodes()).
  virtual bool linearly_complete() const = 0;
  /// Upper bound on the stencil size (for buffer reservation).
  virtual int max_stencil() const = 0;
  /// Radius of the neighbour search of evaluate() (NodeSet::within) for the
  /// families that search (LME, max-ent), else 0.
  virtual double search_radius() const { return 0.0; }
  /// Evaluations since construction whose point was not inside the hull of
  /// its support within the prior's cut-off and that a wider search carried
  /// (max-ent families, docs/theory.md sect. 4.8), else 0.
  virtual long long widened_supports() const { return 0; }
  /// Evaluations since construction whose point lay outside the hull of every
  /// node near it and was moved back into it (PointQuery::moved), else 0.
  virtual long long moved_points() const { return 0; }
  /// The box of points evaluate() takes, for the families whose domain the
  /// nodes carry as a box (B-splines: the knot vectors' ranges), else
  /// nothing (a family whose support follows the points). `ul` mode's node
  /// reset lays the nodes out anew before a particle could leave it within
  /// a step (Engine::reset_due).
  virtual std::optional<std::pair<Vec<D>, Vec<D>>> domain() const { return std::nullopt; }
  /// The stencil size when every point has the same one (linear: 2^D,
  /// B-splines: (p+1)^D), else 0. fill_basis_table then writes rows in place
  /// (and starts again on its general path when a point gives another size).
  virtual int fixed_stencil() const { return 0; }
  /// Fast path of evaluate() for fixed-stencil families: writes the
  /// fixed_stencil() entries of q.x to node/N/dN and returns true, or returns
  /// false (nothing written) when the family must go through evaluate().
  /// Throws as evaluate() does (BasisError, also for a non-finite q.x).
  virtual bool evaluate_fixed(const PointQuery<D>& q, int* node, double* N, Vec<D>* dN) const {
    (void)q, (void)node, (void)N, (void)dN;
    return false;
  }
  /// True when evaluate_into() may write rows in place now (a table fill
  /// then calls it; otherwise evaluate() and a copy). The default: false.
  virtual bool writes_in_place() const { return false; }
  /// A table fill's form of evaluate() for families of varying stencils:
  /// writes the stencil of q.x straight to node/N/dN and returns its size
  /// when the family can and it fits in `room` entries, else evaluates it
  /// into `st` as evaluate() does and returns -1 (the caller copies it).
  /// Either way the same entries, bits and per-point state as evaluate(),
  /// and the same errors. The default: evaluate(q, st), -1.
  virtual int evaluate_into(const PointQuery<D>& q, int room, int* node, double* N, Vec<D>* dN,
                            Stencil<D>& st) const {
    (void)room, (void)node, (void)N, (void)dN;
    evaluate(q, st);
    return -1;
  }
  /// Batched fast path of a table fill for fixed-stencil families that keep
  /// no per-point state but the cell hint: evaluates the points x[0],
  /// x[1], ... in order, writing the S = fixed_stencil() entries of point i
  /// to node/N/dN + i S (and its cell to cell_hint[i] when cell_hint is not
  /// null), the same bits as evaluate_fixed() (or, where that declines, as
  /// evaluate()). Never throws: stops before the first point it cannot
  /// evaluate that way (outside the domain, not finite, or needing
  /// evaluate()'s search) and returns the number of points written, at most
  /// `count`; the caller takes that point through
  /// evaluate_fixed()/evaluate(), which report its error, and calls the
  /// batch again from the next point. -1: the family has no batch in its
  /// present state (nothing written; the caller stops asking). The
  /// default: -1.
  virtual int evaluate_fixed_points(const Vec<D>* x, int count, Index<D>* cell_hint, int* node, double* N,
                                    Vec<D>* dN) const {
    (void)x, (void)count, (void)cell_hint, (void)node, (void)N, (void)dN;
    return -1;
  }
  /// The compact rows of the points x (LatticeRows) when the family has
  /// them in its present state (`linear` on an untouched lattice): true, and
  /// `rows` holds them; false when it has none or a point lies outside its
  /// domain or is not finite (`rows` then unspecified: the caller builds the
  /// table, which reports the point). Keeps no per-point state. The default:
  /// false.
  virtual bool evaluate_lattice_rows(const AlignedVector<Vec<D>>& x, LatticeRows<D>& rows) const {
    (void)x, (void)rows;
    return false;
  }
  /// The product rows of the bound points at x (ProductRows) when the
  /// family's functions there are products of one factor per lattice axis
  /// (`lme_box` on its untouched lattice): true, `rows` holds them and the
  /// per-point state is updated as evaluate_points() updates it; false when
  /// it has none or a point lies where its table does not reach (`rows` and
  /// the state then unspecified: the caller builds the table, which
  /// evaluates or reports that point). The default: false.
  virtual bool evaluate_product_rows(const AlignedVector<Vec<D>>& x, ProductRows<D>& rows) {
    (void)x, (void)rows;
    return false;
  }
  /// Which per-point state the family keeps when it evaluates the same points
  /// step after step (the particles, bind_points): the Lagrange multiplier
  /// of the max-ent families (warm start) and the cell hint of the element
  /// walk (linear on a perturbed or moving lattice) and of the B-splines.
  /// `nodes_move`: the nodes will be advected (`ul` mode).
  virtual PointStateUse point_state_use(bool nodes_move) const {
    (void)nodes_move;
    return {};
  }

  /// Binds the family to `n` points evaluated every step (the particles):
  /// allocates the per-point state point_state_use(nodes_move) asks for
  /// (lambda = 0, cell hints = 0) and the Verlet lists of the families that
  /// search nodes. std::invalid_argument for n < 0.
  void bind_points(int n, bool nodes_move);
  /// Evaluates the bound points at their positions x (one per bound point)
  /// into `table` (fill_basis_table with the per-point state and the Verlet
  /// lists). `deformation`: the points' deformation gradients, read only
  /// when point_state_use().deformation. `moved` (one entry per point, zero
  /// on entry, or null): a point the family moved into its support's hull
  /// gets its displacement there (PointQuery::moved), and its row is that
  /// of the moved position. std::invalid_argument when x (or a
  /// needed `deformation`) has another size than bound. Once per step: the
  /// per-point state predicts the next call's solve from this one's (the
  /// history of `ul` mode counts calls as steps), so a second call at the
  /// same positions is not free of effect.
  void evaluate_points(const AlignedVector<Vec<D>>& x, BasisTable<D>& table,
                       const AlignedVector<Mat<D>>* deformation = nullptr,
                       AlignedVector<Vec<D>>* moved = nullptr);
  /// The per-point state of the bound points.
  PointState<D>& point_state() { return points_; }
  const PointState<D>& point_state() const { return points_; }

  /// Writes the state that evolves during a run - the per-point state of the
  /// bound points and the family's own (save_family_state) - into a
  /// checkpoint group (state.hpp).
  void save_state(StateGroup& out) const;
  /// Restores what save_state wrote, called after the node positions were
  /// restored. InputError (StateGroup::error) when it does not fit.
  void restore_state(const StateGroup& in);
  /// A distributed run: the family's nodes this rank owns (counted[I] != 0)
  /// and the sum over the ranks (in place), for a family whose state sums
  /// over its nodes (the B-splines' knot advection). The default: nothing.
  virtual void distribute(std::vector<char> counted, std::function<void(std::span<double>)> sum) {
    (void)counted, (void)sum;
  }

protected:
  /// Family state beyond the node positions that evolves during a run (the
  /// advected B-spline knot vectors). The default: none.
  virtual void save_family_state(StateGroup& /*out*/) const {}
  /// Restores what save_family_state wrote; also refreshes what the family
  /// derives from the nodes.
  virtual void restore_family_state(const StateGroup& /*in*/) {}

private:
  PointState<D> points_;
  /// point_state_use() at bind_points: which per-point arrays a checkpoint
  /// holds, also for no points (a rank without particles), and whether the
  /// points' deformation gradients are read.
  PointStateUse use_{};
};

/// Creates the basis family `opt.kind` on `nodes` (for B-splines: on the
/// lattice `nodes.grid()`, building the control points). Throws InputError on
/// an unknown kind, a layout the family cannot use (uGIMP off-lattice,
/// B-splines without a lattice) or an option of the chosen family out of range
/// (gamma_lme, d_max, newton_tolerance > 0 and finite, 0 < tolerance < 1,
/// max_newton_iterations >= 1, 0 < ugimp_half_width[k] <= h_k / 2).
template <int D>
std::unique_ptr<Basis<D>> make_basis(const BasisOptions& opt, NodeSet<D> nodes);

/// Per-particle basis table in compressed rows (docs/architecture.md): row p holds
/// the stencil of particle p, entries offset[p] .. offset[p+1]-1. Filled once
/// per step and reused by every stage of that step.
template <int D> struct BasisTable {
  std::vector<int> offset{0};
  std::vector<int> node;
  std::vector<double> N;
  AlignedVector<Vec<D>> dN;

  int rows() const { return static_cast<int>(offset.size()) - 1; }
  int begin(int p) const { return offset[p]; }
  int end(int p) const { return offset[p + 1]; }
  int size(int p) const { return offset[p + 1] - offset[p]; } ///< entries of row p
  std::size_t entries() const { return node.size(); }
};

/// The gradient of a hat for lanes of type T: Vec<D> for one point (T =
/// double), D lane vectors for several points at once (T a GCC vector of
/// doubles, one point per lane: LatticeView::visit_two_rows).
template <int D, class T>
using HatGradient = std::conditional_t<std::is_same_v<T, double>, Vec<D>, std::array<T, D>>;

/// The 2^D hat functions of a point at t_k in [0, 1] of its cell along each
/// axis (docs/theory.md eq. 4.1): w_k = (1 - t_k, t_k), d_k = (-1/h_k,
/// 1/h_k), N_a = prod_k w_k[a_k] and (grad N_a)_m the same product with d_m in
/// place of w_m, corner a having bit k set at the upper node of axis k. Calls
/// f(a, N_a, grad N_a) for a = 0, 1, ..., 2^D - 1, each product formed left
/// to right in axis order where it is used: LinearBasis' table (through
/// hat_products; its SSE2 form in 2D and 3D computes the same products, the
/// same bits - tests/test_linear.cpp) and the compact rows (LatticeRows)
/// take their values from here, so a row rebuilt from t has the table's bits.
/// `t` is a Vec<D>, or D lane vectors for several points at once: each
/// lane's products are then the one point's, in its order, so its bits.
/// `d[k]` is axis k's (-1/h_k, 1/h_k); t and d may have more axes than D,
/// of which the first D are read.
template <int D, class Point, class Slopes, class F>
[[gnu::always_inline]] inline void visit_hats(const Point& t, const Slopes& d, F&& f) {
  using T = std::remove_cvref_t<decltype(t[0])>;
  using G = HatGradient<D, T>;
  T w[D][2];
  for (int k = 0; k < D; ++k) w[k][0] = 1.0 - t[k], w[k][1] = t[k];
  if constexpr (D == 1) {
    for (int a = 0; a < 2; ++a) f(a, w[0][a], G{d[0][a]});
  } else {
    for (int a2 = 0; a2 < (D == 3 ? 2 : 1); ++a2)
      for (int a1 = 0; a1 < 2; ++a1)
        for (int a0 = 0; a0 < 2; ++a0) {
          const T ww = w[0][a0] * w[1][a1], dw = d[0][a0] * w[1][a1], wd = w[0][a0] * d[1][a1];
          if constexpr (D == 2)
            f(a0 + 2 * a1, ww, G{dw, wd});
          else
            f(a0 + 2 * a1 + 4 * a2, ww * w[2][a2], G{dw * w[2][a2], wd * w[2][a2], ww * d[2][a2]});
        }
  }
}

/// Corner a alone of visit_hats: the same products in the same order, so
/// the same bits as the entry visit_hats gives for a (a gather over nodes
/// that meets each of a row's entries apart: the column gather over
/// LatticeRows).
template <int D>
[[gnu::always_inline]] inline void hat_corner(const Vec<D>& t, const std::array<std::array<double, 2>, D>& d,
                                              int a, double& N, Vec<D>& dN) {
  // the weights picked by index, not by a branch: a gather over nodes meets
  // the corners in no predictable order
  const int a0 = a & 1;
  const double w0[2] = {1.0 - t[0], t[0]};
  if constexpr (D == 1) {
    N = w0[a0], dN = Vec<D>(d[0][a0]);
  } else {
    const int a1 = (a >> 1) & 1;
    const double w1[2] = {1.0 - t[1], t[1]};
    const double ww = w0[a0] * w1[a1], dw = d[0][a0] * w1[a1], wd = w0[a0] * d[1][a1];
    if constexpr (D == 2) {
      N = ww, dN = Vec<D>(dw, wd);
    } else {
      const int a2 = (a >> 2) & 1;
      const double w2[2] = {1.0 - t[2], t[2]};
      N = ww * w2[a2], dN = Vec<D>(dw * w2[a2], wd * w2[a2], ww * d[2][a2]);
    }
  }
}

/// visit_hats into N[a] and dN[a].
template <int D>
[[gnu::always_inline]] inline void
hat_products(const Vec<D>& t, const std::array<std::array<double, 2>, D>& d, double* N, Vec<D>* dN) {
  visit_hats<D>(t, d, [N, dN](int a, double Na, const Vec<D>& dNa) { N[a] = Na, dN[a] = dNa; });
}

/// The rows of the `linear` family on an untouched lattice, kept compact
/// (docs/architecture.md, "Lattice rows"): for point p the node id of the
/// lowest corner of its cell (base) and its place t_k in [0, 1] in that cell
/// along each axis, 4 + 8 D bytes where the table's row takes 2^D (12 + 8 D)
/// + 4. Row p's 2^D entries are nodes base + corner_offset[a] with the
/// weights visit_hats(t_p): entry for entry the table's row, bit for bit.
template <int D> struct LatticeRows {
  static constexpr int kCorners = 1 << D;
  std::vector<int> base;
  AlignedVector<Vec<D>> t;
  std::array<int, kCorners> corner_offset{}; ///< node id of corner a minus that of corner 0
  std::array<std::array<double, 2>, D> d{};  ///< d N / d x_k of the lower / upper 1D hat: -1/h_k, 1/h_k

  int rows() const { return static_cast<int>(base.size()); }
  /// f(I, N_Ip, grad N_Ip) for the entries of a row with lowest node `b` and
  /// place `tp` (its base and t), in the table's order, each weight formed
  /// where it is used (visit_hats: a caller that reads only N or only grad N
  /// forms only those). Static, so that a pass may hold the arrays in its own
  /// locals (engine/rows.hpp, LatticeView).
  template <class F>
  [[gnu::always_inline]] static void visit(int b, const Vec<D>& tp, const std::array<int, kCorners>& offset,
                                           const std::array<std::array<double, 2>, D>& d, F&& f) {
    visit_hats<D>(
        tp, d, [&](int a, double N, const Vec<D>& dN) __attribute__((always_inline)) {
          f(b + offset[a], N, dN);
        });
  }
  /// visit() for row p.
  template <class F> [[gnu::always_inline]] void visit_row(int p, F&& f) const {
    visit(base[static_cast<std::size_t>(p)], t[static_cast<std::size_t>(p)], corner_offset, d, f);
  }
  /// Entry e = p 2^D + a (row p's corner a): its node, and N_Ip and grad
  /// N_Ip with the bits visit_row gives them.
  int node(int e) const {
    return lowest(e / kCorners) + corner_offset[static_cast<std::size_t>(e % kCorners)];
  }
  void entry(int e, double& N, Vec<D>& dN) const {
    hat_corner<D>(t[static_cast<std::size_t>(e / kCorners)], d, e % kCorners, N, dN);
  }
  /// The smallest and largest node id of row p.
  int lowest(int p) const { return base[static_cast<std::size_t>(p)]; }
  int highest(int p) const { return base[static_cast<std::size_t>(p)] + corner_offset[kCorners - 1]; }
};

/// Rebuilds the full table of `rows` (the same entries and bits as the
/// family's own table at the same points).
template <int D> void expand_lattice_rows(const LatticeRows<D>& rows, BasisTable<D>& table);

/// The rows of a family whose functions on an untouched lattice are
/// products of one 1D factor per axis over a box of lattice lines
/// (`lme_box`, docs/theory.md sect. 4.9): for point p, per axis k the
/// m_k lines lo_k .. lo_k + m_k - 1 of its box and their 1D values n_k
/// and derivatives d_k (per unit length), D (4 + 16 M) + 8 bytes with M
/// the lanes of an axis, where the table's row takes prod_k m_k (12 + 8 D)
/// + 4. Row p's entries are the box's nodes with node ids ascending (axis 0
/// innermost), N_I = n_0 (n_1 n_2) and grad N_I = (d_0 (n_1 n_2), n_0 (d_1
/// n_2), n_0 (n_1 d_2)) formed in that order where they are used, so each
/// entry has the bits of the family's table (tests/test_lme_box.cpp).
template <int D> struct ProductRows {
  int lanes = 0;                     ///< M: the factors of one axis take M doubles (n), then M (d)
  /// Node-id stride of each axis; axis 0's must be 1 (the lattice's node
  /// order): visit, entry and highest add i_0 to a line's id.
  std::array<int, D> stride{};
  std::vector<int> base;             ///< the row's lowest node id, sum_k lo_k stride_k
  std::vector<std::array<int, D>> m; ///< lines per axis
  std::vector<int> offset{0};        ///< row p's entries are offset[p] .. offset[p + 1] - 1
  AlignedVector<double> f;           ///< row p's factors from p 2 D M on: axis k's n, then its d

  int rows() const { return static_cast<int>(base.size()); }
  /// Sizes the arrays for `n` rows of `lanes` lanes (the values unset).
  void resize(int n, int lanes_per_axis) {
    lanes = lanes_per_axis;
    base.resize(static_cast<std::size_t>(n));
    m.resize(static_cast<std::size_t>(n));
    offset.resize(static_cast<std::size_t>(n) + 1);
    f.resize(static_cast<std::size_t>(n) * 2 * D * static_cast<std::size_t>(lanes));
  }
  /// Sets offset from the lines m of every row (in fixed blocks, the same
  /// for any thread count); false (offset unspecified) when the entries
  /// exceed the int range of the offsets.
  bool count_entries();
  /// Row p's factors (axis k's n at 2 k M, d at (2 k + 1) M).
  const double* factors(int p) const { return f.data() + static_cast<std::size_t>(p) * 2 * D * lanes; }
  double* factors(int p) { return f.data() + static_cast<std::size_t>(p) * 2 * D * lanes; }
  /// f(I, N_Ip, grad N_Ip) for the entries of row p in the table's order.
  template <class F> [[gnu::always_inline]] void visit_row(int p, F&& f) const {
    visit(base[static_cast<std::size_t>(p)], m[static_cast<std::size_t>(p)], factors(p), lanes, stride, f);
  }
  /// f(I) for the node ids of row p in the table's order, without reading
  /// its factors (the passes that only mark or number nodes). The lines and
  /// strides in locals, so that f's stores cannot make them reload.
  template <class F> [[gnu::always_inline]] void visit_nodes(int p, F&& f) const {
    const std::array<int, D> mp = m[static_cast<std::size_t>(p)], s = stride;
    walk_lines(
        base[static_cast<std::size_t>(p)], mp, s, [&](int, int, int id) __attribute__((always_inline)) {
          for (int i0 = 0; i0 < mp[0]; ++i0) f(id + i0);
        });
  }
  /// visit_row() of a row given by its parts (static, so that a pass may
  /// hold the arrays in its own locals: engine/rows.hpp, ProductView). M0 >
  /// 0: axis 0 has M0 lines (its loop unrolled); 0: any.
  template <int M0 = 0, class F>
  [[gnu::always_inline]] static void visit(int b, const std::array<int, D>& mp, const double* r, int M,
                                           const std::array<int, D>& stride, F&& f) {
    const int m0 = M0 > 0 ? M0 : mp[0];
    walk_lines(
        b, mp, stride, [&](int i1, int i2, int id) __attribute__((always_inline)) {
          double w;
          Vec<D> g;
          cross(r, M, i1, i2, w, g);
          for (int i0 = 0; i0 < m0; ++i0) {
            double N;
            Vec<D> dN;
            product(r[i0], r[M + i0], w, g, N, dN);
            f(id + i0, N, dN);
          }
        });
  }
  /// Entry e of row p (offset[p] <= e < offset[p + 1]): its node, and N_Ip
  /// and grad N_Ip with the bits visit_row gives them (the column gather).
  void entry(int p, int e, int& I, double& N, Vec<D>& dN) const {
    const std::array<int, D>& mp = m[static_cast<std::size_t>(p)];
    int i[3] = {0, 0, 0};
    for (int k = 0, l = e - offset[static_cast<std::size_t>(p)]; k < D; ++k) i[k] = l % mp[k], l /= mp[k];
    double w;
    Vec<D> g;
    const double* r = factors(p);
    cross(r, lanes, i[1], i[2], w, g);
    product(r[i[0]], r[lanes + i[0]], w, g, N, dN);
    I = line_id(base[static_cast<std::size_t>(p)], i[1], i[2], stride) + i[0];
  }
  /// The smallest and largest node id of row p.
  int lowest(int p) const { return base[static_cast<std::size_t>(p)]; }
  int highest(int p) const {
    const std::array<int, D>& mp = m[static_cast<std::size_t>(p)];
    return line_id(base[static_cast<std::size_t>(p)], D > 1 ? mp[1 % D] - 1 : 0, D > 2 ? mp[2 % D] - 1 : 0,
                   stride) +
           mp[0] - 1;
  }

private:
  /// The node id of the first entry of line (i1, i2) of axes 1 and 2 (those
  /// that exist) of a row whose lowest node is b: b + i1 stride_1 + i2 stride_2.
  [[gnu::always_inline]] static int line_id(int b, int i1, int i2, const std::array<int, D>& s) {
    return b + (D > 1 ? i1 * s[1 % D] : 0) + (D > 2 ? i2 * s[2 % D] : 0);
  }
  /// g(i1, i2, id) for every line of axes 1 and 2 of a row with lines mp and
  /// lowest node b, in the table's order (axis 2 outermost), id its first
  /// node (line_id): the walk visit() and visit_nodes() share.
  template <class G>
  [[gnu::always_inline]] static void walk_lines(int b, const std::array<int, D>& mp,
                                                const std::array<int, D>& s, G&& g) {
    const int m1 = D > 1 ? mp[1 % D] : 1, m2 = D > 2 ? mp[2 % D] : 1;
    for (int i2 = 0; i2 < m2; ++i2)
      for (int i1 = 0; i1 < m1; ++i1) g(i1, i2, line_id(b, i1, i2, s));
  }
  /// The factors of lines i1 and i2 of axes 1 and 2 (those that exist): w
  /// = n_1 n_2, g = (-, d_1 n_2, n_1 d_2).
  [[gnu::always_inline]] static void cross(const double* r, int M, int i1, int i2, double& w, Vec<D>& g) {
    w = 1.0, g = Vec<D>::Zero();
    if constexpr (D > 1) {
      const double n1 = r[2 * M + i1], d1 = r[3 * M + i1];
      const double n2 = D > 2 ? r[4 * M + i2] : 1.0, d2 = D > 2 ? r[5 * M + i2] : 0.0;
      w = n1 * n2;
      g[1 % D] = d1 * n2;
      if constexpr (D > 2) g[2 % D] = n1 * d2;
    }
  }
  /// The entry of axis 0's factors (n_0, d_0) with cross()'s w and g.
  [[gnu::always_inline]] static void product(double n0, double d0, double w, const Vec<D>& g, double& N,
                                             Vec<D>& dN) {
    N = n0 * w;
    dN[0] = d0 * w;
    for (int k = 1; k < D; ++k) dN[k] = n0 * g[k];
  }
};

/// Rebuilds the full table of `rows` (the same entries and bits as the
/// family's own table at the same points).
template <int D> void expand_product_rows(const ProductRows<D>& rows, BasisTable<D>& table);

/// S when every row of a table with these row offsets holds the same number
/// S >= 1 of entries (offset[p] = p S), else 0 (also for no rows). An OR of
/// offset[p] - p S in unsigned arithmetic (vectorises); it is 0 exactly when
/// the rows are even: before the first uneven row offset[p - 1] = (p - 1) S
/// < 2^31, so p S < 2^32 and the difference there cannot wrap to 0.
inline int uniform_row_width(const std::vector<int>& offset) {
  if (offset.size() < 2) return 0;
  const unsigned S = static_cast<unsigned>(offset[1]) - static_cast<unsigned>(offset[0]);
  unsigned differ = 0, expected = 0; // expected = p S (mod 2^32)
  for (const int o : offset) {
    differ |= static_cast<unsigned>(o) - expected;
    expected += S;
  }
  return differ == 0 ? static_cast<int>(S) : 0;
}

/// 2^D when every row of `table` holds the 2^D entries of the linear
/// stencil (row p is then entries [p 2^D, (p + 1) 2^D)), else 0. The passes
/// over the table take the fixed width as a compile-time trip count
/// (row_entries): the same operations in the same order, fewer loop tests.
template <int D> int linear_row_width(const BasisTable<D>& table) {
  constexpr int W = 1 << D;
  if (table.offset.size() < 2) return W; // no rows: trivially fixed
  return uniform_row_width(table.offset) == W ? W : 0;
}

/// Entries [first, second) of row p: W > 0 is a fixed row width.
template <int W> std::pair<int, int> row_entries(const int* offset, int p) {
  if constexpr (W > 0) return {p * W, p * W + W};
  else return {offset[p], offset[p + 1]};
}

/// The node-ordered (transposed) view of a BasisTable or of LatticeRows:
/// column I lists the entries e (and their particles p) whose node is I,
/// entries offset[I] .. offset[I+1]-1, in increasing particle order (entry
/// e of LatticeRows: row p's corner a, e = p 2^D + a). Gathering over a
/// column visits a node's contributions in the same order as a serial
/// scatter over particles, so parallel node loops reproduce its bits.
struct NodeColumns {
  std::vector<int> offset{0};
  std::vector<int> entry;
  std::vector<int> particle;
  /// Per-thread counts (scratch kept between steps).
  std::vector<int> scratch;
};

/// Builds `columns` for `table` over `nodes` nodes (OpenMP; the result does
/// not depend on the thread count).
template <int D> void transpose_basis_table(const BasisTable<D>& table, int nodes, NodeColumns& columns);
/// The same for the compact lattice rows (entry e = p 2^D + a).
template <int D> void transpose_basis_table(const LatticeRows<D>& rows, int nodes, NodeColumns& columns);
/// The same for the product rows (entry e: row p's entry e - offset[p]).
template <int D> void transpose_basis_table(const ProductRows<D>& rows, int nodes, NodeColumns& columns);

/// The per-point arrays of a table fill, one entry per point each (a null or
/// empty array: not used). `lambda`, `slope`, `history` and `cell_hint` are read and
/// updated (PointQuery); `neighbours` are the Verlet lists of the
/// points, kept from call to call; `deformation` the points' deformation
/// gradients (PointQuery::deformation).
template <int D> struct PointArrays {
  AlignedVector<Vec<D>>* lambda = nullptr;
  AlignedVector<MultiplierSlope<D>>* slope = nullptr;
  AlignedVector<MultiplierHistory<D>>* history = nullptr;
  std::vector<Index<D>>* cell_hint = nullptr;
  NeighbourLists<D>* neighbours = nullptr;
  const AlignedVector<Mat<D>>* deformation = nullptr;
  AlignedVector<Vec<D>>* moved = nullptr; ///< PointQuery::moved
};

/// Evaluates `basis` at every point x[p] into `table` with the per-point
/// arrays `a` (OpenMP over particles; the result does not depend on the
/// thread count). A BasisError is rethrown with the point's index prepended.
/// Throws std::invalid_argument when a non-empty array does not have one
/// entry per point.
template <int D>
void fill_basis_table(const Basis<D>& basis, const AlignedVector<Vec<D>>& x, const PointArrays<D>& a,
                      BasisTable<D>& table);

/// Evaluates `basis` at every point x[p] into `table` (OpenMP over particles;
/// the result does not depend on the thread count). lambda (may be empty) is
/// the per-point warm start of LME/max-ent, updated in place; cell_hint (may be
/// empty) the per-point cell hint; neighbours (may be null) the Verlet lists
/// of the points, used when the family searches nodes (search_radius() > 0)
/// and kept from call to call - the table is the same with or without them.
/// A BasisError is rethrown with the point's index prepended. Throws
/// std::invalid_argument when a non-empty lambda or cell_hint does not have
/// one entry per point. (lambda, cell_hint and neighbours are non-deduced: D
/// comes from the basis, so nullptr may be passed, and std::array's size_t
/// extent need not deduce the int D.)
template <int D>
void fill_basis_table(const Basis<D>& basis, const AlignedVector<Vec<D>>& x,
                      std::type_identity_t<AlignedVector<Vec<D>>>* lambda,
                      std::type_identity_t<std::vector<Index<D>>>* cell_hint,
                      BasisTable<D>& table,
                      std::type_identity_t<NeighbourLists<D>>* neighbours = nullptr);

} // namespace otmpm
