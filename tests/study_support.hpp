// Helpers of the `otmpm study` tests (test_study.cpp, test_study_files.cpp):
// a study directory around the Dyka bar, running the study, reading its CSV.
#pragma once

#include "cli_support.hpp"

#include <doctest/doctest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace otmpm::test {

/// The mesh h = L/13 of the Dyka bar as a [[mesh]] table.
inline const char* const kMeshN13 = "[[mesh]]\nname = \"n13\"\nh = 0.010253846\n"
                                    "set = [\"grid.cells=[15]\", \"grid.lower=[-0.020507692]\"]\n";

/// The first lines of every test study file: the Dyka bar scene and study.csv.
inline std::string study_head() {
  return "scene = \"" OTMPM_SOURCE_DIR "/examples/dyka.toml\"\ncsv = \"study.csv\"\n";
}

/// A fresh directory with study.toml: study_head() and `body`.
inline std::filesystem::path study_dir(const std::string& name, const std::string& body) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("otmpm_study_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "study.toml") << study_head() << body;
  return dir;
}

/// Two integrators x two meshes (h = L/13, L/20), 2e-5 s each.
inline std::filesystem::path make_study_dir(const std::string& name) {
  return study_dir(name, std::string("jobs = 2\n"
                                     "set = [\"output.every=1e-5\", \"simulation.t_end=2e-5\"]\n"
                                     "[sweep]\n\"simulation.integrator\" = [\"fe\", \"npc\"]\n") +
                             kMeshN13 +
                             "[[mesh]]\nname = \"n20\"\nh = 0.006665\n"
                             "set = [\"grid.cells=[22]\", \"grid.lower=[-0.01333]\"]\n");
}

/// Runs a shell command; returns its exit status and fills `out` with its stdout and stderr.
inline int run_command(const std::string& cmd, std::string& out) {
  ShellResult r = shell(cmd);
  out = std::move(r.output);
  return r.status;
}

/// Runs `otmpm study study.toml` (and `args`, options for the shell) in dir;
/// returns the exit status and fills `out` with its output.
inline int run_study(const std::filesystem::path& dir, std::string& out, const std::string& args = "") {
  return run_command("cd " + quote(dir.string()) + " && '" OTMPM_BINARY "' study study.toml" + args, out);
}

/// The rows of a CSV file, as cells (RFC 4180: "a, ""b""" is one cell; trailing empty cells are kept).
inline std::vector<std::vector<std::string>> read_csv(const std::filesystem::path& file) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cols(1);
    bool quoted = false;
    for (std::size_t i = 0; i < line.size(); ++i) {
      const char c = line[i];
      if (c == '"' && quoted && i + 1 < line.size() && line[i + 1] == '"') cols.back() += line[++i];
      else if (c == '"') quoted = !quoted;
      else if (c == ',' && !quoted) cols.emplace_back();
      else cols.back() += c;
    }
    rows.push_back(cols);
  }
  return rows;
}

/// The index of column `name` in a CSV header (a test failure if there is none).
inline std::size_t column(const std::vector<std::string>& header, const std::string& name) {
  for (std::size_t i = 0; i < header.size(); ++i)
    if (header[i] == name) return i;
  FAIL("no column " << name);
  return 0;
}

} // namespace otmpm::test
