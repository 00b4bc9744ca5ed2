// bench_models: whole-step cost of each material model in the engine (the target:
// a j2 step costs at most 1.3x the same step with neo_hookean).
//
//   OMP_NUM_THREADS=1 build/bench/bench_models [--cells N] [--warmup W] [--steps S] [--repeat R]
//       [--basis linear|lme|...] [--integrator fe|npc|...] [--mode mpm|ul] [--case SUBSTRING]
//
// The block of bench_step (2D plane strain, E = 10 MPa, rho = 1000, nu = 0.3,
// N x N cells, 2 x 2 particles per cell, under gravity with its base fixed)
// with each model in turn:
//  - neo_hookean;
//  - j2 elastic: yield stress 1 GPa, never reached (the elastic predictor,
//    the Hencky strains and the yield check of every step);
//  - j2 plastic: yield stress 2 kPa, hardening 100 kPa: the self-weight
//    (up to rho g H = 9.8 kPa) drives most of the block into plastic flow;
//  - drucker_prager: friction angle 30 deg, cohesion 1 kPa;
//  - drucker_prager cohesionless: 30 deg, no cohesion (the block collapses);
//  - mu_i: the same static cone (mu_s = eta(30 deg) = 0.48, mu_2 = 0.74,
//    I_0 = 0.28, d = 0.5 mm, packing 0.6, critical 0.55): the block collapses
//    with the rate-dependent friction (the ratio mu_i / drucker_prager
//    cohesionless is the model's own cost).
// Each repetition builds every model's engine, takes W warm-up steps (the
// default lets the relief wave from the base cross the block, so the
// plastic cases are in flow where they will be) and then times S steps of
// each, in turn (interleaved, so that drift of the machine's speed hits all
// alike), in process CPU time. Prints the median over R repetitions of the
// time per particle-step, the ratio of each model to neo_hookean, and the
// share of the particles whose plastic strain grew in the timed steps.
// --case keeps only the models whose label contains SUBSTRING (and
// neo_hookean, the reference), e.g. to profile one of them.
#include "otmpm/openmp_wait.hpp"
#include "bench_scenes.hpp"
#include "bench_util.hpp"
#include "otmpm/assembly/assembler.hpp"

#include <cstdio>
#include <ctime>
#include <string>
#include <vector>

using namespace otmpm;
using otmpm::bench::block_scene;
using otmpm::bench::median;

namespace {

struct ModelCase {
  const char* label;
  const char* material; // the model line and its keys in the [[material]] table
};

const std::vector<ModelCase> kCases{
    {"neo_hookean", "model = \"neo_hookean\""},
    {"j2 elastic", "model = \"j2\"\nyield_stress = 1.0e9"},
    {"j2 plastic", "model = \"j2\"\nyield_stress = 2.0e3\nhardening_modulus = 1.0e5"},
    {"drucker_prager", "model = \"drucker_prager\"\nfriction_angle = 30.0\ncohesion = 1.0e3"},
    {"dp cohesionless", "model = \"drucker_prager\"\nfriction_angle = 30.0"},
    {"mu_i", "model = \"mu_i\"\nmu_s = 0.48038\nmu_2 = 0.74\nI_0 = 0.28\ngrain_diameter = 5e-4\n"
             "grain_density = 1666.7\ncritical_packing = 0.55"},
};

double process_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

/// The equivalent plastic strain of every particle (empty for an elastic model).
std::vector<double> plastic_strain(const Engine<2>& e) {
  const StateField* f = e.particles().find_state("plastic_strain");
  return f ? f->values : std::vector<double>{};
}

/// The share of the particles whose plastic strain grew from `before` to `after`.
double grown_share(const std::vector<double>& before, const std::vector<double>& after) {
  if (after.empty()) return 0.0;
  std::size_t n = 0;
  for (std::size_t p = 0; p < after.size(); ++p) n += after[p] > before[p];
  return double(n) / double(after.size());
}

} // namespace

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv); // as the otmpm command waits (openmp_wait.hpp)
  int cells = 50, warmup = 200, steps = 50, repeat = 5;
  std::string basis = "linear", integrator = "fe", mode = "mpm", only;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (a == "--cells") cells = std::stoi(v);
    else if (a == "--steps") steps = std::stoi(v);
    else if (a == "--warmup") warmup = std::stoi(v);
    else if (a == "--repeat") repeat = std::stoi(v);
    else if (a == "--basis") basis = v;
    else if (a == "--integrator") integrator = v;
    else if (a == "--mode") mode = v;
    else if (a == "--case") only = v;
  }
  std::vector<ModelCase> cases;
  for (const ModelCase& c : kCases)
    if (cases.empty() || std::string(c.label).find(only) != std::string::npos) cases.push_back(c);
  std::vector<Scene> scenes;
  for (const ModelCase& c : cases)
    scenes.push_back(parse_scene(block_scene(cells, basis, integrator, mode, 3.0, c.material), "bench_models.toml"));
  std::vector<std::vector<double>> us(cases.size());
  std::vector<double> plastic_fraction(cases.size(), 0.0);
  long particles = 0;
  for (int r = 0; r < repeat; ++r)
    for (std::size_t c = 0; c < cases.size(); ++c) {
      Engine<2> e = assemble<2>(scenes[c]);
      for (int s = 0; s < warmup; ++s) e.step();
      particles = e.particles().size();
      const std::vector<double> before = plastic_strain(e);
      const double t0 = process_seconds();
      for (int s = 0; s < steps; ++s) e.step();
      us[c].push_back(1e6 * (process_seconds() - t0) / (double(particles) * steps));
      plastic_fraction[c] = grown_share(before, plastic_strain(e));
    }
  std::printf("block %dx%d cells, %ld particles, %s %s %s, %d steps, median of %d:\n", cells, cells, particles,
              mode.c_str(), basis.c_str(), integrator.c_str(), steps, repeat);
  const double ref = median(us[0]);
  for (std::size_t c = 0; c < cases.size(); ++c)
    std::printf("  %-16s %.3f us/particle-step  ratio %.2f  plastic flow in %.0f%% of the particles\n",
                cases[c].label, median(us[c]), median(us[c]) / ref, 100 * plastic_fraction[c]);
  return 0;
}
