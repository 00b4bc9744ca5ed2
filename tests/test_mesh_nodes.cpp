// A mesh body's vertices as the nodes of `ul` mode (`nodes = "mesh"`, the
// classic OTM discretisation): the nodes are the vertices, each element one
// particle at its centroid with its volume and mass; the bases for node
// clouds reproduce constants and linear fields there, before and after a
// homogeneous deformation of the nodes; a step reproduces a homogeneous
// motion; two bodies that collide keep their momentum; F-bar's patches hold
// one volume change; what cannot work is refused with a clear message.
#include <doctest/doctest.h>

#include "otmpm/assembly/assembler.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/distributed/comm.hpp"
#include "otmpm/distributed/local_parts.hpp"
#include "otmpm/scene/file_shapes.hpp"

#include <algorithm>
#include <map>
#include <string>

using namespace otmpm;

namespace {

/// The unit cube in tetrahedra (physical volume "cube").
const std::string kCube = std::string(OTMPM_SOURCE_DIR) + "/tests/scenes/geometry/cube_tets.msh";

/// A steel cube of the mesh in `ul` mode, its vertices the nodes, on `basis`.
Scene cube_scene(const std::string& basis, const std::vector<std::string>& sets = {}) {
  const std::string text = R"(
[simulation]
dimension = 3
mode = "ul"
integrator = "fe"
t_end = 1.0e-2
cfl = 0.3
[basis]
kind = ")" + basis + R"("
[grid]
lower = [0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0]
cells = [2, 2, 2]
[[material]]
name = "steel"
model = "linear_elastic"
density = 7800.0
young = 2.0e11
poisson = 0.3
[[body]]
name = "cube"
material = "steel"
shape = "mesh"
file = ")" + kCube + R"("
physical = "cube"
nodes = "mesh"
[output]
every = 0.0
)";
  return parse_scene(text, "cube.toml", sets);
}

/// The bases that take a node cloud (BasisKind::needs_lattice false).
std::vector<std::string> cloud_bases() {
  std::vector<std::string> out;
  for (const BasisKind& k : basis_kinds())
    if (!k.needs_lattice) out.emplace_back(k.name);
  return out;
}

/// The bases that take a mesh's vertices: as a cloud, or on the mesh's elements.
std::vector<std::string> mesh_bases() {
  std::vector<std::string> out;
  for (const BasisKind& k : basis_kinds())
    if (!k.needs_lattice || k.mesh_elements) out.emplace_back(k.name);
  return out;
}

/// Checks that `table` reproduces constants and the linear field X at every
/// point: sum N_I = 1, sum N_I X_I = x_p, sum grad N_I = 0, sum X_I (x)
/// grad N_I = G (the identity for X = x; F^-1 after a homogeneous deformation F).
void check_reproduction(const BasisTable<3>& table, const AlignedVector<Vec<3>>& X_nodes,
                        const AlignedVector<Vec<3>>& X_points, const Mat<3>& G, double tol) {
  for (int p = 0; p < static_cast<int>(X_points.size()); ++p) {
    double sum = 0;
    Vec<3> X = Vec<3>::Zero(), dsum = Vec<3>::Zero();
    Mat<3> grad = Mat<3>::Zero();
    for (int e = table.begin(p); e < table.end(p); ++e) {
      const Vec<3>& XI = X_nodes[static_cast<std::size_t>(table.node[e])];
      sum += table.N[e];
      X += table.N[e] * XI;
      dsum += table.dN[e];
      grad += XI * table.dN[e].transpose();
    }
    REQUIRE(std::abs(sum - 1.0) < tol);
    REQUIRE((X - X_points[static_cast<std::size_t>(p)]).norm() < tol);
    REQUIRE(dsum.norm() < tol * 10);
    REQUIRE((grad - G).norm() < tol * 10);
  }
}

} // namespace

TEST_CASE("mesh nodes: the vertices are the nodes, each element one particle at its centroid") {
  const MeshBody<3> mesh = read_mesh_body<3>(kCube, "cube", Placement{});
  for (const std::string& basis : mesh_bases()) {
    CAPTURE(basis);
    EngineParts<3> parts = assemble_parts<3>(cube_scene(basis));
    const NodeSet<3>& nodes = parts.basis->nodes();
    CHECK(nodes.layout() == NodeLayout::cloud);
    REQUIRE(nodes.size() == static_cast<int>(mesh.vertices.size()));
    for (int I = 0; I < nodes.size(); ++I) CHECK(nodes.position(I) == mesh.vertices[static_cast<std::size_t>(I)]);
    const Particles<3>& P = parts.particles;
    REQUIRE(P.size() == static_cast<int>(mesh.elements.size()));
    double V = 0;
    for (int p = 0; p < P.size(); ++p) {
      const ElementPoint<3> c = element_points<3>(mesh.elements[static_cast<std::size_t>(p)], false).front();
      CHECK(P.X[p] == c.x);
      CHECK(P.V[p] == c.volume);
      CHECK(P.m[p] == doctest::Approx(7800.0 * c.volume).epsilon(1e-15));
      V += P.V[p];
    }
    CHECK(V == doctest::Approx(1.0).epsilon(1e-13)); // the cube's volume
  }
}

TEST_CASE("mesh nodes: two bodies of one mesh share the vertices of their interface (2D)") {
  const std::string dir = std::string(OTMPM_SOURCE_DIR) + "/examples/geometry/";
  const Scene s = load_scene(dir + "embankment.toml", {"simulation.mode=ul", "basis.kind=lme", "body.core.nodes=mesh",
                                                       "body.shoulders.nodes=mesh"});
  const EngineParts<2> parts = assemble_parts<2>(s);
  const MeshBody<2> core = read_mesh_body<2>(dir + "embankment.msh", "core", Placement{});
  const MeshBody<2> fill = read_mesh_body<2>(dir + "embankment.msh", "fill", Placement{});
  const MeshBody<2> all = read_mesh_body<2>(dir + "embankment.msh", "", Placement{});
  CHECK(parts.basis->nodes().size() == static_cast<int>(all.vertices.size()));
  CHECK(all.vertices.size() < core.vertices.size() + fill.vertices.size()); // the interface, once
  CHECK(parts.particles.size() == static_cast<int>(core.elements.size() + fill.elements.size()));
  CHECK(parts.dirichlet.node.size() > 0); // the base: the vertices on y = 0
  for (int I : parts.dirichlet.node) CHECK(parts.basis->nodes().position(I)[1] == doctest::Approx(0.0));
}

TEST_CASE("mesh nodes: the bases reproduce linear fields at the particles, also after a homogeneous "
          "deformation (patch test)") {
  Mat<3> F; // a stretch with shear, and a translation
  F << 1.2, 0.1, 0.0, 0.05, 0.9, 0.2, 0.0, 0.1, 1.1;
  const Vec<3> b(0.3, -0.2, 0.1);
  for (const std::string& basis : mesh_bases()) {
    CAPTURE(basis);
    EngineParts<3> parts = assemble_parts<3>(cube_scene(basis));
    Basis<3>& B = *parts.basis;
    const AlignedVector<Vec<3>> X_nodes = B.nodes().positions();
    const AlignedVector<Vec<3>>& X = parts.particles.X;
    B.bind_points(static_cast<int>(X.size()), true);
    BasisTable<3> table;
    B.evaluate_points(X, table);
    check_reproduction(table, X_nodes, X, Mat<3>::Identity(), 1e-9);
    // the nodes and the points moved by x = F X + b: the reference positions are reproduced, grad X = F^-1
    AlignedVector<Vec<3>> dx(X_nodes.size()), x(X.size());
    for (std::size_t I = 0; I < dx.size(); ++I) dx[I] = (F - Mat<3>::Identity()) * X_nodes[I] + b;
    for (std::size_t p = 0; p < x.size(); ++p) x[p] = F * X[p] + b;
    B.nodes().advect(dx);
    B.nodes_moved(dx);
    B.evaluate_points(x, table);
    check_reproduction(table, X_nodes, X, F.inverse(), 1e-9);
  }
}

TEST_CASE("mesh nodes: linear on the mesh's elements finds a point's element from any hint, refuses one outside") {
  EngineParts<3> parts = assemble_parts<3>(cube_scene("linear"));
  const Basis<3>& B = *parts.basis;
  Stencil<3> st;
  for (const Vec<3>& x : {Vec<3>(0.13, 0.71, 0.42), Vec<3>(0.999, 0.001, 0.5), Vec<3>(1.0 + 1e-3, 0.3, 0.6)}) {
    for (int hint : {0, 7, static_cast<int>(parts.particles.size()) - 1}) {
      Index<3> cell{hint, 0, 0};
      PointQuery<3> q;
      q.x = x;
      q.cell_hint = &cell;
      B.evaluate(q, st);
      double sum = 0;
      Vec<3> y = Vec<3>::Zero();
      for (int i = 0; i < st.size(); ++i) sum += st.N[static_cast<std::size_t>(i)], y += st.N[static_cast<std::size_t>(i)] * B.nodes().position(st.node[static_cast<std::size_t>(i)]);
      CHECK(st.size() == 4); // a tetrahedron's corners
      CHECK(std::abs(sum - 1.0) < 1e-12);
      CHECK((y - x).norm() < 1e-12);
    }
  }
  PointQuery<3> far;
  far.x = Vec<3>(1.5, 0.5, 0.5);
  CHECK_THROWS_WITH_AS(B.evaluate(far, st), doctest::Contains("outside every element of the mesh"), BasisError);
}

TEST_CASE("mesh nodes: a step reproduces a homogeneous motion (consistent mass, patch test of the engine)") {
  Mat<3> L; // a velocity gradient, 1/s
  L << 2.0, -1.0, 0.5, 0.3, -1.5, 1.0, -0.4, 0.2, 1.0;
  for (const std::string& basis : mesh_bases()) {
    CAPTURE(basis);
    EngineParts<3> parts = assemble_parts<3>(cube_scene(basis, {"simulation.mass=consistent"}));
    Particles<3>& P = parts.particles;
    for (int p = 0; p < P.size(); ++p) P.v[p] = L * P.X[p];
    Engine<3> e(std::move(parts));
    e.step();
    const double dt = e.last_dt();
    const Mat<3> dF = Mat<3>::Identity() + dt * L;
    const Particles<3>& Q = e.particles();
    for (int p = 0; p < Q.size(); ++p) {
      REQUIRE((Q.F[p] - dF).norm() < 1e-9 * dt * L.norm());
      REQUIRE((Q.x[p] - dF * Q.X[p]).norm() < 1e-9 * dt * L.norm());
    }
  }
}

TEST_CASE("mesh nodes: two cubes collide and keep their momentum") {
  // the cloud bases: their supports reach across bodies (a mesh's elements do not: two meshes meet only at shared vertices)
  for (const std::string& basis : cloud_bases()) {
    CAPTURE(basis);
    Scene s = cube_scene(basis, {"body.cube.velocity=[200.0, 50.0, 0.0]", "simulation.integrator=npc"});
    BodySection other = s.bodies.front(); // the same cube 0.15 m to the right of the first, 0.2 m higher in y
    other.name = "other";
    other.translate = {1.15, 0.2, 0.0};
    other.lower[0] += 1.15, other.upper[0] += 1.15, other.lower[1] += 0.2, other.upper[1] += 0.2;
    other.velocity = {-100.0, 0.0, 10.0};
    s.bodies.push_back(other);
    Engine<3> e(assemble_parts<3>(s));
    const Vec<3> p0 = e.momentum();
    const double scale = 7800.0 * 200.0; // |m v| of the first cube
    REQUIRE((p0 - 7800.0 * Vec<3>(100.0, 50.0, 10.0)).norm() < 1e-12 * scale);
    while (e.time() < 1e-3) { // they meet after 0.5 ms
      e.step();
      REQUIRE((e.momentum() - p0).norm() < 1e-9 * scale);
    }
    const Particles<3>& P = e.particles();
    double first = 0; // the first cube's momentum along x, 7800 x 200 at t = 0
    for (int p = 0; p < P.size(); ++p)
      if (P.body[p] == 0) first += P.m[p] * P.v[p][0];
    CHECK(first < 0.5 * scale); // the collision took more than half of it
  }
}

TEST_CASE("mesh nodes: a cube squeezed while it flies keeps its momentum") {
  Mat<3> L = Mat<3>::Zero(); // squeezed along x, stretched along y, 1/s
  L(0, 0) = -100.0, L(1, 1) = 50.0;
  for (const std::string& basis : mesh_bases()) {
    CAPTURE(basis);
    EngineParts<3> parts = assemble_parts<3>(cube_scene(basis, {"simulation.integrator=npc"}));
    Particles<3>& P = parts.particles;
    for (int p = 0; p < P.size(); ++p) P.v[p] = Vec<3>(20.0, -10.0, 5.0) + L * (P.X[p] - Vec<3>::Constant(0.5));
    Engine<3> e(std::move(parts));
    const Vec<3> p0 = e.momentum();
    const double scale = 7800.0 * 50.0;
    while (e.time() < 2e-4) {
      e.step();
      REQUIRE((e.momentum() - p0).norm() < 1e-9 * scale);
    }
    e.update_energy();
    CHECK(e.energy().strain > 1e-3 * e.energy().kinetic); // the squeeze loaded the cube
  }
}

TEST_CASE("mesh nodes: F-bar patches are the grid's cells at t = 0 (one volume change each)") {
  Scene s = cube_scene("lme", {"body.cube.velocity=[0.0, 0.0, -200.0]", "simulation.volumetric=fbar",
                               "simulation.integrator=npc"});
  s.walls.push_back({"floor", {0, 0, 0}, {0, 0, 1}, {0, 0, 0}, 0.0, {}});
  EngineParts<3> parts = assemble_parts<3>(s);
  const CartesianGrid<3> grid = *parts.settings.patch_grid;
  Engine<3> e(std::move(parts));
  for (int n = 0; n < 20; ++n) e.step();
  const Particles<3>& P = e.particles();
  std::map<int, std::pair<double, double>> J; // patch -> (min, max) det F
  double lo = 1e9, hi = -1e9;
  for (int p = 0; p < P.size(); ++p) {
    const double j = P.F[p].determinant();
    auto [it, fresh] = J.try_emplace(grid.node_id(grid.cell_of(P.X[p])), j, j);
    it->second = {std::min(it->second.first, j), std::max(it->second.second, j)};
    lo = std::min(lo, j), hi = std::max(hi, j);
  }
  REQUIRE(J.size() > 1);
  CHECK(hi - lo > 1e-4); // the impact compresses the cube unevenly
  for (const auto& [patch, range] : J) CHECK(range.second - range.first < 1e-12);
}

TEST_CASE("mesh nodes: a node reset lays the nodes out on the grid's lattice") {
  Scene s = cube_scene("lme", {"body.cube.velocity=[0.0, 0.0, -200.0]", "simulation.node_reset=0.95",
                               "simulation.integrator=npc"});
  s.walls.push_back({"floor", {0, 0, 0}, {0, 0, 1}, {0, 0, 0}, 0.0, {}});
  Engine<3> e(assemble_parts<3>(s));
  while (e.node_resets() == 0 && e.steps() < 400) e.step();
  REQUIRE(e.node_resets() == 1);
  CHECK(e.basis().nodes().layout() == NodeLayout::cartesian);
  for (int n = 0; n < 10; ++n) e.step(); // and it goes on, on the lattice
  for (int p = 0; p < e.particles().size(); ++p) REQUIRE(e.particles().x[p].allFinite());
}

TEST_CASE("mesh nodes: refused with a lattice basis, in mpm mode, with a body on the lattice, under mpirun") {
  for (const BasisKind& k : basis_kinds()) {
    if (!k.needs_lattice || k.mesh_elements) continue;
    CAPTURE(k.name);
    try {
      (void)cube_scene(std::string(k.name));
      FAIL("accepted");
    } catch (const InputError& err) {
      const std::string what = err.what(); // uGIMP's fixed grid is refused first
      CHECK((what.find("needs the nodes of a lattice") != std::string::npos ||
             what.find("its nodes cannot move") != std::string::npos));
      CHECK(what.find(std::string(k.name)) != std::string::npos);
      CHECK(std::string(err.what()).find("cube.toml") != std::string::npos);
    }
  }
  CHECK_THROWS_WITH_AS(cube_scene("lme", {"body.cube.nodes=vertices"}), doctest::Contains("body.cube.nodes"),
                       InputError);
  Scene coded = cube_scene("lme"); // a scene changed in code: validate_scene's check
  coded.bodies[0].nodes = "vertices";
  CHECK_THROWS_WITH_AS(assemble_parts<3>(coded),
                       doctest::Contains("must be one of \"lattice\", \"mesh\" (got \"vertices\")"), InputError);
  CHECK_THROWS_WITH_AS(cube_scene("lme", {"simulation.mode=mpm"}),
                       doctest::Contains("nodes = \"mesh\" needs simulation.mode = \"ul\""), InputError);
  Scene mixed = cube_scene("lme");
  BodySection box;
  box.name = "box";
  box.material = "steel";
  box.lower = {2, 0, 0}, box.upper = {3, 1, 1};
  mixed.bodies.push_back(box);
  CHECK_THROWS_WITH_AS(assemble_parts<3>(mixed), doctest::Contains("a scene has one node set"), InputError);
  CHECK_THROWS_WITH_AS(distributed::plan_ranks<3>(cube_scene("lme"), distributed::Comm::self()),
                       doctest::Contains("run in one process only"), InputError);
  CHECK_THROWS_WITH_AS(distributed::seeded_parts<3>(cube_scene("lme"), distributed::Comm::self()),
                       doctest::Contains("run in one process only"), InputError);
}
