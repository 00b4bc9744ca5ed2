#pragma once
/// \file validate.hpp
/// Checks of a Scene as plain data. parse_scene() checks every value as it
/// reads the file (with line numbers); a Scene built or changed in code skips
/// that, so the library entry points that take a Scene (Engine<D>, and through
/// it run_scene(), and seed_particles()) call these first. A bad value then
/// gives an InputError naming the scene key ("FILE:LINE: key 'grid.cells': ..."
/// when the scene came from a file, "key 'grid.cells': ..." otherwise) instead
/// of undefined behaviour, a hang or a NaN in the first step.
#include "otmpm/parameters.hpp"
#include "otmpm/scene/scene.hpp"

namespace otmpm {

struct ParticleFileRules; // io/particle_file.hpp

/// The ranges of the scene's scalar keys (`key`: the key within its table;
/// the defaults are the Scene's): one row per quantity, which the scene
/// reader checks each value against as it reads it (FILE:LINE: key) and
/// validate_scene checks again on a Scene built in code or from a Python
/// dict (key 'K'), with the same message ("must be > 0 (got -1)"). The
/// material constants are kDensity, kYoung and kPoisson (materials/
/// elasticity.hpp), the model and integrator parameters their own rows; a
/// particle file's columns meet the row of the same quantity
/// (particle_file_rules).
namespace scene_keys {
inline constexpr ParameterSpec kTEnd{"t_end", "end time [s]", std::nullopt, 0.0, true};
inline constexpr ParameterSpec kCfl{"cfl", "Courant number of the time step", std::nullopt, 0.0, true};
inline constexpr ParameterSpec kDt{"dt", "fixed time step [s]", std::nullopt, 0.0, true};
inline constexpr ParameterSpec kMassTolerance{"mass_tolerance", "relative mass below which a node is inactive",
                                              std::nullopt, 0.0, false, 1.0, true};
inline constexpr ParameterSpec kEnergyLimit{"energy_limit", "runaway energy, a multiple of energy and work",
                                            std::nullopt, 1.0};
inline constexpr ParameterSpec kMaxSteps{"max_steps", "the most steps a run may take", std::nullopt, 1.0};
inline constexpr ParameterSpec kMemoryLimit{"memory_limit", "bytes a run may use (0: what the process may use)",
                                            std::nullopt, 0.0};
inline constexpr ParameterSpec kEquilibriumTime{"time", "longest time of the initial equilibrium phase [s]",
                                                std::nullopt, 0.0, true};
inline constexpr ParameterSpec kEquilibriumDamping{"damping", "local damping factor of the initial equilibrium phase",
                                                   0.7, 0.0, false, 1.0, true};
inline constexpr ParameterSpec kEquilibriumTolerance{"tolerance", "residual that ends the initial equilibrium phase",
                                                     1e-3, 0.0, true, 1.0, true};
inline constexpr ParameterSpec kPerturbation{"perturbation", "node perturbation, a fraction of h", std::nullopt, 0.0,
                                             false, 0.5, true};
inline constexpr ParameterSpec kFriction{"friction", "Coulomb friction coefficient", std::nullopt, 0.0};
inline constexpr ParameterSpec kChannelWidth{"width", "distance between a channel's side walls [m]",
                                             std::nullopt, 0.0, true};
inline constexpr ParameterSpec kPeriod{"period", "period of a ramp [s]", std::nullopt, 0.0, true};
inline constexpr ParameterSpec kPorePressure{"pore_pressure", "pore pressure of a drained surface [Pa]", std::nullopt,
                                             -kUnbounded};
inline constexpr ParameterSpec kWaterLevel{"water_level", "height of free water on a drained surface [m]",
                                           std::nullopt, -kUnbounded};
inline constexpr ParameterSpec kWaterRise{"water_rise", "rise of a water level over its time function [m]",
                                          std::nullopt, -kUnbounded};
inline constexpr ParameterSpec kWaterTable{"water_table", "height of a saturated body's water table [m]",
                                           std::nullopt, -kUnbounded};
inline constexpr ParameterSpec kK0{"k0", "lateral earth pressure coefficient at rest", std::nullopt, 0.0};
inline constexpr ParameterSpec kPlateForce{"force", "force on a rigid plate [N] (2D: N/m, 1D: N/m^2)", 0.0,
                                           -kUnbounded};
inline constexpr ParameterSpec kNodeReset{"node_reset", "ul: the fraction of h below which the nodes are laid out anew",
                                          0.0, 0.0, false, 1.0, true};
} // namespace scene_keys

/// Throws InputError naming the key unless the scene can run in `dimension`
/// dimensions: every check parse_scene makes of the values it reads.
/// Checked: simulation (dimension == `dimension`, mode, integrator, its
/// parameters and the mode and mass matrix it needs, t_end, cfl, dt,
/// mass_tolerance, finite energy_limit >= 1, max_steps, memory_limit), grid
/// (kind, finite lower < upper and upper - lower, cells >= 1, perturbation),
/// the basis kind and the grid and mode it needs, at least one material and
/// body, every material (unique name, model and its parameters), every body
/// (see validate_bodies), the particle and node caps (kMaxSceneParticles,
/// kMaxSceneNodes, kMaxCellsPerAxis; and, split evenly over `processes`,
/// kMaxRankParticles and kMaxRankNodes per process - 0 processes: a rank's
/// share, whose own size is checked where it is known), the initial-velocity, boundary, wall and traction boxes,
/// values, axes and functions, the body force, the time functions, and the
/// output section (file, every, known and distinct fields and formats,
/// probes with a known particle choice and a finite point, checkpoint_every
/// >= 0, checkpoint_file != file). Every name - of a material, wall or probe
/// (required: a wall's and a probe's name the histories of the result file),
/// of a body or boundary (when given) - is one the reader accepts: unique
/// among its kind and able to name a result-file group and a --set key
/// (invalid_name_reason). Options of the basis family are checked by
/// make_basis().
void validate_scene(const Scene& scene, int dimension, int processes = 1);

/// The bodies alone: at least one; each has a unique name (or none), names a
/// defined material, has a known shape with the values it needs (a finite
/// box lower < upper), particles_per_cell in [1, kMaxParticlesPerCell],
/// overlap "error" or "first", placement "gauss" or
/// "cell_centres", a finite velocity and velocity_profile unset or "sin_x";
/// in `mpm` mode it lies inside the grid. InputError naming the key.
void validate_bodies(const Scene& scene, int dimension);

/// The names output.fields may use in this scene: the built-in particle
/// fields (output_fields()), stress_zz (kStressZzField; valid in 2D only)
/// and the internal variables of its material models.
std::vector<std::string_view> output_field_names(const Scene& scene);

/// The name the reader gives the unnamed [[kind]] table at `index` of its
/// array ("body2", "boundary0", "wall1"); validate_scene takes an unnamed
/// body or boundary built in code for it, to_toml leaves it to the reader.
std::string default_name(std::string_view kind, std::size_t index);

/// Why `name` cannot name a `what` ("body", "probe", ...): the reader's and
/// validate_scene's message (invalid_name_reason, the name printable), or
/// "" when it can.
std::string name_error(const std::string& name, std::string_view what);

/// What the particle file of file body `body` must satisfy
/// (ParticleFileRules): a `density` column in the range of
/// material.NAME.density (kDensity), a column named after a scalar state
/// variable of its material's model in that variable's range
/// (StateSpec::range), no other further column, at most kMaxSceneParticles
/// rows (kMaxRankParticles per process when the process count is known).
/// The scene reader and the seeding read the file with them.
/// `processes` > 0: the rows a run on that many processes may hold (kMaxRankParticles each).
ParticleFileRules particle_file_rules(const Scene& scene, const BodySection& body, int processes = 0);

/// What seed_particles() relies on: validate_bodies(), a grid spacing h that
/// is finite and > 0 on every axis, and (`whole`: all particles are stored
/// in one process) a particle count that fits an int. InputError naming the
/// body or the axis of h.
template <int D> void validate_seeding(const Scene& scene, const Vec<D>& h, bool whole = true);

} // namespace otmpm
