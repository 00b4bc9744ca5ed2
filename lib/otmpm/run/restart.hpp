#pragma once
/// \file restart.hpp
/// What a restarted run needs beyond the checkpoint file itself
/// (io/checkpoint.hpp): the scene stored in it and where checkpoints go.
/// The result file of the interrupted run whose frames it copies is found
/// by io/output_files.hpp (find_previous_results, by run id).
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/scene/scene.hpp"

#include <string>

namespace otmpm {

/// The scene stored in a checkpoint, parsed and validated like a scene file
/// (named "PATH (checkpoint scene)" in messages); its text is the stored text.
Scene checkpoint_scene(const Checkpoint& ck);

/// Where checkpoints of a run writing `result_file` go: output.checkpoint_file
/// when set, else default_checkpoint_path(result_file) (io/output_files.hpp:
/// the result file with ".h5" replaced by ".checkpoint.h5"). When checkpoints
/// are on, the location is tried at once (a file of a name unique to this
/// process created and removed beside it), so a directory that does not
/// exist or cannot be written is an InputError naming the key (or the
/// default) before the first step, not at the first checkpoint.
std::string checkpoint_path(const Scene& scene, const std::string& result_file);

} // namespace otmpm
