// The consolidation benchmarks (docs/benchmarks.md, "Saturated soil"):
// examples/terzaghi.toml at h = H/16, H/32, H/64 - its pore-pressure
// isochrones and degree of consolidation at T_v = 0.05, 0.2, 0.5 and 1.0
// against the exact solution of its own values, converging, within 2 % of the
// load at the finest - and examples/mandel.toml at h = a/8 and a/16: the
// centre's pore pressure with its Mandel-Cryer overshoot over the first half
// of the consolidation, within 3 %.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/assembly/exact_solutions.hpp"
#include "otmpm/materials/pore_fluid.hpp"
#include "otmpm/reference/consolidation.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <string>
#include <vector>

using namespace otmpm;

namespace {

std::string example(const std::string& name) { return std::string(OTMPM_SOURCE_DIR) + "/examples/" + name; }

template <int D> void run_to(Engine<D>& e, double t) {
  while (e.time() < t * (1.0 - 1e-12)) e.step();
}

template <int D> double pressure_of(const Engine<D>& e, int p) {
  return e.particles().find_state(kPorePressureField)->values[static_cast<std::size_t>(p)];
}

/// The errors of a Terzaghi run at one time factor, relative to the load q:
/// the largest of the pore pressure and of the settlement of the top
/// particle against the final settlement q H / M (the degree of consolidation).
struct Isochrone {
  double pressure = 0.0, degree = 0.0;
};

std::vector<Isochrone> terzaghi_errors(int cells) {
  const Scene scene =
      load_scene(example("terzaghi.toml"), {"grid.cells=[" + std::to_string(cells) + "]", "simulation.t_end=1.01"});
  Engine<1> e = assemble<1>(scene);
  const auto exact = make_exact_solution<1>(scene);
  const auto& t = dynamic_cast<const Terzaghi<1>&>(*exact);
  const double q = 1e4, final_settlement = q * 1.0 / 1e7;
  const Particles<1>& P = e.particles();
  std::vector<Isochrone> out;
  for (double Tv : {0.05, 0.2, 0.5, 1.0}) {
    run_to(e, Tv / t.consolidation_coefficient()); // H = 1
    Isochrone iso;
    for (int p = 0; p < P.size(); ++p)
      iso.pressure = std::max(iso.pressure, std::abs(pressure_of(e, p) - exact->pore_pressure(P.X[p], e.time())) / q);
    const int top = P.size() - 1; // the seeding's last particle is the column's top
    iso.degree = std::abs((P.x[top][0] - P.X[top][0]) - exact->displacement(P.X[top], e.time())[0]) / final_settlement;
    MESSAGE("Terzaghi, " << cells << " cells, T_v = " << Tv << ": max |p - p_exact| / q = " << iso.pressure
                         << ", settlement error / final settlement = " << iso.degree << " (U = " << t.degree(e.time())
                         << ")");
    out.push_back(iso);
  }
  return out;
}

} // namespace

TEST_CASE("Terzaghi: isochrones and degree of consolidation within 2 % at h = H/64, converging") {
  const std::vector<Isochrone> coarse = terzaghi_errors(16), medium = terzaghi_errors(32), fine = terzaghi_errors(64);
  for (std::size_t i = 0; i < fine.size(); ++i) {
    CHECK(fine[i].pressure < 0.02);
    CHECK(fine[i].degree < 0.02);
    // first order: each halving of h about halves the pressure error
    CHECK(medium[i].pressure < 0.65 * coarse[i].pressure);
    CHECK(fine[i].pressure < 0.65 * medium[i].pressure);
  }
}

TEST_CASE("Mandel: the centre's pore pressure and its overshoot within 3 % over the first half of consolidation") {
  for (const char* cells : {"[10,2]", "[20,4]"}) {
    const Scene scene = load_scene(example("mandel.toml"), {std::string("grid.cells=") + cells});
    Engine<2> e = assemble<2>(scene);
    const auto exact = make_exact_solution<2>(scene);
    const auto& m = dynamic_cast<const Mandel&>(*exact);
    const Particles<2>& P = e.particles();
    int centre = 0;
    for (int p = 1; p < P.size(); ++p)
      if (P.X[p].norm() < P.X[centre].norm()) centre = p;
    const double p0 = 1e4 * m.skempton() * (1.0 + m.undrained_poisson()) / 3.0;
    double worst = 0.0, peak = 0.0, exact_peak = 0.0;
    for (double t = 0.25; t <= scene.simulation.t_end + 1e-9; t += 0.25) { // T_v = 0.01 ... 0.5
      run_to(e, t);
      const double p = pressure_of(e, centre), q = exact->pore_pressure(P.X[centre], e.time());
      worst = std::max(worst, std::abs(p - q) / p0);
      peak = std::max(peak, p), exact_peak = std::max(exact_peak, q);
    }
    MESSAGE("Mandel, grid " << std::string(cells) << ": centre |p - p_exact| / p0 <= " << worst << ", peak " << peak / p0
                            << " p0 (exact " << exact_peak / p0 << " p0)");
    CHECK(worst < 0.03);
    CHECK(peak == doctest::Approx(exact_peak).epsilon(0.01));
  }
}
