// A fresh temporary directory per test, removed with its content afterwards
// (shared by the result-file and restart tests).
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace otmpm::test {

/// The directory otmpm_test_<pid>_<tag> under the system's temporary
/// directory: created empty, removed when the object goes out of scope. The
/// pid keeps test processes that run side by side (ctest -j) apart.
struct TempDir {
  std::filesystem::path dir;
  explicit TempDir(const std::string& tag) {
    dir = std::filesystem::temp_directory_path() / ("otmpm_test_" + std::to_string(::getpid()) + "_" + tag);
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  /// The path of `name` inside the directory.
  std::string file(const std::string& name) const { return (dir / name).string(); }
};

} // namespace otmpm::test
