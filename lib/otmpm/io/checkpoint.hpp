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
#include "otmpm/scene/scene.hpp"

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace otmpm {

/// rows x cols numbers in row-major order: one array of a state group.
template <class T> struct StateArray {
  std::size_t cols = 1;
  std::vector<T> values;
  std::size_t rows() const { return cols ? values.size() / cols : 0; }
};

/// One group of a checkpoint: named scalars and arrays. The accessors throw
/// InputError naming the checkpoint file, the group and the item when it is
/// missing or has the wrong shape, so a damaged file is reported, never used.
struct StateGroup {
  std::string where; ///< "FILE: group 'NAME'", for messages
  std::map<std::string, double> reals;
  std::map<std::string, std::int64_t> integers;
  std::map<std::string, std::string> strings;
  std::map<std::string, StateArray<double>> real_arrays;
  std::map<std::string, StateArray<std::int64_t>> integer_arrays;

  double real(const std::string& name) const;
  std::int64_t integer(const std::string& name) const;
  const std::string& string(const std::string& name) const;
  /// The array `name`, which must hold `rows` x `cols` values.
  const StateArray<double>& real_array(const std::string& name, std::size_t rows, std::size_t cols) const;
  const StateArray<std::int64_t>& integer_array(const std::string& name, std::size_t rows, std::size_t cols) const;
  /// True when the group has an array (real or integer) called `name`.
  bool has_array(const std::string& name) const;
  /// Stores *pointer under each name of `fields`, a range of (name, pointer
  /// to double) pairs - the named members of a struct, listed once for
  /// put_reals and get_reals.
  template <class Fields> void put_reals(const Fields& fields) {
    for (const auto& [name, pointer] : fields) reals[name] = *pointer;
  }
  /// Sets *pointer from each name of `fields` (InputError when one is missing).
  template <class Fields> void get_reals(const Fields& fields) const {
    for (const auto& [name, pointer] : fields) *pointer = real(name);
  }
  /// Throws InputError "WHERE: MESSAGE".
  [[noreturn]] void error(const std::string& message) const;
};

/// The complete state of a run at the end of one step.
struct Checkpoint {
  std::string file;  ///< where it was read from (messages)
  std::string scene; ///< the effective scene text (after --set)
  std::string run_id; ///< the run's id (output_files.hpp), also in its result file; "" : write_checkpoint draws one
  int dimension = 0;
  std::map<std::string, StateGroup> groups;

  /// The group `name`, created empty when absent.
  StateGroup& group(const std::string& name);
  /// The group `name`; InputError naming the file when absent.
  const StateGroup& group(const std::string& name) const;
};

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
/// The scene stored in a checkpoint, parsed and validated like a scene file
/// (named "PATH (checkpoint scene)" in messages); its text is the stored text.
Scene checkpoint_scene(const Checkpoint& ck);

/// Where checkpoints of a run writing `result_file` go: output.checkpoint_file
/// when set, else default_checkpoint_path(result_file) (the result file with
/// ".h5" replaced by ".checkpoint.h5"). When checkpoints are on, the location
/// is tried at once (its temporary created and removed), so a directory that
/// does not exist or cannot be written is an InputError naming the key (or
/// the default) before the first step, not at the first checkpoint.
std::string checkpoint_path(const Scene& scene, const std::string& result_file);

/// The run id stored in the header of an otmpm checkpoint file, read without
/// the HDF5 library; "" when `path` is not a readable otmpm checkpoint of
/// the current format.
std::string checkpoint_run_id(const std::string& path);

} // namespace otmpm
