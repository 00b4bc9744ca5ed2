// Result files and killed runs. A result file a SIGKILLed run left half-written: HDF5 itself crashed while
// iterating its /frames links (H5Literate sorting a half-written dense link
// table), which `otmpm run --force` did to inspect the file it replaces.
// tests/scenes/killed_run.h5 is such a file (left by a killed study in test_study_files.cpp).
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/core.hpp"
#include "h5_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

using namespace otmpm;
namespace fs = std::filesystem;

TEST_CASE("a killed run's half-written result file is inspected without iterating its links") {
  test::TempDir tmp("killed_result");
  const std::string path = tmp.file("a.h5");
  fs::copy_file(OTMPM_SOURCE_DIR "/tests/scenes/killed_run.h5", path);
  // Inspecting it (as claim_outputs does before a replacement) returns, with the run's id.
  CHECK(!result_run_id(path).empty());
}

TEST_CASE("link_count gives the number of links link_names lists") {
  test::TempDir tmp("link_count");
  const auto [path, file] = test::new_h5_file(tmp, "g.h5");
  const h5::Handle group(H5Gcreate2(file.get(), "frames", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  CHECK(h5::link_count(group.get(), path) == 0);
  for (int i = 0; i < 40; ++i) { // past the compact storage (8 links): the dense link table
    const std::string name = std::to_string(i);
    const h5::Handle g(H5Gcreate2(group.get(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  }
  CHECK(h5::link_count(group.get(), path) == 40);
  CHECK(h5::link_count(group.get(), path) == h5::link_names(group.get(), path).size());
}

namespace {

/// Whether `path` holds exactly `text`.
bool holds(const std::string& path, const std::string& text) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {}) == text;
}

} // namespace

TEST_CASE("a new result file takes its path only once its header is on disk, a killed run's temporary is replaced") {
  test::TempDir tmp("result_created");
  const std::string path = tmp.file("r.h5");
  std::ofstream(path + ".tmp") << "left by a run killed while creating its file";
  {
    ResultWriter w(path, "[simulation]\ndimension = 2\n", 2);
    CHECK(!fs::exists(path + ".tmp")); // renamed into place by the constructor
    CHECK(read_string_attribute(path, "status") == "running");
  }
  CHECK(read_string_attribute(path, "status") == "running");
}

TEST_CASE("a result file whose header cannot be written leaves the old file and no temporary") {
  test::TempDir tmp("result_refused");
  const std::string path = tmp.file("r.h5");
  const std::string old = "an older file of the same name";
  std::ofstream(path) << old;
  // A child process with a file size limit below the header (a 1 MB scene
  // text): the constructor refuses the write; the old file stays as it was.
  const pid_t child = ::fork();
  REQUIRE(child >= 0);
  if (child == 0) {
    ::signal(SIGXFSZ, SIG_IGN);
    const rlimit limit{64 * 1024, 64 * 1024};
    ::setrlimit(RLIMIT_FSIZE, &limit);
    int code = 0;
    try {
      ResultWriter w(path, std::string(1 << 20, '#'), 2);
      code = 10; // created against the limit
    } catch (const OutputError&) {
      code = 0;
    } catch (...) {
      code = 11;
    }
    ::_exit(code);
  }
  int status = 0;
  REQUIRE(::waitpid(child, &status, 0) == child);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);
  CHECK(holds(path, old));
  CHECK(!fs::exists(path + ".tmp"));
}
