// Helpers of the tests that drive the otmpm command: through a shell
// (quote), or spawned with posix_spawn (or through /bin/sh for shell limits
// such as `ulimit -f`) with one OpenMP thread, stdout and stderr captured,
// and the exit status or the signal that ended it.
#pragma once

#include <doctest/doctest.h>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include "temp_dir.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace otmpm::test {

/// How a process ended and what it wrote.
struct CliResult {
  int status = -1; ///< exit status, or -1 when a signal ended it
  int signal = 0;  ///< the signal that ended it, or 0
  std::string out, err;
};

/// `s` as one word for /bin/sh (single quotes).
inline std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// The whole content of a file ("" if it cannot be read).
inline std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// The exit status of a shell command line and what it wrote to stdout and
/// stderr (merged).
struct ShellResult {
  int status = -1; ///< the exit status, -1 when the command did not exit normally
  std::string output;
};

/// Runs a shell command line (stderr merged into stdout).
inline ShellResult shell(const std::string& cmd) {
  std::FILE* p = ::popen((cmd + " 2>&1").c_str(), "r");
  REQUIRE(p != nullptr);
  ShellResult r;
  char buf[512];
  while (std::fgets(buf, sizeof buf, p)) r.output += buf;
  const int status = ::pclose(p);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

/// Starts PROGRAM ARGS (argv[0] = program) with OMP_NUM_THREADS=1, the extra
/// environment `env` ("NAME=VALUE"), stdout to `out_file` and stderr to
/// `err_file`; returns its pid.
inline pid_t spawn_process(const std::string& program, const std::vector<std::string>& args,
                           const std::string& out_file, const std::string& err_file,
                           const std::vector<std::string>& env = {}) {
  std::vector<std::string> env_s{"OMP_NUM_THREADS=1"};
  for (char** e = environ; *e; ++e)
    if (std::string(*e).rfind("OMP_NUM_THREADS=", 0) != 0) env_s.emplace_back(*e);
  env_s.insert(env_s.end(), env.begin(), env.end());
  std::vector<std::string> argv_s{program};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv, envp;
  for (std::string& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  for (std::string& e : env_s) envp.push_back(e.data());
  envp.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, out_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, program.c_str(), &actions, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  REQUIRE(rc == 0);
  return pid;
}

/// Waits for `pid` and collects its result (stdout and stderr from the files).
inline CliResult wait_process(pid_t pid, const std::string& out_file, const std::string& err_file) {
  int wstatus = 0;
  REQUIRE(waitpid(pid, &wstatus, 0) == pid);
  CliResult r;
  r.status = WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -1;
  r.signal = WIFSIGNALED(wstatus) ? WTERMSIG(wstatus) : 0;
  r.out = read_text(out_file);
  r.err = read_text(err_file);
  return r;
}

/// Runs PROGRAM ARGS to completion in the current directory; its output goes
/// through files in `scratch` (a directory).
inline CliResult run_process(const std::string& program, const std::vector<std::string>& args,
                             const std::filesystem::path& scratch, const std::vector<std::string>& env = {}) {
  const std::string out = (scratch / "stdout.txt").string(), err = (scratch / "stderr.txt").string();
  return wait_process(spawn_process(program, args, out, err, env), out, err);
}

/// Waits until `path` exists; false if the process `pid` ended first or after `limit`.
inline bool wait_for_file(const std::string& path, pid_t pid, std::chrono::seconds limit) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    if (std::filesystem::exists(path)) return true;
    int wstatus = 0;
    if (waitpid(pid, &wstatus, WNOHANG) == pid) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return false;
}

/// Runs `otmpm ARGS` in the directory of `dir` (relative paths land there).
inline CliResult otmpm_in(const TempDir& dir, const std::vector<std::string>& args,
                          const std::vector<std::string>& env = {}) {
  const std::filesystem::path here = std::filesystem::current_path();
  std::filesystem::current_path(dir.dir);
  const std::filesystem::path scratch = dir.dir.parent_path() / (dir.dir.filename().string() + "_io");
  std::filesystem::create_directories(scratch);
  CliResult r = run_process(OTMPM_BINARY, args, scratch, env);
  std::filesystem::current_path(here);
  std::filesystem::remove_all(scratch);
  return r;
}

/// Names in a directory (hidden ones included).
inline std::set<std::string> listing(const std::filesystem::path& dir) {
  std::set<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

inline bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

/// Checks that a process exited (no signal) with `status`; its output is shown when not.
inline void expect_exit(const CliResult& r, int status) {
  INFO("stderr: " << r.err << "\nstdout: " << r.out);
  CHECK(r.signal == 0);
  CHECK(r.status == status);
}

} // namespace otmpm::test
