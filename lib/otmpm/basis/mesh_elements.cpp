/// \file mesh_elements.cpp
/// The linear family on a mesh's own elements (mesh_elements.hpp).
#include "otmpm/basis/mesh_elements.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace otmpm {

namespace {

/// Newton iterations of the inverse multilinear map, and its tolerance on xi.
constexpr int kNewtonIterations = 30;
constexpr double kNewtonTolerance = 1e-13;

/// The shape functions of an element at xi and their derivatives dN_a/dxi
/// (Gmsh's reference elements: the unit simplex, [-1, 1]^D).
template <int D> struct ElementValues {
  std::array<double, 8> N{};
  std::array<Vec<D>, 8> dN{};
};

template <int D> ElementValues<D> shape(int corners, const Vec<D>& xi) {
  ElementValues<D> v;
  if (corners == D + 1) { // simplex: N_0 = 1 - sum xi, N_k = xi_k
    v.N[0] = 1.0 - xi.sum();
    v.dN[0] = Vec<D>::Constant(-1.0);
    for (int k = 0; k < D; ++k) {
      v.N[static_cast<std::size_t>(k + 1)] = xi[k];
      v.dN[static_cast<std::size_t>(k + 1)] = Vec<D>::Unit(k);
    }
    return v;
  }
  for (int a = 0; a < corners; ++a) { // N_a = prod_k (1 + xi_k s_ak) / 2
    Vec<D> s; // corner a of [-1, 1]^D in Gmsh's order: (0,0) (1,0) (1,1) (0,1) per face
    const int q = a % 4;
    s[0] = (q == 1 || q == 2) ? 1.0 : -1.0;
    s[1] = q >= 2 ? 1.0 : -1.0;
    if constexpr (D == 3) s[2] = a >= 4 ? 1.0 : -1.0;
    double N = 1.0;
    Vec<D> dN = Vec<D>::Ones();
    for (int k = 0; k < D; ++k) {
      const double f = 0.5 * (1.0 + xi[k] * s[k]);
      N *= f;
      for (int j = 0; j < D; ++j) dN[j] *= j == k ? 0.5 * s[k] : f;
    }
    v.N[static_cast<std::size_t>(a)] = N;
    v.dN[static_cast<std::size_t>(a)] = dN;
  }
  return v;
}

/// How far xi lies outside the reference element (0 inside).
template <int D> double outside(int corners, const Vec<D>& xi) {
  if (corners == D + 1) return std::max({0.0, -xi.minCoeff(), xi.sum() - 1.0});
  return std::max(0.0, xi.cwiseAbs().maxCoeff() - 1.0);
}

template <int D> class ElementBasis final : public Basis<D> {
public:
  ElementBasis(NodeSet<D> nodes, std::vector<ElementNodes> elements)
      : nodes_(std::move(nodes)), elements_(std::move(elements)) {
    if (elements_.empty()) throw InputError("linear basis on a mesh: no element");
    const std::size_t n = static_cast<std::size_t>(nodes_.size());
    std::vector<int> count(n + 1, 0);
    for (std::size_t e = 0; e < elements_.size(); ++e) {
      const ElementNodes& el = elements_[e];
      const bool known = el.corners == D + 1 || el.corners == (1 << D);
      if (!known) throw InputError("linear basis on a mesh: element " + std::to_string(e) + " has " +
                                   std::to_string(el.corners) + " corners");
      for (int a = 0; a < el.corners; ++a) {
        const int I = el.node[static_cast<std::size_t>(a)];
        if (I < 0 || static_cast<std::size_t>(I) >= n)
          throw InputError("linear basis on a mesh: element " + std::to_string(e) + " names node " +
                           std::to_string(I) + " of " + std::to_string(n));
        ++count[static_cast<std::size_t>(I) + 1];
      }
    }
    for (std::size_t I = 0; I < n; ++I) count[I + 1] += count[I];
    node_elements_.resize(static_cast<std::size_t>(count[n]));
    start_ = count;
    for (std::size_t e = 0; e < elements_.size(); ++e)
      for (int a = 0; a < elements_[e].corners; ++a)
        node_elements_[static_cast<std::size_t>(count[static_cast<std::size_t>(elements_[e].node[static_cast<std::size_t>(a)])]++)] =
            static_cast<int>(e);
    build_buckets();
  }

  std::string_view kind() const override { return "linear"; }
  const NodeSet<D>& nodes() const override { return nodes_; }
  NodeSet<D>& nodes() override { return nodes_; }
  void nodes_moved(const AlignedVector<Vec<D>>&) override {} // nothing cached of the positions
  bool linearly_complete() const override { return true; }
  int max_stencil() const override { return 1 << D; }
  PointStateUse point_state_use(bool) const override { return {.cell_hint = true}; }

  void evaluate(const PointQuery<D>& q, Stencil<D>& out) const override {
    require_finite_query("linear", q);
    const int hint = q.cell_hint ? (*q.cell_hint)[0] : 0;
    Vec<D> xi;
    const int e = locate(q, hint >= 0 && hint < static_cast<int>(elements_.size()) ? hint : 0, xi);
    if (q.cell_hint) (*q.cell_hint)[0] = e;
    const ElementNodes& el = elements_[static_cast<std::size_t>(e)];
    const ElementValues<D> v = shape<D>(el.corners, xi);
    Mat<D> J = Mat<D>::Zero(); // dx/dxi
    for (int a = 0; a < el.corners; ++a) J += corner(el, a) * v.dN[static_cast<std::size_t>(a)].transpose();
    const double det = J.determinant();
    if (!(det > 0.0) && !(det < 0.0))
      throw BasisError(error_message("linear basis: point ", q.x, ": its element ", e, " is degenerate (det J = ",
                                     det, ")"));
    const Mat<D> JinvT = J.inverse().transpose();
    out.clear();
    for (int a = 0; a < el.corners; ++a)
      out.push(el.node[static_cast<std::size_t>(a)], v.N[static_cast<std::size_t>(a)],
               JinvT * v.dN[static_cast<std::size_t>(a)]);
  }

private:
  const Vec<D>& corner(const ElementNodes& el, int a) const {
    return nodes_.position(el.node[static_cast<std::size_t>(a)]);
  }

  /// xi of x in element e (the inverse of its map) and how far outside the
  /// reference element it lies (infinite when Newton does not converge).
  double local(int e, const Vec<D>& x, Vec<D>& xi) const {
    const ElementNodes& el = elements_[static_cast<std::size_t>(e)];
    xi.setZero();
    for (int it = 0; it < kNewtonIterations; ++it) {
      const ElementValues<D> v = shape<D>(el.corners, xi);
      Vec<D> r = x;
      Mat<D> J = Mat<D>::Zero();
      for (int a = 0; a < el.corners; ++a) {
        r -= v.N[static_cast<std::size_t>(a)] * corner(el, a);
        J += corner(el, a) * v.dN[static_cast<std::size_t>(a)].transpose();
      }
      const Eigen::FullPivLU<Mat<D>> lu(J);
      if (!lu.isInvertible()) break;
      const Vec<D> step = lu.solve(r);
      xi += step;
      if (el.corners == D + 1 || step.norm() < kNewtonTolerance) return outside<D>(el.corners, xi);
    }
    return std::numeric_limits<double>::infinity();
  }

  /// The element that holds x (its xi): the hinted one (or, when x is more
  /// than an element from it, the best of those whose box as read meets the
  /// bucket of x), else a walk over neighbours (elements sharing a node)
  /// that goes on while it gets nearer; when the walk stops farther than kElementSlack outside, the
  /// first of all elements that holds it, or the nearest. BasisError when
  /// that one is farther than kElementSlack too.
  int locate(const PointQuery<D>& q, int e, Vec<D>& xi) const {
    double d = local(e, q.x, xi);
    if (d > 1.0) { // more than an element away: start from the bucket of x (the mesh as read)
      const long long c = flat(cell_of(q.x));
      for (int k = bucket_start_[static_cast<std::size_t>(c)]; d > 0.0 && k < bucket_start_[static_cast<std::size_t>(c) + 1]; ++k) {
        Vec<D> y;
        const int f = bucket_elements_[static_cast<std::size_t>(k)];
        const double df = local(f, q.x, y);
        if (df < d) e = f, d = df, xi = y;
      }
    }
    for (std::size_t walk = 0; d > 0.0 && walk < elements_.size(); ++walk) {
      int best = -1;
      double best_d = d;
      Vec<D> best_xi = xi;
      for (int a = 0; a < elements_[static_cast<std::size_t>(e)].corners; ++a) {
        const std::size_t I = static_cast<std::size_t>(elements_[static_cast<std::size_t>(e)].node[static_cast<std::size_t>(a)]);
        for (int k = start_[I]; k < start_[I + 1]; ++k) {
          const int f = node_elements_[static_cast<std::size_t>(k)];
          Vec<D> y;
          const double df = f == e ? d : local(f, q.x, y);
          if (df < best_d) best = f, best_d = df, best_xi = y;
        }
      }
      if (best < 0) break; // no neighbour nearer: search them all
      e = best, d = best_d, xi = best_xi;
    }
    // stuck within the slack: the point lies on the mesh's surface, moved out a little (no search of all)
    for (int f = 0; d > kElementSlack && f < static_cast<int>(elements_.size()); ++f) {
      Vec<D> y;
      const double df = local(f, q.x, y);
      if (df < d) e = f, d = df, xi = y;
    }
    if (d > kElementSlack)
      throw BasisError(error_message("linear basis: point ", q.x, q.id >= 0 ? " (id " + std::to_string(q.id) + ")" : "",
                                     " lies outside every element of the mesh"));
    return e;
  }

  /// The bucket grid of the elements' boxes as the nodes stand now (at
  /// construction: the mesh as read), about one element per cell.
  void build_buckets() {
    std::vector<std::pair<Vec<D>, Vec<D>>> box(elements_.size());
    lo_ = Vec<D>::Constant(std::numeric_limits<double>::infinity());
    Vec<D> hi = -lo_;
    for (std::size_t e = 0; e < elements_.size(); ++e) {
      box[e] = {corner(elements_[e], 0), corner(elements_[e], 0)};
      for (int a = 1; a < elements_[e].corners; ++a)
        box[e] = {box[e].first.cwiseMin(corner(elements_[e], a)), box[e].second.cwiseMax(corner(elements_[e], a))};
      lo_ = lo_.cwiseMin(box[e].first), hi = hi.cwiseMax(box[e].second);
    }
    const int per_axis = std::max(1, static_cast<int>(std::round(std::pow(static_cast<double>(elements_.size()), 1.0 / D))));
    cells_.fill(per_axis);
    cell_ = ((hi - lo_) / per_axis).cwiseMax(Vec<D>::Constant(std::numeric_limits<double>::min()));
    std::vector<std::vector<int>> lists(static_cast<std::size_t>(std::pow(per_axis, D)));
    for (std::size_t e = 0; e < box.size(); ++e) {
      const Index<D> a = cell_of(box[e].first), b = cell_of(box[e].second);
      Index<D> c = a;
      while (true) { // every cell of [a, b]
        lists[static_cast<std::size_t>(flat(c))].push_back(static_cast<int>(e));
        int k = 0;
        while (k < D && c[k] == b[k]) c[k] = a[k], ++k;
        if (k == D) break;
        ++c[k];
      }
    }
    bucket_start_.assign(1, 0);
    for (const std::vector<int>& l : lists) {
      bucket_elements_.insert(bucket_elements_.end(), l.begin(), l.end());
      bucket_start_.push_back(static_cast<int>(bucket_elements_.size()));
    }
  }
  Index<D> cell_of(const Vec<D>& x) const {
    Index<D> c;
    for (int k = 0; k < D; ++k)
      c[k] = std::clamp(static_cast<int>(std::floor((x[k] - lo_[k]) / cell_[k])), 0, cells_[k] - 1);
    return c;
  }
  long long flat(const Index<D>& c) const {
    long long f = 0;
    for (int k = D - 1; k >= 0; --k) f = f * cells_[k] + c[k];
    return f;
  }

  NodeSet<D> nodes_;
  std::vector<ElementNodes> elements_;
  Vec<D> lo_, cell_;
  Index<D> cells_{};
  std::vector<int> bucket_start_, bucket_elements_; ///< CSR: the elements whose box meets each cell
  std::vector<int> start_;         ///< CSR: the elements of node I are node_elements_[start_[I] .. start_[I+1])
  std::vector<int> node_elements_;
};

} // namespace

template <int D>
std::unique_ptr<Basis<D>> make_element_basis(NodeSet<D> nodes, std::vector<ElementNodes> elements) {
  return std::make_unique<ElementBasis<D>>(std::move(nodes), std::move(elements));
}

template std::unique_ptr<Basis<2>> make_element_basis<2>(NodeSet<2>, std::vector<ElementNodes>);
template std::unique_ptr<Basis<3>> make_element_basis<3>(NodeSet<3>, std::vector<ElementNodes>);

} // namespace otmpm
