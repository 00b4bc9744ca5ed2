// The Dyka bar (molinos sect. 3.1, docs/benchmarks.md) at h = L/40 with LME
// (gamma_lme = 4): the NPC run stays below a velocity error bound, and NPC
// beats forward Euler in both the final RMS velocity error and the history
// error of point A (the paper's claim for every mesh size).
#include "otmpm/run/run.hpp"
#include "otmpm/scene/scene.hpp"

#include <doctest/doctest.h>

#include <string>
#include <vector>

using namespace otmpm;

namespace {

const std::string kDyka = std::string(OTMPM_SOURCE_DIR) + "/examples/dyka.toml";

/// examples/dyka.toml at h = L/40: 42 cells from -2h to L.
RunSummary run_dyka_40(const std::string& integrator) {
  const std::vector<std::string> overrides = {"grid.cells=[42]", "grid.lower=[-0.006665]",
                                              "simulation.integrator=\"" + integrator + "\""};
  RunOptions opt;
  opt.write_results = false;
  const RunSummary s = run_scene(load_scene(kDyka, overrides), opt);
  REQUIRE(s.exit_code == 0);
  REQUIRE(s.errors.count("rms_velocity_error") == 1);
  REQUIRE(s.errors.count("history_error_A") == 1);
  return s;
}

} // namespace

TEST_CASE("Dyka bar h = L/40, LME + NPC: velocity errors below the bound, and NPC beats FE") {
  const RunSummary npc = run_dyka_40("npc");
  const RunSummary fe = run_dyka_40("fe");
  const double rms_npc = npc.errors.at("rms_velocity_error"), rms_fe = fe.errors.at("rms_velocity_error");
  const double hist_npc = npc.errors.at("history_error_A"), hist_fe = fe.errors.at("history_error_A");
  INFO("NPC rms " << rms_npc << ", history A " << hist_npc << "; FE rms " << rms_fe << ", history A " << hist_fe);
  // Measured (this implementation, t_end = 1e-4 s, cfl 0.1, probes every 1e-6 s):
  // NPC rms 0.721 m/s, history A 0.657 m/s; FE rms 0.832, history A 0.714.
  // The error is that of the fronts smeared over a few cells: ~15% of the
  // 5 m/s jump at 40 cells, consistent with the coarse end of molinos Fig. 6
  // (values given only graphically there). The bounds sit ~25% above the
  // measurement (0.9 and 0.82 m/s, i.e. 18% and 16% of the jump): loose
  // enough for harmless changes (quadrature order of the sum, round-off),
  // tight enough to catch a regression that smears or rings more - a wrong
  // gamma_lme, a first-order predictor, or a broken boundary condition all
  // move the error by more than that.
  CHECK(rms_npc < 0.9);
  CHECK(hist_npc < 0.82);
  // Paper's claim: NPC has a lower error than FE.
  CHECK(rms_npc < rms_fe);
  CHECK(hist_npc < hist_fe);
}
