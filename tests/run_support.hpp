// Helpers shared by the tests of runs through the library (result files,
// names and paths): a short scene and the message of an expected InputError.
#pragma once

#include "otmpm/core.hpp"
#include "otmpm/scene/scene.hpp"

#include <doctest/doctest.h>

#include <filesystem>
#include <string>
#include <vector>

namespace otmpm::test {

/// The minimal 1D scene, shortened: 10 us, a frame every 2 us (6 frames, 152 steps); `sets` as --set.
inline Scene small_scene(std::vector<std::string> sets = {}) {
  sets.insert(sets.begin(), {"simulation.t_end=1e-5", "output.every=2e-6"});
  return load_scene((std::filesystem::path(OTMPM_SOURCE_DIR) / "tests/scenes/good_minimal.toml").string(), sets);
}

/// The message of the InputError `call` throws (a test failure when it throws none).
template <class F> std::string input_error_of(F&& call) {
  try {
    call();
  } catch (const InputError& e) {
    return e.what();
  }
  FAIL("no InputError");
  return "";
}

} // namespace otmpm::test
