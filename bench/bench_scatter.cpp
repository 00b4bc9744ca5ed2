// bench_scatter: the particle-to-node pass (engine/scatter.hpp) on its own,
// the path the plan chooses against the column gather, on the tables of real
// scenes after one step.
//
//   OMP_NUM_THREADS=1 build-bench/bench/bench_scatter [--rounds R]
//
// Scenes: the andersen block at h = 0.125 m (25 600 particles) with the
// particles in a fixed random order, linear, LME and bspline2; the 3D block of
// the methods table at 40^3 cells (512 000 particles) in the seeded order
// and shuffled, and at 64^3 (2 097 152 particles) in the seeded order. Each pass forgets the plan first (as in mpm mode, where the
// table is rebuilt every step), so the plan, or the transposition, is in the
// time; the payload is the force pass's (mass, momentum, V sigma grad N).
// Per round: the median time of a set of passes with the plan's path and
// with each path forced; prints the median over the rounds of the per-round
// ratios to the column gather.
#include "otmpm/openmp_wait.hpp"
#include "bench_scenes.hpp"

#include "otmpm/assembly/assembler.hpp"
#include "otmpm/engine/scatter.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <numeric>
#include <optional>
#include <random>
#include <string>
#include <vector>

using namespace otmpm;

namespace {

/// Reorders every particle field by a fixed random permutation.
template <int D> void shuffle_particles(Particles<D>& P) {
  std::vector<int> perm(static_cast<std::size_t>(P.size()));
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), std::mt19937(42));
  auto apply = [&](auto& field) {
    if (field.empty()) return;
    auto copy = field;
    for (std::size_t i = 0; i < perm.size(); ++i) field[i] = copy[static_cast<std::size_t>(perm[i])];
  };
  apply(P.x), apply(P.X), apply(P.v), apply(P.a), apply(P.m), apply(P.V), apply(P.V0), apply(P.rho);
  apply(P.F), apply(P.eps), apply(P.sigma), apply(P.length0);
  apply(P.material), apply(P.body);
}

/// Median seconds of `passes` particle-to-node passes over the engine's
/// table (`forced`: the path forced, or the plan's); `path` receives the path taken.
template <int D>
double pass_seconds(const Engine<D>& e, std::optional<ScatterPath> forced, int passes, ScatterPath& path) {
  const BasisTable<D>& T = e.table();
  const Particles<D>& P = e.particles();
  const int nodes = static_cast<int>(e.nodal().m.size());
  std::vector<double> m(static_cast<std::size_t>(nodes));
  AlignedVector<Vec<D>> q(static_cast<std::size_t>(nodes)), f(static_cast<std::size_t>(nodes));
  struct Payload {
    double m;
    Vec<D> mv;
    Mat<D> Vs;
  };
  ParticleToNodes<D> scatter;
  scatter.force(forced);
  std::vector<double> t;
  for (int r = 0; r < passes; ++r) {
    scatter.invalidate(linear_row_width(T));
    const auto t0 = std::chrono::steady_clock::now();
    scatter.run(
        T, nodes, [](int, int) {},
        [&](int p) {
          return Payload{P.m[p], P.m[p] * P.v[p], P.V[p] * P.sigma[p]};
        },
        [&](NodeSums<D>& acc, double N, const Vec<D>& dN, const Payload& w) {
          acc.m += N * w.m;
          acc.q += N * w.mv;
          acc.f -= w.Vs * dN;
        },
        [&](int I, const NodeSums<D>& acc) {
          m[I] += acc.m;
          q[I] += acc.q;
          f[I] += acc.f;
        },
        [&](int I0, int I1) {
          for (int I = I0; I < I1; ++I) m[I] = 0.0, q[I].setZero(), f[I].setZero();
        });
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  path = scatter.path();
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

const char* path_name(ScatterPath p) {
  return p == ScatterPath::dense ? "dense" : p == ScatterPath::sparse ? "sparse" : "columns";
}

/// One line: the time per particle of the plan's path, and of each path
/// forced, with the median over the rounds of the per-round ratios to the
/// column gather.
template <int D> void compare(const std::string& name, const Engine<D>& e, int passes, int rounds) {
  const std::optional<ScatterPath> paths[4] = {std::nullopt, ScatterPath::dense, ScatterPath::sparse,
                                               ScatterPath::columns};
  ScatterPath chosen = ScatterPath::columns, taken = ScatterPath::columns;
  double t[4] = {};
  std::vector<double> ratio[3];
  for (int k = 0; k < rounds; ++k) {
    for (int i = 0; i < 4; ++i) t[i] = pass_seconds(e, paths[i], passes, i == 0 ? chosen : taken);
    for (int i = 0; i < 3; ++i) ratio[i].push_back(t[i] / t[3]);
  }
  const double n = e.table().rows();
  std::printf("%-28s %7.0f particles %5.1f entries/particle, plan: %-7s | us/particle (last round): plan %.3f, dense "
              "%.3f, sparse %.3f, columns %.3f | median / columns: plan %.3f, dense %.3f, sparse %.3f\n",
              name.c_str(), n, double(e.table().entries()) / n, path_name(chosen), 1e6 * t[0] / n, 1e6 * t[1] / n,
              1e6 * t[2] / n, 1e6 * t[3] / n, median(ratio[0]), median(ratio[1]), median(ratio[2]));
}

} // namespace

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv); // as the otmpm command waits (openmp_wait.hpp)
  int rounds = 5;
  for (int i = 1; i + 1 < argc; i += 2)
    if (std::string(argv[i]) == "--rounds") rounds = std::max(1, std::stoi(argv[i + 1]));
  for (const char* basis : {"linear", "lme", "bspline2"}) {
    Engine<2> e = assemble<2>(load_scene(OTMPM_SOURCE_DIR "/examples/andersen_block.toml",
                                         {"grid.cells=[144, 96]", "output.every=0",
                                          std::string("basis.kind=\"") + basis + "\""}));
    shuffle_particles(e.particles());
    e.step();
    compare(std::string("andersen shuffled, ") + basis, e, 11, rounds);
  }
  for (const int cells : {40, 64}) {
    const Scene s3 = parse_scene(bench::block_scene(3, cells, "linear", "fe", "mpm", 3.0), "block3d.toml");
    Engine<3> e = assemble<3>(s3);
    e.step();
    compare("3D block " + std::to_string(cells) + "^3, seeded", e, 3, rounds);
    if (cells > 40) continue;
    shuffle_particles(e.particles());
    e.step();
    compare("3D block 40^3, shuffled", e, 3, rounds);
  }
  return 0;
}
