#pragma once
/// \file fuzz_common.hpp
/// What the libFuzzer targets in fuzz/ share: the rule that decides whether an
/// input is a finding, and what is done with a scene that reads.
///
/// Bad input must end in an otmpm::InputError whose message says where the
/// mistake is ("FILE:LINE: key 'KEY'", or "--set KEY"); any other exception
/// escaping is a finding, and so is a crash, a hang or a sanitizer report
/// (those libFuzzer and ASan/UBSan detect on their own). A scene that reads is
/// then used the way `otmpm run` uses it before the first step (check_scene).
#include "otmpm/core.hpp"
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/scene/scene.hpp"

#include <cxxabi.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>
#include <string>
#include <string_view>
#include <typeinfo>

namespace otmpm::fuzz {

/// Prints "fuzz finding: WHAT" and aborts, so that libFuzzer stops and writes
/// the input to a crash-* file.
[[noreturn]] inline void finding(const std::string& what) {
  std::fprintf(stderr, "fuzz finding: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

/// True when OTMPM_FUZZ_VERBOSE is set: the targets then print what became of
/// each input (useful when running a target on a few files by hand).
inline bool verbose() {
  static const bool on = std::getenv("OTMPM_FUZZ_VERBOSE") != nullptr;
  return on;
}

/// The demangled name of the dynamic type of `e`.
inline std::string type_name(const std::exception& e) {
  int status = 0;
  const std::unique_ptr<char, void (*)(void*)> name(abi::__cxa_demangle(typeid(e).name(), nullptr, nullptr, &status),
                                                    std::free);
  return status == 0 && name ? name.get() : typeid(e).name();
}

/// True when an InputError message says where the mistake is: "FILE:LINE: ..."
/// for the scene file `file`, or (when `set_allowed`) "--set KEY: ...".
inline bool located(std::string_view message, std::string_view file, bool set_allowed) {
  if (set_allowed && message.substr(0, 6) == "--set ") return true;
  if (message.substr(0, file.size()) != file || message.substr(file.size(), 1) != ":") return false;
  const std::string_view rest = message.substr(file.size() + 1);
  return !rest.empty() && rest.front() >= '1' && rest.front() <= '9';
}

/// Runs `parse` on one input. An InputError is the expected outcome for bad
/// input, as long as it is located (see located); anything else escaping is a
/// finding.
template <class Parse> void expect_input_errors_only(Parse&& parse, std::string_view file, bool set_allowed) {
  try {
    parse();
  } catch (const InputError& e) {
    if (verbose()) std::fprintf(stderr, "InputError: %s\n", e.what());
    if (!located(e.what(), file, set_allowed))
      finding("InputError without file, line and key: " + std::string(e.what()));
  } catch (const std::exception& e) {
    finding(type_name(e) + " escaped the scene reader: " + e.what());
  } catch (...) {
    finding("an exception that is not a std::exception escaped the scene reader");
  }
}

/// Engine construction is skipped above this many particles or nodes: the
/// scene reader accepts up to kMaxSceneParticles / kMaxSceneNodes, which is
/// legitimate for a run but would make one fuzz input take seconds and
/// gigabytes (a false "hang" or "out of memory"). The sizes come from
/// scene_size, which counts what the engine seeds.
constexpr double kMaxEnginePoints = 1e5;

/// What `otmpm run` does with a scene that read, up to the first step:
///  - its resolved text (Scene::text, stored in the result file) must read
///    back, under the same file name, to the same resolved text (a finding
///    otherwise);
///  - Engine<D> is constructed for the scene's dimension, because the geometry
///    checks (node set, basis, Dirichlet boxes, tractions) live there; its
///    InputErrors propagate to expect_input_errors_only.
inline void check_scene(const Scene& scene) {
  try {
    const Scene again = parse_scene(scene.text, scene.file);
    if (again.text != scene.text)
      finding("the resolved text does not read back to itself:\n" + scene.text + "\n---\n" + again.text);
  } catch (const InputError& e) {
    finding(std::string("the resolved text does not read back: ") + e.what() + "\n" + scene.text);
  }
  const SceneSize n = scene_size(scene);
  const bool small = n.particles <= kMaxEnginePoints && n.nodes <= kMaxEnginePoints;
  if (verbose())
    std::fprintf(stderr, "scene read: %g particles, %g nodes%s\n", n.particles, n.nodes,
                 small ? "" : " (too many to build the engine)");
  if (!small) return;
  switch (scene.simulation.dimension) {
  case 1: (void)assemble<1>(scene); break;
  case 2: (void)assemble<2>(scene); break;
  case 3: (void)assemble<3>(scene); break;
  default: finding("the reader accepted dimension " + std::to_string(scene.simulation.dimension));
  }
}

} // namespace otmpm::fuzz
