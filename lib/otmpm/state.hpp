#pragma once
/// \file state.hpp
/// The state of a run as plain data, for checkpoints and restarts: named
/// groups of scalars and arrays, filled by the parts of a run that carry
/// state from step to step (the engine, the basis families, the materials,
/// the recorder) and written to a file by io/checkpoint.hpp. Doubles are kept
/// as doubles, so a state read back is the same bits.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace otmpm {

class CheckpointFile;

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
  std::string run_id; ///< the run's id (io/output_files.hpp), also in its result file; "": write_checkpoint draws one
  int dimension = 0;
  std::map<std::string, StateGroup> groups;
  /// The open file of a checkpoint read without its per-row arrays
  /// (open_checkpoint, io/checkpoint.hpp): a distributed restart reads each
  /// rank's rows from it. Null: every array is in `groups`.
  std::shared_ptr<const CheckpointFile> source;

  /// The group `name`, created empty when absent.
  StateGroup& group(const std::string& name);
  /// The group `name`; InputError naming the file when absent.
  const StateGroup& group(const std::string& name) const;
};

} // namespace otmpm
