#include "system.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/output_files.hpp"

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <sys/wait.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace otmpm::cli {

fs::path self_path() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path("otmpm") : p;
}

fs::path scripts_dir(const std::string& given) {
  if (!given.empty()) return given;
  return (self_path().parent_path() / ".." / "share" / "otmpm").lexically_normal();
}

namespace {
bool executable(const fs::path& p) { return !p.empty() && ::access(p.c_str(), X_OK) == 0 && !fs::is_directory(p); }
} // namespace

std::string find_python(const std::string& given) {
  if (!given.empty()) return given;
  if (executable("/usr/bin/python3")) return "/usr/bin/python3";
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  for (std::string dir; std::getline(dirs, dir, ':');)
    if (executable(fs::path(dir) / "python3")) return (fs::path(dir) / "python3").string();
  return "";
}

int run_and_wait(const std::vector<std::string>& argv) {
  std::vector<char*> cargv;
  std::vector<std::string> copy = argv;
  for (std::string& a : copy) cargv.push_back(a.data());
  cargv.push_back(nullptr);
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error(std::string("fork failed: ") + std::strerror(errno));
  if (pid == 0) {
    execvp(cargv[0], cargv.data());
    _exit(127);
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) throw std::runtime_error(std::string("waitpid failed: ") + std::strerror(errno));
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

void require_file(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (path.empty()) throw InputError("the " + what + " path is empty");
  if (fs::is_directory(path, ec)) throw InputError(path + ": is a directory, not a " + what);
  if (const std::string kind = special_file(path); !kind.empty())
    throw InputError(path + ": is " + kind + ", not a " + what);
  if (!fs::exists(path, ec)) throw InputError(path + ": no such " + what);
}

} // namespace otmpm::cli
