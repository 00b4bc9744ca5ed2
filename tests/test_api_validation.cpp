// The library validates its own arguments: every public entry point
// refuses bad sizes and non-finite or out-of-range values with the documented
// exception type (InputError: a bad value; std::invalid_argument: the caller
// broke the interface; BasisError: a point that cannot be evaluated;
// InstabilityError: a state that stopped making sense) and a message that
// names the function or scene key, the argument and the bad value. One small
// TEST_CASE per entry point and kind of bad argument; each also checks that a
// good call passes, so that a check which rejects everything fails here too.
#include "otmpm/assembly/exact_solutions.hpp"
#include "otmpm/basis/basis.hpp"
#include "otmpm/basis/bspline.hpp"
#include "otmpm/basis/lme.hpp"
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/engine/mass_matrix.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/materials/material.hpp"
#include "otmpm/particles/particles.hpp"
#include "otmpm/reference/exact.hpp"
#include "otmpm/reference/solutions.hpp"
#include "otmpm/scene/scene.hpp"
#include "otmpm/scene/validate.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <limits>
#include <stdexcept>
#include <string>
#include <unistd.h>

using namespace otmpm;

namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();

/// Runs f and returns the message of the E it throws; a failed check (and "")
/// when it throws nothing. Any other exception escapes and fails the test.
template <class E> std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  FAIL_CHECK("no exception was thrown");
  return "";
}

/// Checks that f throws E with every one of `parts` in its message.
template <class E> void expect_error(const std::function<void()>& f, std::initializer_list<const char*> parts) {
  const std::string message = message_of<E>(f);
  for (const char* part : parts) CHECK_MESSAGE(message.find(part) != std::string::npos, "'", part, "' not in: ", message);
}

template <int D> CartesianGrid<D> unit_grid(int cells) {
  CartesianGrid<D> g;
  g.cells.fill(cells);
  return g;
}

/// A valid 1D scene built in code (never through parse_scene): a bar of
/// 6 cells x 2 particles on a grid of 10 cells.
Scene code_scene() {
  Scene s;
  s.simulation.dimension = 1;
  s.simulation.t_end = 1e-3;
  s.basis.kind = "linear";
  s.grid.cells = {10, 1, 1};
  MaterialSection m;
  m.name = "steel";
  m.density = 1000.0;
  m.young = 1e6;
  s.materials.push_back(m);
  BodySection b;
  b.name = "bar";
  b.material = "steel";
  b.lower = {0.2, 0.0, 0.0};
  b.upper = {0.8, 1.0, 1.0};
  s.bodies.push_back(b);
  return s;
}

/// Engine<D>(s) must throw an InputError naming `key` (and `parts`).
template <int D = 1> void expect_scene_error(const Scene& s, const char* key, std::initializer_list<const char*> parts = {}) {
  const std::string message = message_of<InputError>([&] { Engine<D> e = assemble<D>(s); });
  const std::string named = "key '" + std::string(key) + "'";
  CHECK_MESSAGE(message.find(named) != std::string::npos, named, " not in: ", message);
  for (const char* part : parts) CHECK_MESSAGE(message.find(part) != std::string::npos, "'", part, "' not in: ", message);
}

/// A 1D basis table of three particles on three nodes (a regular mass matrix).
BasisTable<1> small_table() {
  BasisTable<1> t;
  t.offset = {0, 2, 4, 6};
  t.node = {0, 1, 0, 1, 1, 2};
  t.N = {0.75, 0.25, 0.25, 0.75, 0.5, 0.5};
  t.dN.assign(6, Vec<1>::Zero());
  return t;
}

/// A result file path in the temporary directory, removed with its sidecar.
struct TempFile {
  std::filesystem::path path = std::filesystem::temp_directory_path() /
                               ("otmpm_api_validation_" + std::to_string(::getpid()) + ".h5");
  ~TempFile() {
    std::error_code ec;
    std::filesystem::remove(path, ec);
    std::filesystem::remove(std::filesystem::path(path).replace_extension(".xdmf"), ec);
  }
};

} // namespace

// ---------------------------------------------------------------- core

TEST_CASE("require: throws the chosen type with the parts formatted, only on failure") {
  CHECK_NOTHROW(require(true, "never ", 1));
  expect_error<std::invalid_argument>([] { require<std::invalid_argument>(false, "f: n = ", 3, ", x = ", 0.5, ", p = ", Vec<2>(1.0, kNaN)); },
                                      {"f: n = 3, x = 0.5, p = (1, nan)"});
  expect_error<InputError>([] { require(false, "default type"); }, {"default type"});
}

// ---------------------------------------------------------------- nodes

TEST_CASE("CartesianGrid::validate: cells < 1 names the axis and the count") {
  CHECK_NOTHROW(unit_grid<2>(3).validate());
  CartesianGrid<2> g = unit_grid<2>(3);
  g.cells[1] = 0;
  expect_error<InputError>([&] { g.validate(); }, {"cells[1]", "got 0"});
  expect_error<InputError>([&] { NodeSet<2>::cartesian(g); }, {"cells[1]"});
}

TEST_CASE("CartesianGrid::validate: non-finite or inverted bounds name the axis") {
  CartesianGrid<2> g = unit_grid<2>(3);
  g.upper[1] = kNaN;
  expect_error<InputError>([&] { g.validate(); }, {"axis 1", "upper", "nan"});
  g = unit_grid<2>(3);
  g.lower[0] = 2.0;
  expect_error<InputError>([&] { g.validate(); }, {"axis 0", "lower = (2, 0)"});
}

TEST_CASE("CartesianGrid::validate: a node count beyond int is refused") {
  const CartesianGrid<2> g = unit_grid<2>(100000);
  expect_error<InputError>([&] { g.validate(); }, {"cells = [100000, 100000]", "more nodes than an int"});
}

TEST_CASE("NodeSet::perturbed: a fraction below 0, from 0.5 on, or NaN") {
  CHECK_NOTHROW(NodeSet<2>::perturbed(unit_grid<2>(3), 0.2, 1u));
  expect_error<InputError>([] { NodeSet<2>::perturbed(unit_grid<2>(3), 0.5, 1u); }, {"fraction", "got 0.5"});
  expect_error<InputError>([] { NodeSet<2>::perturbed(unit_grid<2>(3), kNaN, 1u); }, {"fraction", "nan"});
}

TEST_CASE("NodeSet::cloud: empty positions, bad spacing, a non-finite position") {
  AlignedVector<Vec<2>> x{Vec<2>(0, 0), Vec<2>(1, 0), Vec<2>(0, 1), Vec<2>(1, 1)};
  CHECK_NOTHROW(NodeSet<2>::cloud(x, 1.0));
  expect_error<InputError>([] { NodeSet<2>::cloud({}, 1.0); }, {"NodeSet::cloud", "positions is empty"});
  expect_error<InputError>([&] { NodeSet<2>::cloud(x, kInf); }, {"spacing", "inf"});
  x[3][1] = kNaN;
  expect_error<InputError>([&] { NodeSet<2>::cloud(x, 1.0); }, {"positions[3]", "(1, nan)"});
}

TEST_CASE("NodeSet::advect: wrong size is an interface error, a NaN increment an instability") {
  NodeSet<1> s = NodeSet<1>::cartesian(unit_grid<1>(4));
  const AlignedVector<Vec<1>> x0 = s.positions();
  expect_error<std::invalid_argument>([&] { s.advect(AlignedVector<Vec<1>>(2, Vec<1>::Zero())); },
                                      {"NodeSet::advect", "dx has 2", "5 nodes"});
  AlignedVector<Vec<1>> dx(5, Vec<1>(0.01));
  dx[3] = Vec<1>(kNaN);
  expect_error<InstabilityError>([&] { s.advect(dx); }, {"dx[3]", "not finite"});
  CHECK(s.positions() == x0); // refused moves leave the set as it was
  CHECK(s.on_lattice());
  dx[3] = Vec<1>(0.01);
  CHECK_NOTHROW(s.advect(dx));
}

TEST_CASE("NodeSet::set_positions: wrong size or a non-finite position") {
  NodeSet<1> s = NodeSet<1>::cartesian(unit_grid<1>(4));
  expect_error<std::invalid_argument>([&] { s.set_positions(AlignedVector<Vec<1>>(3, Vec<1>::Zero())); },
                                      {"set_positions", "x has 3"});
  AlignedVector<Vec<1>> x = s.positions();
  x[0] = Vec<1>(-kInf);
  expect_error<InstabilityError>([&] { s.set_positions(x); }, {"x[0]", "-inf"});
}

TEST_CASE("NodeSet::within: a negative radius is refused, a non-finite point has no neighbours") {
  const NodeSet<2> lattice = NodeSet<2>::cartesian(unit_grid<2>(4));
  const NodeSet<2> cloud = NodeSet<2>::cloud(lattice.positions(), 0.25);
  std::vector<int> out;
  expect_error<std::invalid_argument>([&] { lattice.within(Vec<2>(0.5, 0.5), -1.0, out); }, {"radius", "-1"});
  expect_error<std::invalid_argument>([&] { cloud.within(Vec<2>(0.5, 0.5), kNaN, out); }, {"radius", "nan"});
  expect_error<std::invalid_argument>([&] { lattice.within(Vec<2>(0.5, 0.5), kInf, out); }, {"radius", "inf"});
  for (const NodeSet<2>* s : {&lattice, &cloud}) {
    out.clear();
    s->within(Vec<2>(kNaN, 0.5), 0.3, out);
    CHECK(out.empty());
    s->within(Vec<2>(0.5, 0.5), 0.3, out);
    CHECK(out.size() == 5u);
  }
}

// ---------------------------------------------------------------- bases

TEST_CASE("make_basis: an unknown kind is named") {
  BasisOptions opt;
  opt.kind = "quintic";
  expect_error<InputError>([&] { make_basis<2>(opt, NodeSet<2>::cartesian(unit_grid<2>(4))); },
                           {"basis kind", "'quintic'"});
}

TEST_CASE("make_basis: LME and max-ent options out of range name the option") {
  const NodeSet<2> nodes = NodeSet<2>::cartesian(unit_grid<2>(4));
  auto lme = [&](auto set) {
    BasisOptions opt;
    opt.kind = "lme";
    set(opt);
    return [opt, &nodes] { make_basis<2>(opt, nodes); };
  };
  CHECK_NOTHROW(lme([](BasisOptions&) {})());
  expect_error<InputError>(lme([](BasisOptions& o) { o.values["gamma_lme"] = 0.0; }), {"gamma_lme", "got 0"});
  expect_error<InputError>(lme([](BasisOptions& o) { o.values["gamma_lme"] = kNaN; }), {"gamma_lme", "nan"});
  expect_error<InputError>(lme([](BasisOptions& o) { o.values["gamma_lme"] = 1e308; }), {"support radius"});
  expect_error<InputError>(lme([](BasisOptions& o) { o.values["tolerance"] = 1.0; }), {"tolerance", "(0, 1)"});
  expect_error<InputError>(lme([](BasisOptions& o) { o.values["newton_tolerance"] = -1.0; }), {"newton_tolerance"});
  expect_error<InputError>(lme([](BasisOptions& o) { o.values["max_newton_iterations"] = 0; }), {"max_newton_iterations"});
  BasisOptions maxent;
  maxent.kind = "maxent";
  maxent.values["d_max"] = kInf;
  expect_error<InputError>([&] { make_basis<2>(maxent, nodes); }, {"d_max", "inf"});
}

TEST_CASE("make_basis: a uGIMP half-width that is not in (0, h/2) or h/2 names the axis") {
  BasisOptions opt;
  opt.kind = "ugimp";
  opt.particle_half_width[0] = opt.particle_half_width[1] = 0.0625;
  CHECK_NOTHROW(make_basis<2>(opt, NodeSet<2>::cartesian(unit_grid<2>(4))));
  opt.particle_half_width[1] = kNaN;
  expect_error<InputError>([&] { make_basis<2>(opt, NodeSet<2>::cartesian(unit_grid<2>(4))); },
                           {"half-width on axis 1"});
}

TEST_CASE("Basis::evaluate: a non-finite point is a BasisError naming the family and the point, in every family") {
  const CartesianGrid<2> g = unit_grid<2>(4);
  BasisOptions opt;
  opt.particle_half_width[0] = opt.particle_half_width[1] = 0.0625;
  for (const char* kind : {"linear", "ugimp", "bspline2", "bspline3", "lme", "maxent", "linear-perturbed"}) {
    CAPTURE(kind);
    const bool perturbed = std::string(kind) == "linear-perturbed";
    opt.kind = perturbed ? "linear" : kind;
    const auto b = make_basis<2>(opt, perturbed ? NodeSet<2>::perturbed(g, 0.2, 3u) : NodeSet<2>::cartesian(g));
    Stencil<2> st;
    PointQuery<2> q;
    q.x = Vec<2>(0.5, 0.5);
    q.id = 7;
    CHECK_NOTHROW(b->evaluate(q, st));
    for (const Vec<2>& bad : {Vec<2>(0.5, kNaN), Vec<2>(kInf, 0.5)}) {
      q.x = bad;
      expect_error<BasisError>([&] { b->evaluate(q, st); }, {opt.kind.c_str(), "point 7", "not finite"});
    }
  }
}

TEST_CASE("fill_basis_table: lambda and cell_hint of the wrong size are interface errors") {
  const auto b = make_basis<1>(BasisOptions{}, NodeSet<1>::cartesian(unit_grid<1>(4)));
  const AlignedVector<Vec<1>> x(3, Vec<1>(0.5));
  BasisTable<1> t;
  AlignedVector<Vec<1>> lambda(2);
  std::vector<Index<1>> hint(4);
  expect_error<std::invalid_argument>([&] { fill_basis_table(*b, x, &lambda, nullptr, t); },
                                      {"fill_basis_table", "lambda has 2", "3 points"});
  expect_error<std::invalid_argument>([&] { fill_basis_table(*b, x, nullptr, &hint, t); },
                                      {"fill_basis_table", "cell_hint has 4"});
  lambda.resize(3);
  hint.resize(3);
  CHECK_NOTHROW(fill_basis_table(*b, x, &lambda, &hint, t));
}

TEST_CASE("fill_basis_table: a non-finite point is a BasisError naming the particle") {
  const auto b = make_basis<1>(BasisOptions{}, NodeSet<1>::cartesian(unit_grid<1>(4)));
  AlignedVector<Vec<1>> x(3, Vec<1>(0.5));
  x[2] = Vec<1>(kNaN);
  BasisTable<1> t;
  expect_error<BasisError>([&] { fill_basis_table(*b, x, nullptr, nullptr, t); }, {"particle 2", "not finite"});
}

TEST_CASE("KnotVector: bad vertices, degree and uniform arguments are named") {
  CHECK_NOTHROW(KnotVector({0.0, 0.5, 1.0}, 2));
  expect_error<InputError>([] { KnotVector({0.0, 0.5, kNaN}, 2); }, {"vertices", "v[2] = nan"});
  expect_error<InputError>([] { KnotVector({0.0}, 2); }, {"vertices", "got 1"});
  expect_error<InputError>([] { KnotVector({0.0, 1.0}, 5); }, {"degree 5"});
  expect_error<InputError>([] { KnotVector::uniform(0.0, kInf, 4, 2); }, {"KnotVector::uniform", "upper = inf"});
  expect_error<InputError>([] { KnotVector::uniform(0.0, 1.0, 0, 2); }, {"cells = 0"});
}

TEST_CASE("KnotVector: an index out of range is an interface error, a non-finite x a BasisError") {
  const KnotVector kv = KnotVector::uniform(0.0, 1.0, 4, 2); // 4 cells, 6 basis functions
  CHECK_NOTHROW(kv.greville(5));
  expect_error<std::invalid_argument>([&] { kv.greville(6); }, {"greville", "i = 6"});
  expect_error<std::invalid_argument>([&] { kv.evaluate_on_cell(0.5, 4); }, {"evaluate_on_cell", "cell 4"});
  expect_error<std::invalid_argument>([&] { kv.evaluate_on_cell(0.5, -1); }, {"cell -1"});
  expect_error<BasisError>([&] { kv.evaluate_on_cell(kNaN, 1); }, {"x = nan"});
}

TEST_CASE("KnotVector: interpolate and advected check the coefficient vector") {
  const KnotVector kv = KnotVector::uniform(0.0, 1.0, 4, 2);
  std::vector<double> d(6, 0.01);
  CHECK_NOTHROW(kv.advected(d));
  expect_error<std::invalid_argument>([&] { kv.interpolate(0.5, std::vector<double>(5)); }, {"c has 5", "6 basis"});
  expect_error<std::invalid_argument>([&] { kv.advected(std::vector<double>(7)); }, {"d has 7"});
  d[1] = kNaN;
  expect_error<InstabilityError>([&] { kv.advected(d); }, {"d[1] = nan"});
}

TEST_CASE("BsplineBasis: knot_vector axis and nodes_moved sizes, a NaN motion changes nothing") {
  BsplineBasis<2> b(unit_grid<2>(3), 2);
  expect_error<std::invalid_argument>([&] { b.knot_vector(2); }, {"knot_vector", "axis 2"});
  expect_error<std::invalid_argument>([&] { b.nodes_moved(AlignedVector<Vec<2>>(3, Vec<2>::Zero())); },
                                      {"nodes_moved", "dx has 3", "25 control points"});
  const std::vector<double> v0 = b.knot_vector(1).vertices();
  AlignedVector<Vec<2>> dx(25, Vec<2>::Zero());
  dx[7][1] = kNaN;
  expect_error<InstabilityError>([&] { b.nodes_moved(dx); }, {"not finite"});
  CHECK(b.knot_vector(1).vertices() == v0);
}

TEST_CASE("max-ent internals: the stencil bound needs R > 0, the prior a finite support") {
  const NodeSet<2> nodes = NodeSet<2>::cartesian(unit_grid<2>(4));
  CHECK(maxent::max_nodes_within(nodes, 0.3) >= 5);
  expect_error<std::invalid_argument>([&] { maxent::max_nodes_within(nodes, 0.0); }, {"radius R", "got 0"});
  expect_error<std::invalid_argument>([&] { maxent::max_nodes_within(nodes, kNaN); }, {"radius R", "nan"});
  maxent::GaussianPrior<2> prior;
  prior.beta = 0.0; // R = sqrt(-ln tol / 0) = inf
  using Lme = maxent::MaxEntBasis<2, maxent::GaussianPrior<2>>;
  expect_error<InputError>([&] { Lme(nodes, BasisOptions{}, prior, "lme"); }, {"support radius", "inf"});
}

// ---------------------------------------------------------------- materials

TEST_CASE("validate_material: density, young and poisson ranges name the material and the field") {
  MaterialParameters m{.name = "steel", .density = 1.0, .young = 1.0, .poisson = 0.0, .extra = {}};
  CHECK_NOTHROW(validate_material(m));
  m.density = 0.0;
  expect_error<InputError>([&] { validate_material(m); }, {"material 'steel'", "density", "got 0"});
  m.density = 1.0;
  m.young = kNaN;
  expect_error<InputError>([&] { validate_material(m); }, {"young", "nan"});
  m.young = 1.0;
  m.poisson = 0.5;
  expect_error<InputError>([&] { validate_material(m); }, {"poisson", "got 0.5"});
  m.poisson = 0.0;
  m.model = "hookean";
  expect_error<InputError>([&] { make_material<2>(m); }, {"material 'steel'", "unknown model 'hookean'", "neo_hookean"});
  m.model = "neo_hookean";
  m.extra["yield_stress"] = 1.0;
  expect_error<InputError>([&] { validate_material(m); }, {"has no parameter 'yield_stress'"});
}

TEST_CASE("the finite-strain laws: det F <= 0 or a non-finite F is an InstabilityError naming det F") {
  const ElasticConstants c{1.0, 1.0, 0.0};
  CHECK(neo_hookean_stress<2>(c, Mat<2>::Identity()).isZero(0.0));
  Mat<2> F = Mat<2>::Identity();
  F(1, 1) = -0.5;
  expect_error<InstabilityError>([&] { neo_hookean_stress<2>(c, F); }, {"neo_hookean", "det F = -0.5"});
  F(1, 1) = kNaN;
  expect_error<InstabilityError>([&] { linear_elastic_finite_stress<2>(c, F); }, {"det F = nan"});
}

// ---------------------------------------------------------------- mass matrix

TEST_CASE("MassMatrix::assemble: sizes of masses and flags must match the table and the nodes") {
  const BasisTable<1> t = small_table();
  const std::vector<double> m{1.0, 1.0, 1.0};
  const std::vector<char> active(3, 1), constrained(3, 0);
  MassMatrix<1> M;
  CHECK_NOTHROW(M.assemble(t, m, active, constrained, 3));
  expect_error<std::invalid_argument>([&] { M.assemble(t, {1.0}, active, constrained, 3); }, {"m_p has 1", "3 table rows"});
  expect_error<std::invalid_argument>([&] { M.assemble(t, m, {1, 1}, constrained, 3); }, {"active has 2"});
  expect_error<std::invalid_argument>([&] { M.assemble(t, m, active, {0}, 3); }, {"constrained has 1"});
}

TEST_CASE("MassMatrix::assemble: a node id outside the node count and a bad mass are refused") {
  const BasisTable<1> t = small_table();
  const std::vector<char> active(2, 1), constrained(2, 0);
  MassMatrix<1> M;
  expect_error<std::invalid_argument>([&] { M.assemble(t, {1.0, 1.0, 1.0}, active, constrained, 2); },
                                      {"table entry 5", "node 2", "[0, 2)"});
  expect_error<InputError>([&] { M.assemble(t, {1.0, -kInf, 1.0}, {1, 1, 1}, {0, 0, 0}, 3); }, {"m_p[1] = -inf"});
}

TEST_CASE("MassMatrix::solve: before assemble, or with wrong sizes") {
  MassMatrix<1> M;
  AlignedVector<Vec<1>> r(3, Vec<1>(1.0)), y(3, Vec<1>::Zero());
  expect_error<std::invalid_argument>([&] { M.solve(r, y); }, {"assemble() first"});
  M.assemble(small_table(), {1.0, 1.0, 1.0}, {1, 1, 1}, {0, 0, 0}, 3);
  CHECK_NOTHROW(M.solve(r, y));
  AlignedVector<Vec<1>> short_y(2);
  expect_error<std::invalid_argument>([&] { M.solve(r, short_y); }, {"MassMatrix::solve", "y 2", "3 nodes"});
}

// ---------------------------------------------------------------- particles

TEST_CASE("seed_particles: the grid spacing h must be finite and > 0 on every axis") {
  CHECK(seed_particles<1>(code_scene(), Vec<1>(0.1)).size() == 12);
  expect_error<InputError>([] { seed_particles<1>(code_scene(), Vec<1>(0.0)); }, {"h[0] = 0"});
  expect_error<InputError>([] { seed_particles<1>(code_scene(), Vec<1>(kNaN)); }, {"h[0] = nan"});
}

TEST_CASE("seed_particles: bad bodies name the body key") {
  Scene s = code_scene();
  s.bodies[0].particles_per_cell = 0;
  expect_error<InputError>([&] { seed_particles<1>(s, Vec<1>(0.1)); }, {"key 'body.bar.particles_per_cell'", "got 0"});
  s = code_scene();
  s.bodies[0].placement = "random";
  expect_error<InputError>([&] { seed_particles<1>(s, Vec<1>(0.1)); }, {"key 'body.bar.placement'", "random"});
  s = code_scene();
  s.bodies[0].material = "wood";
  expect_error<InputError>([&] { seed_particles<1>(s, Vec<1>(0.1)); }, {"key 'body.bar.material'", "wood"});
}

TEST_CASE("seed_particles: a particle count beyond int is refused before seeding") {
  expect_error<InputError>([] { seed_particles<1>(code_scene(), Vec<1>(1e-12)); },
                           {"key 'body.bar'", "more than an int can count"});
}

TEST_CASE("Particles::resize: a negative count is an interface error") {
  Particles<2> P;
  expect_error<std::invalid_argument>([&] { P.resize(-1); }, {"Particles::resize", "got -1"});
}

// ---------------------------------------------------------------- engine

TEST_CASE("Engine: a valid Scene built in code runs") {
  Engine<1> e = assemble<1>(code_scene());
  CHECK(e.particles().size() == 12);
  CHECK_NOTHROW(e.step());
}

TEST_CASE("Engine: the scene's dimension must be the engine's") {
  expect_scene_error<2>(code_scene(), "simulation.dimension", {"1D but the run is 2D"});
}

TEST_CASE("Engine: at least one material and one body") {
  Scene s = code_scene();
  s.bodies.clear();
  expect_scene_error(s, "body", {"at least one [[body]]"});
  s = code_scene();
  s.materials.clear();
  expect_scene_error(s, "material", {"at least one [[material]]"});
}

TEST_CASE("Engine: a body's material must be defined") {
  Scene s = code_scene();
  s.bodies[0].material = "wood";
  expect_scene_error(s, "body.bar.material", {"no [[material]] named \"wood\""});
}

TEST_CASE("Engine: names of materials, bodies, boundaries and walls are those the reader accepts") {
  // A scene built in code is held to read_name's rules: a name must be able
  // to name a result-file group and a --set key, and be unique in its kind
  // (a wall's or boundary's name names its history in the result file).
  Scene s = code_scene();
  s.materials[0].name = s.bodies[0].material = "steel/hard";
  expect_scene_error(s, "material.steel/hard.name", {"cannot name a material", "'/'"});
  s = code_scene();
  s.bodies[0].name = "bar\tone";
  expect_scene_error(s, "body.bar\\x09one.name", {"\"bar\\x09one\" cannot name a body", "control character"});
  s = code_scene();
  BoundarySection fixed;
  fixed.name = "left.end";
  fixed.upper = {0.0, 1.0, 1.0};
  fixed.fix = {true, true, true};
  s.boundaries.push_back(fixed);
  expect_scene_error(s, "boundary.left.end.name", {"cannot name a boundary"});
  s.boundaries.back().name = "left";
  s.boundaries.push_back(s.boundaries.back());
  expect_scene_error(s, "boundary.left.name", {"duplicate name \"left\""});
  s = code_scene();
  WallSection w;
  w.name = " floor";
  w.normal = {1.0, 0.0, 0.0};
  s.walls.push_back(w);
  expect_scene_error(s, "wall. floor.name", {"cannot name a wall", "space"});
  s.walls.back().name = "floor";
  s.walls.push_back(s.walls.back());
  expect_scene_error(s, "wall.floor.name", {"duplicate name \"floor\""});
  // A wall's name names its history in the result file: it is required.
  s.walls.pop_back();
  s.walls.back().name.clear();
  expect_scene_error(s, "wall.0.name", {"must not be empty"});
  // A body or boundary may be left without a name, as a scene in code may:
  // it stands for the reader's name of that place ("body0", "boundary1"),
  // which to_toml leaves to the reader, so the scene reads back (a restart
  // parses the stored text) with the same names...
  s = code_scene();
  s.bodies[0].name.clear();
  fixed.name.clear();
  s.boundaries = {fixed, fixed};
  CHECK_NOTHROW(assemble<1>(s));
  const Scene back = parse_scene(to_toml(s), "code.toml");
  CHECK(back.bodies[0].name == "body0");
  CHECK(back.boundaries[1].name == "boundary1");
  // ... and a given name may not take an unnamed one's place.
  s.boundaries[0].name = "boundary1";
  expect_scene_error(s, "boundary.1.name", {"duplicate name \"boundary1\"", "unnamed boundary"});
}

TEST_CASE("Engine: grid cells >= 1 and finite bounds") {
  Scene s = code_scene();
  s.grid.cells[0] = 0;
  expect_scene_error(s, "grid.cells", {"axis 0", "got 0"});
  s = code_scene();
  s.grid.upper[0] = kInf;
  expect_scene_error(s, "grid.upper", {"not finite"});
  s = code_scene();
  s.grid.lower[0] = 2.0;
  expect_scene_error(s, "grid.upper", {"lower 2, upper 1"});
}

TEST_CASE("Engine: simulation values (t_end, cfl, dt, mode, integrator) are checked") {
  Scene s = code_scene();
  s.simulation.t_end = kNaN;
  expect_scene_error(s, "simulation.t_end", {"nan"});
  s = code_scene();
  s.simulation.cfl = 0.0;
  expect_scene_error(s, "simulation.cfl");
  s = code_scene();
  s.simulation.dt = -1.0;
  expect_scene_error(s, "simulation.dt", {"got -1"});
  s = code_scene();
  s.simulation.mode = "eulerian";
  expect_scene_error(s, "simulation.mode", {"eulerian"});
  s = code_scene();
  s.simulation.integrator = "rk4";
  expect_scene_error(s, "simulation.integrator", {"rk4"});
}

TEST_CASE("Engine: material values are checked with the material's key") {
  Scene s = code_scene();
  s.materials[0].poisson = 0.5;
  expect_scene_error(s, "material.steel", {"poisson", "got 0.5"});
  s = code_scene();
  s.materials[0].model = "plastic";
  expect_scene_error(s, "material.steel", {"plastic"});
}

TEST_CASE("Engine: a ramp needs a period > 0, loads and boxes must be finite") {
  Scene s = code_scene();
  s.body_force = BodyForceSection{};
  s.body_force->time.kind = "ramp";
  expect_scene_error(s, "body_force.time.period", {"got 0"});
  s = code_scene();
  BoundarySection b;
  b.name = "left";
  b.upper[0] = kNaN;
  s.boundaries.push_back(b);
  expect_scene_error(s, "boundary.left.upper", {"not finite"});
}

TEST_CASE("Engine: output.every must not ask for an endless number of frames") {
  Scene s = code_scene();
  s.output.every = 1e-300;
  expect_scene_error(s, "output.every", {"1e-300"});
}

TEST_CASE("Engine: a body outside the grid in mpm mode is an input error, not a first-step instability") {
  Scene s = code_scene();
  s.bodies[0].upper[0] = 1.5;
  expect_scene_error(s, "body.bar", {"not inside the grid"});
}

TEST_CASE("Engine: basis options of a Scene built in code are reported at their key, checked against their row") {
  Scene s = code_scene();
  s.basis.kind = "lme";
  s.basis.values["gamma_lme"] = -1.0;
  expect_scene_error(s, "basis.gamma_lme", {"must be > 0", "got -1"});
  s.basis.values = {{"max_newton_iterations", 2.5}};
  expect_scene_error(s, "basis.max_newton_iterations", {"whole number", "got 2.5"});
  s.basis.values = {{"gamma", 3.0}};
  expect_scene_error(s, "basis.gamma", {"unknown key"});
}

TEST_CASE("validate_scene: the dimension argument must be 1, 2 or 3") {
  expect_error<std::invalid_argument>([] { validate_scene(code_scene(), 4); }, {"dimension", "got 4"});
}

// ---------------------------------------------------------------- scene

TEST_CASE("load_scene: an empty path is named as such") {
  expect_error<InputError>([] { load_scene(""); }, {"load_scene", "path is empty"});
}

TEST_CASE("SourceRef::describe: a Scene built in code names only the key") {
  CHECK(SourceRef{"", 0, "grid.cells"}.describe() == "key 'grid.cells'");
  CHECK(SourceRef{"a.toml", 3, "grid.cells"}.describe() == "a.toml:3: key 'grid.cells'");
}

// ---------------------------------------------------------------- results

TEST_CASE("ResultWriter: an empty path and a bad dimension") {
  expect_error<InputError>([] { ResultWriter w("", "", 1); }, {"path is empty"});
  TempFile f;
  expect_error<std::invalid_argument>([&] { ResultWriter w(f.path.string(), "", 4); }, {"dimension", "got 4"});
}

TEST_CASE("ResultWriter::write_frame: a field shape that does not describe its data") {
  TempFile f;
  ResultWriter w(f.path.string(), "", 2);
  const std::vector<double> x{0.0, 0.0, 1.0, 1.0};
  CHECK_NOTHROW(w.write_frame(0.0, {{"x", 2, 2, x.data()}}));
  expect_error<std::invalid_argument>([&] { w.write_frame(1.0, {{"x", -1, 2, x.data()}}); }, {"'x'", "rows", "-1"});
  expect_error<std::invalid_argument>([&] { w.write_frame(1.0, {{"v", 2, 0, x.data()}}); }, {"'v'", "cols", "got 0"});
  expect_error<std::invalid_argument>([&] { w.write_frame(1.0, {{"v", 2, 2, nullptr}}); }, {"data is null"});
  expect_error<std::invalid_argument>([&] { w.write_frame(1.0, {{"x", 1, 4, x.data()}}); }, {"'x'", "cols = 4"});
  CHECK(w.frames() == 1);
}

TEST_CASE("ResultWriter::set_attribute and read_*_attribute: empty names and paths") {
  TempFile f;
  {
    ResultWriter w(f.path.string(), "", 1);
    expect_error<std::invalid_argument>([&] { w.set_attribute("", 1.0); }, {"attribute name"});
    CHECK_NOTHROW(w.set_attribute("answer", 42.0));
  }
  CHECK(read_double_attribute(f.path.string(), "answer") == 42.0);
  expect_error<std::invalid_argument>([&] { read_double_attribute(f.path.string(), ""); }, {"attribute name"});
  expect_error<InputError>([] { read_string_attribute("", "status"); }, {"path is empty"});
}

// ---------------------------------------------------------------- reference

TEST_CASE("make_exact_solution: the run's dimension and the solution name") {
  Scene s = code_scene();
  s.reference.solution = "dyka";
  expect_error<InputError>([&] { make_exact_solution<2>(s); }, {"key 'reference.solution'", "1D but the run is 2D"});
  s.reference.solution = "kepler";
  expect_error<InputError>([&] { make_exact_solution<1>(s); }, {"key 'reference.solution'", "'kepler'"});
}

TEST_CASE("exact solutions: each constructor names its bad parameter") {
  DykaParameters d{1.0, 1.0, 1.0, -5.0, 0.0, 0.25, 0.0, 0.0};
  CHECK_NOTHROW(DykaBar<1>{d});
  d.length = kNaN;
  expect_error<InputError>([&] { DykaBar<1>{d}; }, {"DykaBar: length", "nan"});
  FixedBarParameters fb{1.0, 1.0, 0.0, 0.1, 0.0};
  expect_error<InputError>([&] { FixedBar<1>{fb}; }, {"FixedBar: density", "got 0"});
  TractionBarParameters tb{1.0, 1.0, 1.0, kInf, 0.0};
  expect_error<InputError>([&] { TractionBar<1>{tb}; }, {"TractionBar: amplitude"});
  MmsPlateParameters mp;
  mp.young = mp.density = 1.0;
  mp.poisson = 0.5;
  expect_error<InputError>([&] { MmsPlate{mp}; }, {"Poisson", "0.5"});
}
