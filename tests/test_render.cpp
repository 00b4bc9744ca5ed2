// `otmpm render`: a PNG of one frame and a GIF of every frame of short 1D,
// 2D and 3D runs, with the picture size and frame count checked; and exit
// status 2 with a clear message for a missing file, an unknown field (the
// message lists the fields), a frame out of range, no Python and a Python
// without matplotlib.
#include "cli_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace fs = std::filesystem;
using otmpm::test::quote;
using otmpm::test::shell;
using Result = otmpm::test::ShellResult;
using otmpm::test::TempDir;

namespace {

const fs::path kSource = OTMPM_SOURCE_DIR;
const std::string kBinary = OTMPM_BINARY;

/// Runs `otmpm ARGS` with one thread.
Result run_otmpm(const std::vector<std::string>& args) {
  std::string cmd = "OMP_NUM_THREADS=1 " + quote(kBinary);
  for (const std::string& a : args) cmd += " " + quote(a);
  return shell(cmd);
}

/// Width and height of a PNG from its IHDR chunk (big-endian at bytes 16..23), after checking the signature.
std::array<unsigned, 2> png_size(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::array<unsigned char, 24> b{};
  in.read(reinterpret_cast<char*>(b.data()), b.size());
  REQUIRE(in.gcount() == 24);
  const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  for (int i = 0; i < 8; ++i) REQUIRE(b[static_cast<std::size_t>(i)] == signature[i]);
  auto be32 = [&](int at) {
    unsigned v = 0;
    for (int i = 0; i < 4; ++i) v = (v << 8) | b[static_cast<std::size_t>(at + i)];
    return v;
  };
  return {be32(16), be32(20)};
}

/// Frame count of a GIF, read by Pillow (python3-pil, a dependency of Debian's matplotlib).
int gif_frames(const fs::path& file) {
  const Result r = shell("/usr/bin/python3 -c 'import sys; from PIL import Image; im = Image.open(sys.argv[1]); "
                         "assert im.format == \"GIF\"; print(im.n_frames)' " +
                         quote(file.string()));
  INFO(r.output);
  REQUIRE(r.status == 0);
  return std::stoi(r.output);
}

/// A short run of `scene` with frames every `every` seconds up to `t_end`.
fs::path short_run(const TempDir& dir, const std::string& scene, const std::string& t_end, const std::string& every) {
  const fs::path out = dir.dir / (fs::path(scene).stem().string() + ".h5");
  const Result r = run_otmpm({"run", (kSource / "examples" / scene).string(), "--set", "simulation.t_end=" + t_end, "--set",
                          "output.every=" + every, "--out", out.string(), "--quiet"});
  INFO(r.output);
  REQUIRE(r.status == 0);
  return out;
}

} // namespace

TEST_CASE("render: a PNG of one frame and a GIF of all frames, in 1D, 2D and 3D") {
  TempDir dir("render");
  // Dyka bars: 2e-5 s with a frame every 5e-6 s = 5 frames (t = 0 included).
  for (const char* scene : {"dyka.toml", "dyka_2d.toml", "dyka_3d.toml"}) {
    INFO(scene);
    const fs::path result = short_run(dir, scene, "2e-5", "5e-6");
    const fs::path png = dir.dir / (fs::path(scene).stem().string() + ".png");
    const Result p = run_otmpm({"render", result.string(), "--field", "v", "--out", png.string()});
    INFO(p.output);
    REQUIRE(p.status == 0);
    // 7 in wide at 100 dpi; 1D and flat bodies (the bars, "not to scale") 4.5 in high.
    CHECK(png_size(png) == std::array<unsigned, 2>{700, 450});
    CHECK(fs::file_size(png) > 10000); // axes, colour bar, title and particles, not an empty canvas
    const fs::path gif = dir.dir / (fs::path(scene).stem().string() + ".gif");
    const Result g = run_otmpm({"render", result.string(), "--field", "stress", "--component", "xx", "--all", "--out",
                            gif.string()});
    INFO(g.output);
    REQUIRE(g.status == 0);
    CHECK(gif_frames(gif) == 5);
  }
  // --stride 2 of 5 frames: 0, 2, 4.
  const fs::path gif = dir.dir / "stride.gif";
  REQUIRE(run_otmpm({"render", (dir.dir / "dyka.h5").string(), "--field", "v", "--all", "--stride", "2", "--out",
                     gif.string()})
              .status == 0);
  CHECK(gif_frames(gif) == 3);
  // A square plate is drawn to scale: the figure is taller than for a bar.
  const fs::path plate = short_run(dir, "plate_impact.toml", "0.02", "0.01");
  const fs::path png = dir.dir / "plate.png";
  REQUIRE(run_otmpm({"render", plate.string(), "--field", "v", "--frame", "1", "--out", png.string()}).status == 0);
  CHECK(png_size(png)[1] > 450);
}

TEST_CASE("render: bad input exits with 2 and says what is wrong") {
  TempDir dir("render_errors");
  const fs::path result = short_run(dir, "dyka.toml", "2e-5", "1e-5");
  const fs::path png = dir.dir / "r.png";
  auto expect = [&](const std::vector<std::string>& args, const std::vector<std::string>& fragments) {
    const Result r = run_otmpm(args);
    INFO(r.output);
    CHECK(r.status == 2);
    for (const std::string& f : fragments) CHECK(r.output.find(f) != std::string::npos);
    CHECK(!fs::exists(png));
  };
  expect({"render", (dir.dir / "missing.h5").string(), "--field", "v", "--out", png.string()},
         {"missing.h5", "no such result file"});
  expect({"render", dir.dir.string(), "--field", "v", "--out", png.string()}, {"is a directory"});
  expect({"render", result.string(), "--field", "velocity", "--out", png.string()},
         {"no field 'velocity'", "fields: ", "stress", "v", "x"});
  expect({"render", result.string(), "--field", "v", "--frame", "3", "--out", png.string()},
         {"frame 3 out of range", "3 frames"});
  expect({"render", result.string(), "--field", "stress", "--component", "yy", "--out", png.string()}, {"yy"});
  expect({"render", result.string(), "--field", "v", "--all", "--out", png.string()}, {".gif"});
  expect({"render", result.string(), "--field", "v", "--out", png.string(), "--python", "/nonexistent/python3"},
         {"cannot start /nonexistent/python3"});
  // A Python without matplotlib: a module of that name that fails to import, first on the path.
  const fs::path fake = dir.dir / "no_matplotlib";
  fs::create_directories(fake / "matplotlib");
  std::ofstream(fake / "matplotlib" / "__init__.py") << "raise ImportError('No module named matplotlib')\n";
  const fs::path python = dir.dir / "python3";
  std::ofstream(python) << "#!/bin/sh\nPYTHONPATH=" << quote(fake.string()) << " exec /usr/bin/python3 \"$@\"\n";
  fs::permissions(python, fs::perms::owner_all);
  expect({"render", result.string(), "--field", "v", "--out", png.string(), "--python", python.string()},
         {"needs Python 3 with numpy, h5py and matplotlib"});
}

TEST_CASE("render: a file with symmetric tensors (output.symmetric_tensors) gives the same picture as the full tensor") {
  // The same scene written with 4 and with 3 stress components, under the
  // same file name in two folders (the name is in the picture's title).
  TempDir dir("render_symmetric");
  for (const char* layout : {"full", "symmetric"}) {
    fs::create_directories(dir.dir / layout);
    const Result r = run_otmpm({"run", (kSource / "examples" / "mms_plate.toml").string(), "--set", "grid.cells=[8, 8]",
                                "--set", std::string("output.symmetric_tensors=") + (layout[0] == 's' ? "true" : "false"),
                                "--out", (dir.dir / layout / "plate.h5").string(), "--quiet"});
    INFO(r.output);
    REQUIRE(r.status == 0);
  }
  for (const char* component : {"xy", "yx", "yy", "norm"}) {
    INFO(component);
    std::string png[2];
    int k = 0;
    for (const char* layout : {"full", "symmetric"}) {
      const fs::path out = dir.dir / layout / (std::string(component) + ".png");
      const Result r = run_otmpm({"render", (dir.dir / layout / "plate.h5").string(), "--field", "stress", "--component",
                                  component, "--out", out.string()});
      INFO(r.output);
      REQUIRE(r.status == 0);
      std::ifstream in(out, std::ios::binary);
      png[k++] = std::string(std::istreambuf_iterator<char>(in), {});
    }
    CHECK(png[0].size() > 10000);
    CHECK(png[0] == png[1]);
  }
}

TEST_CASE("render: plane strain's sigma_zz as --component zz of a symmetric 2D stress or as the field stress_zz") {
  // The same scene written with output.symmetric_tensors (stress "xx xy yy
  // zz") and with the field stress_zz, under the same file name in two
  // folders: the two pictures are the same bytes. Without either, zz is refused.
  TempDir dir("render_zz");
  const std::vector<std::pair<const char*, const char*>> layouts{
      {"symmetric", "output.symmetric_tensors=true"},
      {"field", "output.fields=[\"x\", \"v\", \"stress\", \"stress_zz\"]"},
      {"full", "output.symmetric_tensors=false"}};
  for (const auto& [layout, set] : layouts) {
    fs::create_directories(dir.dir / layout);
    const Result r = run_otmpm({"run", (kSource / "examples" / "mms_plate.toml").string(), "--set", "grid.cells=[8, 8]",
                                "--set", set, "--out", (dir.dir / layout / "plate.h5").string(), "--quiet"});
    INFO(r.output);
    REQUIRE(r.status == 0);
  }
  std::string png[2];
  int k = 0;
  for (const auto& [layout, field, component] : {std::tuple{"symmetric", "stress", "zz"}, std::tuple{"field", "stress_zz", "norm"}}) {
    const fs::path out = dir.dir / layout / "zz.png";
    const Result r = run_otmpm({"render", (dir.dir / layout / "plate.h5").string(), "--field", field, "--component",
                                component, "--out", out.string()});
    INFO(r.output);
    REQUIRE(r.status == 0);
    std::ifstream in(out, std::ios::binary);
    png[k++] = std::string(std::istreambuf_iterator<char>(in), {});
  }
  CHECK(png[0].size() > 10000);
  CHECK(png[0] == png[1]);
  const Result r = run_otmpm({"render", (dir.dir / "full" / "plate.h5").string(), "--field", "stress", "--component",
                              "zz", "--out", (dir.dir / "full" / "zz.png").string()});
  CHECK(r.status == 2);
  CHECK(r.output.find("stress_zz") != std::string::npos);
}
