// Bodies from geometry files through the otmpm command: the STL impactor
// (3D) and the Gmsh embankment (2D) of examples/geometry run in both node
// modes, the tetrahedral bracket (3D) with its mesh's vertices as the nodes
// (lme, linear on its tetrahedra) and on the lattice, `run --check` reports their seeded volumes against their shapes',
// and bad files end the run with exit status 2 and a message naming the
// file and the triangle or element.
#include "cli_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <array>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

namespace fs = std::filesystem;
using otmpm::test::quote;
using otmpm::test::shell;
using otmpm::test::TempDir;

namespace {

const std::string kExamples = std::string(OTMPM_SOURCE_DIR) + "/examples/geometry/";
const std::string kBinary = OTMPM_BINARY;

bool has(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

/// The relative error (%) that run --check prints for a body's volume.
double volume_error(const std::string& check, const std::string& body) {
  const std::regex line("body '" + body + "' \\([a-z]+\\): particles [^ ]+, shape [^ ]+ \\(error ([^ ]+) %\\)");
  std::smatch m;
  REQUIRE(std::regex_search(check, m, line));
  return std::stod(m[1].str());
}

} // namespace

TEST_CASE("geometry examples: the STL impactor and the mesh embankment run in both modes") {
  TempDir dir("cli_geometry_runs");
  for (const std::string mode : {"mpm", "ul"}) {
    const auto impactor = shell("OMP_NUM_THREADS=1 " + quote(kBinary) + " run " + quote(kExamples + "impactor.toml") +
                                " --quiet --out " + quote(dir.file("impactor_" + mode + ".h5")) +
                                " --set simulation.mode=" + mode +
                                " --set simulation.t_end=4e-6 --set 'grid.cells=[9,9,13]'");
    CHECK_MESSAGE(impactor.status == 0, impactor.output);
    const auto embankment = shell("OMP_NUM_THREADS=1 " + quote(kBinary) + " run " +
                                  quote(kExamples + "embankment.toml") + " --quiet --out " +
                                  quote(dir.file("embankment_" + mode + ".h5")) + " --set simulation.mode=" + mode +
                                  " --set simulation.t_end=0.1");
    CHECK_MESSAGE(embankment.status == 0, embankment.output);
  }
  // as written (lme on the mesh's nodes), on the tetrahedra's own shape functions, and on the lattice
  for (const std::string variant : {"body.bracket.nodes=mesh", "basis.kind=linear", "body.bracket.nodes=lattice"}) {
    const auto bracket = shell("OMP_NUM_THREADS=1 " + quote(kBinary) + " run " + quote(kExamples + "bracket.toml") +
                               " --quiet --force --out " + quote(dir.file("bracket.h5")) + " --set " + variant);
    CHECK_MESSAGE(bracket.status == 0, bracket.output);
  }
}

TEST_CASE("geometry examples: run --check reports the seeded volume against the shape's") {
  const auto emb = shell(quote(kBinary) + " run --check " + quote(kExamples + "embankment.toml"));
  REQUIRE_MESSAGE(emb.status == 0, emb.output);
  CHECK(std::abs(volume_error(emb.output, "core")) < 1e-9); // element volumes: exact
  CHECK(std::abs(volume_error(emb.output, "shoulders")) < 1e-9);
  CHECK(has(emb.output, "particles  322\n")); // one per element: 40 quadrangles, 282 triangles
  // the bracket's tetrahedra: the L-shaped solid's exact volume (20 x 6 + 6 x 14) x 10 mm^3, its 241
  // vertices the nodes
  const auto bracket = shell(quote(kBinary) + " run --check " + quote(kExamples + "bracket.toml"));
  REQUIRE_MESSAGE(bracket.status == 0, bracket.output);
  CHECK(std::abs(volume_error(bracket.output, "bracket")) < 1e-9);
  CHECK_MESSAGE(has(bracket.output, "particles 2.04e-06, shape 2.04e-06"), bracket.output);
  CHECK(has(bracket.output, "nodes      241\n"));
  // the impactor at h = 1 mm (2 particles per cell per axis): within 1 %, closer at h = 0.5 mm
  const auto coarse = shell(quote(kBinary) + " run --check " + quote(kExamples + "impactor.toml"));
  const auto fine = shell(quote(kBinary) + " run --check " + quote(kExamples + "impactor.toml") +
                          " --set 'grid.cells=[36,36,52]'");
  REQUIRE_MESSAGE(coarse.status == 0, coarse.output);
  REQUIRE_MESSAGE(fine.status == 0, fine.output);
  CHECK(std::abs(volume_error(coarse.output, "impactor")) < 1.0);
  CHECK(std::abs(volume_error(fine.output, "impactor")) < std::abs(volume_error(coarse.output, "impactor")));
}

TEST_CASE("geometry files: an open STL surface and a bad mesh exit with status 2, naming file and item") {
  TempDir dir("cli_geometry_bad");
  // the impactor's scene next to a cube with one face missing (ASCII STL)
  std::string scene;
  {
    std::ifstream in(kExamples + "impactor.toml");
    scene.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  std::ofstream(dir.file("impactor.toml")) << scene;
  {
    std::ofstream stl(dir.file("impactor.stl"));
    stl << "solid open_box\n";
    const double c[8][3] = {{0, 0, 0}, {.01, 0, 0}, {.01, .01, 0}, {0, .01, 0},
                            {0, 0, .01}, {.01, 0, .01}, {.01, .01, .01}, {0, .01, .01}};
    const int f[5][4] = {{0, 3, 2, 1}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}}; // no top
    for (const auto& q : f)
      for (const auto& tri : {std::array{q[0], q[1], q[2]}, std::array{q[0], q[2], q[3]}}) {
        stl << "facet normal 0 0 0\nouter loop\n";
        for (int v : tri) stl << "vertex " << c[v][0] << " " << c[v][1] << " " << c[v][2] << "\n";
        stl << "endloop\nendfacet\n";
      }
    stl << "endsolid open_box\n";
  }
  const auto open = shell(quote(kBinary) + " run --check " + quote(dir.file("impactor.toml")));
  CHECK(open.status == 2);
  CHECK_MESSAGE(has(open.output, dir.file("impactor.stl") + ": triangle "), open.output);
  CHECK(has(open.output, "the surface is open"));
  CHECK(has(open.output, "impactor.toml:")); // and the scene's line of the key
  // the embankment's scene with a mesh whose element names a node that is not there
  std::string mesh;
  {
    std::ifstream in(std::string(OTMPM_SOURCE_DIR) + "/tests/scenes/geometry/embankment_ascii.msh");
    mesh.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::size_t block = mesh.find("\n2 2 3 ", mesh.find("$Elements")); // the quadrangles of the core
  const std::size_t line = mesh.find('\n', block + 1) + 1;
  const std::size_t tag_end = mesh.find(' ', line);
  const std::string tag = mesh.substr(line, tag_end - line);
  mesh.replace(tag_end + 1, mesh.find(' ', tag_end + 1) - tag_end - 1, "123456");
  std::ofstream(dir.file("embankment.msh")) << mesh;
  std::string emb;
  {
    std::ifstream in(kExamples + "embankment.toml");
    emb.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  std::ofstream(dir.file("embankment.toml")) << emb;
  const auto bad = shell(quote(kBinary) + " run " + quote(dir.file("embankment.toml")) + " --out " +
                         quote(dir.file("e.h5")));
  CHECK(bad.status == 2);
  CHECK_MESSAGE(has(bad.output, dir.file("embankment.msh") + ":"), bad.output);
  CHECK(has(bad.output, "element " + tag + ": node 123456 is not in $Nodes"));
  CHECK_FALSE(fs::exists(dir.file("e.h5")));
}
