// The `otmpm` command (docs/user-guide.md, "Command line"): exit status 2 with a
// message naming file and line for every malformed scene, 0 and a readable
// HDF5 file with status "ok" for a good one, 1 and a diagnosis for a run that
// becomes unstable, 2 for an unknown --set key or an unknown command.
#include <doctest/doctest.h>
#include <hdf5.h>

#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

const fs::path kSource = OTMPM_SOURCE_DIR;
const std::string kBinary = OTMPM_BINARY;

/// A fresh temporary directory, removed when the object goes out of scope.
class TempDir {
public:
  TempDir() {
    std::string pattern = (fs::temp_directory_path() / "otmpm_test_cli_XXXXXX").string();
    REQUIRE(mkdtemp(pattern.data()) != nullptr);
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

private:
  fs::path path_;
};

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

struct CliResult {
  int status = -1;
  std::string err;
};

/// Runs `otmpm ARGS` (one thread, so the run does not depend on how busy the
/// machine is), returning the exit status and what it wrote to stderr.
CliResult run_cli(const TempDir& dir, const std::vector<std::string>& args) {
  const fs::path err_file = dir.path() / "stderr.txt";
  // Appended piece by piece: g++ 12 at -O3 warns (-Wrestrict, a known false
  // positive) on `"literal" + std::string`.
  std::string cmd = "OMP_NUM_THREADS=1 ";
  cmd += quote(kBinary);
  for (const auto& a : args) {
    cmd += ' ';
    cmd += quote(a);
  }
  cmd += " >/dev/null 2>";
  cmd += quote(err_file.string());
  const int rc = std::system(cmd.c_str());
  CliResult r;
  r.status = rc != -1 && WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  std::ifstream in(err_file);
  std::stringstream ss;
  ss << in.rdbuf();
  r.err = ss.str();
  return r;
}

/// A string attribute of the root group of an HDF5 file ("" and a failed
/// check when it cannot be read).
std::string root_string_attribute(const fs::path& file, const std::string& name) {
  std::string value;
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(f >= 0);
  const hid_t attr = H5Aopen_by_name(f, "/", name.c_str(), H5P_DEFAULT, H5P_DEFAULT);
  CHECK(attr >= 0);
  if (attr >= 0) {
    const hid_t type = H5Aget_type(attr);
    CHECK(H5Tget_class(type) == H5T_STRING);
    CHECK(H5Tis_variable_str(type) == 0); // fixed-length, as results.cpp writes it
    std::vector<char> buf(H5Tget_size(type) + 1, '\0');
    CHECK(H5Aread(attr, type, buf.data()) >= 0);
    value = buf.data();
    H5Tclose(type);
    H5Aclose(attr);
  }
  H5Fclose(f);
  return value;
}

/// True when s contains ":<digits>:" (the "FILE:LINE:" of a message). Written
/// by hand: std::regex trips GCC 12's -Wmaybe-uninitialized under the sanitizers.
bool has_line_number(const std::string& s) {
  for (std::size_t i = s.find(':'); i != std::string::npos; i = s.find(':', i + 1)) {
    std::size_t j = i + 1;
    while (j < s.size() && s[j] >= '0' && s[j] <= '9') ++j;
    if (j > i + 1 && j < s.size() && s[j] == ':') return true;
  }
  return false;
}

std::vector<fs::path> bad_scenes() {
  std::vector<fs::path> out;
  for (const auto& entry : fs::directory_iterator(kSource / "tests" / "scenes" / "bad"))
    if (entry.path().extension() == ".toml") out.push_back(entry.path());
  std::sort(out.begin(), out.end());
  return out;
}

} // namespace

TEST_CASE("cli: every malformed scene exits with 2 and names file and line") {
  TempDir dir;
  const std::vector<fs::path> scenes = bad_scenes();
  REQUIRE(scenes.size() >= 10); // the directory is really there
  for (const fs::path& scene : scenes) {
    INFO("scene " << scene.filename().string());
    const fs::path out = dir.path() / (scene.stem().string() + ".h5");
    const CliResult r = run_cli(dir, {"run", scene.string(), "--out", out.string(), "--quiet"});
    INFO("stderr: " << r.err);
    CHECK(r.status == 2);
    CHECK(r.err.find(scene.filename().string()) != std::string::npos);
    CHECK((r.err.find("line") != std::string::npos || has_line_number(r.err)));
    // Nothing runs on a half-read scene: no result file.
    CHECK(!fs::exists(out));
  }
}

TEST_CASE("cli: a good scene exits with 0 and writes an HDF5 file with status ok") {
  TempDir dir;
  const fs::path out = dir.path() / "good.h5";
  const CliResult r =
      run_cli(dir, {"run", (kSource / "tests" / "scenes" / "good_minimal.toml").string(), "--out", out.string(), "--quiet"});
  INFO("stderr: " << r.err);
  CHECK(r.status == 0);
  REQUIRE(fs::exists(out));
  CHECK(H5Fis_hdf5(out.c_str()) > 0);
  CHECK(root_string_attribute(out, "status") == "ok");
  // The resolved scene is stored too (docs/user-guide.md, "Result file").
  CHECK(root_string_attribute(out, "scene").find("[simulation]") != std::string::npos);
}

TEST_CASE("cli: a run that leaves the grid exits with 1 and leaves a valid file with the diagnosis") {
  TempDir dir;
  const fs::path out = dir.path() / "unstable.h5";
  const CliResult r = run_cli(
      dir, {"run", (kSource / "tests" / "scenes" / "engine" / "leaves_grid.toml").string(), "--out", out.string(), "--quiet"});
  INFO("stderr: " << r.err);
  CHECK(r.status == 1);
  CHECK(r.err.find("would leave the grid") != std::string::npos);
  REQUIRE(fs::exists(out));
  const std::string status = root_string_attribute(out, "status");
  CHECK(status.rfind("unstable", 0) == 0);
  CHECK(status.find("would leave the grid") != std::string::npos);
}

TEST_CASE("cli: --set of an unknown key exits with 2 and names the key") {
  TempDir dir;
  const std::string good = (kSource / "tests" / "scenes" / "good_minimal.toml").string();
  for (const char* key : {"simulation.no_such_key=1", "no_such_table.value=1", "material.steel.yuong=1e9"}) {
    INFO("--set " << key);
    const fs::path out = dir.path() / "set.h5";
    const CliResult r = run_cli(dir, {"run", good, "--set", key, "--out", out.string(), "--quiet"});
    INFO("stderr: " << r.err);
    CHECK(r.status == 2);
    const std::string path = std::string(key).substr(0, std::string(key).find('='));
    CHECK(r.err.find(path.substr(path.rfind('.') + 1)) != std::string::npos); // the offending key
    CHECK(!fs::exists(out));
  }
}

TEST_CASE("cli: the line-number detector used above") {
  CHECK(has_line_number("otmpm: error: a.toml:14: key 'x'"));
  CHECK(has_line_number("b.toml:21:11: syntax error"));
  CHECK(!has_line_number("otmpm: error: a.toml: key 'x'"));
  CHECK(!has_line_number("12:"));
}

TEST_CASE("cli: an unknown command or no command exits with 2") {
  TempDir dir;
  const CliResult r = run_cli(dir, {"frobnicate"});
  CHECK(r.status == 2);
  CHECK(r.err.find("frobnicate") != std::string::npos);
  CHECK(run_cli(dir, {}).status == 2);
  CHECK(run_cli(dir, {"--help"}).status == 0);
}

TEST_CASE("cli: basis options that are not an int (out of range, fractional, negative seed) exit with 2") {
  TempDir dir;
  const std::string out = (dir.path() / "basis.csv").string();
  for (const char* bad : {"--cells=1e20", "--cells=2.5", "--samples=-1e300", "--seed=-3"}) {
    INFO(bad);
    const std::string arg(bad);
    const std::string opt = arg.substr(0, arg.find('='));
    const CliResult r = run_cli(dir, {"basis", "--kind", "linear", opt, arg.substr(arg.find('=') + 1), "--out", out});
    INFO("stderr: " << r.err);
    CHECK(r.status == 2);
    CHECK(r.err.find(opt) != std::string::npos);
  }
  CHECK(run_cli(dir, {"basis", "--kind", "linear", "--cells", "4", "--samples", "3", "--out", out}).status == 0);
}
