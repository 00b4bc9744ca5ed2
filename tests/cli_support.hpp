// Helpers of the tests that drive the otmpm command through a shell.
#pragma once

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

} // namespace otmpm::test
