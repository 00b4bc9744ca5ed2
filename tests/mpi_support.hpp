// mpirun started in the background by the tests of distributed runs under
// hostile use (tests/test_mpi.cpp, tests/test_mpi_fuzz.cpp): one rank per
// command line (MPMD), each in its own working directory or mount
// namespace if asked, with the pid of each rank for a signal to one of
// them, and a deadline after which the whole launch is killed (a hang).
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

namespace otmpm::test {

/// One rank of an MPMD command line: otmpm with `args`, started in `wdir`
/// ("": the launch's directory), inside `unshare -m` after the shell
/// commands `mount` when given (a file system this rank alone sees).
struct RankLine {
  std::vector<std::string> args;
  std::string wdir = "";
  std::string mount = "";
  std::string env = ""; ///< NAME=VALUE in this rank's environment alone
};

/// Waits up to `seconds` until process `pid` catches signal `sig` (its
/// /proc status lists a handler: otmpm installs its own once it runs a
/// command); false if it does not by then.
inline bool catches(pid_t pid, int sig, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  const std::string status = "/proc/" + std::to_string(pid) + "/status";
  while (std::chrono::steady_clock::now() < end) {
    std::ifstream in(status);
    for (std::string line; std::getline(in, line);)
      if (line.rfind("SigCgt:", 0) == 0 && (std::stoull(line.substr(7), nullptr, 16) >> (sig - 1)) & 1ULL) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

/// mpirun as root needs these (CI containers run as root): set for this process and the ones it starts.
struct RootMpi {
  RootMpi() {
    ::setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
    ::setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
  }
};

/// True when this process may give one rank a file system of its own
/// (`unshare -m`: root, as in CI containers).
inline bool private_mounts() { return ::geteuid() == 0 && std::system("unshare -m true > /dev/null 2>&1") == 0; }

/// mpirun with one rank per RankLine, started in the background.
class MpiLaunch {
public:
  /// Starts `mpiexec -q --oversubscribe` with the rank lines in `dir` (one
  /// OpenMP thread per rank); its stderr goes to `err_file`.
  MpiLaunch(const std::string& mpiexec, const std::string& binary, const std::filesystem::path& dir,
            const std::vector<RankLine>& ranks, const std::string& err_file) {
    std::string cmd = "exec " + mpiexec + " -q --oversubscribe";
    for (std::size_t r = 0; r < ranks.size(); ++r) {
      cmd += std::string(r ? " :" : "") + " -np 1";
      if (!ranks[r].wdir.empty()) cmd += " -wdir '" + ranks[r].wdir + "'";
      if (!ranks[r].mount.empty()) cmd += " unshare -m sh -c '" + ranks[r].mount + " && exec \"$@\"' sh";
      if (!ranks[r].env.empty()) cmd += " env '" + ranks[r].env + "'";
      cmd += " '" + binary + "'";
      for (const std::string& a : ranks[r].args) cmd += " '" + a + "'";
    }
    pid_ = ::fork();
    if (pid_ != 0) return;
    ::setpgid(0, 0); // its own process group: a hang is ended by killing the group
    ::setenv("OMP_NUM_THREADS", "1", 1);
    if (::chdir(dir.c_str()) != 0 || !std::freopen(err_file.c_str(), "w", stderr) ||
        !std::freopen("/dev/null", "w", stdout) || !std::freopen("/dev/null", "r", stdin))
      std::_Exit(126);
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    std::_Exit(127);
  }
  MpiLaunch(const MpiLaunch&) = delete;
  MpiLaunch& operator=(const MpiLaunch&) = delete;
  ~MpiLaunch() {
    if (!ended_) end_within(0.0);
  }

  /// The pid of rank `r` (a child of mpirun whose environment says so), or
  /// 0 when it has not started within `seconds`.
  pid_t rank(int r, double seconds = 30.0) const {
    const std::string tag = "OMPI_COMM_WORLD_RANK=" + std::to_string(r) + '\0';
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      for (const auto& p : std::filesystem::directory_iterator("/proc")) {
        std::ifstream stat(p.path() / "stat");
        std::string pid, comm, state;
        long ppid = 0;
        if (!(stat >> pid >> comm >> state >> ppid) || ppid != pid_) continue;
        std::ifstream env(p.path() / "environ");
        const std::string all((std::istreambuf_iterator<char>(env)), std::istreambuf_iterator<char>());
        if (all.find(tag) != std::string::npos) return static_cast<pid_t>(std::stol(pid));
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return 0;
  }

  /// Sends `sig` to mpirun itself (not to its ranks).
  void signal(int sig) const { ::kill(pid_, sig); }

  /// Waits up to `seconds` for mpirun to end: its exit status (128 + N when
  /// signal N ended it), or -1 when it had not ended - then the launch is
  /// killed (SIGKILL to its process group) and reaped.
  int end_within(double seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    int raw = 0;
    for (;;) {
      if (::waitpid(pid_, &raw, WNOHANG) == pid_) break;
      if (std::chrono::steady_clock::now() >= end) {
        ::kill(-pid_, SIGKILL);
        ::waitpid(pid_, &raw, 0);
        ended_ = true;
        return -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ended_ = true;
    return WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw);
  }

private:
  pid_t pid_ = -1;
  bool ended_ = false;
};

} // namespace otmpm::test
