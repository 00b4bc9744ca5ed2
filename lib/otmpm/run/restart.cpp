/// \file restart.cpp
/// The scene of a checkpoint and checkpoint paths (restart.hpp).
#include "otmpm/run/restart.hpp"

#include "otmpm/io/output_files.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <sstream>

namespace otmpm {

namespace fs = std::filesystem;

namespace {

/// The note a restart adds to an error of a file body's particle file.
constexpr const char* kFileNote = " - a restart seeds the file bodies from their particle files again (their state "
                                  "comes from the checkpoint): give it the file the interrupted run read";

/// The key of the file of body `name`.
std::string file_key(const std::string& name) { return "body." + name + ".file"; }

/// InputError when a file body's particle file holds other particles than the
/// interrupted run read (the checkpoint's particle_file_record).
void check_particle_files(const Scene& scene, const Checkpoint& ck) {
  const auto g = ck.groups.find("recorder");
  if (g == ck.groups.end()) return; // an engine's state alone (Engine::save_state)
  const auto it = g->second.strings.find("particle_files");
  if (it == g->second.strings.end()) return; // written before the record was kept
  std::istringstream before(it->second), now(particle_file_record(scene));
  for (std::string was, is; std::getline(now, is);) {
    std::getline(before, was);
    if (was == is) continue;
    const std::string body = is.substr(0, is.find('\t'));
    input_error(scene.locate(file_key(body)),
                "the particle file changed since the checkpoint was written (the interrupted run read " +
                    was.substr(was.find('\t') + 1) + ", the file now holds " + is.substr(is.find('\t') + 1) + ")" +
                    kFileNote);
  }
}

} // namespace

std::string particle_file_record(const Scene& scene) {
  std::string out;
  const int dim = scene.simulation.dimension;
  for (const BodySection& b : scene.bodies) {
    if (b.shape != "file") continue;
    out += b.name + "\t" + std::to_string(b.file_particles) + " particles in " +
           format_point<3>(first_components(b.lower, dim)) + " - " + format_point<3>(first_components(b.upper, dim)) +
           "\n";
  }
  return out;
}

Scene checkpoint_scene(const Checkpoint& ck) {
  Scene scene;
  try {
    scene = parse_scene(ck.scene, ck.file + " (checkpoint scene)");
  } catch (const InputError& e) { // a file body's particle file the restart cannot read again
    const InputSource* at = e.source();
    if (!at || !at->key.starts_with("body.") || !at->key.ends_with(".file")) throw;
    throw InputError(e.what() + std::string(kFileNote), *at);
  }
  check_particle_files(scene, ck);
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
