#include "process_pool.hpp"

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <fcntl.h>
#include <sched.h>
#include <stdexcept>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

extern char** environ;

namespace otmpm::study {

ProcessPool::~ProcessPool() {
  terminate_all();
  for (pid_t pid : children_) {
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
  }
}

void ProcessPool::share_cpus(std::vector<int> cpus, int slots) {
  cpus_ = std::move(cpus);
  slots_ = cpus_.empty() ? 0 : std::max(slots, 1);
}

std::vector<int> ProcessPool::group(int slot) const {
  const auto n = static_cast<int>(cpus_.size());
  if (n < slots_) return {cpus_[static_cast<std::size_t>(slot % n)]};
  return {cpus_.begin() + n * slot / slots_, cpus_.begin() + n * (slot + 1) / slots_};
}

pid_t ProcessPool::start(const std::string& program, const std::vector<std::string>& argv,
                         const std::filesystem::path& log, const std::vector<std::string>& env) {
  // Everything the child needs is prepared before fork: after it, only
  // async-signal-safe calls.
  std::vector<std::string> args = argv, vars = env;
  std::vector<char*> cargv, cenv;
  for (std::string& a : args) cargv.push_back(a.data());
  cargv.push_back(nullptr);
  for (char** e = environ; *e; ++e) {
    const std::string entry(*e);
    const std::string name = entry.substr(0, entry.find('='));
    const bool overridden = std::any_of(vars.begin(), vars.end(), [&](const std::string& v) {
      return v.compare(0, name.size() + 1, name + "=") == 0;
    });
    if (!overridden) cenv.push_back(*e);
  }
  for (std::string& v : vars) cenv.push_back(v.data());
  cenv.push_back(nullptr);
  int slot = -1; // the first group no running child holds
  for (int g = 0; g < slots_ && slot < 0; ++g)
    if (std::find(slot_.begin(), slot_.end(), g) == slot_.end()) slot = g;
  cpu_set_t cpus;
  CPU_ZERO(&cpus);
  if (slot >= 0)
    for (const int id : group(slot))
      if (id < CPU_SETSIZE) CPU_SET(id, &cpus);
  const std::string log_path = log.string(), cannot = "otmpm study: cannot start " + argv.at(0) + ": ";
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error(std::string("fork failed: ") + std::strerror(errno));
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent) _exit(128 + SIGTERM); // the study died before prctl took effect
    if (slot >= 0) sched_setaffinity(0, sizeof cpus, &cpus); // on failure the child keeps the study's mask
    const int fd = open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd >= 0) {
      dup2(fd, STDOUT_FILENO);
      dup2(fd, STDERR_FILENO);
    }
    execve(program.c_str(), cargv.data(), cenv.data());
    const char* why = std::strerror(errno); // the study has no other thread: no lock is held here
    if (write(STDERR_FILENO, cannot.data(), cannot.size()) >= 0 &&
        write(STDERR_FILENO, why, std::strlen(why)) >= 0)
      (void)!write(STDERR_FILENO, "\n", 1);
    _exit(kNotStarted);
  }
  children_.push_back(pid);
  slot_.push_back(slot);
  return pid;
}

ChildExit ProcessPool::wait_any(std::chrono::milliseconds limit) {
  constexpr std::chrono::milliseconds poll{20};
  ChildExit c;
  int status = 0;
  for (auto waited = std::chrono::milliseconds(0); !children_.empty(); waited += poll) {
    const pid_t pid = waitpid(-1, &status, WNOHANG);
    if (pid < 0 && errno != EINTR)
      throw std::runtime_error(std::string("waitpid failed: ") + std::strerror(errno));
    if (pid > 0) {
      const auto at = std::find(children_.begin(), children_.end(), pid) - children_.begin();
      if (at < static_cast<std::ptrdiff_t>(children_.size())) {
        children_.erase(children_.begin() + at);
        slot_.erase(slot_.begin() + at);
      }
      c.pid = pid;
      c.signalled = WIFSIGNALED(status);
      c.status = c.signalled ? 128 + WTERMSIG(status) : WEXITSTATUS(status);
      return c;
    }
    if (waited >= limit) break;
    std::this_thread::sleep_for(poll);
  }
  return c;
}

void ProcessPool::terminate_all() {
  for (pid_t pid : children_) kill(pid, SIGTERM);
}

} // namespace otmpm::study
