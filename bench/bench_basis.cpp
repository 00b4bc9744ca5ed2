// bench_basis: basis evaluations per second for each family in 2D, on one core.
//
//   OMP_NUM_THREADS=1 build/bench/bench_basis [--points N] [--repeat R]
//
// For each family: a 64 x 64 Cartesian grid of the unit square, N random
// points (fixed seed) away from the boundary by 2 cells, the whole table
// filled with fill_basis_table (as the engine does once per step); the
// "every cell" rows take N points over the whole square instead, the cells
// at the grid's ends included (where lme_box reads its boundary tables and
// its outermost cells take the Newton solve). LME and
// max-ent run twice per repetition: cold (lambda = 0) and warm (lambda from
// the previous fill of the same points moved by 1e-3 h, as between two time
// steps). "linear, moved nodes": the nodes displaced by a smooth field of
// amplitude h/10 (as advected nodes in `ul` mode), so that each point is
// evaluated on its isoparametric element (cold: no cell hints; warm: the
// hints of the previous fill). Prints the median over R repetitions and the
// mean stencil size.
#include "otmpm/openmp_wait.hpp"
#include "bench_util.hpp"
#include "otmpm/basis/basis.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

using namespace otmpm;
using otmpm::bench::median;

namespace {

struct Case {
  std::string label;
  BasisOptions opt;
  bool moved = false; ///< the nodes displaced off their lattice
  bool every_cell = false; ///< the points over every cell, those at the grid's ends included
};

/// Displaces the nodes by dx = (h/10) (sin(2 pi y), sin(2 pi x)): every
/// element stays convex, none is on its lattice any more.
void displace(Basis<2>& basis, double h) {
  NodeSet<2>& nodes = basis.nodes();
  AlignedVector<Vec<2>> dx(static_cast<std::size_t>(nodes.size()));
  const double two_pi = 2.0 * 3.141592653589793;
  for (int I = 0; I < nodes.size(); ++I) {
    const Vec<2> x = nodes.position(I);
    dx[static_cast<std::size_t>(I)] = 0.1 * h * Vec<2>(std::sin(two_pi * x[1]), std::sin(two_pi * x[0]));
  }
  nodes.advect(dx);
  basis.nodes_moved(dx);
}

} // namespace

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv); // as the otmpm command waits (openmp_wait.hpp)
  int points = 100000, repeat = 5;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--points")) points = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--repeat")) repeat = std::atoi(argv[i + 1]);
  }
  constexpr int cells = 64;
  CartesianGrid<2> grid;
  grid.cells = {cells, cells};
  const double h = 1.0 / cells;
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(2 * h, 1 - 2 * h);
  std::uniform_real_distribution<double> u_all(0.0, 1 - 1e-3 * h);
  AlignedVector<Vec<2>> x(points), x_moved(points), x_all(points), x_all_moved(points);
  for (int p = 0; p < points; ++p) {
    x[p] = Vec<2>(u(rng), u(rng));
    x_moved[p] = x[p] + Vec<2>::Constant(1e-3 * h);
    x_all[p] = Vec<2>(u_all(rng), u_all(rng));
    x_all_moved[p] = x_all[p] + Vec<2>::Constant(1e-3 * h);
  }
  std::vector<Case> cases;
  auto add = [&](const std::string& label, const std::string& kind, double gamma = 4.0, double d_max = 2.0) {
    Case c{label, {}};
    c.opt.kind = kind;
    c.opt.values["gamma_lme"] = gamma;
    c.opt.values["d_max"] = d_max;
    for (double& w : c.opt.particle_half_width) w = h / 4;
    cases.push_back(c);
  };
  add("linear", "linear");
  add("linear, moved nodes", "linear");
  cases.back().moved = true;
  add("ugimp", "ugimp");
  add("bspline2", "bspline2");
  add("bspline3", "bspline3");
  add("lme gamma_lme=4", "lme", 4.0);
  add("lme gamma_lme=1.5", "lme", 1.5);
  add("lme gamma_lme=3", "lme", 3.0);
  add("lme_box gamma_lme=3", "lme_box", 3.0);
  add("lme_box gamma_lme=4", "lme_box", 4.0);
  add("maxent d_max=2", "maxent", 4.0, 2.0);
  add("lme gamma_lme=3, every cell", "lme", 3.0);
  cases.back().every_cell = true;
  add("lme_box gamma_lme=3, every cell", "lme_box", 3.0);
  cases.back().every_cell = true;
  std::printf("%-32s %14s %14s %12s\n", "family (2D)", "evals/s cold", "evals/s warm", "mean stencil");
  for (const Case& c : cases) {
    const auto basis = make_basis<2>(c.opt, NodeSet<2>::cartesian(grid));
    if (c.moved) displace(*basis, h);
    const bool maxent = c.opt.kind == "lme" || c.opt.kind == "lme_box" || c.opt.kind == "maxent";
    BasisTable<2> table;
    std::vector<double> cold, warm;
    const AlignedVector<Vec<2>>& x0 = c.every_cell ? x_all : x;
    const AlignedVector<Vec<2>>& x1 = c.every_cell ? x_all_moved : x_moved;
    for (int r = 0; r < repeat; ++r) {
      AlignedVector<Vec<2>> lambda(points, Vec<2>::Zero());
      // moved nodes: no hint at first (the Cartesian guess starts each walk)
      std::vector<Index<2>> hint(points, c.moved ? Index<2>{-1, -1} : Index<2>{});
      auto t0 = std::chrono::steady_clock::now();
      fill_basis_table(*basis, x0, maxent ? &lambda : nullptr, &hint, table);
      auto t1 = std::chrono::steady_clock::now();
      fill_basis_table(*basis, x1, maxent ? &lambda : nullptr, &hint, table);
      auto t2 = std::chrono::steady_clock::now();
      cold.push_back(points / std::chrono::duration<double>(t1 - t0).count());
      warm.push_back(points / std::chrono::duration<double>(t2 - t1).count());
    }
    std::printf("%-32s %14.3e %14.3e %12.1f\n", c.label.c_str(), median(cold), median(warm),
                double(table.entries()) / points);
  }
  return 0;
}
