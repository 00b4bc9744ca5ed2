// Tests of the adapted locality of LME (basis.metric, docs/theory.md
// sect. 4.6): the deformation metric beta_p = gamma_lme / h^2 M_p, M_p =
// (F F^T)^-1 scaled to det 1, and the node-spacing metric beta_I =
// gamma_lme / h_I^2.
//
// Tolerances (h = nodal spacing):
// * partition of unity |sum N - 1| <= 1e-12 and |sum grad N| <= 1e-12 sum
//   |grad N|: normalised explicitly / exact by construction, round-off only;
// * linear completeness |sum N_I x_I - x| <= 1e-10 h and |sum x_I (x) grad N_I
//   - I| <= 1e-10: the Newton tolerance (1e-12 h) plus round-off times the
//   conditioning of J, which grows with the anisotropy (M's eigenvalues
//   1/4 .. 4 here);
// * gradients vs central differences with step 2e-6 h, Newton solved to
//   1e-14 h: truncation and solver noise near 1e-9 / h (as in test_lme.cpp);
//   tolerance 2e-8 / h.
#include "otmpm/basis/families.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/basis/lme.hpp"
#include "otmpm/scene/scene.hpp"
#include "support.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

using namespace otmpm;
using namespace otmpm::test;

namespace {

constexpr IdentityTolerances kIdentityTol{1e-12, 1e-12, 1e-10, 1e-10};
constexpr double kFdStep = 2e-6; // times h
constexpr double kFdTol = 2e-8;  // times 1/h

BasisOptions lme_options(const std::string& metric, double gamma = 4.0) {
  BasisOptions opt;
  opt.kind = "lme";
  opt.values["gamma_lme"] = gamma;
  opt.metric = metric;
  return opt;
}

/// A stretch along a rotated axis, with shear: F F^T has eigenvalues far from
/// one and M_p is not diagonal in the lattice axes.
Mat<2> stretch_2d() {
  Mat<2> F;
  F << 1.6, 0.3, -0.2, 0.8;
  return F;
}

Mat<3> stretch_3d() {
  Mat<3> F;
  F << 1.5, 0.2, 0.0, -0.1, 0.9, 0.15, 0.05, 0.0, 0.8;
  return F;
}

template <int D> void evaluate_with(const Basis<D>& b, const Vec<D>& x, const Mat<D>* F, Stencil<D>& st) {
  PointQuery<D> q;
  q.x = x;
  q.deformation = F;
  b.evaluate(q, st);
}

/// The identities of check_identities (support.hpp) at points evaluated with F.
template <int D> Identities<D> identities_with(const Basis<D>& basis, const AlignedVector<Vec<D>>& pts, const Mat<D>& F) {
  Identities<D> id;
  Stencil<D> st;
  const double h = basis.nodes().spacing();
  for (const Vec<D>& x : pts) {
    evaluate_with<D>(basis, x, &F, st);
    const StencilSums<D> s = stencil_sums<D>(basis, st);
    double abs_dN = 0;
    for (int a = 0; a < st.size(); ++a) {
      abs_dN += st.dN[a].norm();
      id.min_N = std::min(id.min_N, st.N[a]);
    }
    const double e_c = (s.sumX - x).norm() / h, e_gc = (s.sumXG - Mat<D>::Identity()).norm();
    if (e_gc > id.gradient_consistency || e_c > id.completeness) id.worst_point = x;
    id.partition = std::max(id.partition, std::abs(s.sumN - 1.0));
    id.gradient_sum = std::max(id.gradient_sum, s.sumG.norm() / abs_dN);
    id.completeness = std::max(id.completeness, e_c);
    id.gradient_consistency = std::max(id.gradient_consistency, e_gc);
  }
  return id;
}

/// Random points of [0.3, 0.7]^D (the stretched supports stay inside the unit box).
template <int D> AlignedVector<Vec<D>> inner_points(int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.3, 0.7);
  AlignedVector<Vec<D>> pts(static_cast<std::size_t>(count));
  for (auto& p : pts)
    for (int k = 0; k < D; ++k) p[k] = u(rng);
  return pts;
}

/// max_I |grad N_I - central difference| h at x, all evaluated with F.
template <int D> double fd_error_with(const Basis<D>& b, const Vec<D>& x, const Mat<D>& F) {
  const double h = b.nodes().spacing(), eps = kFdStep * h;
  auto dense = [&](const Vec<D>& y, std::vector<double>& N, AlignedVector<Vec<D>>* dN) {
    Stencil<D> st;
    evaluate_with<D>(b, y, &F, st);
    N.assign(static_cast<std::size_t>(b.nodes().size()), 0.0);
    if (dN) dN->assign(N.size(), Vec<D>::Zero());
    for (int a = 0; a < st.size(); ++a) {
      N[st.node[a]] = st.N[a];
      if (dN) (*dN)[st.node[a]] = st.dN[a];
    }
  };
  std::vector<double> N, Np, Nm;
  AlignedVector<Vec<D>> dN;
  dense(x, N, &dN);
  double err = 0;
  for (int k = 0; k < D; ++k) {
    Vec<D> e = Vec<D>::Zero();
    e[k] = eps;
    dense(x + e, Np, nullptr);
    dense(x - e, Nm, nullptr);
    for (std::size_t I = 0; I < N.size(); ++I) err = std::max(err, std::abs((Np[I] - Nm[I]) / (2 * eps) - dN[I][k]) * h);
  }
  return err;
}

template <int D> void require_same(const Stencil<D>& a, const Stencil<D>& b) {
  REQUIRE(a.size() == b.size());
  for (int i = 0; i < a.size(); ++i) {
    CHECK(a.node[i] == b.node[i]);
    CHECK(a.N[i] == b.N[i]);
    CHECK(a.dN[i] == b.dN[i]);
  }
}

/// M_p of the deformation metric, written out.
template <int D> Mat<D> metric_of(const Mat<D>& F) {
  const Mat<D> b = F * F.transpose();
  return b.inverse() * std::pow(b.determinant(), 1.0 / D);
}

/// Distance from node I to its nearest other node, by brute force.
template <int D> double nearest(const NodeSet<D>& nodes, int I) {
  double d = std::numeric_limits<double>::infinity();
  for (int J = 0; J < nodes.size(); ++J)
    if (J != I) d = std::min(d, (nodes.position(J) - nodes.position(I)).norm());
  return d;
}

} // namespace

TEST_CASE("lme metric deformation: partition of unity and linear completeness with an anisotropic metric") {
  const auto n2 = NodeSet<2>::cartesian(unit_grid<2>(12));
  const auto b2 = make_lme_basis<2>(n2, lme_options("deformation"));
  Identities<2> id2 = identities_with<2>(*b2, inner_points<2>(60, 3), stretch_2d());
  require_identities<2>(id2, id2.worst_point, kIdentityTol);
  const auto p2 = NodeSet<2>::perturbed(unit_grid<2>(12), 0.3, 4);
  id2 = identities_with<2>(*make_lme_basis<2>(p2, lme_options("deformation")), inner_points<2>(60, 5), stretch_2d());
  require_identities<2>(id2, id2.worst_point, kIdentityTol);
  const auto n3 = NodeSet<3>::cartesian(unit_grid<3>(8));
  const Identities<3> id3 =
      identities_with<3>(*make_lme_basis<3>(n3, lme_options("deformation")), inner_points<3>(30, 6), stretch_3d());
  require_identities<3>(id3, id3.worst_point, kIdentityTol);
}

TEST_CASE("lme metric deformation: gradients agree with central differences") {
  BasisOptions opt = lme_options("deformation");
  opt.values["newton_tolerance"] = 1e-14;
  const auto b2 = make_lme_basis<2>(NodeSet<2>::perturbed(unit_grid<2>(10), 0.3, 7), opt);
  const auto b3 = make_lme_basis<3>(NodeSet<3>::cartesian(unit_grid<3>(6)), opt);
  double err2 = 0, err3 = 0;
  for (const auto& x : inner_points<2>(20, 8)) err2 = std::max(err2, fd_error_with<2>(*b2, x, stretch_2d()));
  for (const auto& x : inner_points<3>(8, 9)) err3 = std::max(err3, fd_error_with<3>(*b3, x, stretch_3d()));
  CHECK(err2 <= kFdTol);
  CHECK(err3 <= kFdTol);
}

TEST_CASE("lme metric deformation: the support is the ellipse dx^T beta M_p dx <= -ln(tol)") {
  // F = diag(2, 1): M = diag(1/2, 2), the support reaches sqrt(2) R along x
  // and R / sqrt(2) along y (R = h sqrt(-ln tol / gamma)).
  const auto nodes = NodeSet<2>::cartesian(unit_grid<2>(20));
  const BasisOptions opt = lme_options("deformation");
  const auto b = make_lme_basis<2>(nodes, opt);
  const Mat<2> F = Vec<2>(2.0, 1.0).asDiagonal();
  const Mat<2> B = opt.value("gamma_lme") / (nodes.spacing() * nodes.spacing()) * metric_of<2>(F);
  const Vec<2> x(0.512, 0.487);
  Stencil<2> st;
  evaluate_with<2>(*b, x, &F, st);
  std::vector<int> expected;
  for (int I = 0; I < nodes.size(); ++I) {
    const Vec<2> d = x - nodes.position(I);
    if (d.dot(B * d) <= -std::log(opt.value("tolerance"))) expected.push_back(I);
  }
  std::vector<int> got(st.node.begin(), st.node.end());
  std::sort(got.begin(), got.end());
  CHECK(got == expected);
  double reach_x = 0, reach_y = 0;
  for (const int I : got) {
    reach_x = std::max(reach_x, std::abs(nodes.position(I)[0] - x[0]));
    reach_y = std::max(reach_y, std::abs(nodes.position(I)[1] - x[1]));
  }
  const double R = nodes.spacing() * std::sqrt(-std::log(opt.value("tolerance")) / opt.value("gamma_lme"));
  CHECK(reach_x > R);                  // beyond the isotropic radius along the stretch
  CHECK(reach_y <= R / std::sqrt(2.0)); // within R / sqrt(2) across it
}

TEST_CASE("lme metric deformation: F = I (or no F) reproduces the isotropic basis bit for bit") {
  const auto nodes = NodeSet<2>::perturbed(unit_grid<2>(10), 0.25, 11);
  const auto iso = make_lme_basis<2>(nodes, lme_options("isotropic"));
  const auto def = make_lme_basis<2>(nodes, lme_options("deformation"));
  const Mat<2> I = Mat<2>::Identity();
  Stencil<2> a, b, c;
  for (const auto& x : unit_box_points<2>(nodes, 40, 12)) {
    evaluate_with<2>(*iso, x, nullptr, a);
    evaluate_with<2>(*def, x, &I, b);
    evaluate_with<2>(*def, x, nullptr, c);
    require_same<2>(a, b);
    require_same<2>(a, c);
  }
  // through the table fill with the Verlet lists and warm starts, as the engine calls it
  const AlignedVector<Vec<2>> x = unit_box_points<2>(nodes, 200, 13);
  const AlignedVector<Mat<2>> F(x.size(), Mat<2>::Identity());
  iso->bind_points(static_cast<int>(x.size()), true);
  def->bind_points(static_cast<int>(x.size()), true);
  CHECK(def->point_state_use(true).deformation);
  CHECK(!iso->point_state_use(true).deformation);
  BasisTable<2> ta, tb;
  for (int step = 0; step < 2; ++step) {
    iso->evaluate_points(x, ta);
    def->evaluate_points(x, tb, &F);
    CHECK(ta.node == tb.node);
    CHECK(ta.N == tb.N);
    CHECK(ta.dN == tb.dN);
  }
}

TEST_CASE("lme metric deformation: missing or singular F is refused") {
  const auto nodes = NodeSet<2>::cartesian(unit_grid<2>(8));
  const auto b = make_lme_basis<2>(nodes, lme_options("deformation"));
  const AlignedVector<Vec<2>> x(3, Vec<2>(0.5, 0.5));
  b->bind_points(3, false);
  BasisTable<2> t;
  CHECK_THROWS_AS(b->evaluate_points(x, t), std::invalid_argument);
  const AlignedVector<Mat<2>> two(2, Mat<2>::Identity());
  CHECK_THROWS_AS(b->evaluate_points(x, t, &two), std::invalid_argument);
  Mat<2> singular;
  singular << 1.0, 2.0, 0.5, 1.0;
  Stencil<2> st;
  CHECK_THROWS_WITH_AS(evaluate_with<2>(*b, Vec<2>(0.5, 0.5), &singular, st),
                       doctest::Contains("not positive definite"), BasisError);
}

TEST_CASE("lme metric node_spacing: beta_I = gamma_lme / h_I^2 with h_I the nearest-node distance") {
  const auto nodes = NodeSet<2>::perturbed(unit_grid<2>(8), 0.3, 21);
  const BasisOptions opt = lme_options("node_spacing");
  const auto b = make_lme_basis<2>(nodes, opt);
  const auto* lme = dynamic_cast<const maxent::MaxEntBasis<2, maxent::GaussianPrior<2>>*>(b.get());
  REQUIRE(lme != nullptr);
  REQUIRE(lme->node_beta().size() == static_cast<std::size_t>(nodes.size()));
  double R_max = 0;
  for (int I = 0; I < nodes.size(); ++I) {
    const double hI = nearest<2>(nodes, I);
    CHECK(lme->node_beta()[I] == doctest::Approx(opt.value("gamma_lme") / (hI * hI)).epsilon(1e-14));
    R_max = std::max(R_max, hI * std::sqrt(-std::log(opt.value("tolerance")) / opt.value("gamma_lme")));
  }
  CHECK(b->search_radius() >= R_max);
}

TEST_CASE("lme metric node_spacing: the search radius from the largest nearest-node distance, bit for bit") {
  // A distributed run finds the whole lattice's search radius from each
  // rank's largest h_I (distributed/local_parts.cpp): the same bits as the
  // basis built on every node, for several perturbations, seeds and gammas.
  for (const unsigned seed : {21u, 22u, 23u})
    for (const double fraction : {0.1, 0.3, 0.45})
      for (const double gamma : {0.8, 2.0, 4.0}) {
        CAPTURE(seed);
        CAPTURE(fraction);
        CAPTURE(gamma);
        const auto nodes = NodeSet<2>::perturbed(unit_grid<2>(9), fraction, seed);
        const BasisOptions opt = lme_options("node_spacing", gamma);
        const auto b = make_lme_basis<2>(nodes, opt);
        const double h = nodes.spacing();
        double largest = 0.0;
        for (int I = 0; I < nodes.size(); ++I) largest = std::max(largest, maxent::nearest_node_distance(nodes, I, h));
        CHECK(maxent::node_spacing_search_radius(opt, h, largest) == b->search_radius());
      }
  // On the lattice itself (every h_I = h): the isotropic radius.
  const auto lattice = NodeSet<2>::cartesian(unit_grid<2>(9));
  const BasisOptions opt = lme_options("node_spacing");
  CHECK(maxent::node_spacing_search_radius(opt, lattice.spacing(), lattice.spacing()) ==
        make_lme_basis<2>(lattice, opt)->search_radius());
}

TEST_CASE("lme metric node_spacing: identities and gradients on perturbed grids") {
  // gamma_lme = 2: h_I (the nearest distance) falls to ~0.4 h on these
  // layouts, and R_I = 2.6 h_I must still leave D + 1 nodes around every point
  const auto p2 = NodeSet<2>::perturbed(unit_grid<2>(10), 0.3, 31);
  const auto b2 = make_lme_basis<2>(p2, lme_options("node_spacing", 2.0));
  Identities<2> id2 = check_identities<2>(*b2, unit_box_points<2>(p2, 60, 32));
  test::require_identities<2>(id2, id2.worst_point, kIdentityTol);
  const auto p3 = NodeSet<3>::perturbed(unit_grid<3>(5), 0.3, 35);
  const Identities<3> id3 =
      check_identities<3>(*make_lme_basis<3>(p3, lme_options("node_spacing", 2.0)), unit_box_points<3>(p3, 30, 36));
  test::require_identities<3>(id3, id3.worst_point, kIdentityTol);
  BasisOptions opt = lme_options("node_spacing", 2.0);
  opt.values["newton_tolerance"] = 1e-14;
  CHECK(max_fd_gradient_error<2>(*make_lme_basis<2>(p2, opt), 37, kFdStep) <= kFdTol);
  CHECK(max_fd_gradient_error<3>(*make_lme_basis<3>(p3, opt), 38, kFdStep) <= kFdTol);
}

TEST_CASE("lme metric node_spacing: on a uniform grid it is the isotropic basis bit for bit") {
  const auto nodes = NodeSet<2>::cartesian(unit_grid<2>(10));
  const auto iso = make_lme_basis<2>(nodes, lme_options("isotropic"));
  const auto ns = make_lme_basis<2>(nodes, lme_options("node_spacing"));
  CHECK(ns->search_radius() == iso->search_radius());
  Stencil<2> a, b;
  for (const auto& x : unit_box_points<2>(nodes, 60, 41)) {
    evaluate_with<2>(*iso, x, nullptr, a);
    evaluate_with<2>(*ns, x, nullptr, b);
    require_same<2>(a, b);
  }
}

TEST_CASE("lme metric node_spacing: a cloud keeps the locality of its actual spacing") {
  // The lattice of spacing 1/8 given as a cloud whose nominal spacing is
  // 3/4 of it: isotropic LME takes beta from the nominal spacing (1.8 times
  // too local), node_spacing from the nodes - the basis of the lattice.
  const auto grid = NodeSet<2>::cartesian(unit_grid<2>(8));
  const auto cloud = NodeSet<2>::cloud(grid.positions(), 0.75 * grid.spacing());
  const auto reference = make_lme_basis<2>(grid, lme_options("isotropic"));
  const auto iso = make_lme_basis<2>(cloud, lme_options("isotropic"));
  const auto ns = make_lme_basis<2>(cloud, lme_options("node_spacing"));
  double err_ns = 0, err_iso = 0;
  for (const auto& x : inner_points<2>(40, 51)) {
    const auto r = values_at<2>(*reference, x), a = values_at<2>(*ns, x), b = values_at<2>(*iso, x);
    for (const auto& [I, N] : r) {
      err_ns = std::max(err_ns, std::abs(a.count(I) ? a.at(I) - N : N));
      err_iso = std::max(err_iso, std::abs(b.count(I) ? b.at(I) - N : N));
    }
  }
  CHECK(err_ns <= 1e-12); // the nearest distances agree with 1/8 to round-off
  CHECK(err_iso > 1e-2);
}

TEST_CASE("lme metric node_spacing: moved nodes update h_I") {
  auto nodes = NodeSet<2>::cartesian(unit_grid<2>(8));
  auto b = make_lme_basis<2>(nodes, lme_options("node_spacing"));
  const auto* lme = dynamic_cast<const maxent::MaxEntBasis<2, maxent::GaussianPrior<2>>*>(b.get());
  REQUIRE(lme != nullptr);
  const double beta0 = lme->node_beta()[0];
  // a uniform stretch by 1.5 makes every nearest distance 1.5 h
  AlignedVector<Vec<2>> dx(static_cast<std::size_t>(b->nodes().size()));
  for (int I = 0; I < b->nodes().size(); ++I) dx[I] = 0.5 * b->nodes().position(I);
  b->nodes().advect(dx);
  b->nodes_moved(dx);
  for (double beta : lme->node_beta()) CHECK(beta == doctest::Approx(beta0 / 2.25).epsilon(1e-12));
}

TEST_CASE("lme metric: bad values are refused") {
  const auto nodes = NodeSet<2>::cartesian(unit_grid<2>(4));
  CHECK_THROWS_WITH_AS(make_lme_basis<2>(nodes, lme_options("anisotropic")), doctest::Contains("unknown metric"),
                       InputError);
  BasisOptions maxent;
  maxent.kind = "maxent";
  maxent.metric = "deformation";
  CHECK_THROWS_WITH_AS(make_maxent_basis<2>(nodes, maxent), doctest::Contains("only lme"), InputError);
  CHECK(basis_metric_list() == "isotropic, deformation or node_spacing");
  CHECK(find_basis_kind("lme")->adapts_metric);
  CHECK(!find_basis_kind("linear")->adapts_metric);
}

TEST_CASE("lme metric: scene key basis.metric") {
  const std::string scene = std::string(OTMPM_SOURCE_DIR) + "/tests/scenes/good_minimal.toml"; // basis.kind = "lme"
  CHECK(load_scene(scene).basis.metric == "isotropic");
  CHECK(load_scene(scene, {"basis.metric=deformation"}).basis.metric == "deformation");
  CHECK(load_scene(scene, {"basis.metric=node_spacing"}).basis.metric == "node_spacing");
  CHECK_THROWS_WITH_AS(load_scene(scene, {"basis.metric=stretched"}), doctest::Contains("metric"), InputError);
  CHECK_THROWS_WITH_AS(load_scene(scene, {"basis.metric=deformation", "basis.kind=linear"}),
                       doctest::Contains("basis.metric"), InputError);
  CHECK_THROWS_WITH_AS(load_scene(scene, {"basis.metric=node_spacing", "basis.kind=maxent"}),
                       doctest::Contains("adapts its locality"), InputError);
}
