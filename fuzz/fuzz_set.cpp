/// \file fuzz_set.cpp
/// libFuzzer target for the `--set KEY=VALUE` overrides. The first input byte
/// picks one of three valid base scenes (1D, 2D, 3D, read from the source tree
/// at start-up); the remaining bytes, split at newlines, are the override
/// strings applied to it by parse_scene. Overrides mostly keep the scene valid
/// TOML, so this target also reaches the value checks and, through
/// check_scene, the engine's geometry checks more often than fuzz_scene does.
/// An InputError naming "--set KEY" or the scene file is the expected outcome
/// for bad overrides; see fuzz_common.hpp for what counts as a finding.
#include "fuzz_common.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

/// Base scenes, relative to the source tree (one per dimension).
constexpr std::array<const char*, 3> kBaseFiles = {"tests/scenes/good_minimal.toml", "examples/mms_plate.toml",
                                                   "examples/dyka_3d.toml"};
/// Their text, read once by LLVMFuzzerInitialize.
std::array<std::string, kBaseFiles.size()> base_text;

/// The whole file at OTMPM_SOURCE_DIR/relative (aborts if unreadable: the
/// target is useless without its base scenes).
std::string read_source_file(const std::string& relative) {
  const std::string path = std::string(OTMPM_SOURCE_DIR) + "/" + relative;
  std::ifstream in(path, std::ios::binary);
  if (!in) otmpm::fuzz::finding("cannot read the base scene " + path);
  std::ostringstream buf;
  buf << in.rdbuf();
  return buf.str();
}

/// The override strings: the bytes split at '\n' (empty lines included, as
/// `--set ""` would pass them).
std::vector<std::string> split_lines(const char* data, std::size_t size) {
  std::vector<std::string> lines(1);
  for (std::size_t i = 0; i < size; ++i) {
    if (data[i] == '\n') lines.emplace_back();
    else lines.back() += data[i];
  }
  return lines;
}

} // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  for (std::size_t i = 0; i < kBaseFiles.size(); ++i) base_text[i] = read_source_file(kBaseFiles[i]);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::size_t base = data[0] % kBaseFiles.size();
  const std::vector<std::string> overrides = split_lines(reinterpret_cast<const char*>(data) + 1, size - 1);
  const std::string name = kBaseFiles[base];
  otmpm::fuzz::expect_input_errors_only(
      [&] { otmpm::fuzz::check_scene(otmpm::parse_scene(base_text[base], name, overrides)); }, name, true);
  return 0;
}
