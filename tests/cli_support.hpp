// Helpers of the tests that drive the otmpm command through a shell.
#pragma once

#include <doctest/doctest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace otmpm::test {

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

} // namespace otmpm::test
