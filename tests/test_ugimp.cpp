// The `ugimp` family: uniform GIMP weights (Bardenhagen & Kober 2004) on an
// untouched Cartesian grid.
#include "otmpm/basis/families.hpp"
#include "otmpm/basis/linear.hpp"

#include "support.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <map>
#include <random>
#include <type_traits>

using namespace otmpm;
using namespace otmpm::test;

namespace {

using Dims = std::tuple<std::integral_constant<int, 1>, std::integral_constant<int, 2>, std::integral_constant<int, 3>>;

// Round-off tolerance of a sum of at most 4^3 terms a_I: about
// n * eps * sum |a_I| = 1.4e-14 sum |a_I|, so 1e-12 sum |a_I| is safe and
// still orders of magnitude below any modelling error.
constexpr double kRelTol = 1e-12;

template <int D> CartesianGrid<D> test_grid() { return offset_grid<D>({6, 4, 3}); }

/// Half-widths: a quarter cell (2 particles per cell and axis) on axis 0,
/// half a cell (1 per cell, the widest allowed) on axis 1, a sixth on axis 2.
template <int D> Vec<D> test_half_width(const CartesianGrid<D>& g) {
  const double frac[3] = {0.25, 0.5, 1.0 / 6.0};
  Vec<D> l;
  for (int k = 0; k < D; ++k) l[k] = frac[k] * g.h()[k];
  return l;
}

/// Random points, nodes, points next to nodes and to the boundary, the
/// breakpoints x_I +- l_p and x_I +- (h - l_p) of the weight.
template <int D> AlignedVector<Vec<D>> sample_points(const CartesianGrid<D>& g, const Vec<D>& lp, unsigned seed) {
  std::mt19937 rng(seed);
  AlignedVector<Vec<D>> pts;
  for (int n = 0; n < 150; ++n) pts.push_back(random_in_box<D>(rng, g.lower, g.upper));
  const Vec<D> h = g.h();
  for (int id = 0; id < g.num_nodes(); id += 2) {
    const Vec<D> xn = g.node_position(g.node_index(id));
    pts.push_back(xn);
    for (double off : {1.0, -1.0}) {
      Vec<D> y = xn + off * lp;
      Vec<D> z = xn + off * (h - lp);
      pts.push_back(y.cwiseMax(g.lower).cwiseMin(g.upper));
      pts.push_back(z.cwiseMax(g.lower).cwiseMin(g.upper));
    }
  }
  for (int n = 0; n < 40; ++n) {
    Vec<D> x = random_in_box<D>(rng, g.lower, g.upper);
    const int k = n % D;
    x[k] = (n / D) % 2 ? g.upper[k] : std::nextafter(g.lower[k], g.upper[k]);
    pts.push_back(x);
  }
  pts.push_back(g.lower);
  pts.push_back(g.upper);
  return pts;
}

template <int D> bool particle_inside(const CartesianGrid<D>& g, const Vec<D>& lp, const Vec<D>& x) {
  return ((x - lp).array() >= g.lower.array()).all() && ((x + lp).array() <= g.upper.array()).all();
}

/// Partition of unity, sum grad S = 0 and non-negativity everywhere; linear
/// completeness (sum S_I x_I = x, sum x_I (x) grad S_I = I) where the particle
/// box lies in the grid.
template <int D> void check_identities(const Basis<D>& b, const CartesianGrid<D>& g, const Vec<D>& lp, const Vec<D>& x) {
  Stencil<D> st;
  evaluate_at(b, x, st);
  REQUIRE(st.size() > 0);
  CHECK(st.size() <= b.max_stencil());
  for (int a = 0; a < st.size(); ++a) CHECK(st.N[a] > 0.0); // zero weights are not part of the stencil
  const StencilSums<D> s = stencil_sums(b, st);
  INFO("point ", format_point<D>(x));
  CHECK(std::abs(s.sumN - 1.0) <= kRelTol * s.absN);
  for (int k = 0; k < D; ++k) CHECK(std::abs(s.sumG[k]) <= kRelTol * s.absG[k] + 1e-300);
  if (!particle_inside(g, lp, x)) return;
  check_linear_completeness(s, x, kRelTol);
}

template <int D> std::unique_ptr<Basis<D>> test_basis() {
  const CartesianGrid<D> g = test_grid<D>();
  return make_ugimp_basis<D>(NodeSet<D>::cartesian(g), test_half_width(g));
}

} // namespace

TEST_CASE("ugimp 1D weight is the hat function averaged over the particle") {
  // S(xi) = (1 / 2 lp) int_{xi - lp}^{xi + lp} hat(s) ds, checked against a
  // midpoint rule with 20000 cells: its error is below 1e-8 (O(dx^2) on the
  // smooth pieces, O(dx^2 / h) at the kinks of the hat).
  const double h = 0.7;
  for (double lp : {0.1 * h, 0.25 * h, 0.5 * h}) {
    for (double xi = -1.6 * h; xi <= 1.6 * h; xi += 0.0371 * h) {
      const int n = 20000;
      double avg = 0;
      for (int i = 0; i < n; ++i) {
        const double s = xi - lp + (i + 0.5) * 2 * lp / n;
        avg += std::max(0.0, 1.0 - std::abs(s) / h);
      }
      avg /= n;
      CHECK(detail::ugimp_weight(xi, h, lp).S == doctest::Approx(avg).epsilon(1e-8));
    }
  }
}

TEST_CASE("ugimp 1D weight and its derivative are continuous at the breakpoints") {
  // One step of 1e-9 h changes S by at most 1e-9 (|dS| <= 1/h) and dS by at
  // most 1e-9 h * max|S''| = 1e-9 / lp; 1e-8 bounds both with margin.
  const double h = 1.3, lp = 0.3 * h, eps = 1e-9 * h;
  for (double b : {lp, h - lp, h + lp, -lp, -(h - lp), -(h + lp), 0.0}) {
    const auto lo = detail::ugimp_weight(b - eps, h, lp), hi = detail::ugimp_weight(b + eps, h, lp);
    CHECK(std::abs(lo.S - hi.S) <= 1e-8);
    CHECK(std::abs(lo.dS - hi.dS) * h <= 1e-8 * h / lp);
  }
  CHECK(detail::ugimp_weight(0.0, h, lp).S == doctest::Approx(1.0 - lp / (2 * h)));
  CHECK(detail::ugimp_weight(h + lp, h, lp).S == 0.0);
  CHECK(detail::ugimp_weight(h + lp, h, lp).dS == 0.0);
}

TEST_CASE_TEMPLATE_DEFINE("ugimp: partition of unity everywhere, linear completeness in the interior", T, pu_id) {
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  const Vec<D> lp = test_half_width(g);
  const auto b = test_basis<D>();
  CHECK(b->kind() == "ugimp");
  for (const Vec<D>& x : sample_points(g, lp, 1u)) check_identities(*b, g, lp, x);
}
TEST_CASE_TEMPLATE_APPLY(pu_id, Dims);

TEST_CASE_TEMPLATE_DEFINE("ugimp: next to the grid edge the ghost weight goes to the boundary node", T, edge_id) {
  // Documents what is lost at the edge: a particle box poking out of the
  // grid keeps partition of unity but not linear completeness.
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  const Vec<D> lp = test_half_width(g);
  const auto b = test_basis<D>();
  Vec<D> x = 0.5 * (g.lower + g.upper);
  x[0] = g.lower[0] + 0.5 * lp[0]; // box reaches lp / 2 beyond the lower edge
  Stencil<D> st;
  evaluate_at(*b, x, st);
  double sumN = 0, sumX0 = 0;
  for (int a = 0; a < st.size(); ++a) {
    sumN += st.N[a];
    sumX0 += st.N[a] * b->nodes().position(st.node[a])[0];
  }
  CHECK(sumN == doctest::Approx(1.0).epsilon(1e-14));
  // The ghost node at lower - h lies h + lp/2 < h + lp away, so it has the
  // weight S_ghost = lp / (16 h) > 0, which node 0 (h further right) takes
  // over: sum S_I x_I overshoots x by h * S_ghost.
  const double h0 = g.h()[0];
  const double S_ghost = detail::ugimp_weight(x[0] - (g.lower[0] - h0), h0, lp[0]).S;
  REQUIRE(S_ghost > 0.0);
  CHECK(sumX0 - x[0] == doctest::Approx(h0 * S_ghost).epsilon(1e-10));
  CHECK_FALSE(b->linearly_complete());
}
TEST_CASE_TEMPLATE_APPLY(edge_id, Dims);

TEST_CASE_TEMPLATE_DEFINE("ugimp gradients equal central differences", T, fd_id) {
  // S is C1 with |S''| <= 1 / (h lp), so a central difference with step
  // delta errs by at most delta / (2 h lp) anywhere, kinks of S' included:
  // with delta = 1e-6 h and lp >= h/6 that is 3e-6 / h; cancellation adds
  // eps / delta ~ 2e-10 / h. Tolerance 1e-5 / h.
  constexpr int D = T::value;
  const CartesianGrid<D> g = test_grid<D>();
  const Vec<D> lp = test_half_width(g);
  const auto b = test_basis<D>();
  const double h = g.h().minCoeff();
  const double delta = 1e-6 * h, tol = 1e-5 / h;
  // Keep x +- delta in the grid.
  for (const Vec<D>& x0 : sample_points(g, lp, 2u)) {
    const Vec<D> x = x0.cwiseMax(g.lower + Vec<D>::Constant(2 * delta)).cwiseMin(g.upper - Vec<D>::Constant(2 * delta));
    Stencil<D> st;
    evaluate_at(*b, x, st);
    for (int k = 0; k < D; ++k) {
      Vec<D> e = Vec<D>::Zero();
      e[k] = delta;
      auto plus = values_at(*b, Vec<D>(x + e));
      auto minus = values_at(*b, Vec<D>(x - e));
      for (int a = 0; a < st.size(); ++a) {
        INFO("point ", format_point<D>(x), " node ", st.node[a], " axis ", k);
        CHECK(std::abs((plus[st.node[a]] - minus[st.node[a]]) / (2 * delta) - st.dN[a][k]) <= tol);
      }
    }
  }
}
TEST_CASE_TEMPLATE_APPLY(fd_id, Dims);

TEST_CASE("ugimp tends to the linear hat functions as the particle shrinks") {
  // |S - hat| <= lp / (2 h) (the largest gap is at the node, 1 - lp / 2h).
  const CartesianGrid<2> g = test_grid<2>();
  const Vec<2> lp = 1e-4 * g.h();
  const auto ug = make_ugimp_basis<2>(NodeSet<2>::cartesian(g), lp);
  const auto lin = make_linear_basis<2>(NodeSet<2>::cartesian(g));
  std::mt19937 rng(5);
  for (int n = 0; n < 100; ++n) {
    const Vec<2> x = random_in_box<2>(rng, g.lower + lp, g.upper - lp);
    auto a = values_at(*ug, x);
    for (const auto& [I, N] : values_at(*lin, x)) CHECK(std::abs(a[I] - N) <= 1.0001e-4);
  }
}

TEST_CASE("ugimp stencil sizes: 3 nodes per axis at most below half-cell particles") {
  const CartesianGrid<3> g = test_grid<3>();
  const auto b = make_ugimp_basis<3>(NodeSet<3>::cartesian(g), 0.25 * g.h());
  CHECK(b->max_stencil() == 27);
  // lp = h/4 at a node: the node and both neighbours (|xi| = h < h + lp).
  const Vec<3> node = g.node_position({2, 2, 1});
  CHECK(values_at(*b, node).size() == 27u);
  // At a cell centre: |xi| = h/2 or 3h/2 > h + lp, so 2 nodes per axis.
  CHECK(values_at(*b, Vec<3>(node + 0.5 * g.h())).size() == 8u);
  CHECK(make_ugimp_basis<3>(NodeSet<3>::cartesian(g), 0.5 * g.h())->max_stencil() == 64);
}

TEST_CASE("ugimp is refused on a perturbed grid, a cloud, and bad half-widths") {
  const CartesianGrid<2> g = test_grid<2>();
  const Vec<2> lp = 0.25 * g.h();
  CHECK_THROWS_WITH_AS(make_ugimp_basis<2>(NodeSet<2>::perturbed(g, 0.2, 1u), lp),
                       doctest::Contains("ugimp needs an unperturbed Cartesian grid"), InputError);
  AlignedVector<Vec<2>> x{Vec<2>(0, 0), Vec<2>(1, 0), Vec<2>(0, 1)};
  CHECK_THROWS_WITH_AS(make_ugimp_basis<2>(NodeSet<2>::cloud(x, 1.0), lp),
                       doctest::Contains("ugimp needs an unperturbed Cartesian grid"), InputError);
  NodeSet<2> moved = NodeSet<2>::cartesian(g);
  moved.advect(AlignedVector<Vec<2>>(static_cast<std::size_t>(moved.size()), Vec<2>(1e-3, 0)));
  CHECK_THROWS_AS(make_ugimp_basis<2>(moved, lp), InputError);
  CHECK_THROWS_AS(make_ugimp_basis<2>(NodeSet<2>::cartesian(g), Vec<2>::Zero()), InputError);
  CHECK_THROWS_AS(make_ugimp_basis<2>(NodeSet<2>::cartesian(g), 0.6 * g.h()), InputError);
}

TEST_CASE("ugimp refuses to evaluate after its nodes moved") {
  const CartesianGrid<2> g = test_grid<2>();
  auto b = make_ugimp_basis<2>(NodeSet<2>::cartesian(g), 0.25 * g.h());
  const AlignedVector<Vec<2>> dx(static_cast<std::size_t>(b->nodes().size()), Vec<2>(1e-3, 0));
  CHECK_THROWS_AS(b->nodes_moved(dx), InputError);
  b->nodes().advect(dx);
  Stencil<2> st;
  PointQuery<2> q;
  q.x = 0.5 * (g.lower + g.upper);
  CHECK_THROWS_WITH_AS(b->evaluate(q, st), doctest::Contains(format_point<2>(q.x).c_str()), BasisError);
}

TEST_CASE_TEMPLATE_DEFINE("ugimp: a point outside the grid is a BasisError naming the point", T, out_id) {
  constexpr int D = T::value;
  const auto b = test_basis<D>();
  const CartesianGrid<D> g = test_grid<D>();
  for (const Vec<D>& x : {Vec<D>(g.lower - 0.01 * g.h()), Vec<D>(g.upper + 1e-9 * g.h())}) {
    Stencil<D> st;
    PointQuery<D> q;
    q.x = x;
    CHECK_THROWS_WITH_AS(b->evaluate(q, st), doctest::Contains(format_point<D>(x).c_str()), BasisError);
  }
}
TEST_CASE_TEMPLATE_APPLY(out_id, Dims);
