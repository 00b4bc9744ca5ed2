/// \file test_scenes_peers.cpp
/// bench/peers/block_2d.toml, the 2D block the comparisons with other codes
/// run, is the throughput block of the benchmarks (bench/bench_scenes.hpp,
/// block_scene with 200 cells) with a fixed time step: a change to one that
/// does not reach the other fails here.
#include <doctest/doctest.h>

#include "../bench/bench_scenes.hpp"
#include "otmpm/scene/scene.hpp"

#include <string>
#include <vector>

using namespace otmpm;

TEST_CASE("the peers' 2D block is the benchmarks' throughput block with a fixed time step") {
  // what the two may differ in: the run's length and output, the time step
  // rule, and gamma_lme (unused by the linear basis)
  const std::vector<std::string> same{"simulation.dt=1e-5", "simulation.t_end=1e-3", "output.every=0.0",
                                      "output.file='block.h5'", "basis.gamma_lme=3.0"};
  const Scene peers = load_scene(OTMPM_SOURCE_DIR "/bench/peers/block_2d.toml", same);
  const Scene bench = parse_scene(bench::block_scene(200, "linear", "fe", "mpm", 3.0), "block.toml", same);
  CHECK(to_toml(peers) == to_toml(bench));
}
