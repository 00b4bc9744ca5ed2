// output.compression (docs/user-guide.md, "Result file size"): frame
// datasets stored chunked along their rows with HDF5's shuffle and deflate
// filters read back as the same bits as the contiguous ones (double and
// single precision, full and symmetric tensors, on the stepping thread and on
// the writer thread), carry those filters at the level asked for in chunks of
// at most 1 MiB, make the file of a smooth field smaller, and a bad level is
// an InputError naming the key (exit status 2). Level 0 keeps the contiguous layout.
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/results.hpp"

#include "otmpm/core.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/scene/scene.hpp"
#include "otmpm/scene/validate.hpp"

#include "cli_support.hpp"
#include "h5_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

using namespace otmpm;
using test::TempDir;
namespace fs = std::filesystem;

namespace {

/// The storage of one dataset: layout, chunk shape and filters (id and first parameter).
struct Storage {
  H5D_layout_t layout = H5D_LAYOUT_ERROR;
  std::vector<hsize_t> dims, chunk;
  std::vector<std::pair<H5Z_filter_t, unsigned>> filters;
  std::size_t element_bytes = 0;
  hsize_t stored_bytes = 0; ///< H5Dget_storage_size
};

Storage storage(const std::string& path, const std::string& name) {
  Storage s;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(file >= 0);
  const hid_t set = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  REQUIRE_MESSAGE(set >= 0, name);
  const hid_t space = H5Dget_space(set);
  s.dims.resize(static_cast<std::size_t>(H5Sget_simple_extent_ndims(space)));
  H5Sget_simple_extent_dims(space, s.dims.data(), nullptr);
  H5Sclose(space);
  const hid_t type = H5Dget_type(set);
  s.element_bytes = H5Tget_size(type);
  H5Tclose(type);
  s.stored_bytes = H5Dget_storage_size(set);
  const hid_t dcpl = H5Dget_create_plist(set);
  s.layout = H5Pget_layout(dcpl);
  if (s.layout == H5D_CHUNKED) {
    s.chunk.resize(s.dims.size());
    CHECK(H5Pget_chunk(dcpl, static_cast<int>(s.chunk.size()), s.chunk.data()) == static_cast<int>(s.chunk.size()));
  }
  for (int i = 0; i < H5Pget_nfilters(dcpl); ++i) {
    unsigned flags = 0, config = 0;
    std::size_t n = 4;
    unsigned values[4] = {0, 0, 0, 0};
    char filter_name[64];
    const H5Z_filter_t id =
        H5Pget_filter2(dcpl, static_cast<unsigned>(i), &flags, &n, values, sizeof filter_name, filter_name, &config);
    s.filters.emplace_back(id, n > 0 ? values[0] : 0u);
  }
  H5Pclose(dcpl);
  H5Dclose(set);
  H5Fclose(file);
  return s;
}

/// Every dataset of a result file as its shape, element size and values read
/// as doubles (integers exactly: they are small), and the frames' times.
std::map<std::string, std::vector<double>> contents(const std::string& path) {
  std::map<std::string, std::vector<double>> out;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(file >= 0);
  const std::vector<std::string> names = otmpm::test::dataset_names(file);
  for (const std::string& n : names) {
    const hid_t set = H5Dopen2(file, n.c_str(), H5P_DEFAULT);
    const hid_t space = H5Dget_space(set);
    std::vector<hsize_t> dims(static_cast<std::size_t>(H5Sget_simple_extent_ndims(space)));
    H5Sget_simple_extent_dims(space, dims.data(), nullptr);
    std::vector<double> values(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
    if (!values.empty()) CHECK(H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) >= 0);
    const hid_t type = H5Dget_type(set);
    std::vector<double> v(dims.begin(), dims.end());
    v.push_back(static_cast<double>(H5Tget_size(type)));
    v.insert(v.end(), values.begin(), values.end());
    out[n] = std::move(v);
    H5Tclose(type);
    H5Sclose(space);
    H5Dclose(set);
  }
  for (std::size_t k = 0;; ++k) {
    char frame[32];
    std::snprintf(frame, sizeof frame, "frames/%06zu", k);
    if (H5Lexists(file, "frames", H5P_DEFAULT) <= 0 || H5Lexists(file, frame, H5P_DEFAULT) <= 0) break;
    const hid_t attr = H5Aopen_by_name(file, frame, "time", H5P_DEFAULT, H5P_DEFAULT);
    double t = 0;
    H5Aread(attr, H5T_NATIVE_DOUBLE, &t);
    H5Aclose(attr);
    out[std::string(frame) + "@time"] = {t};
  }
  H5Fclose(file);
  return out;
}

/// The two files hold the same datasets with the same shapes, element sizes and bits.
void check_same_contents(const std::string& a_path, const std::string& b_path) {
  const auto a = contents(a_path), b = contents(b_path);
  CHECK(a.size() == b.size());
  REQUIRE(a.count("frames/000001/x") == 1);
  for (const auto& entry : a) {
    const std::string& name = entry.first; // not a structured binding: doctest's INFO captures it
    INFO(name);
    REQUIRE(b.count(name) == 1);
    CHECK((b.at(name) == entry.second));
  }
}

RunSummary run(const std::string& scene, const std::string& out, const std::vector<std::string>& sets,
               bool background = false) {
  RunOptions opt;
  opt.out_file = out;
  opt.background_output = background;
  return run_scene(load_scene(std::string(OTMPM_SOURCE_DIR) + scene, sets), opt);
}

/// True when `s` is chunked with shuffle then deflate at `level`.
bool compressed_at(const Storage& s, unsigned level) {
  return s.layout == H5D_CHUNKED && s.filters.size() == 2 && s.filters[0].first == H5Z_FILTER_SHUFFLE &&
         s.filters[1].first == H5Z_FILTER_DEFLATE && s.filters[1].second == level;
}

} // namespace

TEST_CASE("chunk_rows: the fewest chunks of at most 1 MiB, equal rows, at least one row") {
  CHECK(h5::kMaxChunkBytes == 1048576);
  CHECK(h5::chunk_rows(10, 3, 8) == 10);      // a small dataset is one chunk
  CHECK(h5::chunk_rows(0, 3, 8) == 1);        // (never used: an empty dataset stays contiguous)
  CHECK(h5::chunk_rows(43690, 3, 8) == 43690); // 1048560 bytes: still one chunk
  CHECK(h5::chunk_rows(43691, 3, 8) == 21846); // 1048584 bytes: two equal halves
  CHECK(h5::chunk_rows(1, 1 << 18, 8) == 1);   // a row above 1 MiB is its own chunk
  for (hsize_t rows : {1000u, 100000u, 524288u, 2097152u, 3000001u})
    for (hsize_t cols : {1u, 3u, 6u, 9u})
      for (std::size_t bytes : {4u, 8u}) {
        const hsize_t c = h5::chunk_rows(rows, cols, bytes);
        const hsize_t chunks = (rows + c - 1) / c;
        CAPTURE(rows);
        CAPTURE(cols);
        CAPTURE(bytes);
        CHECK(c * cols * bytes <= h5::kMaxChunkBytes);
        // The fewest: one chunk fewer could not hold the rows in 1 MiB each.
        CHECK((chunks - 1) * (h5::kMaxChunkBytes / (cols * bytes)) < rows);
        CHECK(c * (chunks - 1) < rows); // no empty last chunk
      }
}

TEST_CASE("a compressed writer stores each frame dataset chunked with shuffle + deflate, with the same values") {
  TempDir t("writer");
  std::vector<double> x(3 * 50000), s(9 * 50000);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = 0.001 * static_cast<double>(i / 3) + 1e-7 * static_cast<double>(i % 3);
  for (std::size_t i = 0; i < s.size(); ++i) s[i] = -1e3 * static_cast<double>(i % 9) + 1.0 / (1.0 + i);
  for (const int level : {1, 6, 9}) {
    for (const bool single : {false, true}) {
      CAPTURE(level);
      CAPTURE(single);
      const std::string plain = t.file("plain.h5"), packed = t.file("packed.h5");
      for (const std::string& path : {plain, packed}) {
        ResultOptions o;
        o.single_precision = single;
        o.compression = path == packed ? level : 0;
        ResultWriter w(path, "", 3, o);
        w.write_frame(0.0, {{"x", 50000, 3, x.data()}, {"stress", 50000, 9, s.data()}});
        w.write_frame(1.0, {{"x", 0, 3, x.data()}}); // an empty frame: nothing to chunk
        w.publish();
      }
      check_same_contents(plain, packed);
      const std::size_t bytes = single ? 4 : 8;
      const Storage sx = storage(packed, "/frames/000000/x"), ss = storage(packed, "/frames/000000/stress");
      CHECK(compressed_at(sx, static_cast<unsigned>(level)));
      CHECK(compressed_at(ss, static_cast<unsigned>(level)));
      CHECK(sx.element_bytes == bytes);
      CHECK(sx.chunk == std::vector<hsize_t>{h5::chunk_rows(50000, 3, bytes), 3});
      CHECK(ss.chunk == std::vector<hsize_t>{h5::chunk_rows(50000, 9, bytes), 9});
      CHECK(ss.chunk[0] < 50000); // 3.6 MB of doubles (1.8 MB of floats): more than one chunk
      CHECK(compressed_at(storage(packed, "/xdmf/vertices_50000"), static_cast<unsigned>(level)));
      CHECK(storage(packed, "/frames/000001/x").layout == H5D_CONTIGUOUS);
      // Smooth coordinates and a repetitive stress compress well.
      CHECK(sx.stored_bytes < 50000 * 3 * bytes / 2);
      CHECK(ss.stored_bytes < 50000 * 9 * bytes / 2);
      const Storage plain_x = storage(plain, "/frames/000000/x");
      CHECK(plain_x.layout == H5D_CONTIGUOUS);
      CHECK(plain_x.filters.empty());
      CHECK(storage(plain, "/xdmf/vertices_50000").layout == H5D_CONTIGUOUS);
    }
  }
  ResultOptions bad;
  bad.compression = 10;
  CHECK_THROWS_AS(ResultWriter(t.file("bad.h5"), "", 3, bad), std::invalid_argument);
  bad.compression = -1;
  CHECK_THROWS_AS(ResultWriter(t.file("bad.h5"), "", 3, bad), std::invalid_argument);
  CHECK(h5::deflate_available());
}

TEST_CASE("compressed runs: the same frames, probes and series bit for bit as uncompressed ones") {
  TempDir t("runs");
  struct Case {
    const char* scene;
    std::vector<std::string> sets;
    bool background;
  };
  const std::vector<Case> cases{
      // 3D, every tensor field: full tensors in double, symmetric ones in single (on the writer thread).
      {"/examples/dyka_3d.toml",
       {"simulation.t_end=4e-6", "output.every=1e-6", "output.fields=[\"x\",\"v\",\"stress\",\"strain\",\"F\",\"density\"]"},
       false},
      {"/examples/dyka_3d.toml",
       {"simulation.t_end=4e-6", "output.every=1e-6", "output.fields=[\"x\",\"v\",\"stress\",\"strain\",\"F\",\"density\"]",
        "output.precision=\"single\"", "output.symmetric_tensors=true"},
       true},
      {"/examples/dyka_3d.toml",
       {"simulation.t_end=4e-6", "output.every=1e-6", "output.symmetric_tensors=true"}, false},
      // 1D (the padded x3 geometry) and a 2D run with walls, probes and the energy series.
      {"/examples/dyka.toml", {"simulation.t_end=2e-5", "output.every=5e-6"}, true},
      {"/examples/sliding_block.toml", {"simulation.t_end=0.05", "output.every=0.01"}, false},
  };
  int index = 0;
  for (const Case& c : cases) {
    ++index;
    CAPTURE(index);
    const std::string plain = t.file("plain" + std::to_string(index) + ".h5"),
                      packed = t.file("packed" + std::to_string(index) + ".h5");
    REQUIRE(run(c.scene, plain, c.sets, c.background).exit_code == 0);
    std::vector<std::string> sets = c.sets;
    sets.push_back("output.compression=" + std::to_string(index == 1 ? 9 : 4));
    REQUIRE(run(c.scene, packed, sets, c.background).exit_code == 0);
    check_same_contents(plain, packed);
    const Storage x = storage(packed, "/frames/000001/x");
    CHECK(compressed_at(x, index == 1 ? 9u : 4u));
    const std::string other = index == 5 ? "mass" : "stress";
    CHECK(compressed_at(storage(packed, "/frames/000001/" + other), index == 1 ? 9u : 4u));
    CHECK(storage(plain, "/frames/000001/x").layout == H5D_CONTIGUOUS);
    if (index == 4) CHECK(compressed_at(storage(packed, "/frames/000001/x3"), 4u)); // 1D: the sidecar's geometry
    // The histories keep their own chunked, unfiltered layout.
    if (index == 5) CHECK(storage(packed, "/energy/kinetic").filters.empty());
    // The stored scene says so; the uncompressed one does not name the key.
    CHECK(read_string_attribute(packed, "scene").find("compression = ") != std::string::npos);
    CHECK(read_string_attribute(plain, "scene").find("compression") == std::string::npos);
  }
}

TEST_CASE("a block at rest under gravity: level 1 makes the result file at most 0.55 (single: 0.45) of the uncompressed one") {
  // The elastic block of scripts/bench-output.sh at 16^3 cells (32 768
  // particles) settling under gravity, 62 steps, 6 frames of x, v, stress.
  // Measured (HDF5 1.10.8, Debian's zlib): compressed / uncompressed file
  // bytes 0.478 at level 1 and 0.464 at level 6 in double; with single
  // precision and symmetric tensors 0.359 and 0.342. Frame 0 (v and stress
  // zero) shrinks to 0.4% but for x; the later frames to 0.5-0.7 (double)
  // and 0.3-0.5 (single): the shuffle filter lines up the exponent and
  // leading mantissa bytes of the smooth fields for deflate, the low
  // mantissa bytes of computed doubles are noise no lossless filter removes
  // (so single precision gains more). The bounds leave 15% for another zlib.
  TempDir t("gravity");
  const std::string scene = t.file("block.toml");
  {
    std::FILE* f = std::fopen(scene.c_str(), "w");
    REQUIRE(f);
    std::fputs(R"([simulation]
dimension = 3
mode = "mpm"
integrator = "fe"
t_end = 0.01
cfl = 0.3
[basis]
kind = "linear"
[grid]
lower = [-0.125, -0.125, 0.0]
upper = [1.125, 1.125, 1.125]
cells = [20, 20, 18]
[[material]]
name = "m"
model = "linear_elastic"
density = 1000.0
young = 1.0e7
poisson = 0.3
[[body]]
name = "block"
material = "m"
lower = [0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0]
particles_per_cell = 2
velocity = [0.0, 0.0, 0.0]
[[boundary]]
name = "base"
lower = [-0.125, -0.125, 0.0]
upper = [1.125, 1.125, 0.0]
fix = [true, true, true]
[body_force]
value = [0.0, 0.0, -9.81]
[output]
every = 0.002
fields = ["x", "v", "stress"]
)",
               f);
    std::fclose(f);
  }
  const auto bytes = [&](const std::string& name, const std::vector<std::string>& sets) {
    RunOptions opt;
    opt.out_file = t.file(name);
    REQUIRE(run_scene(load_scene(scene, sets), opt).exit_code == 0);
    return static_cast<double>(fs::file_size(t.file(name)));
  };
  const double plain = bytes("plain.h5", {}), level1 = bytes("level1.h5", {"output.compression=1"});
  const std::vector<std::string> single{"output.precision=\"single\"", "output.symmetric_tensors=true"};
  std::vector<std::string> single1 = single;
  single1.push_back("output.compression=1");
  const double plain_single = bytes("plain_single.h5", single), level1_single = bytes("level1_single.h5", single1);
  MESSAGE("compressed / uncompressed: double " << level1 / plain << ", single + symmetric " << level1_single / plain_single);
  CHECK(plain > 32768.0 * 6 * 15 * 8); // the datasets are really there: 6 frames of 15 doubles per particle
  CHECK(level1 <= 0.55 * plain);
  CHECK(level1_single <= 0.45 * plain_single);
  check_same_contents(t.file("plain.h5"), t.file("level1.h5"));
}

TEST_CASE("output.compression: read, validated, kept in the stored scene only when set, bad values name the key") {
  const std::string dyka = OTMPM_SOURCE_DIR "/examples/dyka.toml";
  const Scene d = load_scene(dyka);
  CHECK(d.output.compression == 0);
  CHECK(to_toml(d).find("compression") == std::string::npos);
  const Scene s = load_scene(dyka, {"output.compression=6"});
  CHECK(s.output.compression == 6);
  CHECK(to_toml(s).find("compression = 6") != std::string::npos);
  CHECK(load_scene(dyka, {"output.compression=0"}).output.compression == 0);
  CHECK(load_scene(dyka, {"output.compression=9"}).output.compression == 9);
  for (const char* bad : {"output.compression=10", "output.compression=-1", "output.compression=true",
                          "output.compression=\"6\"", "output.compression=2.5", "output.compression=[1]"}) {
    CAPTURE(bad);
    bool thrown = false;
    try {
      load_scene(dyka, {bad});
    } catch (const InputError& e) {
      thrown = true;
      CHECK(std::string(e.what()).find("compression") != std::string::npos);
    }
    CHECK(thrown);
  }
  Scene bad = d;
  bad.output.compression = 12;
  bool thrown = false;
  try {
    validate_scene(bad, 1);
  } catch (const InputError& e) {
    thrown = true;
    CHECK(std::string(e.what()).find("output.compression") != std::string::npos);
  }
  CHECK(thrown);
}

TEST_CASE("otmpm run with a bad output.compression: exit status 2 and a message naming the key") {
  TempDir t("cli");
  for (const char* bad : {"output.compression=10", "output.compression=\"fast\""}) {
    CAPTURE(bad);
    const test::CliResult r = test::run_process(
        OTMPM_BINARY, {"run", OTMPM_SOURCE_DIR "/examples/dyka.toml", "--quiet", "--out", t.file("bad.h5"), "--set", bad},
        t.dir);
    CHECK(r.status == 2);
    CHECK(r.err.find("output.compression") != std::string::npos);
    CHECK_FALSE(fs::exists(t.file("bad.h5")));
  }
}
