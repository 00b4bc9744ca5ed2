// Crash-safe result files: a POSIX HDF5 file driver that journals the bytes
// each write replaces until the next complete flush.
//
// HDF5 1.10 updates its metadata in place, in address order, during a flush,
// so a process killed inside a flush (SIGKILL, the out-of-memory killer)
// leaves a file whose groups point at object headers not yet written: no
// reader opens it. With this driver every write below the end of the last
// flushed state first appends the bytes it replaces to an undo journal
// beside the file; when a flush completes the journal is emptied. After a
// kill, roll_back_interrupted_flush writes the journalled bytes back in
// reverse order, which restores the file exactly as it was after its last
// complete flush - every frame and history sample flushed before the kill.
// Internal header (needs hdf5.h).
#pragma once

#include <hdf5.h>

#include <string>

namespace otmpm::h5 {

/// Sets `fapl` to otmpm's journaling POSIX driver for the result file `path`,
/// with its undo journal at `journal` (undo_journal_path of the result file).
/// Files it writes are plain HDF5 files (no driver information is stored):
/// any reader opens them with its default driver.
void use_undo_journal(hid_t fapl, const std::string& journal, const std::string& path);

/// Restores `path` to its last completely flushed state from the undo
/// journal a killed writer left (see the file comment) and removes the
/// journal; true when it changed the file. The caller holds otmpm's lock on
/// `path` (OutputLock does this for each path it takes) and does not have
/// the file open. InputError naming file and journal when it cannot write.
bool apply_undo_journal(const std::string& path);

/// Opens the result file `path` read-only, as H5Fopen does, through the
/// result files' driver: in the process that writes it, HDF5 then shares
/// the writer's open file (another driver would open it a second time and
/// meet the writer's lock). Rolls back an interrupted flush first
/// (roll_back_interrupted_flush in output_files.hpp). A negative id when HDF5 cannot open it.
hid_t open_result_read_only(const std::string& path);

} // namespace otmpm::h5
