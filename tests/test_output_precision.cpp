// output.precision = "single" and output.symmetric_tensors (docs/user-guide.md,
// "Result file"): frame datasets stored as 32-bit floats equal the doubles
// rounded to nearest, the sidecar and VTK files say so, a symmetric tensor
// keeps exactly the upper-triangle components of the full one, and a restart
// carries the layout over. Values are compared with ==: a float holds the
// rounded double exactly and HDF5 converts float to double exactly.
#include "otmpm/io/results.hpp"

#include "otmpm/core.hpp"
#include "otmpm/particles/output_fields.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/scene/scene.hpp"
#include "otmpm/scene/validate.hpp"

#include "h5_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

using namespace otmpm;
using test::TempDir;
namespace fs = std::filesystem;

namespace {

/// A frame dataset read back as doubles, with its stored element size and class.
struct Stored {
  std::vector<hsize_t> dims;
  std::vector<double> values;
  std::size_t element_bytes = 0;
  H5T_class_t cls = H5T_NO_CLASS;
  std::string components; ///< the attribute `components`, "" when absent
};

Stored read_stored(const std::string& path, const std::string& name) {
  Stored out;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(file >= 0);
  const hid_t set = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  REQUIRE(set >= 0);
  const hid_t type = H5Dget_type(set);
  out.element_bytes = H5Tget_size(type);
  out.cls = H5Tget_class(type);
  H5Tclose(type);
  const hid_t space = H5Dget_space(set);
  out.dims.resize(static_cast<std::size_t>(H5Sget_simple_extent_ndims(space)));
  H5Sget_simple_extent_dims(space, out.dims.data(), nullptr);
  out.values.resize(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
  if (!out.values.empty()) CHECK(H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.values.data()) >= 0);
  H5Sclose(space);
  if (H5Aexists(set, "components") > 0) {
    const hid_t attr = H5Aopen(set, "components", H5P_DEFAULT);
    const hid_t atype = H5Aget_type(attr);
    std::string s(H5Tget_size(atype), '\0');
    CHECK(H5Aread(attr, atype, s.data()) >= 0);
    out.components = s.c_str();
    H5Tclose(atype);
    H5Aclose(attr);
  }
  H5Dclose(set);
  H5Fclose(file);
  return out;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<double> rounded_to_float(const std::vector<double>& v) {
  std::vector<double> out;
  for (double x : v) out.push_back(static_cast<double>(static_cast<float>(x)));
  return out;
}

/// The 3D Dyka bar for a few steps, with every tensor field in the frames.
RunSummary run_bar_3d(const std::string& out, const std::vector<std::string>& extra) {
  std::vector<std::string> sets{"simulation.t_end=4e-6", "output.every=2e-6",
                                "output.fields=[\"x\",\"v\",\"stress\",\"strain\",\"F\",\"density\"]"};
  sets.insert(sets.end(), extra.begin(), extra.end());
  RunOptions opt;
  opt.out_file = out;
  return run_scene(load_scene(OTMPM_SOURCE_DIR "/examples/dyka_3d.toml", sets), opt);
}

} // namespace

TEST_CASE("single precision: frame datasets are float32, equal to the doubles rounded to nearest") {
  TempDir t("single");
  const std::string path = t.file("run.h5");
  // Values a float cannot hold exactly, one below its smallest subnormal, one near its largest.
  const std::vector<double> x = {0.1, 1.0 / 3.0, 2.0, 1e-50};
  const std::vector<double> s = {1.0 + 1e-12, -3.4e38, 0.7, 5e-324, 1, 2, 3, 4};
  {
    ResultOptions o;
    o.single_precision = true;
    ResultWriter w(path, "", 2, o);
    w.write_frame(0.125, {{"x", 2, 2, x.data()}, {"stress", 2, 4, s.data()}});
    w.append_series("energy", 0.125, {{"kinetic", 0.1}});
    w.publish();
  }
  const Stored sx = read_stored(path, "/frames/000000/x"), ss = read_stored(path, "/frames/000000/stress");
  CHECK(sx.cls == H5T_FLOAT);
  CHECK(sx.element_bytes == 4);
  CHECK(ss.element_bytes == 4);
  CHECK(sx.dims == std::vector<hsize_t>{2, 2});
  CHECK(sx.values == rounded_to_float(x));
  CHECK(ss.values == rounded_to_float(s));
  CHECK(sx.values[0] != x[0]); // really rounded: 0.1 is not a float
  // Series, times and attributes stay double.
  const Stored kinetic = read_stored(path, "/energy/kinetic");
  CHECK(kinetic.element_bytes == 8);
  CHECK(kinetic.values == std::vector<double>{0.1});
  const std::string xdmf = slurp(t.file("run.xdmf"));
  CHECK(xdmf.find("Precision=\"8\"") != std::string::npos); // the connectivity (integers)
  CHECK(xdmf.find("NumberType=\"Float\" Precision=\"8\"") == std::string::npos);
  CHECK(xdmf.find("NumberType=\"Float\" Precision=\"4\"") != std::string::npos);
}

TEST_CASE("single precision: a value beyond the float range is refused as an instability, nothing written") {
  TempDir t("single_range");
  const std::string path = t.file("run.h5");
  ResultOptions o;
  o.single_precision = true;
  ResultWriter w(path, "", 1, o);
  const std::vector<double> x = {0.5, 1.5}, big = {1.0, 1e39};
  w.write_frame(0.0, {{"x", 2, 1, x.data()}});
  CHECK_THROWS_AS(w.write_frame(1.0, {{"x", 2, 1, x.data()}, {"stress", 2, 1, big.data()}}), InstabilityError);
  CHECK(w.frames() == 1);
  // A double file takes the same value.
  ResultWriter d(t.file("double.h5"), "", 1);
  d.write_frame(0.0, {{"x", 2, 1, x.data()}, {"stress", 2, 1, big.data()}});
  CHECK(d.frames() == 1);
}

TEST_CASE("the default stays double: 8-byte datasets, Precision 8, no components attribute") {
  TempDir t("double");
  const std::string path = t.file("run.h5");
  const std::vector<double> x = {0.1, 0.2};
  {
    ResultWriter w(path, "", 1);
    w.write_frame(0.0, {{"x", 2, 1, x.data()}});
  }
  const Stored sx = read_stored(path, "/frames/000000/x");
  CHECK(sx.element_bytes == 8);
  CHECK(sx.values == x);
  CHECK(sx.components.empty());
  CHECK(slurp(t.file("run.xdmf")).find("Precision=\"4\"") == std::string::npos);
}

TEST_CASE("pack_symmetric keeps the upper triangle in the XDMF Tensor6 order") {
  CHECK(symmetric_components(3) == "xx xy xz yy yz zz");
  CHECK(symmetric_components(2) == "xx xy yy");
  CHECK(symmetric_components(1) == "xx");
  std::vector<double> out;
  const std::vector<double> full3 = {11, 12, 13, 12, 22, 23, 13, 23, 33, 1, 2, 3, 2, 4, 5, 3, 5, 6};
  pack_symmetric(full3.data(), 2, 3, out);
  CHECK(out == std::vector<double>{11, 12, 13, 22, 23, 33, 1, 2, 3, 4, 5, 6});
  const std::vector<double> full2 = {11, 12, 12, 22};
  pack_symmetric(full2.data(), 1, 2, out);
  CHECK(out == std::vector<double>{11, 12, 22});
  CHECK(is_symmetric_tensor_field("stress"));
  CHECK(is_symmetric_tensor_field("strain"));
  CHECK_FALSE(is_symmetric_tensor_field("F"));
  CHECK_THROWS_AS(pack_symmetric(full2.data(), 1, 4, out), std::invalid_argument);
}

TEST_CASE("a field's components must name its columns") {
  TempDir t("components");
  ResultWriter w(t.file("run.h5"), "", 2);
  const std::vector<double> x = {0, 1}, s = {1, 2, 3};
  CHECK_THROWS_AS(w.write_frame(0.0, {{"x", 1, 2, x.data()}, {"stress", 1, 3, s.data(), -1, 0, "xx xy xz yy"}}),
                  std::invalid_argument);
  w.write_frame(0.0, {{"x", 1, 2, x.data()}, {"stress", 1, 3, s.data(), -1, 0, "xx xy yy"}});
  CHECK(w.frames() == 1);
}

TEST_CASE("a 3D run with symmetric tensors: stress and strain by 6 components equal to the full tensors'") {
  TempDir t("symmetric_run");
  const std::string full = t.file("full.h5"), sym = t.file("sym.h5"), single = t.file("single.h5");
  REQUIRE(run_bar_3d(full, {}).exit_code == 0);
  REQUIRE(run_bar_3d(sym, {"output.symmetric_tensors=true", "output.format=[\"hdf5\",\"vtp\"]"}).exit_code == 0);
  REQUIRE(run_bar_3d(single, {"output.symmetric_tensors=true", "output.precision=\"single\""}).exit_code == 0);
  const char* frame = "/frames/000002/";
  for (const char* field : {"stress", "strain"}) {
    INFO(field);
    const Stored a = read_stored(full, std::string(frame) + field), b = read_stored(sym, std::string(frame) + field);
    REQUIRE(a.dims.size() == 2);
    REQUIRE(a.dims[1] == 9);
    CHECK(b.dims == std::vector<hsize_t>{a.dims[0], 6});
    CHECK(b.components == "xx xy xz yy yz zz");
    CHECK(b.element_bytes == 8);
    std::vector<double> packed;
    pack_symmetric(a.values.data(), a.dims[0], 3, packed);
    CHECK(b.values == packed);
    // The full tensors are symmetric, so the six components lose nothing.
    bool symmetric = true;
    for (std::size_t p = 0; p < a.dims[0]; ++p)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) symmetric = symmetric && a.values[p * 9 + i * 3 + j] == a.values[p * 9 + j * 3 + i];
    CHECK(symmetric);
    bool nonzero = false;
    for (double v : b.values) nonzero = nonzero || v != 0.0;
    CHECK(nonzero); // the bar is loaded: the comparison is not of zeros
    const Stored c = read_stored(single, std::string(frame) + field);
    CHECK(c.element_bytes == 4);
    CHECK(c.components == "xx xy xz yy yz zz");
    CHECK(c.values == rounded_to_float(packed));
  }
  // F is not symmetric: all 9 components, in every layout.
  CHECK(read_stored(sym, std::string(frame) + "F").dims[1] == 9);
  CHECK(read_stored(sym, std::string(frame) + "F").values == read_stored(full, std::string(frame) + "F").values);
  // Everything else is the same bits.
  for (const char* field : {"x", "v", "density"})
    CHECK(read_stored(sym, std::string(frame) + field).values == read_stored(full, std::string(frame) + field).values);
  CHECK(read_stored(sym, "/probes/A/stress").values == read_stored(full, "/probes/A/stress").values);
  const std::string xdmf = slurp(t.file("sym.xdmf"));
  CHECK(xdmf.find("Name=\"stress\" AttributeType=\"Tensor6\"") != std::string::npos);
  CHECK(xdmf.find("Name=\"F\" AttributeType=\"Tensor\"") != std::string::npos);
  // The VTK frames name the six components.
  const std::string vtp = slurp(t.file("sym_vtk/frame_000002.vtp"));
  CHECK(vtp.find("Name=\"stress\" NumberOfComponents=\"6\" ComponentName0=\"xx\" ComponentName1=\"xy\"") !=
        std::string::npos);
  const std::string vtp_single = slurp(t.file("sym_vtk/frame_000000.vtp"));
  CHECK(vtp_single.find("type=\"Float64\" Name=\"stress\"") != std::string::npos);
}

TEST_CASE("single precision VTK frames hold Float32 points and point data, the time stays Float64") {
  TempDir t("single_vtk");
  const std::string out = t.file("bar.h5");
  REQUIRE(run_bar_3d(out, {"output.precision=\"single\"", "output.format=[\"hdf5\",\"vtu\"]"}).exit_code == 0);
  const std::string vtu = slurp(t.file("bar_vtk/frame_000001.vtu"));
  CHECK(vtu.find("type=\"Float32\" Name=\"Points\"") != std::string::npos);
  CHECK(vtu.find("type=\"Float32\" Name=\"stress\" NumberOfComponents=\"9\"") != std::string::npos);
  CHECK(vtu.find("type=\"Float64\" Name=\"TimeValue\"") != std::string::npos);
  CHECK(vtu.find("type=\"Float64\" Name=\"v\"") == std::string::npos);
}

TEST_CASE("the output keys are read, validated and kept in the stored scene only when set") {
  const Scene d = load_scene(OTMPM_SOURCE_DIR "/examples/dyka.toml");
  CHECK(d.output.precision == "double");
  CHECK_FALSE(d.output.symmetric_tensors);
  CHECK(to_toml(d).find("precision") == std::string::npos);
  CHECK(to_toml(d).find("symmetric_tensors") == std::string::npos);
  const Scene s = load_scene(OTMPM_SOURCE_DIR "/examples/dyka.toml",
                             {"output.precision=\"single\"", "output.symmetric_tensors=true"});
  CHECK(s.output.precision == "single");
  CHECK(s.output.symmetric_tensors);
  CHECK(to_toml(s).find("precision = 'single'") != std::string::npos);
  CHECK(to_toml(s).find("symmetric_tensors = true") != std::string::npos);
  CHECK_THROWS_AS(load_scene(OTMPM_SOURCE_DIR "/examples/dyka.toml", {"output.precision=\"half\""}), InputError);
  CHECK_THROWS_AS(load_scene(OTMPM_SOURCE_DIR "/examples/dyka.toml", {"output.symmetric_tensors=1"}), InputError);
  Scene bad = d;
  bad.output.precision = "float";
  CHECK_THROWS_AS(validate_scene(bad, 1), InputError);
}

namespace {

/// Every dataset of a result file (path -> shape and values read as doubles)
/// and every attribute of the frames; root attributes are wall times or
/// summaries that a writer thread does not touch.
std::map<std::string, std::vector<double>> datasets(const std::string& path) {
  std::map<std::string, std::vector<double>> out;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(file >= 0);
  const std::vector<std::string> names = otmpm::test::dataset_names(file);
  H5Fclose(file);
  for (const std::string& n : names) {
    const Stored s = read_stored(path, "/" + n);
    std::vector<double> v(s.dims.begin(), s.dims.end());
    v.push_back(static_cast<double>(s.element_bytes));
    v.insert(v.end(), s.values.begin(), s.values.end());
    out[n] = std::move(v);
  }
  for (std::size_t k = 0;; ++k) {
    char frame[32];
    std::snprintf(frame, sizeof frame, "frames/%06zu", k);
    if (!out.count(std::string(frame) + "/x")) break;
    const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    const hid_t attr = H5Aopen_by_name(f, frame, "time", H5P_DEFAULT, H5P_DEFAULT);
    double t = 0;
    H5Aread(attr, H5T_NATIVE_DOUBLE, &t);
    H5Aclose(attr);
    H5Fclose(f);
    out[std::string(frame) + "@time"] = {t};
  }
  return out;
}

} // namespace

TEST_CASE("background output (the writer thread of otmpm run) writes the same file as writing on the stepping thread") {
  TempDir t("background");
  struct Case {
    const char* scene;
    std::vector<std::string> sets;
  };
  const std::vector<Case> cases{
      {"/examples/dyka_3d.toml", {"simulation.t_end=4e-6", "output.every=1e-6", "output.symmetric_tensors=true",
                                  "output.precision=\"single\"", "output.format=[\"hdf5\",\"vtp\"]"}},
      {"/examples/sliding_block.toml", {"simulation.t_end=0.1", "output.every=0.01"}}, // walls, energy, probes
  };
  int index = 0;
  for (const Case& c : cases) {
    INFO(std::string(c.scene));
    ++index;
    std::map<std::string, std::vector<double>> files[2];
    for (int background = 0; background < 2; ++background) {
      RunOptions opt;
      opt.out_file = t.file("run" + std::to_string(index) + "_" + std::to_string(background) + ".h5");
      opt.background_output = background == 1;
      const RunSummary s = run_scene(load_scene(std::string(OTMPM_SOURCE_DIR) + c.scene, c.sets), opt);
      REQUIRE(s.exit_code == 0);
      files[background] = datasets(opt.out_file);
      CHECK(read_string_attribute(opt.out_file, "status") == "ok");
    }
    CHECK(files[0].size() > 5);
    CHECK(files[0] == files[1]);
  }
}

TEST_CASE("check_frame throws what write_frame would, and writes nothing") {
  // The writer thread's run checks each frame with check_frame on the
  // stepping thread, so that an instability stops the run at that output time.
  TempDir t("check_frame");
  ResultOptions o;
  o.single_precision = true;
  ResultWriter w(t.file("run.h5"), "", 1, o);
  const std::vector<double> x = {0.5, 1.5}, big = {1.0, -1e39}, nan = {1.0, std::nan("")};
  CHECK_THROWS_AS(w.check_frame(0.0, {{"x", 2, 1, x.data()}, {"stress", 2, 1, big.data()}}), InstabilityError);
  CHECK_THROWS_AS(w.check_frame(0.0, {{"x", 2, 1, x.data()}, {"v", 2, 1, nan.data()}}), InstabilityError);
  CHECK_THROWS_AS(w.check_frame(0.0, {{"x", 2, 1, x.data()}, {"x", 2, 1, x.data()}}), std::invalid_argument);
  CHECK_THROWS_AS(w.check_frame(std::nan(""), {{"x", 2, 1, x.data()}}), InstabilityError);
  CHECK_NOTHROW(w.check_frame(0.0, {{"x", 2, 1, x.data()}}));
  CHECK(w.frames() == 0);
}
