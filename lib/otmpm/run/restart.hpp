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
/// A restart seeds the bodies again - file bodies from their particle files -
/// before it restores the particles' state: a particle file that is missing,
/// or holds other particles than the interrupted run read (its count and
/// bounds differ from the checkpoint's particle_file_record), is an
/// InputError that says the particle file changed, at the body's key.
Scene checkpoint_scene(const Checkpoint& ck);

/// What the scene reader found in the particle files of the scene's file
/// bodies - per body its name, particle count and bounds, one line each -
/// stored in a checkpoint (group "recorder", string "particle_files") and
/// compared by checkpoint_scene on restart.
std::string particle_file_record(const Scene& scene);

/// Where checkpoints of a run writing `result_file` go: output.checkpoint_file
/// when set, else default_checkpoint_path(result_file) (io/output_files.hpp:
/// the result file with ".h5" replaced by ".checkpoint.h5"). When checkpoints
/// are on, the location is tried at once (a file of a name unique to this
/// process created and removed beside it), so a directory that does not
/// exist or cannot be written is an InputError naming the key (or the
/// default) before the first step, not at the first checkpoint.
std::string checkpoint_path(const Scene& scene, const std::string& result_file);

} // namespace otmpm
