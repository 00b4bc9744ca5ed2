#pragma once
/// \file restart.hpp
/// What a restarted run needs beyond the checkpoint file itself
/// (io/checkpoint.hpp): the scene stored in it, where checkpoints go, and
/// the result file of the interrupted run whose frames it copies.
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/scene/scene.hpp"

#include <string>

namespace otmpm {

/// The scene stored in a checkpoint, parsed and validated like a scene file
/// (named "PATH (checkpoint scene)" in messages); its text is the stored text.
Scene checkpoint_scene(const Checkpoint& ck);

/// Where checkpoints of a run writing `result_file` go: output.checkpoint_file
/// when set, else the result file with ".h5" replaced by ".checkpoint.h5".
/// Throws InputError naming the key when checkpoints are on and the
/// directory of output.checkpoint_file does not exist (before the first step).
std::string checkpoint_path(const Scene& scene, const std::string& result_file);

/// The result file a restarted run copies the frames written before its
/// checkpoint from (copy_results in results.hpp).
struct PreviousResults {
  std::string path;       ///< the file to copy from
  bool set_aside = false; ///< a renamed copy of the output file, removed once copied
};
/// Finds the interrupted run's result file `previous`. When the restarted run
/// writes to the same path `out`, it is first renamed to previous +
/// ".before-restart" (and a file of that name left by a restart that was
/// itself killed while copying is used as it is). InputError when missing.
PreviousResults set_aside_results(const std::string& previous, const std::string& out);
/// Removes the set-aside file once everything was copied from it.
void release_previous_results(const PreviousResults& previous);

} // namespace otmpm
