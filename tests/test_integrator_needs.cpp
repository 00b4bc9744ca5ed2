// What an integrator needs reaches the engine (StepNeeds, declared by its row
// in the integrator table): for every integrator of integrator_kinds(),
// parts that lack the particle fields it keeps (a_p, x_p^{s-1}: a run built
// in code, as examples/dyka_in_code.cpp builds one) are given them by the
// engine and step to the same bits as the assembled run; parts that lack
// what cannot be allocated (advected nodes, a B-spline basis, the consistent
// mass, a parameter or a parameter in range) are refused with
// std::invalid_argument naming the integrator and the need.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/integrators/integrator.hpp"

#include <doctest/doctest.h>

#include <cstring>
#include <stdexcept>
#include <string>

using namespace otmpm;

namespace {

/// A 1D bar, its left half moving, its right end held: the run each
/// integrator's row asks for (advected nodes, a B-spline basis, its mass).
Scene bar_for(const IntegratorKind& k) {
  const std::string text = std::string("[simulation]\ndimension = 1\nmode = \"") + (k.needs_ul ? "ul" : "mpm") +
                           "\"\nintegrator = \"" + std::string(k.name) + "\"\nt_end = 10.0\ncfl = 0.2\n" +
                           "[basis]\nkind = \"" + (k.needs_bspline ? "bspline2" : "linear") + "\"\n" +
                           "[grid]\nlower = [-0.25]\nupper = [1.0]\ncells = [10]\n"
                           "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1.0\nyoung = 1.0\npoisson = 0.0\n"
                           "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.0]\nupper = [1.0]\n"
                           "particles_per_cell = 2\nvelocity = [0.0]\n"
                           "[[initial_velocity]]\nlower = [0.0]\nupper = [0.5]\nvelocity = [-0.1]\n"
                           "[[boundary]]\nname = \"end\"\nlower = [1.0]\nupper = [1.0]\nfix = [true]\n";
  return parse_scene(text, "needs.toml");
}

/// Same length and bytes (two empty arrays are the same: memcmp is not given their null data).
template <class T> bool same_bits(const T& a, const T& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(a[0])) == 0);
}

/// Builds an engine from `parts` and returns the message of the
/// std::invalid_argument it throws ("" when it builds).
std::string refusal(EngineParts<1> parts) {
  try {
    Engine<1> e(std::move(parts));
  } catch (const std::invalid_argument& err) {
    return err.what();
  }
  return "";
}

} // namespace

TEST_CASE("integrator needs: the engine allocates the fields an integrator keeps, the run keeps its bits") {
  int kept = 0;
  for (const IntegratorKind& k : integrator_kinds()) {
    CAPTURE(k.name);
    const Scene scene = bar_for(k);
    EngineParts<1> bare = assemble_parts<1>(scene);
    // A run built in code that leaves out the fields (the engine's job now).
    bare.particles.a.clear();
    bare.particles.x_prev.clear();
    Engine<1> reference = assemble<1>(scene);
    Engine<1> engine(std::move(bare));
    CHECK(engine.particles().a.size() == (k.needs_acceleration ? reference.particles().a.size() : 0u));
    CHECK(engine.particles().x_prev.size() == (k.needs_previous_position ? reference.particles().x.size() : 0u));
    kept += k.needs_acceleration + k.needs_previous_position;
    for (int s = 0; s < 30; ++s) {
      reference.step();
      engine.step();
    }
    CHECK(same_bits(engine.particles().x, reference.particles().x));
    CHECK(same_bits(engine.particles().v, reference.particles().v));
    CHECK(same_bits(engine.particles().sigma, reference.particles().sigma));
    CHECK(same_bits(engine.particles().a, reference.particles().a));
  }
  CHECK(kept >= 2); // npc and explicit_alpha keep a_p, otm keeps x_p^{s-1}
}

TEST_CASE("integrator needs: parts without what an integrator needs are refused, naming it and the need") {
  int refused = 0;
  for (const IntegratorKind& k : integrator_kinds()) {
    CAPTURE(k.name);
    const Scene scene = bar_for(k);
    const std::string who = "integrator '" + std::string(k.name) + "'";
    CHECK(refusal(assemble_parts<1>(scene)).empty());
    // The scene's parts with `remove` taking a need away: refused, naming the integrator and `need`.
    const auto check_refused = [&](const auto& remove, const std::string& need) {
      EngineParts<1> parts = assemble_parts<1>(scene);
      remove(parts);
      const std::string m = refusal(std::move(parts));
      CHECK(m.find(who) != std::string::npos);
      CHECK(m.find(need) != std::string::npos);
      ++refused;
    };
    if (k.needs_ul)
      check_refused([](EngineParts<1>& parts) { parts.mode = NodeMode<1>::fixed_grid(Vec<1>(-0.25), Vec<1>(1.0)); },
                    "nodes that move");
    if (k.needs_bspline)
      check_refused(
          [](EngineParts<1>& parts) {
            BasisOptions linear;
            linear.kind = "linear";
            CartesianGrid<1> grid;
            grid.lower = Vec<1>(0.0);
            grid.upper = Vec<1>(1.0);
            grid.cells = {8};
            parts.basis = make_basis<1>(linear, NodeSet<1>::cartesian(grid));
          },
          "B-spline basis, not 'linear'");
    if (k.needs_consistent_mass)
      check_refused([](EngineParts<1>& parts) { parts.settings.consistent_mass = false; }, "consistent mass");
    for (const ParameterSpec& p : k.parameters) {
      CAPTURE(p.key);
      EngineParts<1> missing = assemble_parts<1>(scene);
      missing.settings.parameters.values.erase(std::string(p.key));
      const std::string m = refusal(std::move(missing));
      CHECK(m.find(who + " reads parameter '" + std::string(p.key) + "'") != std::string::npos);
      EngineParts<1> outside = assemble_parts<1>(scene);
      outside.settings.parameters.values[std::string(p.key)] = p.upper < kUnbounded ? p.upper + 1.0 : p.lower - 1.0;
      CHECK(refusal(std::move(outside)).find(who + " parameter '" + std::string(p.key) + "'") != std::string::npos);
      ++refused;
    }
  }
  CHECK(refused >= 4); // otm and unified (ul), unified (B-spline, consistent mass), npc and explicit_alpha (parameters)
}
