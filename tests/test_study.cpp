// `otmpm study`: a 2 x 2 sweep (two integrators x two meshes of the Dyka bar)
// writes one CSV row per run with the expected parameters and errors, and a
// rerun resumes: rows already present are not run again.
#include <doctest/doctest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <sys/wait.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace {

fs::path make_study_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("otmpm_study_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "study.toml") << "scene = \"" OTMPM_SOURCE_DIR "/examples/dyka.toml\"\n"
                                    << "csv = \"study.csv\"\n"
                                    << "jobs = 2\n"
                                    << "set = [\"output.every=1e-5\", \"simulation.t_end=2e-5\"]\n"
                                    << "[sweep]\n\"simulation.integrator\" = [\"fe\", \"npc\"]\n"
                                    << "[[mesh]]\nname = \"n13\"\nh = 0.010253846\n"
                                    << "set = [\"grid.cells=[15]\", \"grid.lower=[-0.020507692]\"]\n"
                                    << "[[mesh]]\nname = \"n20\"\nh = 0.006665\n"
                                    << "set = [\"grid.cells=[22]\", \"grid.lower=[-0.01333]\"]\n";
  return dir;
}

/// Runs `otmpm study` in dir; returns the exit status and fills `out` with stdout.
int run_study(const fs::path& dir, std::string& out) {
  const std::string cmd = "cd '" + dir.string() + "' && '" OTMPM_BINARY "' study study.toml 2>&1";
  std::FILE* p = ::popen(cmd.c_str(), "r");
  REQUIRE(p != nullptr);
  char buf[512];
  out.clear();
  while (std::fgets(buf, sizeof buf, p)) out += buf;
  const int status = ::pclose(p);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::vector<std::vector<std::string>> read_csv(const fs::path& file) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cols;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) cols.push_back(c);
    rows.push_back(cols);
  }
  return rows;
}

int column(const std::vector<std::string>& header, const std::string& name) {
  for (std::size_t i = 0; i < header.size(); ++i)
    if (header[i] == name) return static_cast<int>(i);
  FAIL("no column " << name);
  return -1;
}

} // namespace

TEST_CASE("study: a 2x2 sweep writes one CSV row per run with parameters, status and errors") {
  const fs::path dir = make_study_dir("rows");
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 5); // header + 2 integrators x 2 meshes
  const auto& h = rows[0];
  std::set<std::string> seen;
  for (std::size_t r = 1; r < rows.size(); ++r) {
    const auto& row = rows[r];
    REQUIRE(row.size() >= h.size() - 1);
    seen.insert(row[column(h, "variant")] + "@" + row[column(h, "mesh")]);
    CHECK(row[column(h, "status")] == "ok");
    CHECK(row[column(h, "simulation.integrator")] == row[column(h, "variant")]);
    // The Dyka velocity error after 2e-5 s is of the order of the 5 m/s jump
    // smeared over a few cells: positive, finite and well below 5 m/s.
    const double e = std::stod(row[column(h, "rms_velocity_error")]);
    CHECK(e > 0.0);
    CHECK(e < 5.0);
    CHECK(std::stod(row[column(h, "wall_seconds")]) > 0.0);
    CHECK(std::stod(row[column(h, "steps")]) > 0.0);
  }
  CHECK(seen == std::set<std::string>{"fe@n13", "npc@n13", "fe@n20", "npc@n20"});
  CHECK(fs::exists(dir / "study_work_precision.png"));
  CHECK(fs::exists(dir / "study_convergence.svg"));
  fs::remove_all(dir);
}

TEST_CASE("study: a rerun skips the runs already in the CSV and completes a truncated one") {
  const fs::path dir = make_study_dir("resume");
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  REQUIRE(run_study(dir, out) == 0);
  CHECK(out.find("0 to do") != std::string::npos);
  CHECK(read_csv(dir / "study.csv").size() == 5);
  // Drop the last row, as if the study had been interrupted: only that run is redone.
  auto rows = read_csv(dir / "study.csv");
  std::ifstream in(dir / "study.csv");
  std::string text, line;
  for (std::size_t i = 0; i + 1 < rows.size() && std::getline(in, line); ++i) text += line + "\n";
  in.close();
  std::ofstream(dir / "study.csv") << text;
  REQUIRE(run_study(dir, out) == 0);
  CHECK(out.find("1 to do") != std::string::npos);
  CHECK(read_csv(dir / "study.csv").size() == 5);
  fs::remove_all(dir);
}

TEST_CASE("study: a malformed study file is refused with exit status 2 and the line") {
  const fs::path dir = make_study_dir("bad");
  std::stringstream text;
  text << "colour = \"red\"\n" << std::ifstream(dir / "study.toml").rdbuf();
  std::ofstream(dir / "study.toml") << text.str();
  std::string out;
  CHECK(run_study(dir, out) == 2);
  CHECK(out.find("study.toml:1:") != std::string::npos);
  CHECK(out.find("colour") != std::string::npos);
  fs::remove_all(dir);
}
