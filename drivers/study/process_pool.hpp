#pragma once
/// \file process_pool.hpp
/// The child processes of a study: started with fork/exec, their stdout and
/// stderr going to a log file, each one bound to the study's life (Linux
/// PR_SET_PDEATHSIG: if the study dies, even by SIGKILL, its children get
/// SIGTERM, which makes an `otmpm run` stop cleanly with status
/// "interrupted"), so no run is left holding a result file.
#include <chrono>
#include <filesystem>
#include <string>
#include <sys/types.h>
#include <vector>

namespace otmpm::study {

/// The exit status of a child that could not execute its program (as a shell's).
constexpr int kNotStarted = 127;

/// How a child ended.
struct ChildExit {
  pid_t pid = -1;
  int status = 0;       ///< exit status, or 128 + signal
  bool signalled = false; ///< killed by a signal (not a normal exit)
};

class ProcessPool {
public:
  ProcessPool() = default;
  /// Sends SIGTERM to the children still running and waits for them.
  ~ProcessPool();
  ProcessPool(const ProcessPool&) = delete;
  ProcessPool& operator=(const ProcessPool&) = delete;

  /// Gives each child its own share of `cpus` (openmp_place_cpus: the
  /// threads are bound): the CPUs split into `slots` contiguous groups (one
  /// CPU each, in turn, when there are fewer CPUs than slots), a child
  /// taking the first group no running child holds. libgomp binds a
  /// process's first thread to the first CPU it may use, so children that
  /// all may use every CPU would all run there. Empty `cpus`: the children
  /// keep the study's mask.
  void share_cpus(std::vector<int> cpus, int slots);
  /// Starts the executable `program` with argv (argv[0] the name it is
  /// given), stdout and stderr to `log` and the extra environment `env`
  /// ("NAME=VALUE"); returns its pid. A child that cannot execute `program`
  /// writes why to `log` and exits with kNotStarted.
  pid_t start(const std::string& program, const std::vector<std::string>& argv,
              const std::filesystem::path& log, const std::vector<std::string>& env);
  /// Waits up to `limit` for the next child to end. Returns pid -1 when none
  /// is running or none ended in time: the caller checks its interrupt flag
  /// between waits, so a signal that arrives just before a wait is seen
  /// within `limit` (a blocking waitpid would miss it until a child ends).
  ChildExit wait_any(std::chrono::milliseconds limit);
  /// Sends SIGTERM to every running child.
  void terminate_all();
  std::size_t running() const { return children_.size(); }

private:
  /// The CPUs of group `slot` of share_cpus.
  std::vector<int> group(int slot) const;

  std::vector<pid_t> children_;
  std::vector<int> slot_; ///< per child: its group of cpus_ (-1: none)
  std::vector<int> cpus_;
  int slots_ = 0;
};

} // namespace otmpm::study
