/// \file scene_rules.cpp
/// The scene rules the reader and the validator share (scene_rules.hpp).
#include "otmpm/scene/scene_rules.hpp"

#include "otmpm/particles/output_fields.hpp"
#include "otmpm/scene/toml_reader.hpp"
#include "otmpm/scene/validate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace otmpm::scene_rules {

std::string choice(std::span<const std::string_view> allowed, std::string_view value) {
  if (std::find(allowed.begin(), allowed.end(), value) != allowed.end()) return "";
  return toml_input::choice_message(allowed, value);
}

std::string box(const Vec3& lo, const Vec3& hi, int dim, bool strict) {
  for (int k = 0; k < dim; ++k)
    if (!(strict ? lo[k] < hi[k] : lo[k] <= hi[k]))
      return error_message("must be ", strict ? ">" : ">=", " lower in every component (axis ", k, ": lower ", lo[k],
                           ", upper ", hi[k], ")");
  return "";
}

std::string extent(const Vec3& lo, const Vec3& hi, int dim) {
  for (int k = 0; k < dim; ++k)
    if (!std::isfinite(hi[k] - lo[k]))
      return error_message("upper - lower overflows on axis ", k, " (lower ", lo[k], ", upper ", hi[k], ")");
  return "";
}

std::string cells(const std::array<int, 3>& cells, int dim) {
  for (int k = 0; k < dim; ++k)
    if (cells[static_cast<std::size_t>(k)] < 1)
      return error_message("axis ", k, ": must be >= 1 (got ", cells[static_cast<std::size_t>(k)], ")");
  return "";
}

std::string node_reset(double node_reset, bool nodes_move) {
  if (node_reset == 0 || nodes_move) return "";
  return "lays the advected nodes out anew: it needs simulation.mode = \"ul\"";
}

std::string material(const std::vector<MaterialSection>& materials, const std::string& name) {
  if (std::any_of(materials.begin(), materials.end(), [&](const MaterialSection& m) { return m.name == name; }))
    return "";
  return "no [[material]] named \"" + name + "\"";
}

std::string particles_per_cell(int n) {
  if (n >= 1 && n <= kMaxParticlesPerCell) return "";
  return error_message("must be in [1, ", kMaxParticlesPerCell, "] (got ", n, ")");
}

std::string size(double value) {
  return finite_positive(value) ? "" : error_message("must be finite and > 0 (got ", value, ")");
}

std::string cylinder_dimension(int dim) {
  return dim == 3 ? "" : "shape \"cylinder\" is three-dimensional (use \"sphere\" for a disk in 2D)";
}

std::string polygon_dimension(int dim) {
  return dim == 2 ? "" : error_message("shape \"polygon\" is two-dimensional (simulation.dimension = ", dim, ")");
}

std::string vertex_count(std::size_t n) {
  return n >= 3 ? "" : error_message("needs at least 3 vertices (got ", n, ")");
}

std::string cylinder_axis(const Vec3& axis, int dim) {
  return is_direction<3>(first_components(axis, dim)) ? "" : "must be finite and not zero";
}

std::string wall_normal(const Vec3& normal, int dim) {
  return is_direction<3>(first_components(normal, dim))
             ? ""
             : "must be finite and not zero (it points to the material's side of the wall)";
}

std::string axis_index(int axis, int dim) {
  if (axis >= 0 && axis < dim) return "";
  return error_message("must be an axis index in [0, ", dim, ") (got ", axis, ")");
}

std::string field(const std::vector<std::string>& fields, std::size_t i, std::span<const std::string_view> known,
                  int dim) {
  const std::string& f = fields[i];
  if (std::find(known.begin(), known.end(), f) == known.end())
    return "unknown field \"" + f + "\"" + toml_input::suggestion(f, known);
  if (std::count(fields.begin(), fields.end(), f) != 1) return "names \"" + f + "\" twice";
  if (f == kStressZzField && dim != 2)
    return "\"stress_zz\" (plane strain's out-of-plane stress) needs simulation.dimension = 2 (got " +
           std::to_string(dim) + (dim == 3 ? "; the 3D \"stress\" holds sigma_zz)" : ")");
  return "";
}

std::string formats(const std::vector<std::string>& formats) {
  for (const std::string& f : formats) {
    if (!is_output_format(f)) return "unknown format \"" + f + "\"" + toml_input::suggestion(f, kOutputFormats);
    if (std::count(formats.begin(), formats.end(), f) != 1) return "names \"" + f + "\" twice";
  }
  const auto has = [&](const char* f) { return std::count(formats.begin(), formats.end(), f) > 0; };
  if (!has("hdf5")) return "must contain \"hdf5\": the HDF5 result file is always written (e.g. [\"hdf5\", \"vtp\"])";
  if (has("vtp") && has("vtu")) return "choose one of \"vtp\" and \"vtu\" (both would be listed by the same .pvd)";
  return "";
}

std::string file_name(const std::string& name) { return name.empty() ? "must not be empty" : ""; }

std::string checkpoint_every(long long every) {
  if (every >= 0 && every <= std::numeric_limits<long>::max()) return "";
  return "must be an integer >= 0 (steps between checkpoints; 0: none; got " + std::to_string(every) + ")";
}

std::string checkpoint_file(const std::string& checkpoint_file, const std::string& file) {
  return checkpoint_file == file ? "must differ from output.file" : "";
}

std::string compression(long long level) {
  if (level >= 0 && level <= 9) return "";
  return "must be an integer 0..9 (deflate level; 0: uncompressed; got " + std::to_string(level) + ")";
}

} // namespace otmpm::scene_rules
