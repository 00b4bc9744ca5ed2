// Result file tests: what ResultWriter writes is read back with the plain
// HDF5 C API (values, shapes, attributes), the XDMF sidecar names every frame,
// and a writer that is destroyed early, or a process killed outright, leaves a
// readable file. Values are compared with ==: they are stored as IEEE doubles
// and read back without any arithmetic.
#include "otmpm/io/results.hpp"

#include "otmpm/core.hpp"
#include "otmpm/run/run.hpp"

#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <sys/wait.h>
#include <unistd.h>

using namespace otmpm;
using test::TempDir;
namespace fs = std::filesystem;

namespace {

/// A dataset read back: its dimensions and values.
struct Dataset {
  std::vector<hsize_t> dims;
  std::vector<double> values;
};

Dataset read_dataset(const std::string& path, const std::string& name) {
  Dataset out;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(file >= 0);
  const hid_t set = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  REQUIRE(set >= 0);
  const hid_t space = H5Dget_space(set);
  out.dims.resize(static_cast<std::size_t>(H5Sget_simple_extent_ndims(space)));
  H5Sget_simple_extent_dims(space, out.dims.data(), nullptr);
  out.values.resize(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
  if (!out.values.empty()) CHECK(H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.values.data()) >= 0);
  H5Sclose(space);
  H5Dclose(set);
  H5Fclose(file);
  return out;
}

/// A scalar double attribute of an object inside the file.
double read_object_attribute(const std::string& path, const std::string& object, const std::string& name) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(file >= 0);
  const hid_t attr = H5Aopen_by_name(file, object.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT);
  REQUIRE(attr >= 0);
  double value = 0;
  CHECK(H5Aread(attr, H5T_NATIVE_DOUBLE, &value) >= 0);
  H5Aclose(attr);
  H5Fclose(file);
  return value;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto pos = text.find(what); pos != std::string::npos; pos = text.find(what, pos + 1)) ++n;
  return n;
}

// Two particles in 2D: x (2 x 2), v (2 x 2), stress (2 x 4), density (2 x 1).
const std::vector<double> kX = {0.0, 1.0, 2.0, 3.0};
const std::vector<double> kV = {-1.5, 0.25, 1e-300, 7.0};
const std::vector<double> kS = {1, 2, 3, 4, 5, 6, 7, 8};
const std::vector<double> kRho = {7833.0, 7834.5};

std::vector<FieldView> fields_2d() {
  return {{"x", 2, 2, kX.data()}, {"v", 2, 2, kV.data()}, {"stress", 2, 4, kS.data()}, {"density", 2, 1, kRho.data()}};
}

} // namespace

TEST_CASE("root attributes are written on creation") {
  TempDir t("root");
  const std::string path = t.file("run.h5");
  {
    ResultWriter w(path, "[simulation]\ndimension = 2\n", 2);
    CHECK(w.path() == path);
    CHECK(w.frames() == 0);
  }
  CHECK_FALSE(read_string_attribute(path, "otmpm_version").empty());
  CHECK(read_string_attribute(path, "scene") == "[simulation]\ndimension = 2\n");
  CHECK(read_string_attribute(path, "status") == "running");
  CHECK(read_double_attribute(path, "dimension") == 2.0);
}

TEST_CASE("frames are written as /frames/NNNNNN with time and one dataset per field") {
  TempDir t("frames");
  const std::string path = t.file("run.h5");
  {
    ResultWriter w(path, "", 2);
    w.write_frame(0.0, fields_2d());
    w.write_frame(0.5, fields_2d());
    CHECK(w.frames() == 2);
  }
  CHECK(read_object_attribute(path, "/frames/000000", "time") == 0.0);
  CHECK(read_object_attribute(path, "/frames/000001", "time") == 0.5);
  const Dataset v = read_dataset(path, "/frames/000001/v");
  CHECK(v.dims == std::vector<hsize_t>{2, 2});
  CHECK(v.values == kV);
  const Dataset s = read_dataset(path, "/frames/000000/stress");
  CHECK(s.dims == std::vector<hsize_t>{2, 4});
  CHECK(s.values == kS);
  CHECK(read_dataset(path, "/frames/000000/density").dims == std::vector<hsize_t>{2, 1});
}

TEST_CASE("probe histories grow by one row per sample") {
  TempDir t("probes");
  const std::string path = t.file("run.h5");
  {
    ResultWriter w(path, "", 2);
    for (int k = 0; k < 3; ++k)
      w.append_probe("A", 0.1 * k, {{"v", {1.0 * k, -1.0 * k}}, {"stress", {1.0, 2.0, 3.0, 4.0 + k}}});
    w.append_probe("B", 0.0, {{"v", {9.0, 9.0}}});
  }
  const Dataset time = read_dataset(path, "/probes/A/time");
  CHECK(time.dims == std::vector<hsize_t>{3});
  CHECK(time.values == std::vector<double>{0.0, 0.1, 0.2});
  const Dataset v = read_dataset(path, "/probes/A/v");
  CHECK(v.dims == std::vector<hsize_t>{3, 2});
  CHECK(v.values == std::vector<double>{0, -0.0, 1, -1, 2, -2});
  CHECK(read_dataset(path, "/probes/A/stress").values[11] == 6.0);
  CHECK(read_dataset(path, "/probes/B/v").dims == std::vector<hsize_t>{1, 2});
}

TEST_CASE("a root-level series grows by one rank-1 row per sample, reserved names are refused") {
  TempDir t("series");
  const std::string path = t.file("run.h5");
  {
    ResultWriter w(path, "", 1);
    for (int k = 0; k < 3; ++k) w.append_series("energy", 0.5 * k, {{"kinetic", 1.0 + k}, {"strain", -2.0 * k}});
    CHECK_THROWS_AS(w.append_series("energy", 2.0, {{"kinetic", 1.0}}), std::invalid_argument);
    CHECK_THROWS_AS(w.append_series("probes", 2.0, {{"kinetic", 1.0}}), std::invalid_argument);
    CHECK_THROWS_AS(w.append_series("frames", 2.0, {{"kinetic", 1.0}}), std::invalid_argument);
    CHECK_THROWS_AS(w.append_series("energy", 2.0, {{"kinetic", std::nan("")}, {"strain", 0.0}}), InstabilityError);
  }
  const Dataset time = read_dataset(path, "/energy/time");
  CHECK(time.dims == std::vector<hsize_t>{3});
  CHECK(time.values == std::vector<double>{0.0, 0.5, 1.0});
  const Dataset kinetic = read_dataset(path, "/energy/kinetic");
  CHECK(kinetic.dims == std::vector<hsize_t>{3});
  CHECK(kinetic.values == std::vector<double>{1.0, 2.0, 3.0});
  CHECK(read_dataset(path, "/energy/strain").values == std::vector<double>{0.0, -2.0, -4.0});
}

TEST_CASE("a run writes its energy history at every output time and the energy summary attributes") {
  // The Dyka bar at h = L/13 for 2e-5 s, an output every 5e-6 s: 5 samples
  // (t = 0 and four more), the same times as the frames.
  TempDir t("run_energy");
  const std::string path = t.file("dyka.h5");
  RunOptions opt;
  opt.out_file = path;
  const RunSummary s = run_scene(load_scene(OTMPM_SOURCE_DIR "/examples/dyka.toml",
                                            {"grid.cells=[15]", "grid.lower=[-0.020507692307692307]",
                                             "simulation.t_end=2e-5", "output.every=5e-6"}),
                                 opt);
  REQUIRE(s.exit_code == 0);
  const Dataset time = read_dataset(path, "/energy/time");
  CHECK(time.dims == std::vector<hsize_t>{5});
  for (std::size_t k = 0; k < time.values.size(); ++k) {
    char frame[32];
    std::snprintf(frame, sizeof frame, "/frames/%06zu", k);
    CHECK(time.values[k] == read_object_attribute(path, frame, "time"));
  }
  const Dataset kinetic = read_dataset(path, "/energy/kinetic"), strain = read_dataset(path, "/energy/strain");
  // t = 0: no strain; the 7 of 26 particles (mass rho L / 26 each, A = 1 in
  // 1D) whose Gauss positions lie in the left quarter move at 5 m/s.
  CHECK(kinetic.values.front() == s.energy.initial);
  CHECK(kinetic.values.front() == doctest::Approx(7.0 * 7833.0 * 0.1333 / 26.0 * 25.0 / 2.0).epsilon(1e-12));
  CHECK(strain.values.front() == 0.0);
  CHECK(strain.values.back() > 0.0);
  for (const char* zero : {"/energy/external_work", "/energy/reaction_work"}) // no load, a fixed support
    for (double w : read_dataset(path, zero).values) CHECK(w == 0.0);
  CHECK(read_double_attribute(path, "max_energy_ratio") == s.energy.max_energy_ratio());
  CHECK(read_double_attribute(path, "energy_drift") == s.energy.energy_drift());
  CHECK(s.energy.max_energy_ratio() >= 1.0);
  CHECK(s.energy.max_energy_ratio() < 1.05);
}

TEST_CASE("a probe sample with different fields is refused") {
  TempDir t("probe_mismatch");
  ResultWriter w(t.file("run.h5"), "", 1);
  w.append_probe("A", 0.0, {{"v", {1.0}}});
  CHECK_THROWS_AS(w.append_probe("A", 1.0, {{"v", {1.0, 2.0}}}), std::invalid_argument);
  CHECK_THROWS_AS(w.append_probe("A", 1.0, {{"x", {1.0}}}), std::invalid_argument);
}

TEST_CASE("set_attribute overwrites, with any type") {
  TempDir t("attributes");
  const std::string path = t.file("run.h5");
  {
    ResultWriter w(path, "", 1);
    w.set_attribute("status", std::string("unstable: particle 3 det F <= 0"));
    w.set_attribute("status", std::string("ok"));
    w.set_attribute("rms_velocity_error", 0.25);
    w.set_attribute("rms_velocity_error", 0.125);
    w.set_attribute("steps", 41LL);
    w.set_attribute("steps", 42LL);
    w.set_attribute("nodes", std::string("replaced by a number below"));
    w.set_attribute("nodes", 7LL);
  }
  CHECK(read_string_attribute(path, "status") == "ok");
  CHECK(read_double_attribute(path, "rms_velocity_error") == 0.125);
  CHECK(read_double_attribute(path, "steps") == 42.0);
  CHECK(read_double_attribute(path, "nodes") == 7.0);
}

TEST_CASE("a long scene text survives (dense attribute storage)") {
  TempDir t("long_scene");
  const std::string path = t.file("run.h5");
  // 200 kB: well above the 64 KiB limit of compact attribute storage.
  std::string scene;
  while (scene.size() < 200000) scene += "# a comment line that makes the scene text long\n";
  { ResultWriter w(path, scene, 3); }
  CHECK(read_string_attribute(path, "scene") == scene);
}

TEST_CASE("the XDMF sidecar names every frame and points into the .h5 file") {
  TempDir t("xdmf");
  const std::string path = t.file("run.h5");
  ResultWriter w(path, "", 2);
  w.write_frame(0.0, fields_2d());
  w.write_frame(0.25, fields_2d());
  w.write_frame(0.5, fields_2d());
  w.publish(); // the sidecar is otherwise rewritten at most every 0.25 s
  const std::string xdmf = slurp(t.file("run.xdmf"));
  CHECK(count(xdmf, "TopologyType=\"Polyvertex\"") == 3);
  CHECK(count(xdmf, "GeometryType=\"XY\"") == 3);
  for (const char* frame : {"000000", "000001", "000002"})
    CHECK(xdmf.find(std::string("run.h5:/frames/") + frame + "/x<") != std::string::npos);
  CHECK(xdmf.find("<Time Value=\"0.25\"/>") != std::string::npos);
  CHECK(xdmf.find("Name=\"v\" AttributeType=\"Vector\"") != std::string::npos);
  CHECK(xdmf.find("Name=\"density\" AttributeType=\"Scalar\"") != std::string::npos);
  CHECK(xdmf.find("Dimensions=\"2 4\"") != std::string::npos); // stress rows x cols
  CHECK(xdmf.find("</Xdmf>") != std::string::npos);
  CHECK_FALSE(fs::exists(t.file("run.xdmf.tmp")));
}

TEST_CASE("1D frames get a zero-padded XYZ geometry for the sidecar") {
  TempDir t("xdmf1d");
  const std::string path = t.file("bar.h5");
  const std::vector<double> x = {0.5, 1.5, 2.5};
  {
    ResultWriter w(path, "", 1);
    w.write_frame(0.0, {{"x", 3, 1, x.data()}});
  }
  const Dataset x3 = read_dataset(path, "/frames/000000/x3");
  CHECK(x3.dims == std::vector<hsize_t>{3, 3});
  CHECK(x3.values == std::vector<double>{0.5, 0, 0, 1.5, 0, 0, 2.5, 0, 0});
  const std::string xdmf = slurp(t.file("bar.xdmf"));
  CHECK(xdmf.find("GeometryType=\"XYZ\"") != std::string::npos);
  CHECK(xdmf.find("bar.h5:/frames/000000/x3<") != std::string::npos);
}

TEST_CASE("NaN is never written: the frame is refused as an instability") {
  TempDir t("nan");
  const std::string path = t.file("run.h5");
  ResultWriter w(path, "", 2);
  w.write_frame(0.0, fields_2d());
  std::vector<double> v = kV;
  v[3] = std::nan("");
  CHECK_THROWS_AS(w.write_frame(1.0, {{"x", 2, 2, kX.data()}, {"v", 2, 2, v.data()}}), InstabilityError);
  CHECK_THROWS_AS(w.append_probe("A", 1.0, {{"v", {v[3], 0.0}}}), InstabilityError);
  CHECK(w.frames() == 1);
}

TEST_CASE("a writer destroyed without a final status leaves a readable file") {
  TempDir t("early");
  const std::string path = t.file("run.h5");
  {
    ResultWriter w(path, "scene", 2);
    w.write_frame(0.0, fields_2d());
    w.append_probe("A", 0.0, {{"v", {1.0, 2.0}}});
  }
  CHECK(read_string_attribute(path, "status") == "running");
  CHECK(read_dataset(path, "/frames/000000/x").values == kX);
  CHECK(read_dataset(path, "/probes/A/v").values == std::vector<double>{1.0, 2.0});
}

TEST_CASE("a process killed after a frame leaves a readable file") {
  TempDir t("killed");
  const std::string path = t.file("run.h5");
  const pid_t child = ::fork();
  REQUIRE(child >= 0);
  if (child == 0) {
    // The child writes and dies by SIGKILL: no destructor, no close.
    try {
      ResultWriter w(path, "scene", 2);
      w.write_frame(0.0, fields_2d());
      w.append_probe("A", 0.0, {{"v", {1.0, 2.0}}});
      w.append_series("energy", 0.0, {{"kinetic", 4.0}});
      w.write_frame(0.5, fields_2d());
      w.publish();
      ::kill(::getpid(), SIGKILL);
    } catch (...) {
    }
    ::_exit(1);
  }
  int status = 0;
  REQUIRE(::waitpid(child, &status, 0) == child);
  REQUIRE(WIFSIGNALED(status));
  CHECK(read_string_attribute(path, "status") == "running");
  CHECK(read_dataset(path, "/frames/000001/v").values == kV);
  CHECK(read_dataset(path, "/probes/A/time").values == std::vector<double>{0.0});
  CHECK(read_dataset(path, "/energy/kinetic").values == std::vector<double>{4.0});
  CHECK(slurp(t.file("run.xdmf")).find("/frames/000001/x<") != std::string::npos);
}

TEST_CASE("reading problems are InputErrors naming the file") {
  TempDir t("read_errors");
  const std::string path = t.file("run.h5");
  { ResultWriter w(path, "", 1); }
  CHECK_THROWS_AS(read_string_attribute(path, "no_such_attribute"), InputError);
  CHECK_THROWS_AS(read_double_attribute(path, "status"), InputError); // a string, not a number
  CHECK_THROWS_AS(read_string_attribute(t.file("missing.h5"), "status"), InputError);
  CHECK_THROWS_AS(ResultWriter(t.file("no/such/dir/run.h5"), "", 1), InputError);
}
