// A result file a SIGKILLed run left half-written: HDF5 itself crashed while
// iterating its /frames links (H5Literate sorting a half-written dense link
// table), which `otmpm run --force` did to inspect the file it replaces.
// tests/scenes/killed_run.h5 is such a file (left by a killed study in test_study_files.cpp).
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/output_files.hpp"
#include "h5_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <filesystem>
#include <string>

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
