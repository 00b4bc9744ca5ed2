// Helpers shared by the basis and node-set tests: test grids and node clouds,
// random and awkward sample points, dense evaluation, finite-difference
// gradient errors and the basis identities (partition of unity, sum grad N = 0,
// linear completeness, gradient consistency), and the thread count of a scope.
// Tolerances stay in each test file.
#pragma once

#include "otmpm/basis/basis.hpp"
#include "otmpm/nodes/node_set.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <random>
#include <vector>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

namespace otmpm::test {

/// A query at x that carries the point's multiplier, slope and Newton count
/// (the per-point state a step keeps for the max-ent families).
template <int D>
PointQuery<D> stateful_query(const Vec<D>& x, Vec<D>* lambda, MultiplierSlope<D>* slope, int* iterations) {
  PointQuery<D> q;
  q.x = x;
  q.lambda = lambda;
  q.slope = slope;
  q.iterations = iterations;
  return q;
}

/// Runs the OpenMP regions with `threads` threads while it lives and restores
/// the count it found (without OpenMP: one thread, nothing to set).
class ScopedThreads {
public:
  explicit ScopedThreads(int threads) {
#ifdef OTMPM_HAVE_OPENMP
    saved_ = omp_get_max_threads();
    omp_set_num_threads(threads);
#else
    (void)threads;
#endif
  }
  ~ScopedThreads() {
#ifdef OTMPM_HAVE_OPENMP
    omp_set_num_threads(saved_);
#endif
  }
  ScopedThreads(const ScopedThreads&) = delete;
  ScopedThreads& operator=(const ScopedThreads&) = delete;

private:
#ifdef OTMPM_HAVE_OPENMP
  int saved_ = 1;
#endif
};

/// The unit box [0, 1]^D with `cells` cells per axis.
template <int D> CartesianGrid<D> unit_grid(int cells) {
  CartesianGrid<D> g;
  g.lower = Vec<D>::Zero();
  g.upper = Vec<D>::Ones();
  g.cells.fill(cells);
  return g;
}

/// Cells per axis used for the D-dimensional tests (keeps 3D small).
template <int D> int cells_for() { return D == 1 ? 10 : D == 2 ? 8 : 5; }

/// A grid with an offset origin and a different width per axis; `cells` per axis chosen by the caller.
template <int D> CartesianGrid<D> offset_grid(const std::array<int, 3>& cells) {
  CartesianGrid<D> g;
  const double lo[3] = {-0.3, 1.2, 0.05};
  const double up[3] = {0.9, 2.0, 0.55};
  for (int k = 0; k < D; ++k) {
    g.lower[k] = lo[k];
    g.upper[k] = up[k];
    g.cells[k] = cells[static_cast<std::size_t>(k)];
  }
  return g;
}

/// A uniformly random point of the box [lo, hi].
template <int D> Vec<D> random_in_box(std::mt19937& rng, const Vec<D>& lo, const Vec<D>& hi) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Vec<D> x;
  for (int k = 0; k < D; ++k) x[k] = lo[k] + u(rng) * (hi[k] - lo[k]);
  return x;
}

/// A random cloud with the same hull as the unit box: the boundary nodes of
/// the lattice plus one uniformly random node inside every cell.
template <int D> NodeSet<D> random_cloud(int cells, unsigned seed) {
  const CartesianGrid<D> g = unit_grid<D>(cells);
  const NodeSet<D> lattice = NodeSet<D>::cartesian(g);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  AlignedVector<Vec<D>> x;
  for (int id = 0; id < lattice.size(); ++id) {
    const Index<D> ijk = g.node_index(id);
    bool boundary = false;
    for (int k = 0; k < D; ++k) boundary = boundary || ijk[k] == 0 || ijk[k] == cells;
    if (boundary) x.push_back(lattice.position(id));
  }
  const double h = 1.0 / cells;
  for (int id = 0; id < lattice.size(); ++id) {
    const Index<D> ijk = g.node_index(id);
    if (*std::max_element(ijk.begin(), ijk.end()) == cells) continue; // not a cell corner
    Vec<D> p;
    for (int k = 0; k < D; ++k) p[k] = (ijk[k] + u(rng)) * h;
    x.push_back(p);
  }
  return NodeSet<D>::cloud(std::move(x), h);
}

/// Test points in the unit box: uniform ones, ones next to the boundary (some
/// coordinates at distance 1e-3 h .. 1e-10 h from a face or an edge) and ones next to a node.
template <int D> AlignedVector<Vec<D>> unit_box_points(const NodeSet<D>& nodes, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double h = nodes.spacing();
  const double gaps[] = {1e-3, 1e-6, 1e-10};
  AlignedVector<Vec<D>> pts;
  for (int i = 0; i < count; ++i) {
    Vec<D> p;
    for (int k = 0; k < D; ++k) p[k] = u(rng);
    pts.push_back(p);
  }
  for (int i = 0; i < count; ++i) {
    Vec<D> p;
    for (int k = 0; k < D; ++k) p[k] = u(rng);
    const int axis = static_cast<int>(rng() % D);
    const double gap = gaps[rng() % 3] * h;
    p[axis] = (rng() % 2) ? gap : 1.0 - gap;
    if (D > 1 && rng() % 4 == 0) p[(axis + 1) % D] = (rng() % 2) ? gap : 1.0 - gap; // near an edge
    pts.push_back(p);
  }
  for (int i = 0; i < count; ++i) {
    const int I = static_cast<int>(rng() % static_cast<unsigned>(nodes.size()));
    Vec<D> p = nodes.position(I);
    for (int k = 0; k < D; ++k) p[k] = std::clamp(p[k] + 1e-7 * h * (2.0 * u(rng) - 1.0), 0.0, 1.0);
    pts.push_back(p);
  }
  return pts;
}

/// Evaluates the basis at x into st (no warm start, no point id).
template <int D> void evaluate_at(const Basis<D>& b, const Vec<D>& x, Stencil<D>& st) {
  PointQuery<D> q;
  q.x = x;
  b.evaluate(q, st);
}

/// Sum of N_I per node id at x (a sparse view of the stencil).
template <int D> std::map<int, double> values_at(const Basis<D>& b, const Vec<D>& x) {
  Stencil<D> st;
  evaluate_at(b, x, st);
  std::map<int, double> m;
  for (int a = 0; a < st.size(); ++a) m[st.node[a]] += st.N[a];
  return m;
}

/// Dense N and grad N over all nodes at x.
template <int D>
void dense_eval(const Basis<D>& b, const Vec<D>& x, std::vector<double>& N, AlignedVector<Vec<D>>* dN = nullptr) {
  Stencil<D> st;
  evaluate_at(b, x, st);
  N.assign(static_cast<std::size_t>(b.nodes().size()), 0.0);
  if (dN) dN->assign(N.size(), Vec<D>::Zero());
  for (int a = 0; a < st.size(); ++a) {
    N[st.node[a]] = st.N[a];
    if (dN) (*dN)[st.node[a]] = st.dN[a];
  }
}

/// max_I |grad N_I - central difference with step `step` h| * h at x.
template <int D> double fd_gradient_error(const Basis<D>& b, const Vec<D>& x, double step) {
  const double h = b.nodes().spacing();
  const double eps = step * h;
  std::vector<double> N, Np, Nm;
  AlignedVector<Vec<D>> dN;
  dense_eval(b, x, N, &dN);
  double err = 0;
  for (int k = 0; k < D; ++k) {
    Vec<D> e = Vec<D>::Zero();
    e[k] = eps;
    dense_eval<D>(b, x + e, Np);
    dense_eval<D>(b, x - e, Nm);
    for (std::size_t I = 0; I < N.size(); ++I)
      err = std::max(err, std::abs((Np[I] - Nm[I]) / (2 * eps) - dN[I][k]) * h);
  }
  return err;
}

/// Largest fd_gradient_error over 30 random points of [0.01, 0.99]^D (central differences stay inside the hull).
template <int D> double max_fd_gradient_error(const Basis<D>& b, unsigned seed, double step) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.01, 0.99);
  double err = 0;
  for (int i = 0; i < 30; ++i) {
    Vec<D> x;
    for (int k = 0; k < D; ++k) x[k] = u(rng);
    err = std::max(err, fd_gradient_error<D>(b, x, step));
  }
  return err;
}

/// Tolerances of the max-ent identities (partition, gradient sum, completeness / h, gradient consistency).
struct IdentityTolerances {
  double partition, gradient_sum, completeness, gradient_consistency;
};

/// Worst violations of the basis identities over a set of points.
template <int D> struct Identities {
  double partition = 0, gradient_sum = 0, completeness = 0, gradient_consistency = 0;
  double min_N = 1;
  Vec<D> worst_point = Vec<D>::Zero();          ///< worst in completeness or gradient consistency
  Vec<D> worst_consistency_point = Vec<D>::Zero(); ///< worst in gradient consistency alone
};

/// Measures the worst identity violations of `basis` over `pts` (no assertion).
template <int D> Identities<D> check_identities(const Basis<D>& basis, const AlignedVector<Vec<D>>& pts) {
  Identities<D> id;
  Stencil<D> st;
  const double h = basis.nodes().spacing();
  for (const Vec<D>& x : pts) {
    evaluate_at(basis, x, st);
    double sumN = 0, abs_dN = 0;
    Vec<D> sum_dN = Vec<D>::Zero(), sum_xN = Vec<D>::Zero();
    Mat<D> sum_xdN = Mat<D>::Zero();
    for (int a = 0; a < st.size(); ++a) {
      const Vec<D>& xI = basis.nodes().position(st.node[a]);
      sumN += st.N[a];
      sum_dN += st.dN[a];
      abs_dN += st.dN[a].norm();
      sum_xN += st.N[a] * xI;
      sum_xdN += xI * st.dN[a].transpose();
      id.min_N = std::min(id.min_N, st.N[a]);
    }
    const double e_c = (sum_xN - x).norm() / h;
    const double e_gc = (sum_xdN - Mat<D>::Identity()).norm();
    if (e_gc > id.gradient_consistency || e_c > id.completeness) id.worst_point = x;
    if (e_gc > id.gradient_consistency) id.worst_consistency_point = x;
    id.partition = std::max(id.partition, std::abs(sumN - 1.0));
    id.gradient_sum = std::max(id.gradient_sum, sum_dN.norm() / abs_dN);
    id.completeness = std::max(id.completeness, e_c);
    id.gradient_consistency = std::max(id.gradient_consistency, e_gc);
  }
  return id;
}

/// Checks the measured identities against `tol` (five CHECKs); `worst` is the point named on failure.
template <int D> void require_identities(const Identities<D>& id, const Vec<D>& worst, const IdentityTolerances& tol) {
  INFO("worst point " << format_point<D>(worst));
  CHECK(id.partition <= tol.partition);
  CHECK(id.gradient_sum <= tol.gradient_sum);
  CHECK(id.completeness <= tol.completeness);
  CHECK(id.gradient_consistency <= tol.gradient_consistency);
  CHECK(id.min_N > 0.0); // non-negative, and zero entries are not listed
}

/// Sums over one stencil of N, grad N, N x_I and x_I (x) grad N_I, and of their magnitudes (round-off scales).
template <int D> struct StencilSums {
  double sumN = 0, absN = 0;
  Vec<D> sumG = Vec<D>::Zero(), absG = Vec<D>::Zero(), sumX = Vec<D>::Zero(), absX = Vec<D>::Zero();
  Mat<D> sumXG = Mat<D>::Zero(), absXG = Mat<D>::Zero();
};

/// The StencilSums of an evaluated stencil of basis b.
template <int D> StencilSums<D> stencil_sums(const Basis<D>& b, const Stencil<D>& st) {
  StencilSums<D> s;
  for (int a = 0; a < st.size(); ++a) {
    const Vec<D>& xI = b.nodes().position(st.node[a]);
    s.sumN += st.N[a];
    s.absN += std::abs(st.N[a]);
    s.sumG += st.dN[a];
    s.absG += st.dN[a].cwiseAbs();
    s.sumX += st.N[a] * xI;
    s.absX += (st.N[a] * xI).cwiseAbs();
    s.sumXG += xI * st.dN[a].transpose();
    s.absXG += (xI * st.dN[a].transpose()).cwiseAbs();
  }
  return s;
}

/// Linear completeness at x, componentwise to rel_tol of the magnitudes: sum N_I x_I = x, sum x_I (x) grad N_I = I.
template <int D> void check_linear_completeness(const StencilSums<D>& s, const Vec<D>& x, double rel_tol) {
  for (int k = 0; k < D; ++k) {
    CHECK(std::abs(s.sumX[k] - x[k]) <= rel_tol * s.absX[k]);
    for (int m = 0; m < D; ++m) CHECK(std::abs(s.sumXG(k, m) - (k == m)) <= rel_tol * s.absXG(k, m));
  }
}

} // namespace otmpm::test
