#pragma once
/// \file material.hpp
/// The constitutive update of docs/theory.md (sect. 9) behind
/// one interface, Material<D>, and the closed set of models (MaterialModel)
/// that the scene reader, the validator and the assembler read.
///
/// A material updates the particles that are made of it from their velocity
/// gradient increment H = dt L_p (or G_p - I for the integrators that move
/// by increments): strain or deformation gradient, density, volume and
/// Cauchy stress. A model with internal variables declares them (StateSpec):
/// they become per-particle arrays (Particles::state), allocated only when a
/// scene uses the model, saved in checkpoints and written to results on
/// request (output.fields names them). It also says how much energy it
/// stores and how much it dissipated, for the energy balance.
///
/// Adding a model (docs/architecture.md, "Adding a part"): a file with the
/// class and its MaterialModel row (parameters, state, factories), and one
/// line in materials/models.cpp.
#include "otmpm/materials/elasticity.hpp"
#include "otmpm/parameters.hpp"
#include "otmpm/particles/particles.hpp"

#include <algorithm>
#include <array>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

namespace otmpm {

/// What a scene gives a material: its name, model, the constants every model
/// has, and the model's own parameters by key (e.g. "yield_stress",
/// "johnson_cook.B"), as listed in its MaterialModel::parameters.
struct MaterialParameters {
  std::string name;
  std::string model = "linear_elastic";
  double density = 0, young = 0, poisson = 0;
  std::map<std::string, double> extra;
  /// rho_0, E and nu.
  ElasticConstants elastic() const { return {density, young, poisson}; }
  /// The parameter `key`: extra[key], or `fallback` when absent.
  double get(const std::string& key, double fallback) const;
  /// True when the scene gave `key`.
  bool has(const std::string& key) const { return extra.count(key) > 0; }
};

/// A per-particle internal variable of a model: `width` (at most 9)
/// doubles per particle named `name` (Particles::state), initially the
/// first `width` values of `initial`; output.fields writes it under that name.
struct StateSpec {
  std::string_view name;
  int width = 1;
  std::array<double, 9> initial{};
  std::string_view description;
  /// The smallest value a particle may start with (0 for an equivalent
  /// plastic strain or an energy; -kUnbounded: any finite value).
  double lower = -kUnbounded;
  /// The range of a scalar variable as a ParameterSpec: what a particle
  /// file's column of its name must satisfy (ParticleFileRules).
  ParameterSpec range() const { return {name, description, initial[0], lower}; }
};

/// A model parameter beyond density, young and poisson (ParameterSpec). A
/// key "table.key" lives in the optional sub-table [material.table]; when
/// the scene gives that table, its required keys must be there.

/// Thrown by a constitutive update for the first particle whose state stops
/// making sense (det F <= 0, a volume change <= 0); the engine names the
/// step, time and position and stops the run (InstabilityError).
struct ParticleFailure {
  int particle;
  std::string what;
};

/// A constitutive model bound to its parameters (one per [[material]]).
template <int D> class Material {
public:
  explicit Material(MaterialParameters p) : params_(std::move(p)) {}
  virtual ~Material() = default;
  const std::string& name() const { return params_.name; }
  const MaterialParameters& parameters() const { return params_; }
  /// P-wave modulus M of the wave speed c_p = sqrt(M / rho_p) of the CFL
  /// condition: the elastic E in 1D, lambda + 2 mu otherwise.
  virtual double p_modulus() const { return params_.elastic().p_modulus(D); }
  /// The largest squared wave speed c_p^2 of particles p0 .. p1-1, all of
  /// this material, maxed into `c2` (the CFL step, docs/theory.md sect. 10):
  /// the P-wave modulus of the model's tangent at the particle's state over
  /// its current density. This default, c_p^2 = M / rho_p with M =
  /// p_modulus(), is exact for a law with a constant Cauchy tangent (the
  /// small-strain model); the finite-strain models give their own.
  virtual void max_wave_speed2(const Particles<D>& P, int p0, int p1, double& c2) const {
    const double M = p_modulus();
    for (int p = p0; p < p1; ++p) c2 = std::max(c2, M / P.rho[p]);
  }
  /// True when the model needs the deformation gradient F_p.
  virtual bool needs_deformation_gradient() const = 0;
  /// The internal variables of the model (none for the elastic models).
  virtual std::span<const StateSpec> state() const { return {}; }
  /// Finds this model's state arrays in P (allocated by the assembler) and
  /// sets the initial state of the particles of this material. Called once,
  /// before the first step.
  virtual void bind(Particles<D>& P) { (void)P; }
  /// A geostatic start (MaterialModel::takes_initial_stress): particle p, of
  /// this material, starts at F_p = I under the Cauchy stress sigma0 (3x3:
  /// with its out-of-plane components in 1D and 2D). The assembler has set
  /// P.sigma[p] to it (and, in plane strain, the state "initial_stress_zz"
  /// to sigma0_zz); a model whose stress follows from a state of its own
  /// (b_e) sets that state here, with its stored energy. Called once, after
  /// the state arrays are allocated and before bind.
  virtual void start_from_stress(Particles<D>& P, int p, const Mat<3>& sigma0) const {
    (void)P, (void)p, (void)sigma0;
  }
  /// The constitutive update of particles p0 .. p1-1, all of this material:
  /// H[i] = dt L_p (or G_p - I) of particle p0 + i, dt the step. Updates F_p
  /// when P.F is allocated, eps_p, rho_p, V_p, sigma_p and the state. Throws
  /// ParticleFailure for the first particle that fails.
  virtual void update(Particles<D>& P, int p0, int p1, const Mat<D>* H, double dt) const = 0;
  /// Adds, in particle order, the stored elastic energy (J) of particles
  /// p0 .. p1-1 to `stored` and the energy they dissipated since t = 0 to
  /// `dissipated` (the order matters: the sums are bit-reproducible).
  virtual void add_energies(const Particles<D>& P, int p0, int p1, double& stored, double& dissipated) const = 0;
  /// Plane strain (D = 2): the out-of-plane Cauchy stress sigma_zz of
  /// particles p0 .. p1-1, all of this material, into out[0 .. p1-p0),
  /// derived from what the model keeps (eps_p, F_p or b_e; docs/theory.md,
  /// sect. 9, "Out-of-plane stress"). Called at output time only: it reads
  /// the particles and changes nothing. std::logic_error in 1D and 3D (the
  /// 3D stress holds sigma_zz itself) and for a model that does not say.
  virtual void out_of_plane_stress(const Particles<D>& P, int p0, int p1, double* out) const {
    (void)P, (void)p0, (void)p1, (void)out;
    require<std::logic_error>(false, "material '", name(), "' (model ", params_.model,
                              "): no out-of-plane stress in ", D, "D");
  }

private:
  MaterialParameters params_;
};

/// Builds a material of one model in D dimensions (parameters validated).
template <int D> using MaterialFactory = std::unique_ptr<Material<D>> (*)(const MaterialParameters&);

/// A value of a material's scene key (MaterialModel::example).
struct ParameterValue {
  std::string_view key;
  double value = 0.0;
};

/// One material model as the scene names it (`model`) with its parameters,
/// internal variables and constructors.
struct MaterialModel {
  std::string_view name;
  std::string_view description;
  std::span<const ParameterSpec> parameters;
  std::span<const StateSpec> state;
  MaterialFactory<1> make1 = nullptr;
  MaterialFactory<2> make2 = nullptr;
  MaterialFactory<3> make3 = nullptr;
  /// A valid material of the model, by scene key (density, young, poisson
  /// and its own parameters): the material the contract tests run every
  /// model with (tests/test_contracts.cpp). A model with required
  /// parameters must give one.
  std::span<const ParameterValue> example{};
  /// It takes a geostatic initial stress (`water_table`): its update adds
  /// a rate to sigma_p, so that a stress set on sigma_p before the run stays,
  /// or Material::start_from_stress sets the state the stress follows from.
  bool takes_initial_stress = false;
  /// Its yield stress grows with the mean pressure (friction: drucker_prager,
  /// mu_i). F-bar gives each particle its patch's mean stress, which such a
  /// yield cone does not follow where dense and separated grains share a
  /// patch: `ul` mode's default volumetric treatment leaves these models out
  /// (docs/benchmarks.md, "Granular column collapse").
  bool frictional = false;
};

/// Every model, in the order the docs list them.
std::span<const MaterialModel* const> material_models();
/// The model named `name`, or null.
const MaterialModel* find_material_model(std::string_view name);
/// "linear_elastic, linear_elastic_finite or neo_hookean", for messages.
std::string material_model_list();
/// The material `p.model` in D dimensions. Throws InputError naming the
/// material and the parameter when the model is unknown, a required
/// parameter is missing or a value is out of range.
template <int D> std::unique_ptr<Material<D>> make_material(const MaterialParameters& p);
/// The checks of make_material without building anything (any dimension).
void validate_material(const MaterialParameters& p);

} // namespace otmpm
