/// \file restart.cpp
/// The scene of a checkpoint and checkpoint paths (restart.hpp).
#include "otmpm/run/restart.hpp"

#include "otmpm/io/output_files.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
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

namespace {

/// Creates and removes a file of a name unique to this process beside
/// `path` (never touching a file another run may be writing); the reason it
/// cannot, or "" when the location takes files.
std::string try_to_write(const std::string& path) {
  const std::string probe = path + ".otmpm-probe-" + std::to_string(::getpid());
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) return std::strerror(errno);
  ::close(fd);
  ::unlink(probe.c_str());
  return "";
}

} // namespace

std::string checkpoint_path(const Scene& scene, const std::string& result_file) {
  const std::string& file = scene.output.checkpoint_file;
  const bool on = scene.output.checkpoint_every > 0;
  const std::string path = file.empty() ? default_checkpoint_path(result_file) : file;
  if (!on) return path;
  const fs::path dir = fs::path(path).parent_path();
  std::error_code ec;
  const std::string where = file.empty() ? "the checkpoint file '" + path + "' (beside the result file)" : "";
  auto refuse = [&](const std::string& why) {
    if (file.empty()) throw InputError(scene.locate("output.checkpoint_every").describe() + ": " + where + ": " + why);
    input_error(scene.locate("output.checkpoint_file"), why);
  };
  if (!dir.empty() && !fs::is_directory(dir, ec)) refuse("directory '" + dir.string() + "' does not exist");
  if (fs::is_directory(path, ec)) refuse("'" + path + "' is a directory");
  const std::string why = try_to_write(path);
  if (!why.empty()) refuse("cannot write checkpoints to '" + path + "': " + why);
  return path;
}

} // namespace otmpm
