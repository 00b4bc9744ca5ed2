#pragma once
/// \file output_fields.hpp
/// The particle fields a result frame can hold (`output.fields`), listed
/// once: the scene reader takes the names from here and the result writer
/// the data. A material's internal variables (Particles::state) can be
/// written too, under their own names.
#include "otmpm/particles/particles.hpp"

#include <span>
#include <string_view>
#include <vector>

namespace otmpm {

/// The values of one particle field for a frame: `cols` doubles per
/// particle, row-major (tensors: D*D components, row by row), pointing
/// either into the particle arrays or into a buffer the caller owns.
struct FieldData {
  const double* data = nullptr;
  int cols = 0;
};

/// Reads field `name` of the particles; `buffer` holds the values when they
/// are not stored as they are written (tensors, the displacement).
template <int D> using FieldGetter = FieldData (*)(const Particles<D>&, std::vector<double>& buffer);

/// One built-in output field.
struct OutputField {
  std::string_view name;
  std::string_view description;
  FieldGetter<1> get1 = nullptr;
  FieldGetter<2> get2 = nullptr;
  FieldGetter<3> get3 = nullptr;
};

/// The built-in fields, in the order the docs list them.
std::span<const OutputField> output_fields();

/// True for the built-in fields that are symmetric D x D tensors (stress,
/// strain; not F), which output.symmetric_tensors stores by their
/// independent components.
bool is_symmetric_tensor_field(std::string_view name);

/// The names of a symmetric tensor's independent components in D
/// dimensions, in the order pack_symmetric writes them (the upper triangle
/// row by row; in 3D the XDMF Tensor6 order): "xx xy xz yy yz zz",
/// "xx xy yy" or "xx". (The 2D stress adds zz: plane_stress_components.)
std::string_view symmetric_components(int D);

/// Packs `rows` row-major D x D tensors (`full`) into their D (D + 1) / 2
/// upper-triangle components each (symmetric_components), into `out`.
void pack_symmetric(const double* full, std::size_t rows, int D, std::vector<double>& out);

/// The output field of plane strain's out-of-plane Cauchy stress sigma_zz
/// (one column; 2D only). Not a particle array: the materials derive it from
/// their state when a frame is written (Material::out_of_plane_stress), so
/// output_field_data does not know it.
inline constexpr std::string_view kStressZzField = "stress_zz";

/// The components of the 2D stress that output.symmetric_tensors stores: the
/// in-plane ones (symmetric_components(2)) and plane strain's sigma_zz,
/// "xx xy yy zz". The 2D strain keeps "xx xy yy" (eps_zz = 0).
std::string_view plane_stress_components();

/// Packs `rows` row-major 2 x 2 tensors (`full`) as pack_symmetric and
/// appends zz[p] to row p: rows x 4 values in plane_stress_components order.
void pack_plane_stress(const double* full, const double* zz, std::size_t rows, std::vector<double>& out);

/// The values of field `name` (a built-in field or a state field of P).
/// std::invalid_argument when P has no such field (or it is not allocated).
template <int D> FieldData output_field_data(std::string_view name, const Particles<D>& P, std::vector<double>& buffer);

} // namespace otmpm
