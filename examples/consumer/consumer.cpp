// consumer.cpp - the smallest program that links the installed otmpm library.
//
// Build (after `cmake --install build --prefix PREFIX`):
//   cmake -S examples/consumer -B build-consumer -DCMAKE_PREFIX_PATH=PREFIX
//   cmake --build build-consumer && ./build-consumer/consumer
//
// It (1) evaluates the LME basis at a point of a 2D grid and checks partition
// of unity and linear completeness, and (2) runs a short 1D Dyka bar from a
// scene given as text and prints its summary line. Exit status 0 on success.
#include <otmpm/basis/basis.hpp>
#include <otmpm/run/run.hpp>
#include <otmpm/scene/scene.hpp>

#include <cmath>
#include <cstdio>

int main() {
  // 1. LME shape functions on a 10 x 10 grid of the unit square.
  otmpm::CartesianGrid<2> grid;
  grid.cells = {10, 10};
  otmpm::BasisOptions opt;
  opt.kind = "lme";
  opt.values["gamma_lme"] = 3.0;
  auto basis = otmpm::make_basis<2>(opt, otmpm::NodeSet<2>::cartesian(grid));
  otmpm::PointQuery<2> q;
  q.x = otmpm::Vec<2>(0.437, 0.618);
  otmpm::Stencil<2> st;
  basis->evaluate(q, st);
  double sum = 0.0;
  otmpm::Vec<2> x = otmpm::Vec<2>::Zero();
  for (int e = 0; e < st.size(); ++e) {
    sum += st.N[e];
    x += st.N[e] * basis->nodes().position(st.node[e]);
  }
  std::printf("LME: %d nodes, sum N - 1 = %.2e, |sum N x_I - x| = %.2e\n", st.size(), sum - 1.0, (x - q.x).norm());
  if (std::abs(sum - 1.0) > 1e-12 || (x - q.x).norm() > 1e-10) return 1;

  // 2. A short Dyka bar run from scene text.
  const char* scene_text = R"(
[simulation]
dimension = 1
integrator = "npc"
t_end = 2.0e-5
[basis]
kind = "lme"
gamma_lme = 4.0
[grid]
lower = [-0.013330]
upper = [0.1333]
cells = [22]
[[material]]
name = "steel"
model = "linear_elastic"
density = 7833.0
young = 200.0e9
poisson = 0.0
[[body]]
name = "bar"
material = "steel"
lower = [0.0]
upper = [0.1333]
[[initial_velocity]]
lower = [0.0]
upper = [0.033325]
velocity = [-5.0]
[[boundary]]
name = "right_end"
lower = [0.1333]
upper = [0.1333]
fix = [true]
[reference]
solution = "dyka"
)";
  const otmpm::Scene scene = otmpm::parse_scene(scene_text, "consumer.toml");
  otmpm::RunOptions run;
  run.write_results = false;
  const otmpm::RunSummary s = otmpm::run_scene(scene, run);
  std::printf("%s\n", otmpm::summary_line(s).c_str());
  return s.exit_code;
}
