#pragma once
/// \file output_files.hpp
/// The files one run writes and the rules that keep them from destroying
/// other data (docs/stability.md, "What otmpm guarantees about your files"):
///
///  - Every path is derived from the result file (OutputFiles) and all of
///    them - with their temporaries and lock files - must be different files
///    once resolved (symbolic links, "." and "..", hard links): check_distinct().
///  - A run holds otmpm's own lock on each of its paths (OutputLock: flock on
///    a hidden lock file beside each, independent of HDF5's file locking), so
///    a second process writing the same files is refused before it changes
///    anything.
///  - An existing file is replaced only when RunOptions::force is set or the
///    file provably belongs to the run being repeated or continued
///    (claim_outputs): a result file of the identical scene written by the
///    same otmpm version (the run reproduces it), or a sidecar, checkpoint or
///    VTK file carrying the run id of that result file.
///  - Every run has a random run id (new_run_id) written into the result
///    file, its sidecars and its checkpoints; a restart copies frames only
///    from a result file with the checkpoint's run id.
#include <optional>
#include <string>
#include <vector>

namespace otmpm {

/// The paths of everything one run writes. All are derived from the result
/// file by output_files(), except the checkpoint (output.checkpoint_file when set).
struct OutputFiles {
  std::string result;        ///< the HDF5 result file
  std::string xdmf;          ///< its XDMF sidecar (output_base + ".xdmf")
  std::string checkpoint;    ///< checkpoints ("" when the run writes none)
  std::string pvd;           ///< the VTK collection ("" without VTK output)
  std::string vtk_dir;       ///< the directory of the VTK frame files ("" without VTK output)
  std::string vtk_extension; ///< "vtp" or "vtu" ("" without VTK output)
  /// Which route gave each of result and checkpoint ("--out", "RunOptions::out_file",
  /// "FILE:LINE: key 'output.file'", ...), for messages naming both paths of a collision.
  std::string result_origin, checkpoint_origin;
};

/// The result path without a trailing ".h5" (the whole path otherwise): the
/// stem of the sidecar, the default checkpoint, the .pvd and the VTK directory.
/// "dyka.h5" -> "dyka"; "dyka.txt" -> "dyka.txt" (its sidecar is dyka.txt.xdmf,
/// so it never takes the sidecar of another run's dyka.h5).
std::string output_base(const std::string& result);
/// The XDMF sidecar of a result file: output_base(result) + ".xdmf".
std::string xdmf_path(const std::string& result);
/// The default checkpoint of a result file: output_base(result) + ".checkpoint.h5".
std::string default_checkpoint_path(const std::string& result);

/// The files of a run writing `result`. `checkpoint`: "" for none;
/// `vtk_format`: "", "vtp" or "vtu". InputError when the result path is empty,
/// names a directory, has an extension reserved for the files beside it
/// (.xdmf, .xmf, .pvd, .vtp, .vtu: "res.xdmf" would be its own sidecar),
/// contains a control character, or has a file name with ':' or not in
/// UTF-8 (the XML sidecar and VTK files quote it), or when one of the paths
/// names a FIFO, a device or a socket (special_file).
OutputFiles output_files(const std::string& result, const std::string& checkpoint, const std::string& vtk_format);

/// Every path the run writes, with its role ("result file", "XDMF sidecar",
/// "checkpoint", "checkpoint temporary", ...), temporaries and lock files included.
std::vector<std::pair<std::string, std::string>> written_paths(const OutputFiles& files);

/// "a FIFO (named pipe)" (or "a character device", "a block device", "a
/// socket") when `path` names such a thing, links followed; "" when it
/// names a regular file, a directory or nothing. Every file otmpm opens
/// is checked first: opening a FIFO blocks until another process opens its
/// other end, and a device is no place for results.
std::string special_file(const std::string& path);

/// True when `a` and `b` name the same file: equal after
/// std::filesystem::weakly_canonical (links, "." and ".." resolved), or the
/// same device and inode when both exist.
bool same_file(const std::string& a, const std::string& b);

/// InputError naming both paths (and where each came from) when two of the
/// paths the run writes are the same file, or one lies inside the VTK directory.
void check_distinct(const OutputFiles& files);

/// The hidden lock file otmpm uses for `path`: DIR/.NAME.otmpm-lock of the
/// path made absolute with its symlinks followed (one lock however it is named).
std::string lock_path(const std::string& path);

/// The undo journal of the result file `path`: DIR/.NAME.otmpm-undo beside
/// it, resolved as lock_path. It holds the bytes the run's writes replaced
/// since the file's last complete flush; a killed run leaves it, and the
/// next otmpm process that opens or locks the file restores the flushed
/// state from it (io/undo_journal.hpp).
std::string undo_journal_path(const std::string& path);

/// For readers of the result file `path`: when its killed writer left an
/// undo journal and no process holds otmpm's lock on it, takes the lock
/// (which restores the last flushed state, io/undo_journal.hpp) and releases
/// it. Does nothing while a writer runs. InputError when the lock cannot be
/// taken or the journal cannot be applied.
void roll_back_interrupted_flush(const std::string& path);

/// Who holds otmpm's lock on `path` now: "process PID on host HOST" (or
/// "another process" when the lock file does not say), or "" when no process
/// holds it - no lock file, or one a killed run left behind unlocked (flock
/// locks end with their process). Changes nothing.
std::string lock_holder_of(const std::string& path);

/// otmpm's exclusive lock on a set of paths, held for the lifetime of the
/// object: flock(LOCK_EX | LOCK_NB) on lock_path() of each, which records the
/// holder's process id and host name; a file whose killed writer left an
/// undo journal is restored from it once its lock is held. The constructor takes every lock or
/// none: when another process holds one it throws InputError naming the path
/// and the holder ("... is being written by process 1234 on host h (lock file
/// ...)"). The destructor removes the lock files. Does not depend on HDF5's
/// file locking (it holds with HDF5_USE_FILE_LOCKING=FALSE).
class OutputLock {
public:
  OutputLock() = default;
  explicit OutputLock(const std::vector<std::string>& paths);
  ~OutputLock();
  OutputLock(OutputLock&& other) noexcept;
  OutputLock& operator=(OutputLock&& other) noexcept;
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

private:
  void release() noexcept;
  struct Held {
    std::string path; ///< the lock file
    int fd = -1;
  };
  std::vector<Held> held_;
};

/// A new random run id: 32 hexadecimal digits (128 bits from std::random_device).
std::string new_run_id();

/// What a run knows when it decides whether existing files may be replaced.
struct ClaimRules {
  std::string scene_text;     ///< the run's resolved scene (Scene::text)
  bool force = false;         ///< RunOptions::force: replace whatever is there
  std::string continued_run;  ///< a restart: the run id it continues ("" for a new run)
};

/// Decides, before anything is written, whether the files at `files` may be
/// replaced (see the file comment), and returns the existing files that
/// belong to the replaced run and must be removed before the run writes
/// (its old checkpoint and VTK frames). InputError naming the file, what it
/// is, and how to proceed (RunOptions::force, `otmpm run --force`, or remove it)
/// otherwise. A restart's own result file (run id = continued_run) is
/// accepted: the restart sets it aside itself (set_aside_results).
std::vector<std::string> claim_outputs(const OutputFiles& files, const ClaimRules& rules);

/// The result file a restarted run copies the frames written before its
/// checkpoint from (copy_results in results.hpp).
struct PreviousResults {
  std::string path;       ///< the file to copy from
  bool set_aside = false; ///< a renamed copy of the output file, removed once copied
  std::string rename_from; ///< set_aside_results renames this file to `path` first ("" : nothing to rename)
};

/// Decides, without changing anything, where a restart of run `run_id` that
/// needs its first `frames` frames and writes to `out` copies them from.
/// Only a file whose root attribute run_id is `run_id` is ever used or
/// renamed. The candidates are the result file `previous` (its path from the
/// checkpoint) and before_restart_path(previous, run_id) (left by a restart
/// of the same run that was killed while copying); the real file is
/// preferred when it holds the frames. When `out` is `previous`, the real file
/// is to be renamed to the second name (rename_from). InputError naming the
/// file(s) when neither qualifies.
PreviousResults find_previous_results(const std::string& previous, const std::string& out, const std::string& run_id,
                                      int frames);
/// Performs the rename find_previous_results decided on (over an older copy of the same run).
void set_aside_results(const PreviousResults& previous);
/// The name a restart of run `run_id` gives the result file it continues.
std::string before_restart_path(const std::string& previous, const std::string& run_id);
/// Removes the set-aside file once everything was copied from it.
void release_previous_results(const PreviousResults& previous);

/// Everything a run needs to know about its output files before it writes.
struct OutputRequest {
  std::string result;            ///< the result file
  std::string result_origin;     ///< where its name came from (messages)
  std::string checkpoint;        ///< "" when the run writes no checkpoint
  std::string checkpoint_origin; ///< where its name came from (messages)
  std::string vtk_format;        ///< "", "vtp" or "vtu"
  std::string scene_text;        ///< Scene::text (the identical-scene rule)
  bool force = false;            ///< RunOptions::force
  std::string continued_run;     ///< a restart: the checkpoint's run id
  std::string previous_result;   ///< a restart: the interrupted run's result file
  int previous_frames = 0;       ///< a restart: frames to copy from it
};

/// The output files of a run, checked, locked and cleared, ready to write.
struct PreparedOutputs {
  OutputFiles files;
  OutputLock lock;
  std::string run_id; ///< new_run_id(), or the continued run's
  std::optional<PreviousResults> previous;
};

/// The paths of `request` with where their names came from (output_files),
/// refused when two are the same file (check_distinct): the checks of
/// prepare_outputs that touch no file (`otmpm run --check` makes them alone).
OutputFiles checked_output_files(const OutputRequest& request);

/// In this order, before anything is written: derives the paths
/// (output_files), refuses collisions (check_distinct; the restart's
/// previous result file included), takes otmpm's locks (OutputLock, the
/// previous result file's too), finds a restart's previous results
/// (find_previous_results), decides what may be replaced (claim_outputs),
/// and only then removes the replaced run's old checkpoint and VTK frames
/// and sets a restart's result file aside. Every refusal is an InputError,
/// raised before anything changed.
PreparedOutputs prepare_outputs(const OutputRequest& request);

/// The run id recorded in an otmpm XML output (.xdmf, .pvd, .vtp, .vtu): ""
/// when the file has none (not written by otmpm, or by an older version).
std::string xml_run_id(const std::string& path);
/// The result file an otmpm XML output belongs to (its path: the name it
/// records, in the output's directory), or "" when it records none.
std::string xml_result(const std::string& path);
/// The root attribute `run_id` of an otmpm result file ("" when absent or
/// the file is not HDF5).
std::string result_run_id(const std::string& path);

} // namespace otmpm
