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
} // namespace otmpm
