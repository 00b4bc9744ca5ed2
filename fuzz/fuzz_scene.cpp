/// \file fuzz_scene.cpp
/// libFuzzer target for the scene reader: the input bytes are the text of a
/// scene file named "fuzz.toml". A scene that reads is then checked the way
/// `otmpm run` uses it before the first step (round trip of the resolved text,
/// engine construction: fuzz_common.hpp check_scene). An InputError naming
/// fuzz.toml is the expected outcome for bad input; see fuzz_common.hpp for
/// what counts as a finding.
#include "fuzz_common.hpp"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  constexpr const char* kName = "fuzz.toml";
  otmpm::fuzz::expect_input_errors_only([&] { otmpm::fuzz::check_scene(otmpm::parse_scene(text, kName)); }, kName,
                                        false);
  return 0;
}
