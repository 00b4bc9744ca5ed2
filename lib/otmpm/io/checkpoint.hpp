#pragma once
/// \file checkpoint.hpp
/// Checkpoint and restart (issue 6): everything a run needs to continue bit
/// for bit, first gathered in memory (Checkpoint: named groups of scalars and
/// arrays, filled by Engine::save_state, the basis families and the run's
/// recorder) and then written to an HDF5 file atomically - to FILE.tmp, flushed,
/// closed, synced, renamed over FILE - so that a process killed while writing
/// leaves the previous checkpoint intact.
///
/// File layout: root attributes `format` ("otmpm checkpoint"),
/// `format_version`, `otmpm_version`, `dimension` and `scene` (the effective
/// scene text after --set, so that a restart needs nothing but this file); one
/// HDF5 group per state group ("engine", "particles", "nodes", "basis",
/// "recorder"), its scalars as attributes (double, int64 or string) and its
/// arrays as rows x cols datasets (double or int64). Doubles are stored as
/// IEEE doubles and read back without arithmetic, so every bit survives.
#include "otmpm/scene/scene.hpp"
#include "otmpm/state.hpp"

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace otmpm {

/// Writes `ck` to `path` atomically: to path.tmp, flushed, closed and synced,
/// then renamed over `path`. A failure leaves any previous file at `path`.
void write_checkpoint(const std::string& path, const Checkpoint& ck);
/// Writes `ck` to `path` directly (the first half of write_checkpoint).
void write_checkpoint_file(const std::string& path, const Checkpoint& ck);
/// Reads a checkpoint file. Throws InputError naming `path` when it is
/// missing, not HDF5, truncated, not an otmpm checkpoint or incomplete.
Checkpoint read_checkpoint(const std::string& path);
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
