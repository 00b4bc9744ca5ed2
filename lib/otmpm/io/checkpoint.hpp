#pragma once
/// \file checkpoint.hpp
/// Checkpoint and restart (issue 6): everything a run needs to continue bit
/// for bit, first gathered in memory (Checkpoint: named groups of scalars and
/// arrays, filled by Engine::save_state, the basis families and the run's
/// recorder) and then written to an HDF5 file atomically - to FILE.tmp, flushed,
/// closed, synced, renamed over FILE - so that a process killed while writing
/// leaves the previous checkpoint intact.
///
/// Integrity: the file starts with a 512-byte header (the HDF5 user block)
/// holding the format, the run id, the file size and a CRC-64 of the whole
/// file. read_checkpoint() verifies size and checksum before the HDF5 library
/// parses a single byte, so a damaged file is an InputError, never a crash
/// inside HDF5.
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
/// then renamed over `path`. A failure leaves any previous file at `path`:
/// OutputError when the space is missing (checked before writing, see
/// h5::reserve_space) or a write fails.
void write_checkpoint(const std::string& path, const Checkpoint& ck);
/// Writes `ck` to `path` directly (the first half of write_checkpoint).
void write_checkpoint_file(const std::string& path, const Checkpoint& ck);
/// Reads a checkpoint file. Throws InputError naming `path` when it is
/// missing, not an otmpm checkpoint (of this format version), truncated,
/// damaged (its checksum does not match: checked before HDF5 reads it) or incomplete.
Checkpoint read_checkpoint(const std::string& path);
/// The run id stored in the header of an otmpm checkpoint file, read without
/// the HDF5 library; "" when `path` is not a readable otmpm checkpoint of
/// the current format.
std::string checkpoint_run_id(const std::string& path);

} // namespace otmpm
