/// \file exact_solutions.cpp
/// The exact solutions of reference/ built from a scene (exact_solutions.hpp):
/// the scene's single material and body checked against what each solution
/// assumes, its parameters taken from them.
#include "otmpm/assembly/exact_solutions.hpp"

#include "otmpm/materials/pore_fluid.hpp"
#include "otmpm/reference/consolidation.hpp"
#include "otmpm/reference/solutions.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace otmpm {

namespace {

/// Relative tolerance for geometric comparisons of scene boxes (a box edge
/// written with the same decimal literal as the body edge must match).
constexpr double kBoxTolerance = 1e-9;

/// wobbes eq. 103 has a unit traction amplitude [Pa].
constexpr double kWobbesTractionAmplitude = 1.0;

/// Displacement amplitude A of the manufactured plate (wobbes sect. 8.3) [m].
constexpr double kMmsAmplitude = 0.005;

/// Name of the built-in traction history of wobbes eq. 103 in a [[traction]] section.
const char* const kTractionBarFunction = "wobbes_traction_bar";

/// The one material (saturated, linear elastic) and body (a box at rest) of
/// a consolidation scene, loaded by one traction (Terzaghi) or one plate (Mandel).
struct ConsolidationScene {
  const MaterialSection* material;
  PoreFluid fluid;
  const BodySection* body;
};

ConsolidationScene consolidation_parts(const Scene& scene, const SourceRef& where, const std::string& name,
                                       bool plate) {
  auto fail = [&](const std::string& why) { input_error(where, "exact solution '" + name + "' " + why); };
  if (scene.materials.size() != 1 || scene.bodies.size() != 1)
    fail("needs exactly one [[material]] and one [[body]]");
  if (plate ? scene.plates.size() != 1 || !scene.tractions.empty()
            : scene.tractions.size() != 1 || !scene.plates.empty())
    fail(plate ? "is loaded by exactly one [[plate]] and no [[traction]]"
               : "is loaded by exactly one [[traction]] and no [[plate]]");
  const MaterialSection& m = scene.materials[0];
  const std::optional<PoreFluid> fluid = pore_fluid(m);
  if (!fluid) fail("needs a saturated material (porosity, permeability, fluid_density, fluid_bulk_modulus, "
                   "fluid_viscosity)");
  if (m.model != "linear_elastic") fail("needs model = \"linear_elastic\" (got \"" + m.model + "\")");
  const BodySection& b = scene.bodies[0];
  if (b.shape != "box") fail("needs a box body");
  if (scene.body_force || !scene.initial_velocities.empty() || b.velocity != Vec3{0, 0, 0} || b.velocity_profile)
    fail("starts at rest and has no body force (the solution is the pore pressure in excess of the hydrostatic)");
  if (!plate && !scene.tractions[0].function.empty()) fail("needs a traction value, not a function");
  return {&m, *fluid, &b};
}

template <int D> std::unique_ptr<ExactSolution<D>> make_terzaghi(const Scene& scene, const SourceRef& where) {
  const ConsolidationScene s = consolidation_parts(scene, where, "terzaghi", false);
  const TractionSection& tr = scene.tractions[0];
  int k = tr.axis.value_or(0); // the traction's axis (its largest component by default)
  if (!tr.axis)
    for (int j = 1; j < D; ++j)
      if (std::abs(tr.value[j]) > std::abs(tr.value[k])) k = j;
  const double lo = s.body->lower[k], hi = s.body->upper[k];
  // The loaded (drained) end: the one nearer the traction box.
  const double mid = 0.5 * (tr.lower[k] + tr.upper[k]);
  const bool top = std::abs(mid - hi) <= std::abs(mid - lo);
  const ElasticConstants c = s.material->elastic();
  TerzaghiParameters p;
  p.height = hi - lo;
  p.base = top ? lo : hi;
  p.direction = top ? 1.0 : -1.0;
  p.axis = k;
  p.modulus = c.p_modulus(D);
  p.lateral = D == 1 ? 0.0 : c.lambda() / c.p_modulus(D);
  p.porosity = s.fluid.porosity;
  p.mobility = s.fluid.permeability / s.fluid.viscosity;
  p.fluid_bulk_modulus = s.fluid.bulk_modulus;
  p.load = -p.direction * tr.value[k];
  p.time = tr.time;
  try {
    return std::make_unique<Terzaghi<D>>(p);
  } catch (const InputError& e) {
    input_error(where, e.what());
  }
}

template <int D> std::unique_ptr<ExactSolution<D>> make_mandel(const Scene& scene, const SourceRef& where) {
  if constexpr (D != 2) {
    input_error(where, "exact solution 'mandel' is two-dimensional (plane strain); the run is " + std::to_string(D) +
                           "D");
  } else {
    const ConsolidationScene s = consolidation_parts(scene, where, "mandel", true);
    const PlateSection& plate = scene.plates[0];
    if (plate.axis != 1) input_error(where, "exact solution 'mandel' needs the plate to press along y (axis 1)");
    MandelParameters p;
    p.width = s.body->upper[0] - s.body->lower[0];
    p.height = s.body->upper[1] - s.body->lower[1];
    p.lower[0] = s.body->lower[0];
    p.lower[1] = s.body->lower[1];
    p.young = s.material->young;
    p.poisson = s.material->poisson;
    p.porosity = s.fluid.porosity;
    p.mobility = s.fluid.permeability / s.fluid.viscosity;
    p.fluid_bulk_modulus = s.fluid.bulk_modulus;
    p.stress = -plate.force / p.width; // the plate on the top of the quarter presses down (-y)
    p.time = plate.time;
    try {
      return std::make_unique<Mandel>(p);
    } catch (const InputError& e) {
      input_error(where, e.what());
    }
  }
}

/// The exact solution `name` ("terzaghi", "mandel") of a scene, or null for
/// another name; InputError naming reference.solution when the scene does
/// not fit it.
template <int D> std::unique_ptr<ExactSolution<D>> make_consolidation(const Scene& scene, const std::string& name) {
  const SourceRef where = scene.locate("reference.solution");
  if (name == "terzaghi") return make_terzaghi<D>(scene, where);
  if (name == "mandel") return make_mandel<D>(scene, where);
  return nullptr;
}

/// The single material and body of a bar or plate scene, checked.
struct SceneParts {
  const MaterialSection* material;
  const BodySection* body;
};

template <int D> SceneParts single_body(const Scene& scene, const SourceRef& where, const std::string& name) {
  if (scene.materials.size() != 1 || scene.bodies.size() != 1)
    input_error(where, "exact solution '" + name + "' needs exactly one [[material]] and one [[body]] (the scene has " +
                           std::to_string(scene.materials.size()) + " and " + std::to_string(scene.bodies.size()) + ")");
  const MaterialSection& m = scene.materials[0];
  const BodySection& b = scene.bodies[0];
  if (!b.material.empty() && b.material != m.name)
    input_error(where, "exact solution '" + name + "': body '" + b.name + "' uses material '" + b.material +
                           "', not '" + m.name + "'");
  if (!(m.density > 0.0) || !(m.young > 0.0))
    input_error(where, "exact solution '" + name + "' needs a positive density and Young's modulus in material '" +
                           m.name + "'");
  for (int k = 0; k < D; ++k)
    if (!(b.upper[k] > b.lower[k]))
      input_error(where, "exact solution '" + name + "': body '" + b.name + "' has no extent along axis " +
                             std::to_string(k));
  return {&m, &b};
}

/// The bar's motion must be along x only: no initial velocity across it.
template <int D> void require_axial(const Vec3& velocity, const SourceRef& where, const std::string& what) {
  for (int k = 1; k < D; ++k)
    if (velocity[k] != 0.0)
      input_error(where, what + " has a non-zero component " + std::to_string(k) +
                             "; the exact solution is for motion along x only");
}

bool covers(double box_lower, double box_upper, double lower, double upper) {
  const double tol = kBoxTolerance * std::max(1.0, std::abs(upper - lower));
  return box_lower <= lower + tol && box_upper >= upper - tol;
}

template <int D> std::unique_ptr<ExactSolution<D>> make_dyka(const Scene& scene, const SourceRef& where) {
  const auto [m, b] = single_body<D>(scene, where, "dyka");
  if (scene.initial_velocities.size() != 1)
    input_error(where, "exact solution 'dyka' needs exactly one [[initial_velocity]] box (the scene has " +
                           std::to_string(scene.initial_velocities.size()) + ")");
  if (b->velocity_profile)
    input_error(where, "exact solution 'dyka' needs a uniform body velocity, not velocity_profile = '" +
                           *b->velocity_profile + "'");
  const InitialVelocitySection& iv = scene.initial_velocities[0];
  require_axial<D>(iv.velocity, where, "the [[initial_velocity]] velocity");
  require_axial<D>(b->velocity, where, "the body velocity");
  for (int k = 1; k < D; ++k)
    if (!covers(iv.lower[k], iv.upper[k], b->lower[k], b->upper[k]))
      input_error(where, "exact solution 'dyka': the [[initial_velocity]] box must span the whole bar across axis " +
                             std::to_string(k));
  DykaParameters p;
  p.length = b->upper[0] - b->lower[0];
  p.young = m->young;
  p.density = m->density;
  p.region_velocity = iv.velocity[0];
  p.rest_velocity = b->velocity[0];
  p.x_free = b->lower[0];
  p.region_begin = std::max(iv.lower[0], b->lower[0]) - p.x_free;
  p.region_end = std::min(iv.upper[0], b->upper[0]) - p.x_free;
  if (p.region_end < p.region_begin)
    input_error(where, "exact solution 'dyka': the [[initial_velocity]] box does not overlap the bar");
  return std::make_unique<DykaBar<D>>(p);
}

template <int D> std::unique_ptr<ExactSolution<D>> make_fixed_bar(const Scene& scene, const SourceRef& where) {
  const auto [m, b] = single_body<D>(scene, where, "fixed_bar");
  if (!b->velocity_profile || *b->velocity_profile != "sin_x")
    input_error(where, "exact solution 'fixed_bar' needs body velocity_profile = \"sin_x\"");
  if (!scene.initial_velocities.empty())
    input_error(where, "exact solution 'fixed_bar' does not allow [[initial_velocity]] boxes");
  require_axial<D>(b->velocity, where, "the body velocity");
  FixedBarParameters p;
  p.length = b->upper[0] - b->lower[0];
  p.young = m->young;
  p.density = m->density;
  p.amplitude = b->velocity[0];
  p.x_left = b->lower[0];
  return std::make_unique<FixedBar<D>>(p);
}

template <int D> std::unique_ptr<ExactSolution<D>> make_traction_bar(const Scene& scene, const SourceRef& where) {
  const auto [m, b] = single_body<D>(scene, where, "traction_bar");
  const auto it = std::find_if(scene.tractions.begin(), scene.tractions.end(),
                               [](const TractionSection& t) { return t.function == kTractionBarFunction; });
  if (it == scene.tractions.end())
    input_error(where, std::string("exact solution 'traction_bar' needs a [[traction]] with function = \"") +
                           kTractionBarFunction + "\"");
  if (!scene.initial_velocities.empty() || b->velocity_profile || b->velocity != Vec3{0, 0, 0})
    input_error(where, "exact solution 'traction_bar' starts at rest: no initial velocity allowed");
  TractionBarParameters p;
  p.length = b->upper[0] - b->lower[0];
  p.young = m->young;
  p.density = m->density;
  p.amplitude = it->value[0] != 0.0 ? it->value[0] : kWobbesTractionAmplitude;
  p.x_fixed = b->lower[0];
  return std::make_unique<TractionBar<D>>(p);
}

template <int D> std::unique_ptr<ExactSolution<D>> make_mms_plate(const Scene& scene, const SourceRef& where) {
  if constexpr (D != 2) {
    input_error(where, "exact solution 'mms_plate' is two-dimensional; the run is " + std::to_string(D) + "D");
  } else {
    const auto [m, b] = single_body<D>(scene, where, "mms_plate");
    const double lx = b->upper[0] - b->lower[0], ly = b->upper[1] - b->lower[1];
    if (std::abs(lx - ly) > kBoxTolerance * lx)
      input_error(where, "exact solution 'mms_plate' needs a square body (got " + std::to_string(lx) + " x " +
                             std::to_string(ly) + ")");
    MmsPlateParameters p;
    p.length = lx;
    p.young = m->young;
    p.poisson = m->poisson;
    p.density = m->density;
    p.amplitude = kMmsAmplitude;
    p.lower[0] = b->lower[0];
    p.lower[1] = b->lower[1];
    try {
      return std::make_unique<MmsPlate>(p);
    } catch (const InputError& e) {
      input_error(where, e.what());
    }
  }
}

} // namespace

template <int D> std::unique_ptr<ExactSolution<D>> make_exact_solution(const Scene& scene) {
  const std::string& name = scene.reference.solution;
  if (name.empty()) return nullptr;
  const SourceRef where = scene.locate("reference.solution");
  if (scene.simulation.dimension != D)
    input_error(where, "the scene is " + std::to_string(scene.simulation.dimension) + "D but the run is " +
                           std::to_string(D) + "D");
  if (name == "dyka") return make_dyka<D>(scene, where);
  if (name == "fixed_bar") return make_fixed_bar<D>(scene, where);
  if (name == "traction_bar") return make_traction_bar<D>(scene, where);
  if (name == "mms_plate") return make_mms_plate<D>(scene, where);
  if (auto consolidation = make_consolidation<D>(scene, name)) return consolidation;
  input_error(where, "unknown exact solution '" + name +
                         "' (expected dyka, fixed_bar, traction_bar, mms_plate, terzaghi or mandel)");
}

template std::unique_ptr<ExactSolution<1>> make_exact_solution<1>(const Scene&);
template std::unique_ptr<ExactSolution<2>> make_exact_solution<2>(const Scene&);
template std::unique_ptr<ExactSolution<3>> make_exact_solution<3>(const Scene&);

} // namespace otmpm
