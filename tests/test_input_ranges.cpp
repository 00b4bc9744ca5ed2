// Every number that enters a run meets one range check with one message
// form, whatever its source: a particle file's column is checked by the
// ParameterSpec of the scene key of the same quantity (material.NAME.density
// for `density`, StateSpec::range for a state variable of the body's model,
// looped over the table of models), an unknown column and an HDF5 file that
// declares more rows than the cap are refused when the file's layout is read.
// Also the set-up checks of the geometry: a wall normal or cylinder axis
// whose square overflows or underflows is the direction it gives (not the
// zero vector), a body that starts behind a wall is refused naming wall,
// body and count, and a file body of tiny particles far apart is indexed
// without an integer overflow (the sanitizer build runs this test).
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/assembly/seeding.hpp"
#include "otmpm/geometry/shapes.hpp"
#include "otmpm/materials/material.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/scene/resources.hpp"
#include "otmpm/scene/validate.hpp"

#include "input_error.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <string>

using namespace otmpm;

namespace {

using test::input_error_of;

/// What follows the source of a message ("FILE:LINE: key 'K': " or
/// "FILE:LINE: column 'C': "): the reason itself.
std::string reason(const std::string& message) {
  const auto at = message.rfind("': ");
  return at == std::string::npos ? message : message.substr(at + 3);
}

/// A 2D scene on [0, 1]^2 (20 x 20 cells) with material "m" of `model`
/// (extra keys in `material`) and the bodies and walls of `rest`.
std::string scene_2d(const std::string& model, const std::string& material, const std::string& rest,
                     const std::string& mode = "mpm") {
  return "[simulation]\ndimension = 2\nmode = \"" + mode +
         "\"\nintegrator = \"musl\"\nt_end = 0.002\ncfl = 0.3\n[basis]\nkind = \"linear\"\n"
         "[grid]\nlower = [0.0, 0.0]\nupper = [1.0, 1.0]\ncells = [20, 20]\n"
         "[[material]]\nname = \"m\"\nmodel = \"" +
         model + "\"\ndensity = 1000.0\nyoung = 1.0e6\npoisson = 0.3\n" + material + rest;
}

/// A file body of `path` made of material "m".
std::string file_body(const std::string& path) {
  return "[[body]]\nname = \"f\"\nmaterial = \"m\"\nshape = \"file\"\nfile = \"" + path + "\"\n";
}

/// 144 particles on a 12 x 12 lattice in [0.3, 0.6]^2 with the extra column
/// `column` (none when empty) holding `value` in every row.
void write_block(const std::string& path, const std::string& column = "", const std::string& value = "") {
  std::ofstream out(path);
  out << "x, y, volume" << (column.empty() ? "" : ", " + column) << "\n";
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j)
      out << 0.3125 + 0.025 * i << ", " << 0.3125 + 0.025 * j << ", 0.000625" << (column.empty() ? "" : ", " + value)
          << "\n";
}

/// The keys a model needs besides density, young and poisson, for a scene.
/// A value in the range of parameter p that also meets the checks across
/// parameters of the scene's material (density 1000): mu_i's grains are
/// denser than the bulk, packed at 1000 / 2500 = 0.4 above its critical packing.
std::string value_of(const ParameterSpec& p) {
  if (p.key == "grain_density") return "2500.0";
  if (p.key == "critical_packing") return "0.3";
  return std::to_string(std::max(1.0, p.lower + 1.0));
}

std::string required_keys(const MaterialModel& model) {
  std::string keys;
  for (const ParameterSpec& p : model.parameters)
    if (!p.fallback && p.key.find('.') == std::string_view::npos)
      keys += std::string(p.key) + " = " + value_of(p) + "\n";
  return keys;
}

} // namespace

TEST_CASE("a particle file's density column meets the check of material.NAME.density, with its message") {
  test::TempDir dir("ranges_density");
  for (const std::string value : {"-1000", "0", "-1e-300"}) {
    CAPTURE(value);
    write_block(dir.file("b.csv"), "density", value);
    std::ofstream(dir.file("s.toml")) << scene_2d("linear_elastic", "", file_body(dir.file("b.csv")));
    const std::string from_file = input_error_of([&] { load_scene(dir.file("s.toml")); });
    std::string text = scene_2d("linear_elastic", "", "[[body]]\nmaterial = \"m\"\nlower = [0.3, 0.3]\nupper = [0.6, 0.6]\n");
    text.replace(text.find("density = 1000.0"), 16, "density = " + value);
    const std::string from_key = input_error_of([&] { parse_scene(text, "key.toml"); });
    CHECK(from_file.find("b.csv:2: column 'density': ") != std::string::npos);
    CHECK(from_key.find("key 'material.m.density': ") != std::string::npos);
    CHECK(reason(from_file) == reason(from_key)); // one check, one message form
  }
  // In range: read, and the first step is the seeded particles' (see test_scenes_check).
  write_block(dir.file("b.csv"), "density", "2000");
  std::ofstream(dir.file("s.toml")) << scene_2d("linear_elastic", "", file_body(dir.file("b.csv")));
  CHECK(load_scene(dir.file("s.toml")).bodies[0].file_min_density == 2000.0);
}

TEST_CASE("a particle file's state columns meet the range of the model's state variable (every model)") {
  test::TempDir dir("ranges_state");
  for (const MaterialModel* model : material_models()) {
    CAPTURE(model->name);
    const std::string scene = scene_2d(std::string(model->name), required_keys(*model), file_body(dir.file("b.csv")));
    std::ofstream(dir.file("s.toml")) << scene;
    for (const StateSpec& st : model->state) {
      if (st.width != 1) continue; // a file column is one value per particle
      CAPTURE(st.name);
      const ParameterSpec range = st.range();
      // the lowest value is accepted (seeded and set), one below is refused with the range's message
      const double lowest = range.lower > -kUnbounded ? range.lower : -1e6;
      write_block(dir.file("b.csv"), std::string(st.name), format_number(lowest));
      CHECK(input_error_of([&] { assemble_parts<2>(load_scene(dir.file("s.toml"))); }) == "");
      if (range.lower > -kUnbounded) {
        write_block(dir.file("b.csv"), std::string(st.name), format_number(range.lower - 5.0));
        const std::string why = input_error_of([&] { load_scene(dir.file("s.toml")); });
        CHECK(why.find("b.csv:2: column '" + std::string(st.name) + "': " + range.check(range.lower - 5.0)) !=
              std::string::npos);
      }
    }
    // A column that is no state variable of this model: refused at the header, naming what may be there.
    write_block(dir.file("b.csv"), "colour", "1");
    const std::string why = input_error_of([&] { load_scene(dir.file("s.toml")); });
    CHECK(why.find("b.csv:1: column 'colour' is not one of the columns") != std::string::npos);
    CHECK(why.find("x, y, vx, vy, volume, density") != std::string::npos);
  }
}

TEST_CASE("an HDF5 particle file declaring more rows than the cap is refused as soon as its layout is read") {
  // 2e9 rows of fill values in a 1.7 kB file: refused in a moment, not after streaming them.
  test::TempDir dir("ranges_rows");
  const std::string path = dir.file("huge.h5");
  {
    const hid_t f = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    for (const auto& [name, cols] : {std::pair{"x", 2}, std::pair{"volume", 1}}) {
      const hsize_t dims[2] = {2000000000ULL, static_cast<hsize_t>(cols)}, chunk[2] = {65536, static_cast<hsize_t>(cols)};
      const hid_t space = H5Screate_simple(cols == 1 ? 1 : 2, dims, nullptr);
      const hid_t plist = H5Pcreate(H5P_DATASET_CREATE);
      H5Pset_chunk(plist, cols == 1 ? 1 : 2, chunk);
      H5Dclose(H5Dcreate2(f, name, H5T_IEEE_F64LE, space, H5P_DEFAULT, plist, H5P_DEFAULT));
      H5Pclose(plist);
      H5Sclose(space);
    }
    H5Fclose(f);
  }
  const auto start = std::chrono::steady_clock::now();
  // read for one process (as the command line does): at most kMaxRankParticles rows
  const std::string why =
      input_error_of([&] { parse_scene(scene_2d("linear_elastic", "", file_body(path)), "s.toml", {}, 1); });
  CHECK(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() < 1.0);
  CHECK(why.find("huge.h5: dataset 'x': 2000000000 rows; at most 100000000 particles are allowed") != std::string::npos);
}

TEST_CASE("each scalar scene key is checked by its row, by the reader and by validate_scene alike") {
  // A value just outside each row's range: the reader's message (--set) and
  // validate_scene's on the same value set in code (a Scene built in code or
  // from a Python dict) both end in the row's reason.
  using namespace scene_keys;
  const std::string text =
      scene_2d("linear_elastic", "",
               "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.3, 0.3]\nupper = [0.6, 0.6]\n"
               "[[wall]]\nname = \"w\"\npoint = [0.0, 0.1]\nnormal = [0.0, 1.0]\n[contact]\nfriction = 0.1\n");
  struct Key {
    std::string key;
    const ParameterSpec* spec;
    double* (*field)(Scene&);
  };
  const std::vector<Key> keys{
      {"simulation.t_end", &kTEnd, [](Scene& s) { return &s.simulation.t_end; }},
      {"simulation.cfl", &kCfl, [](Scene& s) { return &s.simulation.cfl; }},
      {"simulation.mass_tolerance", &kMassTolerance, [](Scene& s) { return &s.simulation.mass_tolerance; }},
      {"simulation.energy_limit", &kEnergyLimit, [](Scene& s) { return &s.simulation.energy_limit; }},
      {"simulation.max_steps", &kMaxSteps, [](Scene& s) { return &s.simulation.max_steps; }},
      {"simulation.memory_limit", &kMemoryLimit, [](Scene& s) { return &s.simulation.memory_limit; }},
      {"simulation.node_reset", &kNodeReset, [](Scene& s) { return &s.simulation.node_reset.emplace(); }},
      {"grid.perturbation", &kPerturbation, [](Scene& s) { return &s.grid.perturbation; }},
      {"wall.w.friction", &kFriction, [](Scene& s) { return &s.walls[0].friction; }},
      {"contact.friction", &kFriction, [](Scene& s) { return &s.contact->friction; }},
      {"material.m.density", &kDensity, [](Scene& s) { return &s.materials[0].density; }},
      {"material.m.poisson", &kPoisson, [](Scene& s) { return &s.materials[0].poisson; }}};
  for (const Key& k : keys) {
    CAPTURE(k.key);
    for (const double value : {k.spec->lower - 1.0, k.spec->upper < kUnbounded ? k.spec->upper + 1.0 : k.spec->lower - 2.0,
                               std::numeric_limits<double>::infinity()}) {
      CAPTURE(value);
      const std::string why = k.spec->check(value);
      REQUIRE(!why.empty());
      std::vector<std::string> sets{k.key + "=" + (std::isinf(value) ? std::string("inf") : format_number(value))};
      if (k.key == "grid.perturbation") sets.push_back("grid.kind=\"perturbed\"");
      const std::string read = input_error_of([&] { parse_scene(text, "keys.toml", sets); });
      CHECK(read.ends_with(why));
      Scene s = parse_scene(text, "keys.toml", k.key == "grid.perturbation" ? std::vector<std::string>{sets[1]}
                                                                             : std::vector<std::string>{});
      *k.field(s) = value;
      const std::string validated = input_error_of([&] { validate_scene(s, 2); });
      CHECK(validated.ends_with(why));
    }
  }
}

TEST_CASE("a range with two ends names the interval, one with one end its bound") {
  CHECK(kPoisson.check(0.5) == "must be in (-1, 0.5) (got 0.5)");
  CHECK(kDensity.check(-2.0) == "must be > 0 (got -2)");
  CHECK(kDensity.check(std::numeric_limits<double>::infinity()) == "must be a finite number (got inf)");
  CHECK(kDensity.check(1e-300).empty());
}

TEST_CASE("a wall normal or a cylinder axis whose square overflows or underflows gives its direction") {
  // The wall 0.02 m below a falling block: its normal as (0, 1), (0, 1e200) and (0, 1e-200).
  const std::string block = "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.3, 0.3]\nupper = [0.6, 0.6]\n"
                            "velocity = [0.0, -1.0]\n";
  for (const std::string normal : {"[0.0, 1.0]", "[0.0, 1e200]", "[0.0, 1e-200]", "[1e300, 1e300]"}) {
    CAPTURE(normal);
    const Scene s = parse_scene(scene_2d("linear_elastic", "", block +
                                         "[[wall]]\nname = \"w\"\npoint = [0.0, 0.28]\nnormal = " + normal + "\n"),
                                "wall.toml");
    const Engine<2> e = assemble<2>(s);
    const Vec<2> expected = normal == "[1e300, 1e300]" ? Vec<2>(std::sqrt(0.5), std::sqrt(0.5)) : Vec<2>(0.0, 1.0);
    CHECK((e.walls().at(0).normal - expected).norm() < 1e-15);
  }
  CHECK(input_error_of([&] {
          parse_scene(scene_2d("linear_elastic", "", block + "[[wall]]\nname = \"w\"\npoint = [0.0, 0.28]\n"
                                                             "normal = [0.0, inf]\n"),
                      "wall.toml");
        }).find("key 'wall.w.normal'") != std::string::npos);
  // A cylinder along z, its axis given as (0, 0, 1) and (0, 0, 1e200): the same particles.
  auto cylinder = [](const std::string& axis) {
    const std::string text =
        "[simulation]\ndimension = 3\nintegrator = \"fe\"\nt_end = 1e-3\n[basis]\nkind = \"linear\"\n[grid]\n"
        "lower = [0.0, 0.0, 0.0]\nupper = [1.0, 1.0, 1.0]\ncells = [10, 10, 10]\n[[material]]\nname = \"m\"\n"
        "model = \"linear_elastic\"\ndensity = 1000.0\nyoung = 1e6\npoisson = 0.3\n[[body]]\nmaterial = \"m\"\n"
        "shape = \"cylinder\"\ncenter = [0.5, 0.5, 0.2]\naxis = " + axis + "\nradius = 0.2\nlength = 0.5\n";
    return seed_particles<3>(parse_scene(text, "cylinder.toml"), Vec<3>::Constant(0.1));
  };
  const Particles<3> a = cylinder("[0.0, 0.0, 1.0]"), b = cylinder("[0.0, 0.0, 1e200]");
  REQUIRE(a.size() == 520);
  REQUIRE(b.size() == a.size());
  for (int p = 0; p < a.size(); ++p) CHECK(a.x[p] == b.x[p]);
}

TEST_CASE("a body that starts behind a wall is refused at set-up, naming wall, body and count") {
  test::TempDir dir("ranges_walls");
  const std::string block = "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.3, 0.3]\nupper = [0.6, 0.6]\n";
  auto wall = [](const std::string& point, const std::string& normal) {
    return "[[wall]]\nname = \"w\"\npoint = " + point + "\nnormal = " + normal + "\n";
  };
  for (const std::string mode : {"mpm", "ul"}) {
    CAPTURE(mode);
    // The block's 144 particles: a wall through its middle (72 behind it), one above it, one below it facing down.
    for (const auto& behind : {std::pair{wall("[0.0, 0.45]", "[0.0, 1.0]"), 72},
                               std::pair{wall("[0.0, 0.7]", "[0.0, 1.0]"), 144},
                               std::pair{wall("[0.0, 0.2]", "[0.0, -1.0]"), 144}}) {
      const std::string text = scene_2d("linear_elastic", "", block + behind.first, mode);
      const std::string why = input_error_of([&] { assemble_parts<2>(parse_scene(text, "behind.toml")); });
      CHECK(why.find("body 'b' starts behind wall 'w': " + std::to_string(behind.second) + " of its particles") !=
            std::string::npos);
    }
    // A wall through the block's lower face (the particles lie above it): accepted.
    CHECK(input_error_of([&] {
            assemble_parts<2>(parse_scene(scene_2d("linear_elastic", "", block + wall("[0.0, 0.3]", "[0.0, 1.0]"), mode),
                                          "touching.toml"));
          }) == "");
  }
  // A file body behind a wall, read in blocks as a rank reads it (seed_bodies_where): the same refusal.
  write_block(dir.file("b.csv"));
  const Scene s = parse_scene(scene_2d("linear_elastic", "", file_body(dir.file("b.csv")) + wall("[0.0, 0.45]", "[0.0, 1.0]")),
                              "file.toml");
  const std::string why = input_error_of([&] {
    seed_bodies_where<2>(s, Vec<2>::Constant(0.05), node_grid<2>(s), [](long long, const Vec<2>&) { return true; },
                         nullptr);
  });
  CHECK(why.find("body 'f' starts behind wall 'w': 72 of its particles") != std::string::npos);
}

TEST_CASE("a file body of tiny particles far apart is indexed without an overflow, and its shape stays exact") {
  // Volumes of 1e-300 over 0.3 m: (x - lower) / cube side is 1e149 per axis.
  AlignedVector<Vec<2>> x;
  std::vector<double> volume;
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j) {
      x.emplace_back(0.3125 + 0.025 * i, 0.3125 + 0.025 * j);
      volume.push_back(1e-300);
    }
  const ParticleCells<2> cells(x, volume);
  for (const Vec<2>& p : x) CHECK(cells.contains(p));
  CHECK(!cells.contains(Vec<2>(0.3125 + 0.0125, 0.3125)));
  CHECK(!cells.contains(Vec<2>(0.3125, 0.3125 + 1e-10))); // beyond the cube's half side of 5e-151
  CHECK(!cells.contains(Vec<2>(5.0, 5.0)));
}
