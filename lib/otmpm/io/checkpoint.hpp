#pragma once
/// \file checkpoint.hpp
/// Checkpoint and restart: everything a run needs to continue bit
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
/// inside HDF5. Each group also carries a checksum of its scalars, its
/// arrays held whole and the names and shapes of its per-row arrays (whose
/// values the CRC-64 covers).
///
/// File layout: root attributes `format` ("otmpm checkpoint"),
/// `format_version`, `otmpm_version`, `dimension` and `scene` (the effective
/// scene text after --set, so that a restart needs nothing but this file); one
/// HDF5 group per state group ("engine", "particles", "nodes", "basis",
/// "recorder", and "decomposition" for a distributed run), its scalars as
/// attributes (double, int64 or string) and its arrays as rows x cols
/// datasets (double or int64). Doubles are stored as IEEE doubles and read
/// back without arithmetic, so every bit survives.
///
/// Per-row arrays (checkpoint_row_kind): one row per particle or per point
/// of the basis' lattice. A distributed run writes its checkpoint with all
/// ranks together (the parallel HDF5): each rank its particles' rows, one
/// block after the other in rank order, and its own lattice points' rows in
/// the lattice's order; a restart reads only each rank's rows
/// (CheckpointFile). The file's CRC-64 is computed by the ranks in parts and
/// combined, so no rank holds or reads the whole file.
#include "otmpm/io/parallel_io.hpp"
#include "otmpm/state.hpp"

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace otmpm {

/// What a row of an array of a checkpoint stands for.
enum class RowKind {
  whole,    ///< none: a small array that every rank holds whole
  particle, ///< one row per particle (the particle fields and the basis' per-point state)
  point     ///< one row per lattice point (node positions, the walls' held nodes, carried momenta)
};
/// The kind of the rows of array `array` of group `group`.
RowKind checkpoint_row_kind(const std::string& group, const std::string& array);

/// Writes `ck` to `path` atomically: to path.tmp, flushed, closed and synced,
/// then renamed over `path`. A failure leaves any previous file at `path`:
/// OutputError when the space is missing (checked before writing, see
/// h5::reserve_space) or a write fails.
void write_checkpoint(const std::string& path, const Checkpoint& ck);
/// Writes `ck` to `path` directly (the first half of write_checkpoint).
void write_checkpoint_file(const std::string& path, const Checkpoint& ck);

/// Where one rank's rows of the per-row arrays lie in a checkpoint of all
/// ranks (a distributed run): the rows of all ranks and this rank's blocks
/// of them, per kind of row.
struct CheckpointShare {
  ParallelIo io;
  long long particles = 0, points = 0; ///< rows of all ranks
  std::vector<RowBlock> particle_rows, point_rows;
};
/// write_checkpoint by all ranks of `share.io` together (collective): each
/// rank gives its own rows of the per-row arrays in `mine` (in the order of
/// its blocks; every rank the same arrays with the same columns) and the
/// root's scalars and whole arrays are written. Atomic as above; the CRC-64
/// is computed by the ranks in parts. The space is not checked ahead (an
/// MPI-IO file has no descriptor): a full disk is a failed write. An error
/// on one rank is thrown on every rank (those without one: OutputError).
/// `mine` is taken by value: its rows are moved into the file's layout.
void write_checkpoint(const std::string& path, Checkpoint mine, const CheckpointShare& share);

/// Reads a checkpoint file. Throws InputError naming `path` when it is
/// missing, not an otmpm checkpoint (of this format version), truncated,
/// damaged (its checksum does not match: checked before HDF5 reads it) or incomplete.
Checkpoint read_checkpoint(const std::string& path);
/// read_checkpoint without the per-row arrays (checkpoint_row_kind: whole
/// arrays and scalars only): what a run's files and its recorder need.
Checkpoint read_checkpoint_head(const std::string& path);
/// The run id stored in the header of an otmpm checkpoint file, read without
/// the HDF5 library; "" when `path` is not a readable otmpm checkpoint of
/// the current format.
std::string checkpoint_run_id(const std::string& path);

/// A checkpoint file opened by all ranks of a distributed run together
/// (collective), with the checks of read_checkpoint (header and size on
/// every rank, the CRC-64 in parts: each rank checksums 1/N of the file and
/// the parts are combined), whose per-row arrays are read in parts: each
/// rank its own rows. head() is the checkpoint without them.
class CheckpointFile {
public:
  CheckpointFile(const std::string& path, const ParallelIo& io);
  ~CheckpointFile();
  CheckpointFile(const CheckpointFile&) = delete;
  CheckpointFile& operator=(const CheckpointFile&) = delete;

  /// The scalars and whole arrays of every group (no per-row array).
  const Checkpoint& head() const { return head_; }
  /// Rows of the arrays of `kind` (particle or point): of all ranks.
  long long rows(RowKind kind) const;
  /// Adds to `into` the rows `blocks` (in increasing order) of every array
  /// of `kind` (collective: every rank calls it, each with its blocks).
  void read(RowKind kind, const std::vector<RowBlock>& blocks, Checkpoint& into) const;
  /// Only the arrays `names` ("group/array") of `kind`.
  void read(RowKind kind, const std::vector<RowBlock>& blocks, Checkpoint& into,
            const std::vector<std::string>& names) const;

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  Checkpoint head_;
};

/// A checkpoint's head (CheckpointFile::head) that keeps its file open for
/// the distributed restart, which reads each rank's rows from it
/// (Checkpoint::source). Collective.
Checkpoint open_checkpoint(const std::string& path, const ParallelIo& io);

/// The rows of all particles (or lattice points: `kind`) of a checkpoint:
/// from its open file (Checkpoint::source) or its arrays in memory.
long long checkpoint_rows(const Checkpoint& ck, RowKind kind);
/// Adds to `into` the rows `blocks` of the arrays of `kind` of `ck` (only
/// `names`, "group/array", when given): read from its open file
/// (collective, CheckpointFile::read) or copied from its arrays in memory.
void read_checkpoint_rows(const Checkpoint& ck, RowKind kind, const std::vector<RowBlock>& blocks, Checkpoint& into,
                          const std::vector<std::string>& names = {});
/// `ck` without its per-row arrays (and without its file).
Checkpoint checkpoint_head(const Checkpoint& ck);
/// Puts the particle rows of `ck` (every array of kind particle) in the
/// order of their global ids (the array particles/global_id of a
/// distributed run's checkpoint; none: they are in that order already).
void order_by_global_id(Checkpoint& ck);

/// CRC-64/XZ of the bytes a b (CRC-64 of a: `a`, of b: `b`, b has `b_bytes`
/// bytes), from the CRCs of the parts (as zlib's crc32_combine).
std::uint64_t crc64_combine(std::uint64_t a, std::uint64_t b, std::uint64_t b_bytes);
/// CRC-64/XZ of `n` bytes.
std::uint64_t crc64(const void* data, std::size_t n);

} // namespace otmpm
