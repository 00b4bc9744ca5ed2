#pragma once
/// \file scene_rules.hpp
/// The rules of scene values that both the scene reader (parse_scene: "FILE:LINE:
/// key 'K': ...") and the validator of a Scene built in code or from Python
/// (validate_scene: "key 'K': ...") apply, each written once here: the reader
/// and the validator call the same function and give the same message. Each
/// rule returns "" when the value passes, else the message (without the key).
/// The ranges of scalar keys are rows of their own (scene_keys,
/// validate.hpp). Internal to scene/ (tests check the two paths agree).
#include "otmpm/scene/scene.hpp"

#include <array>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace otmpm::scene_rules {

// The words of the keys that take one of a closed list (TableReader::choice
// in the reader, choice() in the validator).
inline constexpr std::array<std::string_view, 7> kShapes{"box",     "cylinder", "file", "mesh",
                                                          "polygon", "sphere",   "stl"}; ///< body.shape
inline constexpr std::array<std::string_view, 2> kModes{"mpm", "ul"};                       ///< simulation.mode
inline constexpr std::array<std::string_view, 2> kMasses{"lumped", "consistent"};           ///< simulation.mass
inline constexpr std::array<std::string_view, 3> kVolumetric{"none", "fbar", "fbar_nodal"}; ///< simulation.volumetric
inline constexpr std::array<std::string_view, 2> kGridKinds{"cartesian", "perturbed"};      ///< grid.kind
inline constexpr std::array<std::string_view, 2> kSeedings{"element", "quadrature"};        ///< body.seeding (mesh)
inline constexpr std::array<std::string_view, 2> kNodeSources{"lattice", "mesh"};           ///< body.nodes (mesh)
inline constexpr std::array<std::string_view, 2> kOverlaps{"error", "first"};               ///< body.overlap
inline constexpr std::array<std::string_view, 2> kVolumes{"seeded", "exact"};               ///< body.volume
inline constexpr std::array<std::string_view, 2> kPlacements{"gauss", "cell_centres"};      ///< body.placement
inline constexpr std::array<std::string_view, 2> kVelocityProfiles{"sin_x", "reference"};   ///< body.velocity_profile
inline constexpr std::array<std::string_view, 2> kTimeKinds{"constant", "ramp"};            ///< *.time.kind
inline constexpr std::array<std::string_view, 1> kTractionFunctions{"wobbes_traction_bar"}; ///< traction.function
inline constexpr std::array<std::string_view, 3> kProbeParticles{"leftmost", "rightmost", "nearest"}; ///< probes.particle
inline constexpr std::array<std::string_view, 2> kPrecisions{"double", "single"};           ///< output.precision
inline constexpr std::array<std::string_view, 3> kOutputFormats{"hdf5", "vtp", "vtu"};      ///< output.format

inline constexpr const char* kNoMaterial = "at least one [[material]] is required";
inline constexpr const char* kNoBody = "at least one [[body]] is required";

/// `value` one of `allowed`.
std::string choice(std::span<const std::string_view> allowed, std::string_view value);
/// A box's upper above (strict) or at its lower on every axis.
std::string box(const Vec3& lower, const Vec3& upper, int dim, bool strict);
/// grid: upper - lower finite on every axis.
std::string extent(const Vec3& lower, const Vec3& upper, int dim);
/// grid.cells: at least one per axis.
std::string cells(const std::array<int, 3>& cells, int dim);
/// simulation.node_reset: only with advected nodes.
std::string node_reset(double node_reset, bool nodes_move);
/// body.material: a [[material]] of that name.
std::string material(const std::vector<MaterialSection>& materials, const std::string& name);
/// body.particles_per_cell in [1, kMaxParticlesPerCell].
std::string particles_per_cell(int n);
/// A size a shape needs (sphere and cylinder radius, cylinder length): finite and > 0.
std::string size(double value);
/// shape "cylinder": three-dimensional.
std::string cylinder_dimension(int dim);
/// shape "polygon": two-dimensional.
std::string polygon_dimension(int dim);
/// polygon: at least 3 vertices.
std::string vertex_count(std::size_t n);
/// A cylinder's axis: finite and not zero.
std::string cylinder_axis(const Vec3& axis, int dim);
/// A wall's normal: finite and not zero.
std::string wall_normal(const Vec3& normal, int dim);
/// A plate's or traction's axis: an axis of the run.
std::string axis_index(int axis, int dim);
/// output.fields[i]: a known field (`known`: output_field_names), named once, stress_zz only in 2D.
std::string field(const std::vector<std::string>& fields, std::size_t i, std::span<const std::string_view> known,
                  int dim);
/// output.format: known formats, each once, "hdf5" among them, not both "vtp" and "vtu".
std::string formats(const std::vector<std::string>& formats);
/// output.file (and a given output.checkpoint_file): not empty.
std::string file_name(const std::string& name);
/// output.checkpoint_every: an integer >= 0.
std::string checkpoint_every(long long every);
/// output.checkpoint_file: not output.file.
std::string checkpoint_file(const std::string& checkpoint_file, const std::string& file);
/// output.compression: a deflate level 0..9.
std::string compression(long long level);

} // namespace otmpm::scene_rules
