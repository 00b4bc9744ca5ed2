// bench_lme_lattice: the factorised LME solve on a fixed lattice alone
// (lattice_solve, lib/otmpm/basis/lme_lattice.cpp), one call per point.
//
//   OMP_NUM_THREADS=1 build-bench/bench/bench_lme_lattice [--dim 2|3] [--repeat R]
//
// 2D: a 200 x 200 lattice of the unit square, 100 000 points; 3D: 40^3 and
// 50 000 points; uniformly random in [0.1, 0.9]^D (fixed seed), gamma_lme =
// 3, tolerance 1e-6. Each point is first solved by the general solver on the
// same positions given as a cloud; the timed loop then calls lattice_solve R
// times per point warm-started at that multiplier (the common case of a
// step: one evaluation, no Newton step). Prints ns per solve, how many the
// factorised path took, and the mean stencil size. Instructions per solve:
// run it under `valgrind --tool=callgrind --toggle-collect='bool
// otmpm::maxent::lattice_solve<2>*'` with --repeat 1 and divide by the
// points.
#include "otmpm/basis/families.hpp"
#include "otmpm/basis/lme_lattice.hpp"
#include "otmpm/openmp_wait.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

using namespace otmpm;
using namespace otmpm::maxent;

namespace {

template <int D> int run(int cells, int points, int repeat) {
  CartesianGrid<D> grid;
  grid.lower = Vec<D>::Zero();
  grid.upper = Vec<D>::Ones();
  grid.cells.fill(cells);
  const NodeSet<D> nodes = NodeSet<D>::cartesian(grid);
  BasisOptions opt;
  opt.kind = "lme";
  opt.values["gamma_lme"] = 3.0;
  const double h = nodes.spacing();
  GaussianPrior<D> prior;
  prior.beta = opt.value("gamma_lme") / (h * h);
  prior.max_exponent = -std::log(opt.value("tolerance"));
  NewtonSettings set;
  set.h = h;
  set.residual_tolerance = opt.value("newton_tolerance") * h;
  set.max_iterations = opt.value("max_newton_iterations");
  set.support_radius = prior.support_radius();
  const LatticeAxes<D> axes = LatticeAxes<D>::from(nodes, prior.beta);
  const auto general = make_lme_basis<D>(NodeSet<D>::cloud(nodes.positions(), h), opt);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0.1, 0.9);
  AlignedVector<Vec<D>> x(static_cast<std::size_t>(points)), lambda(x.size(), Vec<D>::Zero());
  Stencil<D> st;
  for (std::size_t i = 0; i < x.size(); ++i) {
    for (int k = 0; k < D; ++k) x[i][k] = u(rng);
    PointQuery<D> q;
    q.x = x[i];
    q.lambda = &lambda[i];
    general->evaluate(q, st);
  }
  LatticeSolve<D> res;
  long taken = 0, entries = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r < repeat; ++r)
    for (std::size_t i = 0; i < x.size(); ++i)
      if (lattice_solve<D>(axes, prior, set, x[i], lambda[i], st, res)) ++taken, entries += st.size();
  const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double calls = double(points) * repeat;
  std::printf("%dD lattice %d^%d, %d points x %d: %.1f ns per solve, %.1f%% taken, %.1f nodes per stencil\n", D,
              cells, D, points, repeat, 1e9 * t / calls, 100.0 * double(taken) / calls,
              taken > 0 ? double(entries) / double(taken) : 0.0);
  return taken == long(calls) ? 0 : 1;
}

} // namespace

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv); // as every bench program (openmp_wait.hpp)
  int dim = 2, repeat = 20;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--dim") dim = std::stoi(argv[i + 1]);
    else if (a == "--repeat") repeat = std::stoi(argv[i + 1]);
  }
  if ((dim != 2 && dim != 3) || repeat < 1) {
    std::fprintf(stderr, "usage: bench_lme_lattice [--dim 2|3] [--repeat R >= 1]\n");
    return 2;
  }
  return dim == 2 ? run<2>(200, 100000, repeat) : run<3>(40, 50000, repeat);
}
