// Plane strain's sigma_zz in the result file (docs/user-guide.md, "Result
// file size"): with output.symmetric_tensors a 2D `stress` holds 4 columns
// "xx xy yy zz" - the in-plane bits of the default layout plus sigma_zz -,
// output.fields "stress_zz" one column with the same sigma_zz, the strain
// keeps 3 columns, the sidecar a 4-component attribute; the values follow the
// models' plane-strain relations; bad uses of stress_zz name output.fields.
#include "otmpm/io/hdf5.hpp"
#include "otmpm/particles/output_fields.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/scene/scene.hpp"
#include "otmpm/scene/validate.hpp"

#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <cmath>
#include <fstream>
#include <sstream>

using namespace otmpm;
using test::TempDir;

namespace {

/// A frame dataset: its values as doubles (rows x cols) and its attribute `components` ("" when absent).
struct Dataset {
  h5::Matrix<double> m;
  std::string components;
};

Dataset read_dataset(const std::string& path, const std::string& frame, const std::string& name) {
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(id >= 0);
  const h5::Handle file(id, H5Fclose);
  const h5::Handle g = h5::open_group(file.get(), "frames/" + frame, path);
  Dataset d;
  d.m = h5::read_double_matrix(g.get(), name, path);
  const h5::Handle set(H5Dopen2(g.get(), name.c_str(), H5P_DEFAULT), H5Dclose);
  if (h5::has_attribute(set.get(), "components")) d.components = h5::read_string(set.get(), "components", path);
  return d;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// A scene run to `out` with `sets` (the scene's own output.fields unless set).
RunSummary run(const std::string& scene, const std::string& out, const std::vector<std::string>& sets) {
  RunOptions opt;
  opt.out_file = out;
  return run_scene(load_scene(std::string(OTMPM_SOURCE_DIR) + "/examples/" + scene, sets), opt);
}

/// The file's 2D stress of `layout` compared with the default layout `full`:
/// columns xx xy yy equal to the full tensor's bits, zz equal to stress_zz.
void check_layout(const Dataset& full, const Dataset& sym, const Dataset& zz) {
  REQUIRE(full.m.cols == 4);
  REQUIRE(sym.m.cols == 4);
  REQUIRE(zz.m.cols == 1);
  REQUIRE(sym.m.rows == full.m.rows);
  REQUIRE(zz.m.rows == full.m.rows);
  CHECK(sym.components == "xx xy yy zz");
  CHECK(full.components.empty());
  CHECK(zz.components.empty());
  bool same = true;
  for (std::size_t p = 0; p < full.m.rows; ++p) {
    const double* f = &full.m.values[p * 4];
    const double* s = &sym.m.values[p * 4];
    same = same && s[0] == f[0] && s[1] == f[1] && s[2] == f[3] && f[1] == f[2] && s[3] == zz.m.values[p];
  }
  CHECK(same);
}

} // namespace

TEST_CASE("2D symmetric stress: 4 columns xx xy yy zz, the in-plane bits of the default layout and sigma_zz") {
  TempDir t("szz_layout");
  // The 2D Dyka bar with nu = 0.3 (linear_elastic): sigma_zz = nu (sigma_xx
  // + sigma_yy) is plane strain of Hooke's law, checked against the stored
  // in-plane stress (accumulated by the update), while the file's sigma_zz
  // comes from the accumulated strain (lambda tr eps).
  const std::vector<std::string> base{"simulation.t_end=2e-5", "output.every=1e-5", "material.steel.poisson=0.3",
                                      "output.format=[\"hdf5\",\"vtp\"]"};
  auto with = [&](std::vector<std::string> extra) {
    extra.insert(extra.begin(), base.begin(), base.end());
    return extra;
  };
  const std::string full = t.file("full.h5"), sym = t.file("sym.h5");
  REQUIRE(run("dyka_2d.toml", full, with({"output.fields=[\"x\",\"v\",\"stress\",\"strain\",\"stress_zz\"]"}))
              .exit_code == 0);
  REQUIRE(run("dyka_2d.toml", sym,
              with({"output.fields=[\"x\",\"v\",\"stress\",\"strain\",\"stress_zz\"]", "output.symmetric_tensors=true"}))
              .exit_code == 0);
  for (const char* frame : {"000000", "000001", "000002"}) {
    INFO(frame);
    const Dataset a = read_dataset(full, frame, "stress"), b = read_dataset(sym, frame, "stress");
    const Dataset zz = read_dataset(sym, frame, "stress_zz");
    check_layout(a, b, zz);
    CHECK(read_dataset(full, frame, "stress_zz").m.values == zz.m.values); // the layout does not change sigma_zz
    // The strain keeps 3 columns (eps_zz = 0 in plane strain).
    const Dataset e = read_dataset(sym, frame, "strain");
    CHECK(e.m.cols == 3);
    CHECK(e.components == "xx xy yy");
    double largest = 0.0, worst = 0.0;
    for (std::size_t p = 0; p < a.m.rows; ++p) {
      const double sxx = a.m.values[p * 4], syy = a.m.values[p * 4 + 3];
      largest = std::max(largest, std::abs(zz.m.values[p]));
      worst = std::max(worst, std::abs(zz.m.values[p] - 0.3 * (sxx + syy)));
    }
    // Round-off of stresses accumulated over ~100 steps: 5e-16 n E (E = 200e9 Pa).
    CHECK(worst <= 5e-16 * 100 * 200e9);
    if (std::string(frame) != "000000") CHECK(largest > 1e6); // the bar is loaded
  }
  // The sidecar: a 4-component attribute (XDMF Matrix, as the default 2 x 2 one), and the scalar.
  const std::string xdmf = slurp(t.file("sym.xdmf"));
  CHECK(xdmf.find("Name=\"stress\" AttributeType=\"Matrix\"") != std::string::npos);
  CHECK(xdmf.find("Name=\"stress_zz\" AttributeType=\"Scalar\"") != std::string::npos);
  CHECK(xdmf.find("/frames/000001/stress</DataItem>") != std::string::npos);
  const std::size_t at = xdmf.find("Name=\"stress\" AttributeType");
  REQUIRE(at != std::string::npos);
  const std::string dims = "Dimensions=\"" + std::to_string(read_dataset(sym, "000001", "x").m.rows) + " 4\"";
  CHECK(xdmf.find(dims, at) < xdmf.find("</Attribute>", at)); // one row per particle, 4 columns
  // The VTK frames name the four components.
  const std::string vtp = slurp(t.file("sym_vtk/frame_000001.vtp"));
  CHECK(vtp.find("Name=\"stress\" NumberOfComponents=\"4\" ComponentName0=\"xx\" ComponentName1=\"xy\" "
                 "ComponentName2=\"yy\" ComponentName3=\"zz\"") != std::string::npos);
}

TEST_CASE("2D symmetric stress of a plastic run: sigma_zz from b_e agrees with the stored in-plane stress") {
  TempDir t("szz_plastic");
  // The column collapse (drucker_prager, Hencky on b_e) for a few steps: the
  // trace of the Kirchhoff stress is 3 K tr(e) = 3/2 K ln det b_e, so
  // sigma_zz = 3/2 K ln(det b_e) / J - sigma_xx - sigma_yy from the stored
  // in-plane stress, b_e and F - a relation the file's sigma_zz (from ln b_zz
  // and ln det B) meets only if it is the model's sigma_zz.
  const std::string out = t.file("collapse.h5");
  REQUIRE(run("column_collapse.toml", out,
              {"simulation.t_end=0.05", "output.every=0.025", "output.symmetric_tensors=true",
               "output.fields=[\"x\",\"stress\",\"F\",\"elastic_left_cauchy_green\",\"plastic_strain\"]"})
              .exit_code == 0);
  const Scene scene = load_scene(std::string(OTMPM_SOURCE_DIR) + "/examples/column_collapse.toml");
  const double E = scene.materials[0].young, nu = scene.materials[0].poisson;
  const double K = E / (3 * (1 - 2 * nu));
  const Dataset s = read_dataset(out, "000002", "stress"), F = read_dataset(out, "000002", "F");
  const Dataset b = read_dataset(out, "000002", "elastic_left_cauchy_green");
  const Dataset ep = read_dataset(out, "000002", "plastic_strain");
  REQUIRE(s.m.cols == 4);
  CHECK(s.components == "xx xy yy zz");
  double largest = 0.0, worst = 0.0, plastic = 0.0;
  for (std::size_t p = 0; p < s.m.rows; ++p) {
    const double* f = &F.m.values[p * 4];
    const double* be = &b.m.values[p * 6]; // xx yy zz xy yz xz
    const double J = f[0] * f[3] - f[1] * f[2];
    const double det_b = (be[0] * be[1] - be[3] * be[3]) * be[2];
    const double zz = 1.5 * K * std::log(det_b) / J - s.m.values[p * 4] - s.m.values[p * 4 + 2];
    largest = std::max(largest, std::abs(s.m.values[p * 4 + 3]));
    worst = std::max(worst, std::abs(s.m.values[p * 4 + 3] - zz));
    plastic = std::max(plastic, ep.m.values[p]);
  }
  MESSAGE("column collapse: largest |sigma_zz| ", largest, " Pa, difference ", worst, " Pa, plastic strain ", plastic);
  CHECK(largest > 1e3); // gravity loads the column (rho g H ~ 1e4 Pa)
  CHECK(plastic > 0.0); // and it yields
  // Both sides are sums of stresses of magnitude K |e| <= K * 1e-2 rounded a
  // few times: 1e-13 K is far above their round-off and far below the ~1e3 Pa signal.
  CHECK(worst <= 1e-13 * K);
}

TEST_CASE("stress_zz: only in 2D, an InputError naming output.fields") {
  for (const char* scene : {"dyka.toml", "dyka_3d.toml"}) {
    INFO(scene);
    try {
      (void)load_scene(std::string(OTMPM_SOURCE_DIR) + "/examples/" + scene,
                       {"output.fields=[\"x\",\"stress_zz\"]"});
      FAIL("no InputError");
    } catch (const InputError& e) {
      const std::string what = e.what();
      CHECK(what.find("output.fields") != std::string::npos);
      CHECK(what.find("stress_zz") != std::string::npos);
      CHECK(what.find("simulation.dimension = 2") != std::string::npos);
    }
    Scene s = load_scene(std::string(OTMPM_SOURCE_DIR) + "/examples/" + scene);
    s.output.fields.push_back("stress_zz");
    try {
      validate_scene(s, s.simulation.dimension);
      FAIL("no InputError");
    } catch (const InputError& e) {
      CHECK(std::string(e.what()).find("output.fields") != std::string::npos);
    }
  }
  const Scene s = load_scene(std::string(OTMPM_SOURCE_DIR) + "/examples/dyka_2d.toml",
                             {"output.fields=[\"x\",\"stress_zz\"]"});
  CHECK(s.output.fields == std::vector<std::string>{"x", "stress_zz"});
  CHECK_NOTHROW(validate_scene(s, 2));
  CHECK_THROWS_AS(load_scene(std::string(OTMPM_SOURCE_DIR) + "/examples/dyka_2d.toml",
                             {"output.fields=[\"stress_zz\",\"stress_zz\"]"}),
                  InputError);
}

TEST_CASE("plane_stress_components and pack_plane_stress: the in-plane upper triangle, then zz") {
  CHECK(plane_stress_components() == "xx xy yy zz");
  const std::vector<double> full = {11, 12, 12, 22, 1, 2, 2, 4}, zz = {33, 5};
  std::vector<double> out;
  pack_plane_stress(full.data(), zz.data(), 2, out);
  CHECK(out == std::vector<double>{11, 12, 22, 33, 1, 2, 4, 5});
}
