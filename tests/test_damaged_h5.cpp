// Damaged HDF5 files read by the library (docs/user-guide.md, "Damaged
// files"): libhdf5 crashed (SIGSEGV) listing a group whose dense link table a
// killed writer left half-written, and a restart copied whatever values the
// interrupted run's result file held. Here: the group is listed without the
// crash and refused as damaged; copy_results refuses values otmpm never
// writes (not finite) and frames whose time disagrees with the histories',
// naming the file and the dataset. scripts/h5damage.py runs the whole
// damage matrix against the command line; tests/test_cli_damaged.cpp the
// command-line cases.
#include "otmpm/core.hpp"
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/results.hpp"
#include "h5_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

using namespace otmpm;
namespace fs = std::filesystem;

namespace {

/// The message of the exception `f` throws, as type E ("" when it throws nothing).
template <class E, class F> std::string message_of(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return "";
}

/// A 1D result file of three frames (x, v), the probe A and the series energy.
void write_result(const std::string& path) {
  ResultWriter w(path, "[simulation]\ndimension = 1\n", 1);
  for (int k = 0; k < 3; ++k) {
    const double t = 0.5 * k;
    w.append_probe("A", t, {{"v", {1.0 * k}}});
    w.append_series("energy", t, {{"kinetic", 1.0 + k}});
    const std::vector<double> x = {0.0, 1.0, 2.0}, v = {0.1 * k, 0.2 * k, 0.3 * k};
    w.write_frame(t, {{"x", 3, 1, x.data()}, {"v", 3, 1, v.data()}});
  }
}

/// Writes `value` over row `row` of the rank-2 dataset `name` of the file `path` (a damaged byte range).
void poke(const std::string& path, const std::string& name, hsize_t row, double value) {
  h5::silence();
  const h5::Handle file(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose);
  REQUIRE(file.valid());
  const h5::Handle set(H5Dopen2(file.get(), name.c_str(), H5P_DEFAULT), H5Dclose);
  REQUIRE(set.valid());
  const h5::Handle space(H5Dget_space(set.get()), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  const hsize_t start[2] = {row, 0}, count[2] = {1, 1};
  REQUIRE(H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr) >= 0);
  const h5::Handle memory(H5Screate_simple(rank, count, nullptr), H5Sclose);
  REQUIRE(H5Dwrite(set.get(), H5T_NATIVE_DOUBLE, memory.get(), space.get(), H5P_DEFAULT, &value) >= 0);
}

/// Copies the three frames and both histories of `from` into a new file in `dir`.
void copy_all(const std::string& from, const test::TempDir& dir) {
  const std::string to = dir.file("copy.h5");
  fs::remove(to);
  ResultWriter w(to, "[simulation]\ndimension = 1\n", 1);
  copy_results(from, w, 3, {{"A", true, {"v"}}, {"energy", false, {"kinetic"}}}, {"x", "v"});
}

} // namespace

TEST_CASE(
    "a group a killed writer left half-written is listed without crashing HDF5, and refused as damaged") {
  // tests/scenes/killed_run.h5: /frames records 206 links, its name index
  // holds 205 (HDF5's listing in name order sorted a table of 206 entries,
  // one of them empty, and crashed).
  test::TempDir tmp("damaged_links");
  const std::string path = tmp.file("killed.h5");
  fs::copy_file(OTMPM_SOURCE_DIR "/tests/scenes/killed_run.h5", path);
  h5::silence();
  const h5::Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  REQUIRE(file.valid());
  const h5::Handle frames = h5::open_group(file.get(), "frames", path);
  CHECK(h5::link_count(frames.get(), path) == 206);
  const std::string what = message_of<h5::Failure>([&] { h5::link_names(frames.get(), path); });
  CHECK(what.find(path) == 0);
  CHECK(what.find("records 206 entries but its index holds 205") != std::string::npos);
  // An intact group of the same file lists as before, in name order.
  const h5::Handle probes = h5::open_group(file.get(), "probes/A", path);
  const std::vector<std::string> names = h5::link_names(probes.get(), path);
  CHECK(names == std::vector<std::string>{"stress", "time", "v", "x"});
}

TEST_CASE("link_names and attribute_names list dense storage in name order") {
  // Past 8 entries HDF5 stores links and attributes in a dense table, which
  // link_names and attribute_names walk in its native (hash) order and sort.
  test::TempDir tmp("dense_names");
  const auto [path, file] = test::new_h5_file(tmp, "dense.h5");
  std::vector<std::string> expected;
  for (int i = 0; i < 30; ++i) {
    const std::string name = "n" + std::to_string(37 * i % 101);
    expected.push_back(name);
    const h5::Handle g(H5Gcreate2(file.get(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    const double value = i;
    h5::write_attribute(file.get(), name, H5T_NATIVE_DOUBLE, &value, path);
  }
  std::sort(expected.begin(), expected.end());
  CHECK(h5::link_names(file.get(), path) == expected);
  CHECK(h5::attribute_names(file.get(), path) == expected);
}

TEST_CASE("copy_results copies an intact result file and refuses values otmpm never writes") {
  test::TempDir tmp("damaged_copy");
  const std::string path = tmp.file("res.h5");
  write_result(path);
  CHECK_NOTHROW(copy_all(path, tmp));

  SUBCASE("a frame value that is not finite") {
    poke(path, "frames/000001/v", 2, std::numeric_limits<double>::quiet_NaN());
    const std::string what = message_of<InputError>([&] { copy_all(path, tmp); });
    CHECK(what.find(path + ": cannot copy the results of the interrupted run") == 0);
    CHECK(what.find("frames/000001/v: row 2 is not finite") != std::string::npos);
  }
  SUBCASE("a history value that is not finite") {
    poke(path, "energy/kinetic", 1, std::numeric_limits<double>::infinity());
    const std::string what = message_of<InputError>([&] { copy_all(path, tmp); });
    CHECK(what.find(path) == 0);
    CHECK(what.find("energy/kinetic: row 1 is not finite") != std::string::npos);
  }
  SUBCASE("history times that decrease") {
    poke(path, "probes/A/time", 2, 0.25);
    const std::string what = message_of<InputError>([&] { copy_all(path, tmp); });
    CHECK(what.find(path) == 0);
    CHECK(what.find("probes/A/time: its times decrease at row 2") != std::string::npos);
  }
  SUBCASE("a frame whose time is not the histories'") {
    poke(path, "energy/time", 1, 0.4); // still increasing: 0, 0.4, 1
    const std::string what = message_of<InputError>([&] { copy_all(path, tmp); });
    CHECK(what.find(path) == 0);
    CHECK(what.find("frame 000001 has time 0.5 but history 'energy' 0.40000000000000002") != std::string::npos);
  }
}
