// The plastic models in runs (docs/theory.md sect. 9): the scene keys of j2
// and drucker_prager and their errors, every integrator and node mode, the
// energy balance E_kin + E_elastic + W_plastic - W_ext - W_R, the
// plastic_strain output field, the wave speed, and restarts bit for bit.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/run/restart.hpp"
#include "otmpm/scene/scene.hpp"

#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

using namespace otmpm;

namespace {

/// A 2D plane-strain steel strip 0.1 m x 5 mm whose left quarter hits the
/// right end at 5 m/s (the Dyka setting); the impact stress (~100 MPa)
/// exceeds the yield stress `yield` (Pa) of a j2 material.
std::string strip(const std::string& material, const std::string& mode, const std::string& integrator,
                  const std::string& basis) {
  const bool ul = mode == "ul";
  return "[simulation]\ndimension = 2\nmode = \"" + mode + "\"\nintegrator = \"" + integrator +
         "\"\nt_end = 2.0e-5\ncfl = 0.1\n"
         "[basis]\nkind = \"" + basis + "\"\n"
         "[grid]\nlower = [-0.01, 0.0]\nupper = [0.1, 0.005]\ncells = [22, 1]\n" + material +
         "[[body]]\nname = \"bar\"\nmaterial = \"m\"\nlower = [0.0, 0.0]\nupper = [0.1, 0.005]\n"
         "[[initial_velocity]]\nlower = [0.0, 0.0]\nupper = [0.025, 0.005]\nvelocity = [-5.0, 0.0]\n"
         "[[boundary]]\nname = \"end\"\nlower = [0.1, 0.0]\nupper = [0.1, 0.005]\nfix = [true, false]\n"
         "[[boundary]]\nname = \"bottom\"\nlower = [" + std::string(ul ? "0.0" : "-0.01") +
         ", 0.0]\nupper = [0.1, 0.0]\nfix = [false, true]\n"
         "[[boundary]]\nname = \"top\"\nlower = [" + std::string(ul ? "0.0" : "-0.01") +
         ", 0.005]\nupper = [0.1, 0.005]\nfix = [false, true]\n";
}

const std::string kJ2 = "[[material]]\nname = \"m\"\nmodel = \"j2\"\ndensity = 7833.0\nyoung = 200.0e9\n"
                        "poisson = 0.3\nyield_stress = 5.0e7\nhardening_modulus = 1.0e9\n";
const std::string kDP = "[[material]]\nname = \"m\"\nmodel = \"drucker_prager\"\ndensity = 7833.0\nyoung = 200.0e9\n"
                        "poisson = 0.3\nfriction_angle = 30.0\ncohesion = 2.0e7\n";

/// The message of the InputError parse_scene throws, or "".
std::string parse_error(const std::string& text) {
  try {
    parse_scene(text, "plastic.toml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

/// Runs to t_end and returns the engine.
Engine<2> run(const std::string& text) {
  Engine<2> e = assemble<2>(parse_scene(text, "plastic.toml"));
  while (e.time() < e.settings().t_end * (1 - 1e-12)) e.step();
  return e;
}

} // namespace

TEST_CASE("j2 and drucker_prager scene keys are read with their defaults") {
  const Scene s = parse_scene(strip(kJ2 + "[material.johnson_cook]\nB = 1e8\nn = 0.5\nC = 0.01\n"
                                          "reference_strain_rate = 1.0\n",
                                    "mpm", "npc", "linear"),
                              "plastic.toml");
  CHECK(s.materials[0].model == "j2");
  CHECK(s.materials[0].extra.at("yield_stress") == 5e7);
  CHECK(s.materials[0].extra.at("johnson_cook.n") == 0.5);
  const Scene d = parse_scene(strip(kDP, "mpm", "npc", "linear"), "plastic.toml");
  CHECK(d.materials[0].extra.at("friction_angle") == 30.0);
  CHECK(d.materials[0].extra.count("dilation_angle") == 0); // default 0, taken by the model
}

TEST_CASE("plastic parameters out of range or missing are input errors with file, line and key") {
  std::string missing = kJ2;
  missing.replace(missing.find("yield_stress = 5.0e7\n"), 21, "");
  CHECK(contains(parse_error(strip(missing, "mpm", "npc", "linear")), "key 'material.m.yield_stress'"));
  std::string negative = kJ2;
  negative.replace(negative.find("1.0e9"), 5, "-1.0");
  const std::string m = parse_error(strip(negative, "mpm", "npc", "linear"));
  CHECK(contains(m, "plastic.toml:"));
  CHECK(contains(m, "hardening_modulus"));
  CHECK(contains(m, "must be >= 0"));
  CHECK(contains(parse_error(strip(kDP + "dilation_angle = 40.0\n", "mpm", "npc", "linear")), "dilation_angle"));
  CHECK(contains(parse_error(strip(kJ2 + "[material.johnson_cook]\nB = 1e8\n", "mpm", "npc", "linear")),
                 "material.m.johnson_cook"));
  CHECK(contains(parse_error(strip(kJ2 + "[material.johnson_cook]\nB = 1e8\nn = 1\nC = 0\nreference_strain_rate = 1\n"
                                         "D = 2\n",
                                   "mpm", "npc", "linear")),
                 "unknown key"));
  CHECK(contains(parse_error(strip(kJ2 + "friction_angle = 30.0\n", "mpm", "npc", "linear")), "unknown key"));
}

TEST_CASE("plastic runs close the energy balance (musl, linear): |E + W_p - E0 - W| <= 2% E0") {
  for (const std::string& material : {kJ2, kDP}) {
    const Engine<2> e = run(strip(material, "mpm", "musl", "linear"));
    const EnergyBalance& E = e.energy();
    INFO(material);
    CHECK(E.dissipated > 0.05 * E.initial); // the impact is plastic
    CHECK(std::abs(E.balance_error()) <= 0.02 * E.initial);
  }
}

TEST_CASE("j2 runs in every node mode and integrator without creating energy") {
  struct Case {
    const char *mode, *integrator, *basis;
  };
  for (const Case& c : {Case{"mpm", "fe", "linear"}, Case{"mpm", "musl", "lme"}, Case{"mpm", "npc", "lme"},
                        Case{"ul", "npc", "linear"}, Case{"ul", "otm", "linear"}, Case{"ul", "unified", "bspline2"}}) {
    INFO(std::string(c.mode) << " " << c.integrator << " " << c.basis);
    std::string text = strip(kJ2, c.mode, c.integrator, c.basis);
    // The consistent B-spline mass needs more particle rows than the 3
    // quadratic functions across the one cell of the strip.
    if (std::string(c.basis) == "bspline2") text.replace(text.find("[[initial_velocity]]"), 0, "particles_per_cell = 3\n");
    const Engine<2> e = run(text);
    const EnergyBalance& E = e.energy();
    CHECK(E.dissipated > 0.0);
    CHECK(E.total() + E.dissipated <= 1.02 * (E.initial + E.work()));
  }
}

TEST_CASE("plastic_strain is an output field: only where the bar yields does it grow") {
  const Engine<2> e = run(strip(kJ2, "mpm", "npc", "linear"));
  const StateField* eps_p = e.particles().find_state("plastic_strain");
  REQUIRE(eps_p != nullptr);
  double largest = 0.0;
  for (double v : eps_p->values) {
    CHECK(v >= 0.0);
    largest = std::max(largest, v);
  }
  CHECK(largest > 1e-5);
  std::string text = strip(kJ2, "mpm", "npc", "linear") + "[output]\nfields = [\"x\", \"plastic_strain\"]\n";
  CHECK_NOTHROW(parse_scene(text, "plastic.toml"));
  std::string elastic = strip(kJ2, "mpm", "npc", "linear");
  elastic.replace(elastic.find("model = \"j2\""), 12, "model = \"linear_elastic\"");
  elastic.replace(elastic.find("yield_stress = 5.0e7\nhardening_modulus = 1.0e9\n"), 46, "");
  CHECK(contains(parse_error(elastic + "[output]\nfields = [\"plastic_strain\"]\n"), "unknown field"));
}

TEST_CASE("the wave speed of a plastic material is the elastic P-wave speed sqrt((K + 4G/3) / rho)") {
  const Engine<2> e = assemble<2>(parse_scene(strip(kJ2, "mpm", "fe", "linear"), "plastic.toml"));
  const double E = 200e9, nu = 0.3, rho = 7833.0;
  const double c = std::sqrt(E * (1 - nu) / ((1 + nu) * (1 - 2 * nu)) / rho);
  // dt = cfl h / max(c, |v|), h = 0.005: the same number to round-off.
  CHECK(e.stable_dt() == doctest::Approx(0.1 * 0.005 / c).epsilon(1e-13));
}

namespace {

/// Steps 40, checkpoints, steps 40 more; restores the checkpoint into a new
/// engine and steps 40: the state arrays and stresses have the same bits.
void check_restart(const std::string& text) {
  test::TempDir tmp("restart");
  const Scene scene = parse_scene(text, "plastic.toml");
  Engine<2> a = assemble<2>(scene);
  for (int s = 0; s < 40; ++s) a.step();
  Checkpoint ck;
  ck.scene = scene.text;
  a.save_state(ck);
  write_checkpoint(tmp.file("ck.h5"), ck);
  for (int s = 0; s < 40; ++s) a.step();
  const Checkpoint back = read_checkpoint(tmp.file("ck.h5"));
  Engine<2> b = assemble<2>(checkpoint_scene(back));
  b.restore_state(back);
  for (int s = 0; s < 40; ++s) b.step();
  const std::vector<double>& eps_p = a.particles().find_state("plastic_strain")->values;
  CHECK(*std::max_element(eps_p.begin(), eps_p.end()) > 0.0); // it flows
  REQUIRE(a.particles().state.size() == b.particles().state.size());
  for (std::size_t i = 0; i < a.particles().state.size(); ++i) {
    const auto& x = a.particles().state[i].values;
    const auto& y = b.particles().state[i].values;
    INFO(a.particles().state[i].name);
    CHECK(std::memcmp(x.data(), y.data(), x.size() * sizeof(double)) == 0);
  }
  CHECK(std::memcmp(a.particles().sigma.data(), b.particles().sigma.data(),
                    a.particles().sigma.size() * sizeof(Mat<2>)) == 0);
}

} // namespace

TEST_CASE("j2 and mu_i runs restart bit for bit (plastic and flowing state in the checkpoint)") {
  // mu_i: cohesionless grains (the strip's density, packed at 0.98) that the
  // pull of the left quarter separates.
  const std::string kMuI = "[[material]]\nname = \"m\"\nmodel = \"mu_i\"\ndensity = 7833.0\nyoung = 200.0e9\n"
                           "poisson = 0.3\nmu_s = 0.4\nmu_2 = 0.66\nI_0 = 0.28\ngrain_diameter = 1e-3\n"
                           "grain_density = 8000.0\ncritical_packing = 0.95\n";
  for (const std::string& material : {kJ2, kMuI}) {
    INFO(material);
    check_restart(strip(material, "mpm", "npc", "lme"));
  }
}

