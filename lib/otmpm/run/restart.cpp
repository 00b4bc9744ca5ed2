/// \file restart.cpp
/// The scene of a checkpoint, checkpoint paths and the set-aside result
/// file of a restart (restart.hpp).
#include "otmpm/run/restart.hpp"

#include <filesystem>

namespace otmpm {

namespace fs = std::filesystem;

Scene checkpoint_scene(const Checkpoint& ck) {
  Scene scene = parse_scene(ck.scene, ck.file + " (checkpoint scene)");
  scene.text = ck.scene;
  if (scene.simulation.dimension != ck.dimension)
    throw InputError(ck.file + ": the stored scene has dimension " + std::to_string(scene.simulation.dimension) +
                     " but the state dimension " + std::to_string(ck.dimension));
  return scene;
}

std::string checkpoint_path(const Scene& scene, const std::string& result_file) {
  const std::string& file = scene.output.checkpoint_file;
  if (!file.empty()) {
    const fs::path dir = fs::path(file).parent_path();
    std::error_code ec;
    if (scene.output.checkpoint_every > 0 && !dir.empty() && !fs::is_directory(dir, ec))
      input_error(scene.locate("output.checkpoint_file"), "directory '" + dir.string() + "' does not exist");
    return file;
  }
  const std::string ext = ".h5";
  const bool h5 = result_file.size() > ext.size() && result_file.ends_with(ext);
  return (h5 ? result_file.substr(0, result_file.size() - ext.size()) : result_file) + ".checkpoint.h5";
}

namespace {
/// True when the two paths name the same file (after resolving links and dots).
bool same_file(const std::string& a, const std::string& b) {
  std::error_code ea, eb;
  const fs::path ca = fs::weakly_canonical(a, ea), cb = fs::weakly_canonical(b, eb);
  return ea || eb ? a == b : ca == cb;
}
} // namespace

PreviousResults set_aside_results(const std::string& previous, const std::string& out) {
  const std::string aside = previous + ".before-restart";
  std::error_code ec;
  if (fs::exists(aside, ec)) return {aside, true};
  if (!fs::exists(previous, ec))
    throw InputError(previous + ": the result file of the interrupted run is missing (it holds the frames written "
                                "before the checkpoint)");
  if (!same_file(previous, out)) return {previous, false};
  fs::rename(previous, aside, ec);
  if (ec) throw InputError(previous + ": cannot rename it to " + aside + ": " + ec.message());
  return {aside, true};
}

void release_previous_results(const PreviousResults& previous) {
  std::error_code ec;
  if (previous.set_aside && !fs::remove(previous.path, ec))
    throw InputError(previous.path + ": cannot remove it after copying its frames: " + ec.message());
}

} // namespace otmpm
