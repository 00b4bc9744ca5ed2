// Tests of the local max-ent basis (docs/theory.md sect. 4, molinos sect. 2.3).
//
// Tolerances used throughout (h = nodal spacing):
// * partition of unity |sum N - 1| <= 1e-12: N_I are normalised explicitly, so
//   only summation round-off (~n eps) remains.
// * |sum grad N| <= 1e-12 sum |grad N|: exact to round-off by construction.
// * linear completeness |sum N_I x_I - x| <= 2e-12 h: equals |r| <= newton_tolerance h
//   (1e-12 h) plus round-off.
// * gradient consistency |sum x_I (x) grad N_I - I| <= 1e-10: J J^{-1} to
//   round-off times the conditioning of J (<= ~1e3 at the points used).
// * gradients vs central differences with step 2e-6 h: the truncation error
//   step^2 / 6 |d^3 N| is at most ~2e-9 / h on these grids (measured: it falls
//   100-fold per decade of the step, 5e-6 / h at step 1e-4 h on a 0.3-perturbed
//   grid where close nodes make d^3 N large); Newton is solved to 1e-14 h so
//   that its noise (/ 4e-6 h) stays near 1e-9 / h; tolerance 2e-8 / h.
#include "otmpm/basis/families.hpp"
#include "otmpm/basis/lme.hpp"
#include "support.hpp"

#include <Eigen/QR>
#include <doctest/doctest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <new>
#include <random>
#include <string>
#include <thread>
#include <vector>

using namespace otmpm;
using namespace otmpm::test;

// Counts heap allocations through operator new (std::vector<int/double>,
// strings, ...) for the no-allocation test below. Eigen's aligned allocator
// bypasses operator new; those buffers are checked by pointer stability.
namespace {
std::atomic<long> g_allocations{0};
}
void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace {

constexpr double kPartitionTol = 1e-12;
constexpr double kGradientSumTol = 1e-12;
constexpr double kCompletenessTol = 2e-12;  // times h
constexpr double kGradientConsistencyTol = 1e-10;
constexpr double kFdStep = 2e-6;            // times h
constexpr double kFdTol = 2e-8;             // times 1/h

constexpr IdentityTolerances kIdentityTol{kPartitionTol, kGradientSumTol, kCompletenessTol, kGradientConsistencyTol};

template <int D> void require_identities(const Basis<D>& basis, const AlignedVector<Vec<D>>& pts) {
  const Identities<D> id = check_identities(basis, pts);
  test::require_identities(id, id.worst_point, kIdentityTol);
}

BasisOptions lme_options(double gamma = 4.0) {
  BasisOptions opt;
  opt.kind = "lme";
  opt.values["gamma_lme"] = gamma;
  return opt;
}

template <int D> void identities_on(const NodeSet<D>& nodes, unsigned seed) {
  const auto basis = make_lme_basis<D>(nodes, lme_options());
  require_identities<D>(*basis, unit_box_points<D>(basis->nodes(), 60, seed));
}

template <int D> void fd_on(const NodeSet<D>& nodes, unsigned seed) {
  BasisOptions opt = lme_options();
  opt.values["newton_tolerance"] = 1e-14;
  const auto basis = make_lme_basis<D>(nodes, opt);
  const double err = max_fd_gradient_error<D>(*basis, seed, kFdStep);
  INFO("layout " << int(nodes.layout()) << ", D = " << D);
  CHECK(err <= kFdTol);
}

} // namespace

TEST_CASE("lme: kind, linear completeness flag and option checks") {
  const auto nodes = NodeSet<2>::cartesian(unit_grid<2>(4));
  const auto b = make_lme_basis<2>(nodes, lme_options());
  CHECK(b->kind() == "lme");
  CHECK(b->linearly_complete());
  BasisOptions bad = lme_options(0.0);
  CHECK_THROWS_AS(make_lme_basis<2>(nodes, bad), InputError);
  bad = lme_options();
  bad.values["tolerance"] = 1.0;
  CHECK_THROWS_AS(make_lme_basis<2>(nodes, bad), InputError);
  bad = lme_options();
  bad.values["newton_tolerance"] = 0.0;
  CHECK_THROWS_AS(make_lme_basis<2>(nodes, bad), InputError);
  bad = lme_options();
  bad.values["max_newton_iterations"] = 0;
  CHECK_THROWS_AS(make_lme_basis<2>(nodes, bad), InputError);
}

TEST_CASE("lme: symmetric 1D values match the closed form (lambda = 0)") {
  // On a uniform 1D grid, at a node and at a cell midpoint lambda = 0 by
  // symmetry, so N_I = exp(-beta d_I^2) / sum_J exp(-beta d_J^2) over the nodes
  // with exp(-beta d^2) >= tol. gamma = 4, tol = 1e-6: R = 1.858 h.
  const auto b = make_lme_basis<1>(NodeSet<1>::cartesian(unit_grid<1>(10)), lme_options());
  std::vector<double> N;
  dense_eval<1>(*b, Vec<1>(0.5), N); // node 5; neighbours at +-h (2h > R)
  const double e1 = std::exp(-4.0);
  CHECK(N[5] == doctest::Approx(1.0 / (1.0 + 2.0 * e1)).epsilon(1e-13));
  CHECK(N[4] == doctest::Approx(e1 / (1.0 + 2.0 * e1)).epsilon(1e-13));
  CHECK(N[3] == 0.0);
  dense_eval<1>(*b, Vec<1>(0.45), N); // midpoint: +-h/2 and +-3h/2
  const double a = std::exp(-1.0), c = std::exp(-9.0);
  CHECK(N[4] == doctest::Approx(a / (2.0 * a + 2.0 * c)).epsilon(1e-13));
  CHECK(N[3] == doctest::Approx(c / (2.0 * a + 2.0 * c)).epsilon(1e-13));
}

TEST_CASE("lme: identities on Cartesian grids (1D, 2D, 3D)") {
  identities_on<1>(NodeSet<1>::cartesian(unit_grid<1>(cells_for<1>())), 11);
  identities_on<2>(NodeSet<2>::cartesian(unit_grid<2>(cells_for<2>())), 12);
  identities_on<3>(NodeSet<3>::cartesian(unit_grid<3>(cells_for<3>())), 13);
}

TEST_CASE("lme: identities on perturbed grids (1D, 2D, 3D)") {
  identities_on<1>(NodeSet<1>::perturbed(unit_grid<1>(cells_for<1>()), 0.3, 5), 21);
  identities_on<2>(NodeSet<2>::perturbed(unit_grid<2>(cells_for<2>()), 0.3, 6), 22);
  identities_on<3>(NodeSet<3>::perturbed(unit_grid<3>(cells_for<3>()), 0.3, 7), 23);
}

TEST_CASE("lme: identities on random clouds (1D, 2D, 3D)") {
  identities_on<1>(random_cloud<1>(cells_for<1>(), 8), 31);
  identities_on<2>(random_cloud<2>(cells_for<2>(), 9), 32);
  identities_on<3>(random_cloud<3>(cells_for<3>(), 10), 33);
}

TEST_CASE("lme: identities for small and large gamma_lme") {
  // With gamma = 10 and tol = 1e-6, R = 1.18 h: next to the boundary of a
  // perturbed grid the support can hold only boundary nodes (the point is then
  // outside the hull of its support - an error). tol = 1e-12 gives R = 1.66 h.
  const auto nodes = NodeSet<2>::perturbed(unit_grid<2>(8), 0.3, 3);
  for (double gamma : {0.8, 10.0}) {
    CAPTURE(gamma);
    BasisOptions opt = lme_options(gamma);
    opt.values["tolerance"] = gamma > 4 ? 1e-12 : 1e-6;
    require_identities<2>(*make_lme_basis<2>(nodes, opt), unit_box_points<2>(nodes, 30, 41));
  }
}

TEST_CASE("lme: gradients agree with central differences") {
  fd_on<1>(NodeSet<1>::perturbed(unit_grid<1>(10), 0.3, 1), 51);
  fd_on<2>(NodeSet<2>::cartesian(unit_grid<2>(8)), 52);
  fd_on<2>(NodeSet<2>::perturbed(unit_grid<2>(8), 0.3, 2), 53);
  fd_on<2>(random_cloud<2>(8, 4), 54);
  fd_on<3>(NodeSet<3>::perturbed(unit_grid<3>(5), 0.3, 3), 55);
}

TEST_CASE("lme: points exactly on the boundary get the limit from inside") {
  // On the hull boundary lambda -> infinity; the solver stops at |r| <= 1e-12 h,
  // where the interior nodes carry at most ~1e-12 / (their distance / h).
  const auto b1 = make_lme_basis<1>(NodeSet<1>::cartesian(unit_grid<1>(10)), lme_options());
  std::vector<double> N;
  dense_eval<1>(*b1, Vec<1>(0.0), N);
  CHECK(N[0] == doctest::Approx(1.0).epsilon(1e-11));
  dense_eval<1>(*b1, Vec<1>(1.0), N);
  CHECK(N[10] == doctest::Approx(1.0).epsilon(1e-11));

  const auto nodes = NodeSet<2>::cartesian(unit_grid<2>(8));
  const auto b2 = make_lme_basis<2>(nodes, lme_options());
  AlignedVector<Vec<2>> edge;
  for (double s : {0.0, 0.1, 0.33, 0.5, 0.77, 1.0}) {
    edge.push_back(Vec<2>(s, 0.0));
    edge.push_back(Vec<2>(1.0, s));
  }
  Stencil<2> st;
  for (const Vec<2>& x : edge) {
    PointQuery<2> q;
    q.x = x;
    b2->evaluate(q, st);
    double off_edge = 0;
    for (int a = 0; a < st.size(); ++a) {
      const Vec<2>& xI = nodes.position(st.node[a]);
      if (std::abs(xI[1]) > 1e-12 && std::abs(xI[0] - 1.0) > 1e-12) off_edge += st.N[a];
    }
    CAPTURE(x.transpose());
    CHECK(off_edge <= 1e-11);
  }
  Identities<2> id = check_identities<2>(*b2, edge);
  CHECK(id.partition <= kPartitionTol);
  CHECK(id.completeness <= kCompletenessTol);
}

TEST_CASE("lme: tends to the linear hat functions in 1D as gamma_lme grows") {
  // Error max_I |N_I - hat_I| over points in one cell; decays roughly like
  // exp(-c gamma). tol = 1e-100 keeps both cell nodes in the support at large gamma.
  const auto nodes = NodeSet<1>::cartesian(unit_grid<1>(10));
  double previous = 1.0;
  for (double gamma : {2.0, 4.0, 8.0, 16.0, 32.0}) {
    BasisOptions opt = lme_options(gamma);
    opt.values["tolerance"] = 1e-100;
    const auto b = make_lme_basis<1>(nodes, opt);
    double err = 0;
    std::vector<double> N;
    for (double xi : {0.1, 0.25, 0.5, 0.6, 0.9}) {
      dense_eval<1>(*b, Vec<1>((4 + xi) * 0.1), N);
      for (std::size_t I = 0; I < N.size(); ++I) {
        const double hat = I == 4 ? 1 - xi : I == 5 ? xi : 0.0;
        err = std::max(err, std::abs(N[I] - hat));
      }
    }
    CAPTURE(gamma);
    CAPTURE(err);
    CHECK(err < previous);
    previous = err;
  }
  CHECK(previous <= 1e-6);
}

TEST_CASE("lme: tends to the bilinear hat functions on 2D cell edges as gamma_lme grows") {
  // On a cell edge of a square lattice every Delaunay triangulation gives the
  // 1D hat along the edge, so N -> (1 - xi) and xi on the two edge nodes.
  const auto nodes = NodeSet<2>::cartesian(unit_grid<2>(6));
  const CartesianGrid<2> g = unit_grid<2>(6);
  double previous = 1.0;
  for (double gamma : {2.0, 4.0, 8.0, 16.0, 24.0}) {
    BasisOptions opt = lme_options(gamma);
    opt.values["tolerance"] = 1e-100;
    const auto b = make_lme_basis<2>(nodes, opt);
    double err = 0;
    std::vector<double> N;
    for (double xi : {0.2, 0.5, 0.7}) {
      for (int dir = 0; dir < 2; ++dir) {
        Index<2> a{2, 3}, c{2, 3};
        c[dir] += 1;
        Vec<2> x = (1 - xi) * g.node_position(a) + xi * g.node_position(c);
        dense_eval<2>(*b, x, N);
        for (std::size_t I = 0; I < N.size(); ++I) {
          const double hat = int(I) == g.node_id(a) ? 1 - xi : int(I) == g.node_id(c) ? xi : 0.0;
          err = std::max(err, std::abs(N[I] - hat));
        }
      }
    }
    CAPTURE(gamma);
    CAPTURE(err);
    CHECK(err < previous);
    previous = err;
  }
  CHECK(previous <= 1e-4);
}

TEST_CASE("lme: support radius R = h sqrt(-ln tol / gamma_lme)") {
  for (double gamma : {0.8, 4.0}) {
    for (double tol : {1e-6, 1e-9}) {
      BasisOptions opt = lme_options(gamma);
      opt.values["tolerance"] = tol;
      const auto nodes = NodeSet<2>::perturbed(unit_grid<2>(8), 0.25, 9);
      const auto b = make_lme_basis<2>(nodes, opt);
      const double h = nodes.spacing();
      const double R = h * std::sqrt(-std::log(tol) / gamma);
      Stencil<2> st;
      int mismatches = 0;
      double farthest = 0;
      for (const Vec<2>& x : unit_box_points<2>(nodes, 40, 61)) {
        PointQuery<2> q;
        q.x = x;
        b->evaluate(q, st);
        std::vector<int> kept(st.node.begin(), st.node.end());
        std::sort(kept.begin(), kept.end());
        std::vector<int> expected;
        for (int I = 0; I < nodes.size(); ++I) {
          const double d = (nodes.position(I) - x).norm();
          if (std::abs(d - R) <= 1e-12 * R) continue; // on the cut-off: either answer is right
          if (d < R) expected.push_back(I);
        }
        for (int I : kept) {
          const double d = (nodes.position(I) - x).norm();
          farthest = std::max(farthest, d);
          if (std::abs(d - R) <= 1e-12 * R) expected.push_back(I);
        }
        std::sort(expected.begin(), expected.end());
        if (kept != expected) ++mismatches;
      }
      CAPTURE(gamma);
      CAPTURE(tol);
      CHECK(mismatches == 0);     // kept exactly the nodes within R
      CHECK(farthest <= R);
      CHECK(farthest >= R - h);   // and nodes close to R are reached
    }
  }
}

TEST_CASE("lme: max_stencil bounds every stencil") {
  auto check = [](const auto& basis, const auto& pts) {
    int largest = 0;
    Stencil<2> st;
    for (const Vec<2>& x : pts) {
      PointQuery<2> q;
      q.x = x;
      basis.evaluate(q, st);
      largest = std::max(largest, st.size());
    }
    CHECK(largest <= basis.max_stencil());
    CHECK(basis.max_stencil() <= 4 * largest); // a useful bound, not the node count
  };
  const auto cart = NodeSet<2>::cartesian(unit_grid<2>(10));
  check(*make_lme_basis<2>(cart, lme_options()), unit_box_points<2>(cart, 100, 71));
  const auto cloud = random_cloud<2>(10, 72);
  check(*make_lme_basis<2>(cloud, lme_options()), unit_box_points<2>(cloud, 100, 73));
  // a clustered cloud: the bound must follow the nodes
  AlignedVector<Vec<2>> x = cart.positions();
  for (int i = 0; i < 40; ++i) x.push_back(Vec<2>(0.5 + 0.001 * (i % 7), 0.5 + 0.001 * (i / 7)));
  const auto clustered = NodeSet<2>::cloud(x, 0.1);
  const auto b = make_lme_basis<2>(clustered, lme_options());
  AlignedVector<Vec<2>> pts = unit_box_points<2>(clustered, 50, 74);
  pts.push_back(Vec<2>(0.503, 0.503));
  check(*b, pts);
}

TEST_CASE("lme: max_nodes_within is sound for lattices and clouds in 3D") {
  const auto cart = NodeSet<3>::cartesian(unit_grid<3>(5));
  const auto cloud = random_cloud<3>(5, 81);
  for (const NodeSet<3>* nodes : {&cart, &cloud}) {
    const double R = 0.37;
    const int bound = maxent::max_nodes_within<3>(*nodes, R);
    std::vector<int> ids;
    int largest = 0;
    for (const Vec<3>& x : unit_box_points<3>(*nodes, 60, 82)) {
      ids.clear();
      nodes->within(x, R, ids);
      largest = std::max(largest, static_cast<int>(ids.size()));
    }
    CHECK(largest <= bound);
    CHECK(bound < nodes->size());
  }
}

TEST_CASE("lme: warm start gives the same answer in fewer iterations") {
  const auto nodes = NodeSet<2>::perturbed(unit_grid<2>(8), 0.3, 12);
  const auto b = make_lme_basis<2>(nodes, lme_options());
  const double h = nodes.spacing();
  std::mt19937 rng(91);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  Stencil<2> cold, warm;
  int cold_total = 0, warm_total = 0;
  double diff = 0;
  for (int i = 0; i < 20; ++i) {
    Vec<2> x(u(rng), u(rng));
    Vec<2> lambda = Vec<2>::Zero();
    int it = -1;
    PointQuery<2> q;
    q.x = x;
    q.lambda = &lambda;
    q.iterations = &it;
    b->evaluate(q, cold); // lambda now holds the multiplier at x
    CHECK(it > 0);
    // same point again: already converged
    b->evaluate(q, warm);
    CHECK(it == 0);
    // a nearby point (a particle after one step)
    q.x = x + Vec<2>(0.01 * h, -0.02 * h);
    b->evaluate(q, warm);
    warm_total += it;
    PointQuery<2> qc;
    qc.x = q.x;
    qc.iterations = &it;
    b->evaluate(qc, cold);
    cold_total += it;
    REQUIRE(warm.node == cold.node);
    for (int a = 0; a < cold.size(); ++a) diff = std::max(diff, std::abs(warm.N[a] - cold.N[a]));
  }
  CHECK(warm_total < cold_total);
  CHECK(diff <= 1e-11); // both converged to |r| <= 1e-12 h; J^{-1} r shifts N by < ~1e-11
}

TEST_CASE("lme: a poor warm start still converges (cold restart)") {
  const auto nodes = NodeSet<2>::cartesian(unit_grid<2>(8));
  const auto b = make_lme_basis<2>(nodes, lme_options());
  Vec<2> lambda(1e6, -1e6); // absurd multiplier
  PointQuery<2> q;
  q.x = Vec<2>(0.41, 0.53);
  q.lambda = &lambda;
  Stencil<2> st;
  b->evaluate(q, st);
  Identities<2> id = check_identities<2>(*b, {q.x});
  CHECK(id.completeness <= kCompletenessTol);
  CHECK(lambda.norm() * nodes.spacing() < 10.0);
}

TEST_CASE("lme: points outside the convex hull are a BasisError naming the point") {
  auto message_of = [](const auto& basis, const auto& q) {
    Stencil<std::decay_t<decltype(q.x)>::RowsAtCompileTime> st;
    try {
      basis.evaluate(q, st);
    } catch (const BasisError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  SUBCASE("1D, half a cell outside") {
    const auto b = make_lme_basis<1>(NodeSet<1>::cartesian(unit_grid<1>(10)), lme_options());
    PointQuery<1> q;
    q.x = Vec<1>(-0.05);
    q.id = 17;
    const std::string m = message_of(*b, q);
    CHECK(m.find("convex hull") != std::string::npos);
    CHECK(m.find("point 17 at (-0.05)") != std::string::npos);
  }
  SUBCASE("2D, far away (no nodes within R)") {
    const auto b = make_lme_basis<2>(NodeSet<2>::cartesian(unit_grid<2>(8)), lme_options());
    PointQuery<2> q;
    q.x = Vec<2>(3.0, 0.5);
    const std::string m = message_of(*b, q);
    CHECK(m.find("convex hull") != std::string::npos);
    CHECK(m.find(format_point<2>(q.x)) != std::string::npos);
  }
  SUBCASE("2D, outside a triangular cloud but inside its bounding box") {
    // nodes i + j <= 8 of a lattice: the hull's hypotenuse is x + y = 1
    const auto g = unit_grid<2>(8);
    const auto lattice = NodeSet<2>::cartesian(g);
    AlignedVector<Vec<2>> x;
    for (int id = 0; id < lattice.size(); ++id) {
      const auto ijk = g.node_index(id);
      if (ijk[0] + ijk[1] <= 8) x.push_back(lattice.position(id));
    }
    const auto b = make_lme_basis<2>(NodeSet<2>::cloud(x, 0.125), lme_options());
    for (double off : {0.02, 0.001}) {
      Vec<2> lambda = Vec<2>::Zero();
      PointQuery<2> q;
      q.x = Vec<2>(0.5 + off, 0.5 + off);
      q.id = 3;
      q.lambda = &lambda;
      CAPTURE(off);
      const std::string m = message_of(*b, q);
      CHECK(m.find("convex hull") != std::string::npos);
      CHECK(m.find("point 3 at " + format_point<2>(q.x)) != std::string::npos);
      CHECK(lambda.isZero(0.0)); // not written on failure
    }
    // just inside the hypotenuse it works
    PointQuery<2> q;
    q.x = Vec<2>(0.5 - 1e-3, 0.5 - 1e-3);
    Identities<2> id = check_identities<2>(*b, {q.x});
    CHECK(id.completeness <= kCompletenessTol);
  }
  SUBCASE("3D, outside a face") {
    const auto b = make_lme_basis<3>(NodeSet<3>::cartesian(unit_grid<3>(5)), lme_options());
    PointQuery<3> q;
    q.x = Vec<3>(0.5, 1.03, 0.5);
    const std::string m = message_of(*b, q);
    CHECK(m.find("convex hull") != std::string::npos);
  }
}

TEST_CASE("lme: degenerate support (collinear nodes) is a singular-J BasisError") {
  // All nodes on the x axis in 2D: points on the segment have a singular J.
  AlignedVector<Vec<2>> x;
  for (int i = 0; i <= 10; ++i) x.push_back(Vec<2>(0.1 * i, 0.0));
  const auto b = make_lme_basis<2>(NodeSet<2>::cloud(x, 0.1), lme_options());
  PointQuery<2> q;
  q.x = Vec<2>(0.43, 0.0);
  Stencil<2> st;
  CHECK_THROWS_WITH_AS(b->evaluate(q, st), doctest::Contains("singular Hessian J"), BasisError);
}

TEST_CASE("lme: moved nodes keep beta from the initial spacing and a fresh search") {
  const auto g = unit_grid<2>(8);
  auto b = make_lme_basis<2>(NodeSet<2>::perturbed(g, 0.2, 4), lme_options());
  const Vec<2> x(0.37, 0.61);
  std::vector<double> before, after;
  dense_eval<2>(*b, x, before);
  // rigid translation: N at the translated point is unchanged
  const Vec<2> shift(0.31, -0.17);
  AlignedVector<Vec<2>> dx(static_cast<std::size_t>(b->nodes().size()), shift);
  b->nodes().advect(dx);
  b->nodes_moved(dx);
  dense_eval<2>(*b, Vec<2>(x + shift), after);
  double diff = 0;
  for (std::size_t I = 0; I < before.size(); ++I) diff = std::max(diff, std::abs(before[I] - after[I]));
  CHECK(diff <= 1e-11);
  // a stretch: h (hence beta) stays the initial one; identities still hold
  for (int I = 0; I < b->nodes().size(); ++I) dx[I] = 0.2 * (b->nodes().position(I) - shift);
  b->nodes().advect(dx);
  b->nodes_moved(dx);
  CHECK(b->nodes().spacing() == doctest::Approx(1.0 / 8));
  AlignedVector<Vec<2>> pts;
  for (const Vec<2>& p : unit_box_points<2>(NodeSet<2>::cartesian(g), 20, 99)) pts.push_back(shift + 1.2 * p);
  require_identities<2>(*b, pts);
}

TEST_CASE("lme: evaluate allocates nothing once the stencil buffers have grown") {
  for (const bool lattice : {true, false}) {
    const auto nodes = lattice ? NodeSet<3>::cartesian(unit_grid<3>(5)) : NodeSet<3>::perturbed(unit_grid<3>(5), 0.3, 2);
    const auto b = make_lme_basis<3>(nodes, lme_options());
    const AlignedVector<Vec<3>> pts = unit_box_points<3>(nodes, 30, 101);
    AlignedVector<Vec<3>> lambda(pts.size(), Vec<3>::Zero());
    Stencil<3> st;
    auto pass = [&] {
      for (std::size_t i = 0; i < pts.size(); ++i) {
        PointQuery<3> q;
        q.x = pts[i];
        q.lambda = &lambda[i];
        b->evaluate(q, st);
      }
    };
    const long start = g_allocations.load();
    pass(); // grows the buffers
    const long growing = g_allocations.load() - start;
    const void* buffers[] = {st.node.data(), st.N.data(), st.dN.data(), st.scratch_ids.data(), st.scratch_w.data()};
    const long before = g_allocations.load();
    pass();
    const long allocations = g_allocations.load() - before;
    const void* after[] = {st.node.data(), st.N.data(), st.dN.data(), st.scratch_ids.data(), st.scratch_w.data()};
    CAPTURE(lattice);
    CHECK(growing > 0); // the counter does see the stencil's vectors grow
    CHECK(allocations == 0);
    CHECK(std::equal(std::begin(buffers), std::end(buffers), std::begin(after)));
  }
}

TEST_CASE("lme: concurrent evaluation gives the serial result") {
  auto nodes = NodeSet<2>::perturbed(unit_grid<2>(8), 0.3, 8);
  const auto b = make_lme_basis<2>(nodes, lme_options());
  const AlignedVector<Vec<2>> pts = unit_box_points<2>(nodes, 40, 111);
  auto run = [&](std::size_t first, std::size_t step, std::vector<double>& sums) {
    Stencil<2> st;
    for (std::size_t i = first; i < pts.size(); i += step) {
      PointQuery<2> q;
      q.x = pts[i];
      b->evaluate(q, st);
      double s = 0;
      for (int a = 0; a < st.size(); ++a) s += st.N[a] * (st.node[a] + 1) + st.dN[a].sum();
      sums[i] = s;
    }
  };
  std::vector<double> serial(pts.size()), parallel(pts.size());
  run(0, 1, serial);
  std::thread t1(run, 0, 2, std::ref(parallel));
  std::thread t2(run, 1, 2, std::ref(parallel));
  t1.join();
  t2.join();
  CHECK(serial == parallel); // bitwise: evaluation is deterministic and shares no state
}

TEST_CASE("lme: exp_shifted is within 2 ulp of std::exp on [-708, 0] and exact at 0") {
  CHECK(maxent::exp_shifted(0.0) == 1.0);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> wide(-708.0, 0.0), narrow(-20.0, 0.0);
  double worst_ulp = 0.0;
  for (int i = 0; i < 200000; ++i) {
    const double x = i % 2 ? wide(rng) : narrow(rng); // the LME range is mostly [-20, 0]
    const double exact = std::exp(x), fast = maxent::exp_shifted(x);
    const double ulp = std::nextafter(exact, INFINITY) - exact;
    worst_ulp = std::max(worst_ulp, std::abs(fast - exact) / ulp);
  }
  MESSAGE("worst error of exp_shifted: " << worst_ulp << " ulp of std::exp");
  CHECK(worst_ulp <= 2.0);
  CHECK(maxent::exp_shifted(-800.0) == std::exp(-800.0)); // libm below -708
  CHECK(std::isnan(maxent::exp_shifted(std::nan(""))));
}

namespace {

/// J^{-1} and 1 / tr(Js^{-1}) (Js = S J S, unit diagonal) in long double,
/// for the ScaledInverse tests.
template <int D> void reference_inverse(const Mat<D>& J, Mat<D>& J_inv, double& lambda_min) {
  using MatL = Eigen::Matrix<long double, D, D>;
  const MatL JL = J.template cast<long double>();
  const MatL inv = JL.inverse();
  long double trace = 0;
  for (int k = 0; k < D; ++k) trace += JL(k, k) * inv(k, k); // (Js^{-1})_kk = J_kk (J^{-1})_kk
  J_inv = inv.template cast<double>();
  lambda_min = static_cast<double>(1.0L / trace);
}

/// A symmetric positive definite J = S M S: M with unit diagonal and
/// eigenvalues in [1 / cond, ~D], S = diag(scale_k) over `decades` decades
/// around `centre`.
template <int D> Mat<D> random_spd(std::mt19937_64& rng, double cond, double centre, double decades) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Mat<D> A;
  for (int i = 0; i < D; ++i)
    for (int j = 0; j < D; ++j) A(i, j) = u(rng);
  const Eigen::HouseholderQR<Mat<D>> qr(A);
  const Mat<D> Q = qr.householderQ();
  Vec<D> ev;
  for (int k = 0; k < D; ++k) ev[k] = std::pow(cond, -0.5 * (u(rng) + 1.0)); // in [1 / cond, 1]
  ev[0] = 1.0;
  ev[D - 1] = 1.0 / cond;
  Mat<D> M = Q * ev.asDiagonal() * Q.transpose();
  const Vec<D> d = M.diagonal().cwiseSqrt().cwiseInverse();
  M = d.asDiagonal() * M * d.asDiagonal();
  Vec<D> s;
  for (int k = 0; k < D; ++k) s[k] = centre * std::pow(10.0, 0.5 * decades * u(rng));
  Mat<D> J = s.asDiagonal() * M * s.asDiagonal();
  return 0.5 * (J + J.transpose()).eval(); // exactly symmetric
}

/// ScaledInverse::compute (the closed forms of 2D and 3D, or the scaled
/// form where they decline) against the long-double reference on random J
/// of the given condition and scale, beside compute_scaled (the form with
/// square roots) on the same J: J^{-1} entries relative to sqrt(ref_kk
/// ref_ll) and lambda_min relative. The round-off of a closed-form inverse
/// grows with the condition (measured up to ~cond^1.8 eps for the smallest
/// eigenvalue in 3D, by both forms), so the bound is the scaled form's own
/// worst error over the same matrices, times 4, plus 8 eps.
template <int D> void scaled_inverse_agrees(double cond, double centre, double decades, unsigned seed) {
  std::mt19937_64 rng(seed);
  double worst[2][2] = {}; // [closed form, scaled form][J^{-1}, lambda_min]
  for (int t = 0; t < 2000; ++t) {
    const Mat<D> J = random_spd<D>(rng, cond, centre, decades);
    Mat<D> ref;
    double lambda_ref = 0;
    reference_inverse<D>(J, ref, lambda_ref);
    maxent::ScaledInverse<D> inv[2];
    inv[0].compute(J);
    inv[1].compute_scaled(J);
    for (int f = 0; f < 2; ++f) {
      INFO("J = " << J << ", form " << f);
      REQUIRE(inv[f].lambda_min > 0.0);
      for (int k = 0; k < D; ++k)
        for (int l = 0; l < D; ++l)
          worst[f][0] = std::max(worst[f][0], std::abs(inv[f].J_inv(k, l) - ref(k, l)) /
                                                  (std::sqrt(ref(k, k)) * std::sqrt(ref(l, l))));
      worst[f][1] = std::max(worst[f][1], std::abs(inv[f].lambda_min - lambda_ref) / lambda_ref);
    }
  }
  const double eps = std::numeric_limits<double>::epsilon();
  MESSAGE("D = " << D << ", cond " << cond << ", J ~ " << centre * centre << " (" << decades
                 << " decades): J^{-1} within " << worst[0][0] << " (scaled form " << worst[1][0]
                 << "), lambda_min within " << worst[0][1] << " (scaled form " << worst[1][1] << ")");
  CHECK(worst[0][0] <= 4.0 * worst[1][0] + 8.0 * eps);
  CHECK(worst[0][1] <= 4.0 * worst[1][1] + 8.0 * eps);
  CHECK(worst[1][1] <= 8.0 * cond * cond * eps + 8.0 * eps); // the scaled form itself is sound
}

} // namespace

TEST_CASE("lme: ScaledInverse gives J^{-1} and lambda_min of the scaled J, without square roots in 2D and 3D") {
  // the closed forms (compute_2d, compute_3d) for J of ordinary size, and
  // the scaled form that takes J with diagonal entries beyond [1e-90, 1e90]
  // (3D) or J00 J11 not a normal number (2D)
  for (const double cond : {1.0 + 1e-9, 10.0, 1e3, 1e6}) {
    scaled_inverse_agrees<2>(cond, 1.0, 6.0, 11);
    scaled_inverse_agrees<3>(cond, 1.0, 6.0, 12);
    scaled_inverse_agrees<3>(cond, 1e-3, 2.0, 13); // J ~ h^2 on a millimetre grid
    scaled_inverse_agrees<2>(cond, 1e-78, 2.0, 14); // J00 J11 below the normal range
    scaled_inverse_agrees<3>(cond, 1e-50, 2.0, 15); // J_kk below 1e-90
    scaled_inverse_agrees<3>(cond, 1e50, 2.0, 16);  // J_kk above 1e90
  }
}

TEST_CASE("lme: ScaledInverse in 3D takes the cofactor form for J_kk in [1e-90, 1e90], the scaled one beyond") {
  std::mt19937_64 rng(17);
  for (const double size : {1e-90, 1e-20, 1.0, 1e20, 1e90}) {
    for (int t = 0; t < 200; ++t) {
      // unit diagonal times size: every J_kk is exactly `size`
      Mat<3> M = random_spd<3>(rng, 100.0, 1.0, 0.0);
      for (int k = 0; k < 3; ++k) M(k, k) = 1.0;
      const Mat<3> J = size * M;
      maxent::ScaledInverse<3> closed, scaled;
      REQUIRE(closed.compute_3d(J));
      scaled.compute_scaled(J);
      CHECK(closed.lambda_min > 0.0);
      CHECK(std::abs(closed.lambda_min - scaled.lambda_min) <= 1e-12 * scaled.lambda_min);
      CHECK((closed.J_inv - scaled.J_inv).norm() <= 1e-12 * scaled.J_inv.norm());
    }
  }
  maxent::ScaledInverse<3> inv;
  for (const double size : {0.5e-90, 2e90, 1e-300}) CHECK_FALSE(inv.compute_3d(size * Mat<3>::Identity()));
  inv.compute(1e-300 * Mat<3>::Identity()); // the scaled form takes it
  CHECK(inv.lambda_min == doctest::Approx(1.0 / 3.0));
  CHECK(inv.J_inv(1, 1) == doctest::Approx(1e300));
}

TEST_CASE("lme: ScaledInverse reports J that is not positive definite as lambda_min = 0") {
  for (const double s : {1.0, 1e-100, 1e100}) {
    Mat<3> J;
    J << 2, 1, 0, 1, 2, 1, 0, 1, -0.5; // indefinite: det < 0
    maxent::ScaledInverse<3> inv;
    inv.compute(s * J);
    CHECK(inv.lambda_min == 0.0);
    J << 1, 2, 0, 2, 1, 0, 0, 0, 1; // the leading 2 x 2 minor negative, det < 0
    inv.compute(s * J);
    CHECK(inv.lambda_min == 0.0);
    J << 1, 2, 0, 2, 1, 0, 0, 0, -1; // det > 0 but the leading 2 x 2 minor negative (Sylvester)
    inv.compute(s * J);
    CHECK(inv.lambda_min == 0.0);
    J << 1, 1, 1, 1, 1, 1, 1, 1, 1; // singular (rank 1): lambda_min is round-off at most
    inv.compute(s * J);
    CHECK(inv.lambda_min <= maxent::kSingularHessian);
  }
  Mat<3> J;
  J << 1, 1e200, 0, 1e200, 1, 0, 0, 0, 1; // an off-diagonal entry whose square overflows
  maxent::ScaledInverse<3> inv;
  inv.compute(J);
  CHECK(inv.lambda_min == 0.0);
  J << 1, 0, 1e200, 0, 1, 0, 1e200, 0, 1;
  inv.compute(J);
  CHECK(inv.lambda_min == 0.0);
  J << 1, 0, 0, 0, 1, 0, 0, 0, std::nan("");
  inv.compute(J);
  CHECK(inv.lambda_min == 0.0);
  // positive diagonal: what the cofactor form itself must refuse
  J << 1, 2, 2, 2, 1, 2, 2, 2, 1; // det J = 5 > 0, C22 = -3
  CHECK(inv.compute_3d(J));
  CHECK(inv.lambda_min == 0.0);
  J << 1, 0, std::nan(""), 0, 1, 0, std::nan(""), 0, 1; // a NaN off the diagonal
  CHECK(inv.compute_3d(J));
  CHECK(inv.lambda_min == 0.0);
  // det J comes out +inf with C22 > 0; the trace (-inf) refuses it
  J << 1.96562e-36, -6.52943e-51, -4.51728e167, -6.52943e-51, 5.99342e-64, 1.08381e151, -4.51728e167, 1.08381e151,
      6.41067e-65;
  CHECK(inv.compute_3d(J)); // every J_kk within [1e-90, 1e90]
  CHECK(inv.lambda_min == 0.0);
  Mat<2> J2;
  J2 << 1, 3, 3, 1;
  maxent::ScaledInverse<2> inv2;
  inv2.compute(J2);
  CHECK(inv2.lambda_min == 0.0);
}
