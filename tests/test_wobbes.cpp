// The three benchmarks of wobbes et al. (sect. 8) run from the example scenes
// (examples/fixed_bar.toml, traction_bar.toml, mms_plate.toml) and checked
// against their exact solutions: convergence orders on the fixed-end bar, the
// free end of the bar with a dynamic traction, the breakdown of B-spline MPM
// with a consistent mass matrix where the unified approach stays stable, and
// the stress of the manufactured plate. Every bound below was set from a
// measured value (quoted next to it, Release build) with the stated margin;
// docs/benchmarks.md (Wobbes section) has the full tables and the figures.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/assembly/exact_solutions.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/reference/exact.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

using namespace otmpm;

namespace {

using Overrides = std::vector<std::string>;

const std::string fixed_bar_file = OTMPM_SOURCE_DIR "/examples/fixed_bar.toml";
const std::string traction_bar_file = OTMPM_SOURCE_DIR "/examples/traction_bar.toml";
const std::string mms_plate_file = OTMPM_SOURCE_DIR "/examples/mms_plate.toml";

// Methods as --set overrides. The mass matrix is always named explicitly
// because the example files carry their own default (mms_plate.toml:
// consistent).
const Overrides mpm_linear = {"simulation.mode=mpm", "simulation.integrator=fe", "simulation.mass=lumped",
                              "basis.kind=linear"};
const Overrides mpm_lme = {"simulation.mode=mpm", "simulation.integrator=fe", "simulation.mass=lumped",
                           "basis.kind=lme"};
const Overrides mpm_lme_consistent = {"simulation.mode=mpm", "simulation.integrator=fe",
                                      "simulation.mass=consistent", "basis.kind=lme"};
const Overrides bsmpm_lumped = {"simulation.mode=mpm", "simulation.integrator=fe", "simulation.mass=lumped",
                                "basis.kind=bspline2"};
const Overrides bsmpm_consistent = {"simulation.mode=mpm", "simulation.integrator=fe",
                                    "simulation.mass=consistent", "basis.kind=bspline2"};
const Overrides otm_linear = {"simulation.mode=ul", "simulation.integrator=otm", "simulation.mass=consistent",
                              "basis.kind=linear"};
const Overrides unified = {"simulation.mode=ul", "simulation.integrator=unified", "simulation.mass=consistent",
                           "basis.kind=bspline2"};

/// The manufactured plate displacement of wobbes eqs. 104-105 has u_1(X_1)
/// and u_2(X_2) only, so it is not zero tangentially on the edges: the exact
/// solution holds only the normal component fixed, as examples/mms_plate.toml
/// does; stated here again so the tests do not depend on the scene's choice.
/// (Fixing both components pins the tangential motion the exact solution has
/// and leaves a boundary layer with ~10% displacement error.)
const Overrides mms_rollers = {"boundary.left.fix=[true,false]", "boundary.right.fix=[true,false]",
                               "boundary.bottom.fix=[false,true]", "boundary.top.fix=[false,true]"};

Overrides operator+(Overrides a, const Overrides& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

Overrides cells(int n) { return {"grid.cells=[" + std::to_string(n) + "]"}; }

RunSummary run(const std::string& file, const Overrides& overrides) {
  const Scene scene = load_scene(file, overrides);
  RunOptions opts;
  opts.write_results = false;
  return run_scene(scene, opts);
}

/// A run that must reach t_end; returns one of its errors.
double error_of(const std::string& file, const Overrides& overrides, const std::string& name) {
  const RunSummary s = run(file, overrides);
  INFO(summary_line(s));
  REQUIRE(s.exit_code == 0);
  REQUIRE(s.errors.count(name) == 1);
  return s.errors.at(name);
}

/// Fixed-bar RMS displacement error (wobbes eq. 102) with `n` cells.
double fixed_bar_error(const Overrides& method, int n) {
  return error_of(fixed_bar_file, method + cells(n), "rms_displacement_error");
}

/// Least-squares slope of log(error) against log(h) with h = 1 / cells.
double fitted_order(const std::vector<int>& cell_counts, const std::vector<double>& errors) {
  const int n = static_cast<int>(errors.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (int i = 0; i < n; ++i) {
    const double x = std::log(1.0 / cell_counts[i]), y = std::log(errors[i]);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

std::vector<double> fixed_bar_errors(const Overrides& method, const std::vector<int>& cell_counts) {
  std::vector<double> e;
  for (int n : cell_counts) e.push_back(fixed_bar_error(method, n));
  return e;
}

/// Largest |u_end - u_exact| of the traction bar's free-end particle over the
/// whole run (every step), its largest exact |u|, and the RMS displacement
/// error over all particles at t_end.
struct EndHistory {
  double max_u_error = 0.0;
  double max_u = 0.0;
  double rms_u_error = 0.0;
};

EndHistory traction_bar_end(const Overrides& method) {
  const Scene scene = load_scene(traction_bar_file, method);
  Engine<1> e = assemble<1>(scene);
  const auto exact = make_exact_solution<1>(scene);
  REQUIRE(exact);
  const Particles<1>& P = e.particles();
  int end = 0;
  for (int p = 1; p < P.size(); ++p)
    if (P.X[p][0] > P.X[end][0]) end = p;
  EndHistory h;
  const double t_end = scene.simulation.t_end;
  constexpr double time_slack = 1e-9; // relative, as in the run loop
  while (e.time() < t_end * (1.0 - time_slack)) {
    e.step();
    const double u_exact = exact->displacement(P.X[end], e.time())[0];
    h.max_u_error = std::max(h.max_u_error, std::abs(P.x[end][0] - P.X[end][0] - u_exact));
    h.max_u = std::max(h.max_u, std::abs(u_exact));
  }
  std::vector<double> squared;
  for (int p = 0; p < P.size(); ++p)
    squared.push_back((P.x[p] - P.X[p] - exact->displacement(P.X[p], e.time())).squaredNorm());
  h.rms_u_error = rms_error(squared);
  return h;
}

} // namespace

// ---------------------------------------------------------------------------
// Fixed-end bar (wobbes sect. 8.1): 12 particles per cell, t_end = 1 ms,
// dt = 1e-5 s. Below about 3e-10 m the error is set by the time step (it drops
// ~3.5x when dt is halved), so orders are fitted on grids above that floor.

TEST_CASE("fixed bar: OTM-linear converges at second order (16 to 128 nodes)") {
  const std::vector<int> n = {15, 31, 63, 127};
  const std::vector<double> e = fixed_bar_errors(otm_linear, n);
  // measured 6.81e-7, 1.59e-7, 3.84e-8, 9.45e-9: fitted order 2.00; the band
  // [1.8, 2.2] leaves room for quadrature noise but excludes first or third order.
  const double order = fitted_order(n, e);
  INFO("errors " << e[0] << " " << e[1] << " " << e[2] << " " << e[3] << ", order " << order);
  CHECK(order > 1.8);
  CHECK(order < 2.2);
}

TEST_CASE("fixed bar: unified (bspline2) converges at third order until the time-error floor") {
  const std::vector<int> n = {7, 15, 31};
  const std::vector<double> e = fixed_bar_errors(unified, n);
  // measured 2.31e-7, 2.25e-8, 2.55e-9: fitted order 3.03 (> 2.7 rules out
  // the second order of the linear basis or of a lumped mass matrix).
  const double order = fitted_order(n, e);
  INFO("errors " << e[0] << " " << e[1] << " " << e[2] << ", order " << order);
  CHECK(order > 2.7);
  // At 128 nodes the error sits on the time-error floor: measured 2.80e-10.
  CHECK(fixed_bar_error(unified, 127) < 4e-10);
}

TEST_CASE("fixed bar: consistent mass gives B-spline MPM its third order and lumped mass does not") {
  const std::vector<int> n = {7, 15, 31};
  const std::vector<double> consistent = fixed_bar_errors(bsmpm_consistent, n);
  const std::vector<double> lumped = fixed_bar_errors(bsmpm_lumped, n);
  // measured consistent 2.31e-7, 2.25e-8, 2.55e-9 (order 3.03); lumped
  // 2.37e-5, 6.74e-6, 1.40e-6 (order 1.90): the O(h^2) error of row-sum
  // lumping (wobbes sect. 7) caps the order at 2.
  CHECK(fitted_order(n, consistent) > 2.7);
  CHECK(fitted_order(n, lumped) < 2.3);
  // The unified approach uses the consistent mass matrix (Algorithm 3): the
  // scene default for it is consistent and its error is that of consistent
  // BSMPM (the nodes barely move in 1 ms), measured 2.55e-9 for both at 32
  // nodes, 550x below lumped BSMPM.
  const Scene scene = load_scene(fixed_bar_file, {"simulation.mode=ul", "simulation.integrator=unified",
                                                  "basis.kind=bspline2", "grid.cells=[31]"});
  CHECK(scene.simulation.mass == "consistent");
  const double e_unified = fixed_bar_error(unified, 31);
  CHECK(e_unified == doctest::Approx(consistent[2]).epsilon(0.05));
  CHECK(e_unified < 0.01 * lumped[2]);
}

TEST_CASE("fixed bar: MPM-linear stops converging on fine grids (grid crossing)") {
  const double e128 = fixed_bar_error(mpm_linear, 127);
  const double e512 = fixed_bar_error(mpm_linear, 511);
  // measured 4.55e-8 and 4.75e-8: second order would give e512 = e128 / 16;
  // requiring more than e128 / 2 shows the loss of convergence.
  INFO("e128 " << e128 << ", e512 " << e512);
  CHECK(e512 > 0.5 * e128);
  // OTM-linear at 512 nodes keeps converging: measured 6.42e-10.
  CHECK(fixed_bar_error(otm_linear, 511) < 0.05 * e512);
}

TEST_CASE("fixed bar: MPM-LME error is below MPM-linear on the same grid") {
  // Lumped mass, 256 nodes, where linear suffers grid crossing: measured LME
  // 1.10e-8 vs linear 2.98e-8.
  CHECK(fixed_bar_error(mpm_lme, 255) < 0.5 * fixed_bar_error(mpm_linear, 255));
  // With its consistent mass matrix LME is below linear on a coarse grid too:
  // measured 1.51e-7 vs 7.33e-7 at 32 nodes. (With lumped mass, gamma_lme = 4
  // and 32 nodes the two agree within 2% - see docs/benchmarks.md (Wobbes section).)
  CHECK(fixed_bar_error(mpm_lme_consistent, 31) < 0.3 * fixed_bar_error(mpm_linear, 31));
}

// ---------------------------------------------------------------------------
// Bar with a dynamic traction (wobbes sect. 8.2): 85 nodes for MPM, 68 on the
// material for the ul mode, 4 particles per cell, t_end = 0.4 s.

TEST_CASE("traction bar: OTM and unified follow the free-end velocity where MPM-linear does not") {
  // history_error_end: RMS over the output times of the end particle's
  // velocity error; the velocity scale is c tau_0 / E = 0.01 m/s.
  const double mpm = error_of(traction_bar_file, mpm_linear, "history_error_end");
  const double otm = error_of(traction_bar_file, otm_linear, "history_error_end");
  const double uni = error_of(traction_bar_file, unified, "history_error_end");
  // measured: MPM-linear 7.38e-4 (7% of the scale), OTM-linear 4.93e-5,
  // unified 4.53e-5 (0.5%). Bounds: 1e-4 (1%) for the ul runs, and MPM-linear
  // at least 5x worse than either.
  INFO("mpm " << mpm << ", otm " << otm << ", unified " << uni);
  CHECK(otm < 1e-4);
  CHECK(uni < 1e-4);
  CHECK(mpm > 5.0 * std::max(otm, uni));
}

TEST_CASE("traction bar: the free-end displacement is within 1.5% of its maximum for MPM-linear as for OTM and unified") {
  // The end displacement integrates the velocity, so MPM-linear's velocity
  // oscillations average out: measured max |u_end - u_exact| over all steps
  // 2.3e-5 (MPM-linear), 1.9e-5 (OTM-linear), 1.5e-5 (unified), with
  // max |u_exact| = 2.18e-3 m. Bound: 3.3e-5 = 1.5% of the maximum. MPM-linear
  // is NOT worse here (docs/benchmarks.md (Wobbes section)).
  // (An instability would throw InstabilityError out of Engine::step.)
  std::vector<EndHistory> h;
  for (const Overrides& method : {mpm_linear, otm_linear, unified}) {
    h.push_back(traction_bar_end(method));
    INFO(method[0] << " " << method[1] << " " << method[3] << ": max error " << h.back().max_u_error);
    CHECK(h.back().max_u > 2.0e-3);
    CHECK(h.back().max_u_error < 0.015 * h.back().max_u);
  }
  // Over the whole bar at t_end the ul runs are more accurate: RMS
  // displacement error measured 5.0e-6 (MPM-linear), 1.9e-6 (OTM), 1.2e-6 (unified).
  CHECK(h[1].rms_u_error < 0.5 * h[0].rms_u_error);
  CHECK(h[2].rms_u_error < 0.5 * h[0].rms_u_error);
}

TEST_CASE("traction bar: B-spline MPM with consistent mass breaks down on 85 nodes but unified and lumped BSMPM do not") {
  // 85 nodes in all (h = 1.25/84): the end particle starts 7.5% of h right of
  // the grid line x = 67 h and moves towards it; the last B-spline degree of
  // freedom is then supported by that one particle with a weight ~ xi^2 / 2,
  // its consistent-mass row ~ xi^4, and the run diverges (measured: energy
  // runaway at t = 0.2452 s, xi = 1.5%).
  const RunSummary broken = run(traction_bar_file, bsmpm_consistent + cells(84));
  INFO(summary_line(broken));
  CHECK(broken.exit_code == 1);
  CHECK(broken.status.find("runaway energy") != std::string::npos);
  CHECK(broken.time > 0.2);
  CHECK(broken.time < 0.3);
  // The same scene with lumped mass, and the unified approach (consistent
  // mass on advected knots), reach t_end.
  const RunSummary lumped = run(traction_bar_file, bsmpm_lumped + cells(84));
  const RunSummary uni = run(traction_bar_file, unified + cells(84));
  CHECK(lumped.exit_code == 0);
  CHECK(uni.exit_code == 0);
  CHECK(uni.time == doctest::Approx(0.4));
}

TEST_CASE("traction bar: B-spline MPM with consistent mass and 81 nodes reaches t_end (unlike wobbes 8.2)") {
  // With 81 nodes (h = 1/64) the bar end is a grid line and the last occupied
  // cell holds four particles for the whole run, so no degree of freedom is
  // left with a vanishing mass; wobbes report a breakdown near 0.3 s for this
  // node count, otmpm finds it for 85 nodes instead (previous test).
  const RunSummary s = run(traction_bar_file, bsmpm_consistent + cells(80));
  INFO(summary_line(s));
  CHECK(s.exit_code == 0);
  CHECK(s.time == doctest::Approx(0.4));
  // and it is accurate: end-velocity history error measured 4.9e-5 m/s.
  CHECK(s.errors.at("history_error_end") < 1e-4);
}

// ---------------------------------------------------------------------------
// Plate with an axis-aligned manufactured displacement (wobbes sect. 8.3):
// 33 x 33 nodes, 4 x 4 particles per cell, t_end = 3.5 ms. At t_end the exact
// sigma_11 reaches 6.65e3 Pa.

TEST_CASE("mms plate: unified (bspline2) stress error at t_end") {
  // measured RMS stress error 6.15 Pa (0.09% of the amplitude); bound 8 Pa
  // (+30%). The smooth B-spline gradient makes the stress continuous.
  const double e = error_of(mms_plate_file, unified + mms_rollers, "rms_stress_error");
  CHECK(e < 8.0);
}

TEST_CASE("mms plate: MPM-LME stress error at t_end is that of a cell-wise constant stress") {
  // measured RMS stress error 265 Pa (MPM-linear and OTM-linear: 278 Pa). With
  // gamma_lme = 4 the LME basis is nearly linear, so the stress is nearly
  // constant per cell; replacing sigma_11 and sigma_22 on every particle by
  // their values at the cell centre gives an RMS error of 277.6 Pa (computed
  // for this particle layout in docs/benchmarks.md (Wobbes section)), 4% of the
  // amplitude. Bound 345 Pa: measured +30%.
  const double e = error_of(mms_plate_file, mpm_lme + mms_rollers, "rms_stress_error");
  CHECK(e < 345.0);
}
