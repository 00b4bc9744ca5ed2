// Body-body contact (engine/contact.hpp, docs/theory.md sect. 6.2): two
// elastic disks meeting head on separate again with [contact], with
// momentum conserved to round-off and no energy gained, with fe, musl,
// npc and central_difference; in an oblique impact the shared grid (no [contact]) holds the
// slip and spins the disks, frictionless contact does not; a block sliding on a
// block decelerates at mu g, and explicit_alpha books its friction once; the
// same bits with 1 and 2 threads; bad
// [contact] input is refused with its line.
#include "otmpm/assembly/assembler.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

using namespace otmpm;

namespace {

/// examples/disks.toml (benchmark 3) at h = 0.05 until t_end, with overrides.
Scene disks(const std::vector<std::string>& sets) {
  std::vector<std::string> all{"output.every=0"};
  all.insert(all.end(), sets.begin(), sets.end());
  return load_scene(OTMPM_SOURCE_DIR "/examples/disks.toml", all);
}

/// The mass-weighted mean of v (or x) over the particles of body b.
Vec<2> body_mean(const Particles<2>& P, const AlignedVector<Vec<2>>& f, int b) {
  Vec<2> s = Vec<2>::Zero();
  double m = 0.0;
  for (int p = 0; p < P.size(); ++p)
    if (P.body[p] == b) s += P.m[p] * f[p], m += P.m[p];
  return s / m;
}

/// The smallest distance between a particle of body 0 and one of body 1.
double gap(const Particles<2>& P) {
  double d = 1e300;
  for (int p = 0; p < P.size(); ++p)
    for (int q = 0; q < P.size(); ++q)
      if (P.body[p] == 0 && P.body[q] == 1) d = std::min(d, (P.x[p] - P.x[q]).norm());
  return d;
}

struct DiskRun {
  Vec<2> v0;          ///< body 0's mean velocity at the end (it starts at (0.1, 0.1))
  double gap;         ///< the distance between the bodies at the end
  double momentum;    ///< |sum m v| at the end over sum m |v| at the start
  double energy_gain; ///< max_t (E(t) - E(0)) / E(0), E = kinetic + strain
};

DiskRun run_disks(const std::vector<std::string>& sets, double t_end) {
  Engine<2> e = assemble<2>(disks(sets));
  double scale = 0.0;
  for (int p = 0; p < e.particles().size(); ++p) scale += e.particles().m[p] * e.particles().v[p].norm();
  double gain = 0.0;
  while (e.time() < t_end - 1e-12) {
    e.step();
    gain = std::max(gain, (e.energy().total() - e.energy().initial) / e.energy().initial);
  }
  return {body_mean(e.particles(), e.particles().v, 0), gap(e.particles()), e.momentum().norm() / scale, gain};
}

/// A 1 m x 0.25 m block (rho = 500) at v0 = 1 m/s on a 3 m x 0.5 m block
/// (rho = 1000) glued to the grid at its base, under gravity g, on a grid of
/// h = 0.0625. The lighter block keeps the base's face normal at the
/// block's leading edge (contact.hpp: the larger mass gradient wins; with
/// equal densities the edge ties with the face, the normal tilts and the
/// edge drags: measured 0.12 m/s^2 on a frictionless slide, docs/theory.md
/// sect. 6.2).
std::string slide(double mu) {
  return "[simulation]\ndimension = 2\nintegrator = \"musl\"\nt_end = 0.3\ncfl = 0.2\n[basis]\nkind = \"linear\"\n"
         "[grid]\nlower = [-0.5, -0.25]\nupper = [3.5, 1.0]\nh = 0.0625\n"
         "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1000.0\nyoung = 2.0e7\npoisson = 0.3\n"
         "[[material]]\nname = \"light\"\nmodel = \"linear_elastic\"\ndensity = 500.0\nyoung = 1.0e7\npoisson = 0.3\n"
         "[[body]]\nname = \"base\"\nmaterial = \"m\"\nlower = [0.0, 0.0]\nupper = [3.0, 0.5]\n"
         "[[body]]\nname = \"block\"\nmaterial = \"light\"\nlower = [0.25, 0.5]\nupper = [1.25, 0.75]\n"
         "velocity = [1.0, 0.0]\n"
         "[[boundary]]\nname = \"glue\"\nlower = [-0.5, 0.0]\nupper = [3.5, 0.0]\nfix = [true, true]\n"
         "[body_force]\nvalue = [0.0, -9.81]\n[contact]\nfriction = " + std::to_string(mu) + "\n";
}

} // namespace

TEST_CASE("two disks meeting head on separate with [contact], conserve momentum and gain no energy") {
  // They touch at t = 1.0 (one cell before the disks' surfaces meet) and
  // part at about t = 2.0; at t = 2.8 each has turned back.
  // central_difference overshoots by 1.5% of E(0) as the disks first touch
  // (measured; its energy then falls with the others'). explicit_alpha is
  // not in the list: on this scene it becomes unstable at t = 2.39, after
  // the disks have parted, when one particle of the contact surface is left
  // behind (docs/benchmarks.md, benchmark 3).
  for (const auto& [integrator, gain] : {std::pair{"fe", 1e-3}, std::pair{"musl", 1e-3}, std::pair{"npc", 1e-3},
                                         std::pair{"central_difference", 0.02}}) {
    const std::string what(integrator); // INFO captures a variable, not a binding (clang 14)
    INFO(what);
    const DiskRun r = run_disks({std::string("simulation.integrator=") + integrator}, 2.8);
    CHECK(r.v0[0] < -0.05); // rebounded: moving back at more than half the approach speed
    CHECK(r.v0[1] < -0.05);
    CHECK(r.gap > 0.05); // more than a cell apart
    CHECK(r.momentum < 1e-12);
    CHECK(r.energy_gain <= gain);
  }
}

TEST_CASE("in an oblique impact the shared grid (no [contact]) sticks the disks and spins them") {
  // Offset disks moving along x hit at about 17 degrees: a frictionless
  // contact pushes along the normal (through the centres, no spin but the
  // error of the gradient normals; measured L = 0.07 R m v0), the shared
  // grid holds the tangential slip too and spins each disk (0.17 R m v0),
  // friction 0.5 in between at this angle (0.21 at t = 2.5).
  const std::vector<std::string> oblique{"body.lower_left.center=[0.25, 0.42]", "body.upper_right.center=[0.75, 0.58]",
                                         "body.lower_left.velocity=[0.1, 0.0]",
                                         "body.upper_right.velocity=[-0.1, 0.0]"};
  auto spin = [&](const char* contact) {
    Scene s = disks(oblique);
    if (contact) s.contact->friction = std::stod(contact);
    else s.contact.reset();
    Engine<2> e = assemble<2>(s);
    while (e.time() < 2.5 - 1e-12) e.step();
    const Particles<2>& P = e.particles();
    const Vec<2> xc = body_mean(P, P.x, 0), vc = body_mean(P, P.v, 0);
    double L = 0.0, m = 0.0;
    for (int p = 0; p < P.size(); ++p)
      if (P.body[p] == 0) {
        const Vec<2> r = P.x[p] - xc, w = P.v[p] - vc;
        L += P.m[p] * (r[0] * w[1] - r[1] * w[0]), m += P.m[p];
      }
    return L / (m * 0.2 * 0.1);
  };
  const double frictionless = spin("0.0"), shared = spin(nullptr), rough = spin("0.5");
  CHECK(std::abs(frictionless) < 0.1);
  CHECK(shared > 2.0 * std::abs(frictionless));
  CHECK(rough > 2.0 * std::abs(frictionless));
}

TEST_CASE("a block sliding on a block with friction mu decelerates at mu g (to 2%)") {
  // v(t) = v0 - mu g t while it slides; the base is glued at its bottom and
  // barely moves. The block's settling under the suddenly applied gravity
  // perturbs the normal force by a few 0.1%.
  for (const double mu : {0.1, 0.3}) {
    INFO("mu = " << mu);
    Engine<2> e = assemble<2>(parse_scene(slide(mu), "slide.toml"));
    while (e.time() < 0.3 - 1e-12) e.step();
    const double v = body_mean(e.particles(), e.particles().v, 1)[0];
    CHECK((1.0 - v) / e.time() == doctest::Approx(mu * 9.81).epsilon(0.02));
  }
}

TEST_CASE("explicit_alpha books the friction between sliding bodies once: the energy balance closes") {
  // The block of the test above on a base that rests on a frictionless
  // floor, on quadratic B-splines (with linear elements explicit_alpha
  // becomes unstable at t = 0.014 s here, as fe and central_difference do:
  // particles crossing into cells whose nodes have almost no mass), to t =
  // 0.1 s. Its rate hands part of each contact change back over the next
  // steps and the contact takes it again, with its friction: booked from
  // each change, friction came to 45.9 J against musl's 30.6 J and the
  // balance error to 25% of E(0) = 62.5 J; booked from the momentum the
  // particles take up in the step (BodyContact::book_carried), 30.63 J
  // against musl's 30.62 J and at most 0.70% (frictionless 0.74%: the rest
  // is explicit_alpha's own response to the contact, not friction; musl
  // 0.03%).
  std::string text = slide(0.3);
  text.replace(text.find("[[boundary]]"), text.find("[body_force]") - text.find("[[boundary]]"),
               "[[wall]]\nname = \"floor\"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\n");
  text.replace(text.find("integrator = \"musl\""), 19, "integrator = \"explicit_alpha\"");
  text.replace(text.find("kind = \"linear\""), 15, "kind = \"bspline2\"");
  Engine<2> e = assemble<2>(parse_scene(text, "slide.toml"));
  double worst = 0.0;
  while (e.time() < 0.1 - 1e-12) {
    e.step();
    worst = std::max(worst, std::abs(e.energy().balance_error()));
  }
  MESSAGE("friction " << e.energy().friction
                      << " J, worst balance error / E(0) = " << worst / e.energy().initial);
  REQUIRE(e.energy().friction > 0.4 * e.energy().initial); // it slid: about half of E(0)
  CHECK(worst < 0.02 * e.energy().initial);
}

TEST_CASE("a frictionless block slides on without losing speed") {
  Engine<2> e = assemble<2>(parse_scene(slide(0.0), "slide.toml"));
  while (e.time() < 0.3 - 1e-12) e.step();
  CHECK(body_mean(e.particles(), e.particles().v, 1)[0] == doctest::Approx(1.0).epsilon(0.01));
}

#ifdef OTMPM_HAVE_OPENMP
TEST_CASE("contact gives the same bits with 1 and 2 threads") {
  // Disks in contact from the start at h = 0.01 (about 9000 particles).
  const std::vector<std::string> sets{"grid.h=0.01", "body.lower_left.center=[0.3, 0.5]",
                                      "body.upper_right.center=[0.7, 0.5]", "contact.friction=0.3"};
  auto run = [&](int threads) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    Engine<2> e = assemble<2>(disks(sets));
    for (int s = 0; s < 5; ++s) e.step();
    omp_set_num_threads(saved);
    return e.particles();
  };
  const Particles<2> one = run(1), two = run(2);
  REQUIRE(one.size() == two.size());
  for (int p = 0; p < one.size(); ++p) {
    CHECK(one.x[p] == two.x[p]);
    CHECK(one.v[p] == two.v[p]);
  }
}
#endif

TEST_CASE("bad [contact] input is refused with its line") {
  const std::string text = slide(0.3);
  const std::string negative = std::string(text).replace(text.find("friction = "), 19, "friction = -1.0");
  CHECK_THROWS_WITH_AS(parse_scene(negative, "c.toml"), doctest::Contains("key 'contact.friction'"), InputError);
  const std::string unknown = std::string(text).replace(text.find("friction = "), 9, "mu");
  CHECK_THROWS_WITH_AS(parse_scene(unknown, "c.toml"), doctest::Contains("c.toml:"), InputError);
  // ul mode: each body would need its own advected nodes - not implemented.
  std::string ul = text;
  ul.insert(ul.find("integrator"), "mode = \"ul\"\n");
  CHECK_THROWS_WITH_AS(parse_scene(ul, "c.toml"), doctest::Contains("contact"), InputError);
  CHECK_THROWS_WITH_AS(parse_scene(ul, "c.toml"), doctest::Contains("mode = \"mpm\""), InputError);
  std::string consistent = text;
  consistent.insert(consistent.find("integrator"), "mass = \"consistent\"\n");
  CHECK_THROWS_WITH_AS(parse_scene(consistent, "c.toml"), doctest::Contains("lumped"), InputError);
}
