// Checkpoint and restart at library level (io/checkpoint.hpp): N steps, a
// checkpoint written to a file, M more steps; a fresh engine built from the
// checkpoint's own scene text and restored from the file, M steps; every
// particle field, the node positions, the B-spline knots, time, step sizes,
// energies and reaction impulse must then be equal bit for bit (memcmp), for
// every integrator of the table in each mode it runs in and the linear,
// bspline2 and lme bases in 1D, and a selection in 2D. Also: a damaged, truncated or
// missing checkpoint is an InputError naming the file; a checkpoint write
// killed before its rename leaves the previous checkpoint readable; the scene
// keys output.checkpoint_every / checkpoint_file are checked like the others.
#include "otmpm/basis/bspline.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/run/restart.hpp"

#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <string>
#include <vector>

using namespace otmpm;
using test::TempDir;
namespace fs = std::filesystem;

namespace {

/// doctest's substring matcher for a std::string.
doctest::Contains contains(const std::string& s) { return doctest::Contains(s.c_str()); }

/// One engine configuration of the restart matrix.
struct Config {
  int dim;
  std::string mode, integrator, basis;
};

/// A small scene: a body moving with a sin(pi x) velocity profile under a
/// ramped body force, the nodes at its lower end and below held (y <= 0 in
/// 2D, x <= 0 in 1D: B-spline control points need not lie on x = 0).
std::string scene_text(const Config& c) {
  const bool two = c.dim == 2;
  const std::string vec = two ? "[%, %]" : "[%]";
  auto v = [&](const char* a, const char* b) {
    std::string s = vec;
    s.replace(s.find('%'), 1, a);
    if (two) s.replace(s.find('%'), 1, b);
    return s;
  };
  std::string t = "[simulation]\ndimension = " + std::to_string(c.dim) + "\nmode = \"" + c.mode +
                  "\"\nintegrator = \"" + c.integrator + "\"\nt_end = 10.0\ncfl = 0.2\n";
  t += "[basis]\nkind = \"" + c.basis + "\"\n";
  t += "[grid]\nlower = " + v("-0.4", "-0.4") + "\nupper = " + v("1.6", "1.6") + "\ncells = " +
       (two ? "[10, 10]" : "[20]") + "\n";
  t += "[[material]]\nname = \"m\"\nmodel = \"" + std::string(two ? "neo_hookean" : "linear_elastic") +
       "\"\ndensity = 1.0\nyoung = 1.0\npoisson = 0.2\n";
  t += "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = " + v("0.0", "0.0") + "\nupper = " + v("1.0", "1.0") +
       "\nparticles_per_cell = 2\nvelocity = " + v("0.1", "-0.05") + "\nvelocity_profile = \"sin_x\"\n";
  t += "[[boundary]]\nname = \"held\"\nlower = " + v("-0.4", "-0.4") + "\nupper = " + v(two ? "1.6" : "0.0", "0.0") +
       "\nfix = " + (two ? "[false, true]" : "[true]") + "\n";
  t += "[body_force]\nvalue = " + v("-0.3", "-0.2") + "\ntime = { kind = \"ramp\", period = 0.5 }\n";
  // 2D: a frictional wall the body force pushes the body onto (its held
  // nodes, the friction it dissipates and, in explicit_alpha, its carried
  // momentum are part of the state).
  if (two) t += "[[wall]]\nname = \"side\"\npoint = [-0.05, 0.0]\nnormal = [1.0, 0.0]\nfriction = 0.5\n";
  return t;
}

template <class T> std::string bytes_of(const T* data, std::size_t n) {
  return std::string(reinterpret_cast<const char*>(data), n * sizeof(T));
}

/// The bytes of everything a continued run must reproduce, by name.
template <int D> std::map<std::string, std::string> state_bytes(const Engine<D>& e) {
  std::map<std::string, std::string> s;
  e.particles().for_each_field([&](const char* name, const auto& f) { s[name] = bytes_of(f.data(), f.size()); });
  const PointState<D>& points = e.basis().point_state();
  s["lambda"] = bytes_of(points.lambda.data(), points.lambda.size());
  s["cell_hint"] = bytes_of(points.cell_hint.data(), points.cell_hint.size());
  std::vector<double> history; // value by value (the struct has padding)
  for (const MultiplierHistory<D>& h : points.history) {
    for (int k = 0; k < D; ++k) history.push_back(h.previous[k]), history.push_back(h.before[k]);
    history.push_back(h.solves);
  }
  s["history"] = bytes_of(history.data(), history.size());
  const auto& x = e.basis().nodes().positions();
  s["nodes"] = bytes_of(x.data(), x.size());
  const double t = e.time(), dt = e.last_dt();
  const long steps = e.steps();
  s["t"] = bytes_of(&t, 1);
  s["dt"] = bytes_of(&dt, 1);
  s["steps"] = bytes_of(&steps, 1);
  s["energy"] = bytes_of(&e.energy(), 1);
  s["reaction_impulse"] = bytes_of(e.reaction_impulse().data(), D);
  if (const auto* b = dynamic_cast<const BsplineBasis<D>*>(&e.basis()))
    for (int k = 0; k < D; ++k) s["knots" + std::to_string(k)] = bytes_of(b->knot_vector(k).vertices().data(), b->knot_vector(k).vertices().size());
  return s;
}

template <int D> void run_steps(Engine<D>& e, int n) {
  for (int i = 0; i < n; ++i) e.step();
}

template <int D> Checkpoint checkpoint_of(const Engine<D>& e, const Scene& scene) {
  Checkpoint ck;
  ck.scene = scene.text;
  e.save_state(ck);
  return ck;
}

constexpr int kBefore = 15; ///< steps before the checkpoint
constexpr int kAfter = 15;  ///< steps after it

/// Runs kBefore steps, checkpoints to `path`, runs kAfter more; returns the state then.
template <int D> std::map<std::string, std::string> uninterrupted(const Scene& scene, const std::string& path) {
  Engine<D> e = assemble<D>(scene);
  run_steps(e, kBefore);
  write_checkpoint(path, checkpoint_of(e, scene));
  run_steps(e, kAfter);
  return state_bytes(e);
}

/// A fresh engine from the checkpoint file (its own scene), restored, kAfter steps.
template <int D> std::map<std::string, std::string> restarted(const Checkpoint& ck) {
  Engine<D> e = assemble<D>(checkpoint_scene(ck));
  e.restore_state(ck);
  CHECK(e.steps() == kBefore);
  run_steps(e, kAfter);
  if (D == 2) CHECK(e.energy().friction > 0.0); // the wall's friction and impacts are part of the state
  if (D == 2) CHECK(e.energy().impact > 0.0);
  return state_bytes(e);
}

void check_same(const std::map<std::string, std::string>& a, const std::map<std::string, std::string>& b) {
  REQUIRE(a.size() == b.size());
  for (const auto& entry : a) {
    const std::string& name = entry.first; // a plain reference: INFO captures it (clang refuses a binding)
    const std::string& bytes = entry.second;
    INFO("state '" << name << "'");
    REQUIRE(b.count(name) == 1);
    CHECK(bytes.size() == b.at(name).size());
    CHECK(std::memcmp(bytes.data(), b.at(name).data(), std::min(bytes.size(), b.at(name).size())) == 0);
  }
}

template <int D> void check_restart(const Config& c, const TempDir& tmp) {
  INFO(c.dim << "D " << c.mode << " " << c.integrator << " " << c.basis);
  const Scene scene = parse_scene(scene_text(c), "restart.toml");
  const std::string path = tmp.file("ck.h5");
  const auto expected = uninterrupted<D>(scene, path);
  check_same(expected, restarted<D>(read_checkpoint(path)));
}

} // namespace

TEST_CASE("restart continues bit for bit: every integrator, linear / bspline2 / lme, 1D and 2D") {
  TempDir tmp("matrix");
  std::vector<Config> configs;
  // Every integrator of the table in each mode it runs in, on one family of
  // each sort (tensor hats, B-splines, max-ent; every family: test_contracts.cpp).
  for (const char* basis : {"linear", "bspline2", "lme"})
    for (const IntegratorKind& k : integrator_kinds()) {
      if (k.needs_bspline && !basis_kind(basis).bspline) continue;
      if (!k.needs_ul) configs.push_back({1, "mpm", std::string(k.name), basis});
      configs.push_back({1, "ul", std::string(k.name), basis});
    }
  configs.push_back({2, "mpm", "npc", "lme"});
  configs.push_back({2, "mpm", "musl", "bspline2"});
  configs.push_back({2, "mpm", "fe", "linear"});
  configs.push_back({2, "ul", "otm", "linear"});
  configs.push_back({2, "ul", "npc", "lme"});
  configs.push_back({2, "ul", "unified", "bspline2"});
  configs.push_back({2, "mpm", "explicit_alpha", "linear"});
  configs.push_back({2, "mpm", "central_difference", "linear"});
  for (const Config& c : configs) {
    if (c.dim == 1) check_restart<1>(c, tmp);
    else check_restart<2>(c, tmp);
  }
}

TEST_CASE(
    "body contact's carried momenta are part of explicit_alpha's state: a restart without them differs") {
  // A block sliding on a base (friction 0.3) that rests on a floor, on
  // quadratic B-splines: explicit_alpha books the contact's friction from
  // the momentum its rate carries from step to step (contact_carried).
  TempDir tmp("contact");
  const std::string text =
      "[simulation]\ndimension = 2\nintegrator = \"explicit_alpha\"\nt_end = 1.0\ncfl = 0.2\n"
      "[basis]\nkind = \"bspline2\"\n[grid]\nlower = [-0.5, -0.25]\nupper = [2.0, 1.0]\nh = 0.125\n"
      "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1000.0\nyoung = 2.0e6\npoisson = "
      "0.3\n"
      "[[body]]\nname = \"base\"\nmaterial = \"m\"\nlower = [0.0, 0.0]\nupper = [1.5, 0.5]\n"
      "[[body]]\nname = \"block\"\nmaterial = \"m\"\nlower = [0.25, 0.5]\nupper = [0.75, 0.75]\n"
      "velocity = [1.0, 0.0]\n"
      "[[wall]]\nname = \"floor\"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\nfriction = 0.5\n"
      "[body_force]\nvalue = [0.0, -9.81]\n[contact]\nfriction = 0.3\n";
  const Scene scene = parse_scene(text, "contact.toml");
  const std::string path = tmp.file("ck.h5");
  const auto expected = uninterrupted<2>(scene, path);
  Checkpoint ck = read_checkpoint(path);
  REQUIRE(ck.groups.at("engine").real_arrays.count("contact_carried") == 1);
  check_same(expected, restarted<2>(ck));
  ck.groups.at("engine").real_arrays.erase("contact_carried");
  Engine<2> e = assemble<2>(checkpoint_scene(ck));
  e.restore_state(ck);
  run_steps(e, kAfter);
  CHECK(state_bytes(e).at("energy") != expected.at("energy")); // the friction booked differs
}

TEST_CASE("the LME warm start is part of the state: a restart without it differs") {
  // Control for the test above: the comparison sees a change in the last bits.
  TempDir tmp("lambda");
  const Scene scene = parse_scene(scene_text({1, "mpm", "npc", "lme"}), "restart.toml");
  const std::string path = tmp.file("ck.h5");
  const auto expected = uninterrupted<1>(scene, path);
  Checkpoint ck = read_checkpoint(path);
  for (double& l : ck.groups.at("basis").real_arrays.at("lambda").values) l = 0.0;
  const auto cold = restarted<1>(ck);
  CHECK(cold.at("lambda") != expected.at("lambda"));
  CHECK(cold.at("x") != expected.at("x"));
}

TEST_CASE("the multiplier history of ul mode is part of the state: a restart without it differs") {
  // Control for the ul LME restart above: the extrapolated start (eq. 4.7c)
  // is used, and a restart that loses it ends in other last bits.
  TempDir tmp("history");
  const Scene scene = parse_scene(scene_text({1, "ul", "npc", "lme"}), "restart.toml");
  const std::string path = tmp.file("ck.h5");
  const auto expected = uninterrupted<1>(scene, path);
  REQUIRE(expected.at("history").size() == 20 * 3 * sizeof(double)); // 20 particles, 2 D + 1 values
  Checkpoint ck = read_checkpoint(path);
  REQUIRE(ck.groups.at("basis").real_arrays.erase("lambda_history") == 1);
  const auto plain = restarted<1>(ck);
  CHECK(plain.at("lambda") != expected.at("lambda"));
  CHECK(plain.at("x") != expected.at("x"));
}

TEST_CASE("B-spline knots are part of the state: restored, not rebuilt from the scene") {
  TempDir tmp("knots");
  const Scene scene = parse_scene(scene_text({1, "ul", "unified", "bspline2"}), "restart.toml");
  Engine<1> e = assemble<1>(scene);
  run_steps(e, kBefore);
  const Checkpoint ck = checkpoint_of(e, scene);
  const auto& saved = ck.group("basis").real_arrays.at("knots_0").values;
  const std::vector<double> initial = KnotVector::uniform(0.0, 1.0, 10, 2).vertices();
  REQUIRE(saved.size() == initial.size());
  CHECK(saved != initial); // advected
  Engine<1> fresh = assemble<1>(scene);
  fresh.restore_state(ck);
  CHECK(dynamic_cast<const BsplineBasis<1>&>(fresh.basis()).knot_vector(0).vertices() == saved);
}

TEST_CASE("restoring into an engine of another scene is an InputError naming the checkpoint") {
  TempDir tmp("mismatch");
  const Scene scene = parse_scene(scene_text({1, "mpm", "npc", "linear"}), "restart.toml");
  Engine<1> e = assemble<1>(scene);
  run_steps(e, 3);
  const std::string path = tmp.file("ck.h5");
  write_checkpoint(path, checkpoint_of(e, scene));
  const Checkpoint ck = read_checkpoint(path);
  std::string other = scene_text({1, "mpm", "npc", "linear"});
  other.replace(other.find("particles_per_cell = 2"), 22, "particles_per_cell = 3");
  Engine<1> wrong = assemble<1>(parse_scene(other, "other.toml"));
  CHECK_THROWS_WITH_AS(wrong.restore_state(ck), contains(path), InputError);
  Engine<2> wrong_dim = assemble<2>(parse_scene(scene_text({2, "mpm", "npc", "linear"}), "other.toml"));
  CHECK_THROWS_WITH_AS(wrong_dim.restore_state(ck), contains("1D run"), InputError);
}

namespace {

/// A checkpoint of a few steps of a small run, written to `path`.
void small_checkpoint(const std::string& path, int steps) {
  const Scene scene = parse_scene(scene_text({1, "mpm", "npc", "lme"}), "restart.toml");
  Engine<1> e = assemble<1>(scene);
  run_steps(e, steps);
  write_checkpoint(path, checkpoint_of(e, scene));
}

/// The file offset of the raw data of a (contiguous) dataset.
haddr_t data_offset(const std::string& path, const std::string& dataset) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(file >= 0);
  const hid_t set = H5Dopen2(file, dataset.c_str(), H5P_DEFAULT);
  REQUIRE(set >= 0);
  const haddr_t offset = H5Dget_offset(set);
  H5Dclose(set);
  H5Fclose(file);
  REQUIRE(offset != HADDR_UNDEF);
  return offset;
}

/// Flips the bits of the byte at `offset` of a file.
void flip_byte(const std::string& path, std::streamoff offset) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  REQUIRE(f);
  f.seekg(offset);
  char c = 0;
  f.get(c);
  f.seekp(offset);
  f.put(static_cast<char>(~c));
}

} // namespace

TEST_CASE("crc64_combine: the CRC of two parts combined is the CRC of the whole, for any cut") {
  // The ranks of a distributed run checksum a checkpoint in parts.
  std::mt19937_64 rng(7);
  std::vector<unsigned char> bytes(5000);
  for (unsigned char& b : bytes) b = static_cast<unsigned char>(rng());
  const std::uint64_t whole = crc64(bytes.data(), bytes.size());
  CHECK(crc64("123456789", 9) == 0x995DC9BBDF1939FAull); // the check value of CRC-64/XZ
  for (std::size_t cut : {std::size_t{0}, std::size_t{1}, std::size_t{511}, std::size_t{512}, std::size_t{4999},
                          std::size_t{5000}}) {
    CAPTURE(cut);
    const std::uint64_t a = crc64(bytes.data(), cut), b = crc64(bytes.data() + cut, bytes.size() - cut);
    CHECK(crc64_combine(a, b, bytes.size() - cut) == whole);
  }
  // three parts, combined left to right
  const std::uint64_t p1 = crc64(bytes.data(), 100), p2 = crc64(bytes.data() + 100, 2000),
                      p3 = crc64(bytes.data() + 2100, 2900);
  CHECK(crc64_combine(crc64_combine(p1, p2, 2000), p3, 2900) == whole);
}

TEST_CASE("a missing, truncated, foreign or damaged checkpoint is an InputError naming the file") {
  TempDir tmp("damaged");
  const std::string good = tmp.file("good.h5");
  small_checkpoint(good, 3);
  CHECK_NOTHROW(read_checkpoint(good));

  const std::string missing = tmp.file("missing.h5");
  CHECK_THROWS_WITH_AS(read_checkpoint(missing), contains(missing), InputError);

  const std::string truncated = tmp.file("truncated.h5");
  fs::copy_file(good, truncated);
  fs::resize_file(truncated, fs::file_size(good) / 2);
  CHECK_THROWS_WITH_AS(read_checkpoint(truncated), contains(truncated), InputError);

  const std::string text = tmp.file("text.h5");
  std::ofstream(text) << "[simulation]\ndimension = 1\n";
  CHECK_THROWS_WITH_AS(read_checkpoint(text), contains(text), InputError);

  // A flipped bit in the raw particle data: the CRC of the file's bytes does
  // not match (checked before HDF5 reads anything).
  const std::string flipped = tmp.file("flipped.h5");
  fs::copy_file(good, flipped);
  flip_byte(flipped, static_cast<std::streamoff>(data_offset(flipped, "/particles/v")) + 3);
  CHECK_THROWS_WITH_AS(read_checkpoint(flipped), contains(flipped + ": checksum mismatch"), InputError);

  // A result file is HDF5 but not a checkpoint.
  const std::string foreign = tmp.file("foreign.h5");
  const hid_t f = H5Fcreate(foreign.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  H5Fclose(f);
  CHECK_THROWS_WITH_AS(read_checkpoint(foreign), contains(foreign + ": not an otmpm checkpoint"),
                       InputError);
}

TEST_CASE("a checkpoint write killed before its rename leaves the previous checkpoint") {
  TempDir tmp("atomic");
  const std::string path = tmp.file("run.checkpoint.h5");
  small_checkpoint(path, 3);
  // The next checkpoint was being written when the process died: a partial .tmp.
  const Scene scene = parse_scene(scene_text({1, "mpm", "npc", "lme"}), "restart.toml");
  Engine<1> e = assemble<1>(scene);
  run_steps(e, 6);
  write_checkpoint_file(path + ".tmp", checkpoint_of(e, scene));
  fs::resize_file(path + ".tmp", fs::file_size(path + ".tmp") / 3);
  const Checkpoint previous = read_checkpoint(path);
  CHECK(previous.group("engine").integer("step") == 3);
  // The stale .tmp does not stop the next checkpoint.
  run_steps(e, 3);
  write_checkpoint(path, checkpoint_of(e, scene));
  CHECK(read_checkpoint(path).group("engine").integer("step") == 9);
  CHECK_FALSE(fs::exists(path + ".tmp"));
}

TEST_CASE("a checkpoint holds the scene text and round-trips every value bit for bit") {
  TempDir tmp("roundtrip");
  Checkpoint ck;
  ck.scene = "# a scene\n";
  ck.dimension = 2;
  StateGroup& g = ck.group("g");
  g.reals["negative_zero"] = -0.0;
  g.reals["tiny"] = 4.9406564584124654e-324;
  g.integers["big"] = -9007199254740993;
  g.strings["s"] = "text";
  g.real_arrays["a"] = {3, {1.0 / 3.0, -0.0, 1e300, 2.0, 3.0, 4.0}};
  g.integer_arrays["i"] = {2, {1, -2, 3, -4}};
  g.real_arrays["empty"] = {2, {}};
  const std::string path = tmp.file("ck.h5");
  write_checkpoint(path, ck);
  const Checkpoint back = read_checkpoint(path);
  CHECK(back.scene == ck.scene);
  CHECK(back.dimension == 2);
  const StateGroup& r = back.group("g");
  CHECK(std::signbit(r.real("negative_zero")));
  CHECK(r.real("tiny") == 4.9406564584124654e-324);
  CHECK(r.integer("big") == -9007199254740993);
  CHECK(r.string("s") == "text");
  const auto& a = r.real_array("a", 2, 3).values;
  CHECK(std::memcmp(a.data(), g.real_arrays["a"].values.data(), 6 * sizeof(double)) == 0);
  CHECK(r.integer_array("i", 2, 2).values == g.integer_arrays["i"].values);
  CHECK(r.real_array("empty", 0, 2).values.empty());
  CHECK_THROWS_WITH_AS(r.real_array("a", 3, 2), contains(path + ": group 'g': array 'a'"), InputError);
  CHECK_THROWS_WITH_AS(r.real("absent"), contains("missing value 'absent'"), InputError);
  CHECK_THROWS_WITH_AS(back.group("nope"), contains(path + ": incomplete checkpoint"), InputError);
}

TEST_CASE("output.checkpoint_every and output.checkpoint_file: defaults, checks with FILE:LINE") {
  const std::string base = scene_text({1, "mpm", "npc", "linear"});
  const Scene plain = parse_scene(base, "s.toml");
  CHECK(plain.output.checkpoint_every == 0);
  CHECK(checkpoint_path(plain, "dir/run.h5") == "dir/run.checkpoint.h5");
  CHECK(checkpoint_path(plain, "run.out") == "run.out.checkpoint.h5");
  const Scene set = parse_scene(base + "[output]\nfile = \"a.h5\"\ncheckpoint_every = 25\ncheckpoint_file = \"c.h5\"\n",
                                "s.toml");
  CHECK(set.output.checkpoint_every == 25);
  CHECK(checkpoint_path(set, "a.h5") == "c.h5");
  const int line = static_cast<int>(std::count(base.begin(), base.end(), '\n')) + 2;
  CHECK_THROWS_WITH_AS(parse_scene(base + "[output]\ncheckpoint_every = -1\n", "s.toml"),
                       contains("s.toml:" + std::to_string(line) + ": key 'output.checkpoint_every': must be"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse_scene(base + "[output]\ncheckpoint_every = 2.5\n", "s.toml"),
                       contains("key 'output.checkpoint_every': expected an integer"), InputError);
  CHECK_THROWS_WITH_AS(parse_scene(base + "[output]\ncheckpoint_file = \"\"\n", "s.toml"),
                       contains("key 'output.checkpoint_file': must not be empty"), InputError);
  CHECK_THROWS_WITH_AS(parse_scene(base + "[output]\nfile = \"x.h5\"\ncheckpoint_file = \"x.h5\"\n", "s.toml"),
                       contains("key 'output.checkpoint_file': must differ"), InputError);
  const Scene nowhere = parse_scene(base + "[output]\ncheckpoint_every = 5\ncheckpoint_file = \"no/such/dir/c.h5\"\n",
                                    "s.toml");
  CHECK_THROWS_WITH_AS(checkpoint_path(nowhere, "out.h5"),
                       contains("s.toml:" + std::to_string(line + 1) + ": key 'output.checkpoint_file': directory"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse_scene(base, "s.toml", {"output.checkpoint_evry=3"}),
                       contains("did you mean 'checkpoint_every'"), InputError);
}
