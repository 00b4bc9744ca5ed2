// Bodies from geometry files (io/stl, io/gmsh, geometry/triangle_surface,
// geometry/volume_mesh, scene/file_bodies): STL surfaces (ASCII and binary,
// the winding number's inside test on a non-convex surface, flaws it
// repairs, files it refuses) and Gmsh meshes (ASCII and binary, exact
// element volumes and centroids, physical groups, files it refuses), and
// the particles the scene seeds from them.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/scene/file_shapes.hpp"
#include "otmpm/io/gmsh.hpp"
#include "otmpm/io/stl.hpp"

#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <random>
#include <string>

using namespace otmpm;

namespace {

const std::string kData = std::string(OTMPM_SOURCE_DIR) + "/tests/scenes/geometry/";
const std::string kExamples = std::string(OTMPM_SOURCE_DIR) + "/examples/geometry/";

bool has(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

using Triangles = std::vector<StlTriangle>;

/// The closed surface of the prism that extrudes the L-shaped polygon
/// [0,2]x[0,2] minus (1,2]x(1,2] along z in [0, 1], outward (11 + 2 * 4 triangles).
Triangles l_prism() {
  const std::vector<Vec<2>> p{{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}}; // counter-clockwise
  Triangles t;
  auto at = [](const Vec<2>& q, double z) { return Vec<3>(q[0], q[1], z); };
  for (std::size_t i = 0; i < p.size(); ++i) { // the sides, two triangles each
    const Vec<2>&a = p[i], &b = p[(i + 1) % p.size()];
    t.push_back({at(a, 0), at(b, 0), at(b, 1)});
    t.push_back({at(a, 0), at(b, 1), at(a, 1)});
  }
  // the caps: a fan from the reflex corner (1, 1), which sees the whole L
  for (std::size_t i = 0; i < p.size(); ++i) {
    const std::size_t j = (i + 1) % p.size();
    if (i == 3 || j == 3) continue;
    t.push_back({at(p[3], 1), at(p[i], 1), at(p[j], 1)}); // top, counter-clockwise seen from above
    t.push_back({at(p[3], 0), at(p[j], 0), at(p[i], 0)}); // bottom, reversed
  }
  return t;
}

bool in_l(const Vec<3>& x) {
  const bool square = x[0] > 0 && x[0] < 2 && x[1] > 0 && x[1] < 2 && x[2] > 0 && x[2] < 1;
  return square && !(x[0] > 1 && x[1] > 1);
}

void write_ascii(const std::string& path, const Triangles& t) {
  std::ofstream out(path);
  out << "solid part made by a test\n";
  for (const StlTriangle& tri : t) {
    out << "  facet normal 0 0 0\n    outer loop\n";
    for (const Vec<3>& v : tri) out << "      vertex " << v[0] << " " << v[1] << " " << v[2] << "\n";
    out << "    endloop\n  endfacet\n";
  }
  out << "endsolid part\n";
}

void write_binary(const std::string& path, const Triangles& t) {
  std::ofstream out(path, std::ios::binary);
  const std::string header(80, ' ');
  out.write(header.data(), 80);
  const auto n = static_cast<std::uint32_t>(t.size());
  out.write(reinterpret_cast<const char*>(&n), 4);
  for (const StlTriangle& tri : t) {
    float f[12] = {};
    for (int v = 0; v < 3; ++v)
      for (int k = 0; k < 3; ++k) f[3 + 3 * v + k] = static_cast<float>(tri[static_cast<std::size_t>(v)][k]);
    out.write(reinterpret_cast<const char*>(f), sizeof f);
    const char attribute[2] = {0, 0};
    out.write(attribute, 2);
  }
}

std::string surface_error(const Triangles& t) {
  try {
    TriangleSurface s(t, "part.stl");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

} // namespace

TEST_CASE("stl: ASCII and binary files give the same triangles") {
  test::TempDir dir("stl_read");
  const Triangles t = l_prism();
  write_ascii(dir.file("a.stl"), t);
  write_binary(dir.file("b.stl"), t);
  const Triangles a = read_stl(dir.file("a.stl")), b = read_stl(dir.file("b.stl"));
  REQUIRE(a.size() == t.size());
  REQUIRE(b.size() == t.size());
  for (std::size_t i = 0; i < t.size(); ++i)
    for (std::size_t v = 0; v < 3; ++v) {
      CHECK(a[i][v] == t[i][v]); // small integers: exact in text and in float
      CHECK(b[i][v] == t[i][v]);
    }
}

TEST_CASE("stl: the L prism's volume, area and inside test (non-convex), also from a scrambled file") {
  Triangles t = l_prism();
  const TriangleSurface s(t, "l.stl");
  CHECK(s.measure() == doctest::Approx(3.0).epsilon(1e-14));
  CHECK(s.boundary_measure() == doctest::Approx(2 * 3.0 + 8.0).epsilon(1e-14)); // caps + sides (perimeter 8)
  CHECK(s.flipped() == 0);
  // flaws the winding number is indifferent to: every third triangle reversed, the order shuffled
  Triangles scrambled = t;
  for (std::size_t i = 0; i < scrambled.size(); i += 3) std::swap(scrambled[i][1], scrambled[i][2]);
  std::mt19937 rng(7);
  std::shuffle(scrambled.begin(), scrambled.end(), rng);
  const TriangleSurface r(scrambled, "scrambled.stl");
  CHECK(r.measure() == doctest::Approx(3.0).epsilon(1e-14));
  CHECK(r.flipped() > 0);
  // the lattice of a seeding, with points on the faces and in the notch's corner
  std::uniform_real_distribution<double> u(-0.5, 2.5);
  int wrong = 0, points = 0;
  for (int i = 0; i <= 30; ++i)
    for (int j = 0; j <= 30; ++j)
      for (int k = 0; k <= 6; ++k) {
        const Vec<3> x(-0.5 + 0.1 * i + 0.013, -0.5 + 0.1 * j + 0.007, -0.25 + 0.25 * k + 0.011);
        wrong += s.contains(x) != in_l(x) || r.contains(x) != in_l(x);
        ++points;
      }
  CHECK(points == 31 * 31 * 7);
  CHECK(wrong == 0);
  // the tree's sum against the exact one, away from the surface (where w is 0 or 1)
  for (int i = 0; i < 200; ++i) {
    const Vec<3> x(u(rng), u(rng), u(rng) * 0.6);
    CHECK(std::abs(s.winding_number(x) - s.exact_winding_number(x)) < 2e-3);
  }
}

TEST_CASE("stl: a box's side of the L prism agrees with contains() at every point of it, and is known away from the faces") {
  // Shape::side lets the counting pass of a distributed set-up take whole
  // runs of seeding cells: `inside` or `outside` must hold at every point of
  // the box; `unknown` only where a triangle's bounding box comes near.
  const TriangleSurface s(l_prism(), "l.stl");
  using Side = Shape<3>::Side;
  CHECK(s.side(Vec<3>(0.2, 0.2, 0.2), Vec<3>(0.8, 0.8, 0.8)) == Side::inside);   // deep in the square
  CHECK(s.side(Vec<3>(1.2, 1.2, 0.2), Vec<3>(1.8, 1.8, 0.8)) == Side::outside);  // in the notch: within the bounds
  CHECK(s.side(Vec<3>(3.0, 3.0, 3.0), Vec<3>(4.0, 4.0, 4.0)) == Side::outside);  // beyond the bounds
  CHECK(s.side(Vec<3>(0.8, 0.2, 0.2), Vec<3>(1.2, 0.8, 0.8)) == Side::inside);   // across x = 1 below the notch
  CHECK(s.side(Vec<3>(0.8, 0.8, 0.2), Vec<3>(1.2, 1.2, 0.8)) == Side::unknown);  // the notch's reflex edge
  CHECK(s.side(Vec<3>(0.2, 0.2, 0.9), Vec<3>(0.8, 0.8, 1.1)) == Side::unknown);  // the top cap
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.3, 2.3), size(0.01, 0.6), f(0.0, 1.0);
  int known = 0, wrong = 0;
  for (int i = 0; i < 2000; ++i) {
    const Vec<3> lo(u(rng), u(rng), u(rng) * 0.5), hi = lo + Vec<3>(size(rng), size(rng), size(rng));
    const Side side = s.side(lo, hi);
    if (side == Side::unknown) continue;
    ++known;
    for (int k = 0; k < 20; ++k) {
      const Vec<3> x = lo + Vec<3>(f(rng), f(rng), f(rng)).cwiseProduct(hi - lo);
      wrong += s.contains(x) != (side == Side::inside);
    }
    for (int m = 0; m < 8; ++m) { // the corners too
      const Vec<3> x((m & 1 ? hi : lo)[0], (m & 2 ? hi : lo)[1], (m & 4 ? hi : lo)[2]);
      wrong += s.contains(x) != (side == Side::inside);
    }
  }
  CHECK(known > 500);
  CHECK(wrong == 0);
}

TEST_CASE("stl: a hollow body (two nested shells) has the shell between them as inside") {
  auto cube = [](double lo, double hi) {
    Triangles t;
    const Vec<3> c[8] = {{lo, lo, lo}, {hi, lo, lo}, {hi, hi, lo}, {lo, hi, lo},
                         {lo, lo, hi}, {hi, lo, hi}, {hi, hi, hi}, {lo, hi, hi}};
    const int f[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
    for (const auto& q : f) {
      t.push_back({c[q[0]], c[q[1]], c[q[2]]});
      t.push_back({c[q[0]], c[q[2]], c[q[3]]});
    }
    return t;
  };
  Triangles t = cube(0, 3);
  for (const StlTriangle& tri : cube(1, 2)) t.push_back(tri); // inner shell, also outward in the file
  const TriangleSurface s(t, "hollow.stl");
  CHECK(s.measure() == doctest::Approx(27.0 - 1.0).epsilon(1e-14));
  CHECK(s.contains(Vec<3>(0.5, 0.5, 0.5)));
  CHECK_FALSE(s.contains(Vec<3>(1.5, 1.5, 1.5)));
  CHECK_FALSE(s.contains(Vec<3>(3.5, 1.5, 1.5)));
}

TEST_CASE("stl: open, non-manifold, self-intersecting and malformed files are refused, naming the triangle") {
  Triangles open = l_prism();
  open.erase(open.begin() + 5); // the 6th triangle gone: its neighbours' edges are free
  const std::string e1 = surface_error(open);
  CHECK(has(e1, "part.stl: triangle "));
  CHECK(has(e1, "the surface is open"));
  Triangles crossing = l_prism();
  for (const StlTriangle& tri : l_prism()) { // a copy shifted through the first
    StlTriangle moved = tri;
    for (Vec<3>& v : moved) v += Vec<3>(0.5, 0.25, 0.3);
    crossing.push_back(moved);
  }
  const std::string e2 = surface_error(crossing);
  CHECK(has(e2, "part.stl: triangle "));
  CHECK(has(e2, "the surface intersects itself"));
  Triangles fin = l_prism();
  fin.push_back({Vec<3>(0, 0, 0), Vec<3>(2, 0, 0), Vec<3>(1, -1, 0.5)}); // a third triangle on an edge
  const std::string e3 = surface_error(fin);
  CHECK(has(e3, "is shared by 3 triangles"));

  test::TempDir dir("stl_bad");
  write_ascii(dir.file("a.stl"), l_prism());
  std::string text;
  {
    std::ifstream in(dir.file("a.stl"));
    text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::size_t at = text.find("vertex", text.find("facet", 200));
  text.replace(at, 6, "vertx");
  std::ofstream(dir.file("bad.stl")) << text;
  try {
    read_stl(dir.file("bad.stl"));
    FAIL("a misspelt keyword is an error");
  } catch (const InputError& e) {
    CHECK(has(e.what(), dir.file("bad.stl") + ":"));
    CHECK(has(e.what(), ": triangle "));
    CHECK(has(e.what(), "expected 'vertex', found 'vertx'"));
  }
  std::ofstream(dir.file("nan.stl")) << "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 nan\n";
  try {
    read_stl(dir.file("nan.stl"));
    FAIL("a coordinate that is not finite is an error");
  } catch (const InputError& e) {
    CHECK(has(e.what(), "nan.stl:4: triangle 1: expected a finite number, found 'nan'"));
  }
}

TEST_CASE("gmsh: ASCII and binary files of the embankment agree, groups, exact areas and centroids") {
  const GmshMesh a = read_gmsh(kData + "embankment_ascii.msh");
  const GmshMesh b = read_gmsh(kExamples + "embankment.msh");
  REQUIRE(a.nodes.size() == b.nodes.size());
  REQUIRE(a.elements.size() == b.elements.size());
  for (std::size_t i = 0; i < a.nodes.size(); ++i) CHECK((a.nodes[i] - b.nodes[i]).norm() < 1e-15 * 12);
  for (std::size_t i = 0; i < a.elements.size(); ++i) CHECK(a.elements[i].node == b.elements[i].node);
  for (const std::string group : {"core", "fill", ""}) {
    const MeshBody<2> m = read_mesh_body<2>(kExamples + "embankment.msh", group, Placement{});
    double area = 0, quadrature = 0;
    for (const MeshElement<2>& e : m.elements) {
      area += element_points<2>(e, false)[0].volume;
      for (const ElementPoint<2>& p : element_points<2>(e, true)) quadrature += p.volume;
    }
    const double exact = group == "core" ? 6.0 : group == "fill" ? 16.5 : 22.5; // 2 x 3; (12 + 3) / 2 x 3 - core
    CHECK(area == doctest::Approx(exact).epsilon(1e-13));
    CHECK(quadrature == doctest::Approx(exact).epsilon(1e-13));
    const ElementUnion<2> shape(m.elements);
    CHECK(shape.measure() == doctest::Approx(exact).epsilon(1e-13));
    CHECK(shape.contains(Vec<2>(6.0, 1.5)) == (group != "fill"));
    CHECK(shape.contains(Vec<2>(3.0, 1.0)) == (group != "core"));
    CHECK_FALSE(shape.contains(Vec<2>(1.0, 2.5)));
  }
  // the base group's box: y = 0, x in [0, 12]
  const auto [lo, hi] = mesh_group_box<2>(kExamples + "embankment.msh", "base", Placement{});
  CHECK(lo == Vec<2>(0, 0));
  CHECK(hi == Vec<2>(12, 0));
}

TEST_CASE("gmsh: tetrahedra and hexahedra fill their boxes to round-off") {
  for (const auto& [file, volume] : {std::pair{"cube_tets.msh", 1.0}, std::pair{"cube_hexes.msh", 2.0}}) {
    const MeshBody<3> m = read_mesh_body<3>(kData + file, "", Placement{});
    double V = 0, Vq = 0;
    Vec<3> moment = Vec<3>::Zero();
    for (const MeshElement<3>& e : m.elements) {
      const ElementPoint<3> p = element_points<3>(e, false)[0];
      V += p.volume, moment += p.volume * p.x;
      for (const ElementPoint<3>& q : element_points<3>(e, true)) Vq += q.volume;
    }
    CHECK(V == doctest::Approx(volume).epsilon(1e-13));
    CHECK(Vq == doctest::Approx(volume).epsilon(1e-13));
    CHECK((moment / V - Vec<3>(volume / 2, 0.5, 0.5)).norm() < 1e-13);
  }
  const MeshBody<3> tets = read_mesh_body<3>(kData + "cube_tets.msh", "cube", Placement{});
  // the vertices (the OTM nodes) are those the elements use, each once, at the corners' positions
  std::vector<int> used(tets.vertices.size(), 0);
  for (std::size_t e = 0; e < tets.elements.size(); ++e)
    for (int a = 0; a < 4; ++a) {
      const auto v = static_cast<std::size_t>(tets.corners[e][static_cast<std::size_t>(a)]);
      used[v] = 1;
      CHECK(tets.vertices[v] == tets.elements[e].x[static_cast<std::size_t>(a)]);
    }
  CHECK(std::count(used.begin(), used.end(), 1) == static_cast<long>(used.size()));
  const ElementUnion<3> shape(tets.elements);
  CHECK(shape.boundary_measure() == doctest::Approx(6.0).epsilon(1e-13));
}

TEST_CASE("gmsh: non-affine quadrangles and hexahedra: exact volume and centroid") {
  const double a = 0.6;
  MeshElement<2> q; // the trapezoid (0,0), (1,0), (1+a,1), (0,1)
  q.kind = ElementKind::quadrangle;
  q.x = {Vec<2>(0, 0), Vec<2>(1, 0), Vec<2>(1 + a, 1), Vec<2>(0, 1)};
  const ElementPoint<2> pq = element_points<2>(q, false)[0];
  CHECK(pq.volume == doctest::Approx(1 + a / 2).epsilon(1e-15));
  // centroid of the trapezoid: x = (1 + a + a^2/3) / 2 / (1 + a/2), y = (1/2 + a/3) / (1 + a/2)
  CHECK(pq.x[0] == doctest::Approx((1 + a + a * a / 3) / 2 / (1 + a / 2)).epsilon(1e-14));
  CHECK(pq.x[1] == doctest::Approx((0.5 + a / 3) / (1 + a / 2)).epsilon(1e-14));
  MeshElement<3> h; // the unit cube with its top face z = 1 + a x y (a bilinear, non-planar face)
  h.kind = ElementKind::hexahedron;
  h.x = {Vec<3>(0, 0, 0), Vec<3>(1, 0, 0), Vec<3>(1, 1, 0), Vec<3>(0, 1, 0),
         Vec<3>(0, 0, 1), Vec<3>(1, 0, 1), Vec<3>(1, 1, 1 + a), Vec<3>(0, 1, 1)};
  const ElementPoint<3> ph = element_points<3>(h, false)[0];
  CHECK(ph.volume == doctest::Approx(1 + a / 4).epsilon(1e-15));
  CHECK(ph.x[0] == doctest::Approx((0.5 + a / 6) / (1 + a / 4)).epsilon(1e-14));
  double Vq = 0;
  for (const ElementPoint<3>& p : element_points<3>(h, true)) Vq += p.volume;
  CHECK(Vq == doctest::Approx(1 + a / 4).epsilon(1e-15));
  // a bow-tie (two corners swapped) is refused, naming the element
  q.tag = 17;
  std::swap(q.x[2], q.x[3]);
  try {
    element_points<2>(q, false);
    FAIL("an inverted quadrangle is an error");
  } catch (const InputError& e) {
    CHECK(has(e.what(), "element 17: inverted"));
  }
}

TEST_CASE("gmsh: bad files are refused, naming the file and the element or node") {
  test::TempDir dir("gmsh_bad");
  std::string text;
  {
    std::ifstream in(kData + "embankment_ascii.msh");
    text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  auto error_of = [&](const std::string& content) {
    std::ofstream(dir.file("m.msh")) << content;
    try {
      read_mesh_body<2>(dir.file("m.msh"), "", Placement{});
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  std::string v2 = text;
  v2.replace(v2.find("4.1 0 8"), 7, "2.2 0 8");
  CHECK(has(error_of(v2), "m.msh:2: Gmsh mesh format 2.2 is not supported"));
  // the first triangle's first node replaced by a tag $Nodes lacks
  std::string missing = text;
  const std::size_t block = missing.find("\n2 1 2 ", missing.find("$Elements"));
  const std::size_t line = missing.find('\n', block + 1) + 1; // "tag n1 n2 n3"
  const std::size_t tag_end = missing.find(' ', line);
  const std::string tag = missing.substr(line, tag_end - line);
  const std::size_t node_end = missing.find(' ', tag_end + 1);
  missing.replace(tag_end + 1, node_end - tag_end - 1, "99999");
  const std::string e = error_of(missing);
  CHECK(has(e, "m.msh:"));
  CHECK(has(e, "element " + tag + ": node 99999 is not in $Nodes"));
  // a second-order element type
  std::string order2 = text;
  order2.replace(block, 7, "\n2 1 9 ");
  CHECK(has(error_of(order2), "type 9 (6-node triangle) is not supported"));
  // truncated
  CHECK(has(error_of(text.substr(0, text.size() / 2)), "m.msh:"));
  CHECK(has(error_of("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"), "the mesh has no $Nodes"));
  // an unknown group names the ones there are
  try {
    read_mesh_body<2>(kExamples + "embankment.msh", "dam", Placement{});
    FAIL("an unknown group is an error");
  } catch (const InputError& err) {
    CHECK(has(err.what(), "no physical group \"dam\" of dimension 2 (it has \"fill\", \"core\")"));
  }
}

TEST_CASE("scene: stl and mesh bodies seed particles whose volume matches the shape's") {
  const std::string materials =
      "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 2.0\nyoung = 1.0\npoisson = 0.0\n";
  // the embankment: one particle per element (or per quadrature point), exact areas
  for (const char* seeding : {"element", "quadrature"}) {
    const std::string text = "[simulation]\ndimension = 2\nt_end = 1.0\n[basis]\nkind = \"linear\"\n[grid]\nlower = [-1, -1]\nupper = [13, 5]\n"
                             "cells = [14, 6]\n" + materials +
                             "[[body]]\nmaterial = \"m\"\nshape = \"mesh\"\nfile = \"" + kExamples +
                             "embankment.msh\"\nseeding = \"" + seeding + "\"\ntranslate = [0.0, 0.5]\n";
    const Scene s = parse_scene(text, "mesh.toml");
    const Particles<2> P = seed_particles<2>(s, Vec<2>::Constant(1.0));
    double V = 0;
    for (double v : P.V) V += v;
    CHECK(V == doctest::Approx(22.5).epsilon(1e-13));
    CHECK(P.size() == s.bodies[0].file_particles);
    CHECK(s.bodies[0].lower[1] == 0.5); // translated
  }
  // a boundary from the mesh's physical group "base", placed as the body
  const std::string base = "[simulation]\ndimension = 2\nt_end = 1.0\n[basis]\nkind = \"linear\"\n[grid]\n"
                           "lower = [-1, -1]\nupper = [13, 5]\ncells = [14, 6]\n" + materials +
                           "[[body]]\nmaterial = \"m\"\nshape = \"mesh\"\nfile = \"" + kExamples +
                           "embankment.msh\"\n[[boundary]]\nfile = \"" + kExamples + "embankment.msh\"\n";
  const Scene placed = parse_scene(base + "physical = \"base\"\ntranslate = [0.0, 1.0]\nfix = [true, true]\n", "b.toml");
  CHECK(placed.boundaries[0].lower[0] == 0.0);
  CHECK(placed.boundaries[0].upper[0] == 12.0);
  CHECK(placed.boundaries[0].lower[1] == 1.0);
  CHECK(placed.boundaries[0].upper[1] == 1.0);
  try {
    parse_scene(base + "physical = \"fill\"\nfix = [true, true]\n", "b.toml"); // a group of surfaces
    FAIL("a boundary needs a group of lines in 2D");
  } catch (const InputError& e) {
    CHECK(has(e.what(), "b.toml:"));
    CHECK(has(e.what(), "no physical group \"fill\" of dimension 1"));
  }
  // the L prism from a binary STL file, rotated 90 degrees about z and scaled by 2 in z: seeded volume -> 6
  test::TempDir dir("stl_scene");
  write_binary(dir.file("l.stl"), l_prism());
  for (int cells : {16, 32}) {
    const std::string text = "[simulation]\ndimension = 3\nt_end = 1.0\n[basis]\nkind = \"linear\"\n[grid]\nlower = [-3, -1, -1]\n"
                             "upper = [1, 3, 3]\ncells = " + std::to_string(cells) + "\n" + materials +
                             "[[body]]\nmaterial = \"m\"\nshape = \"stl\"\nfile = \"" + dir.file("l.stl") +
                             "\"\nscale = [1, 1, 2]\nrotate = [0, 0, 90]\n";
    const Scene s = parse_scene(text, "stl.toml");
    CHECK(s.bodies[0].lower[0] == doctest::Approx(-2.0));
    CHECK(s.bodies[0].upper[2] == doctest::Approx(2.0));
    const Particles<3> P = seed_particles<3>(s, Vec<3>::Constant(4.0 / cells));
    double V = 0;
    for (double v : P.V) V += v;
    CHECK(V == doctest::Approx(6.0).epsilon(1e-12)); // the L's faces lie on cell faces at these spacings: exact
  }
}
