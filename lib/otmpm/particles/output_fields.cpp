/// \file output_fields.cpp
/// The table of output fields (output_fields.hpp).
#include "otmpm/particles/output_fields.hpp"

#include "otmpm/parallel.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>

namespace otmpm {

namespace {

/// A field stored as contiguous doubles (Vec<D> arrays: D per particle;
/// scalars: 1), handed out without a copy; empty when not allocated.
template <int D, class Field> FieldData direct(const Field& f, int cols) {
  return {f.empty() ? nullptr : reinterpret_cast<const double*>(f.data()), cols};
}

/// D x D tensors copied row by row into the buffer.
/// (Threads copy contiguous chunks: the same values for any thread count.)
template <int D> FieldData row_major(const AlignedVector<Mat<D>>& A, std::vector<double>& buf) {
  buf.resize(A.size() * D * D);
  parallel_chunks(static_cast<long long>(A.size()), [&](long long begin, long long end) {
    for (auto p = static_cast<std::size_t>(begin); p < static_cast<std::size_t>(end); ++p)
      for (int i = 0; i < D; ++i)
        for (int j = 0; j < D; ++j) buf[p * D * D + i * D + j] = A[p](i, j);
  });
  return {A.empty() ? nullptr : buf.data(), D * D};
}

template <int D> FieldData position(const Particles<D>& P, std::vector<double>&) { return direct<D>(P.x, D); }
template <int D> FieldData velocity(const Particles<D>& P, std::vector<double>&) { return direct<D>(P.v, D); }
template <int D> FieldData acceleration(const Particles<D>& P, std::vector<double>&) { return direct<D>(P.a, D); }
template <int D> FieldData stress(const Particles<D>& P, std::vector<double>& b) { return row_major<D>(P.sigma, b); }
template <int D> FieldData strain(const Particles<D>& P, std::vector<double>& b) { return row_major<D>(P.eps, b); }
template <int D> FieldData deformation(const Particles<D>& P, std::vector<double>& b) { return row_major<D>(P.F, b); }
template <int D> FieldData density(const Particles<D>& P, std::vector<double>&) { return direct<D>(P.rho, 1); }
template <int D> FieldData volume(const Particles<D>& P, std::vector<double>&) { return direct<D>(P.V, 1); }
template <int D> FieldData mass(const Particles<D>& P, std::vector<double>&) { return direct<D>(P.m, 1); }
template <int D> FieldData displacement(const Particles<D>& P, std::vector<double>& buf) {
  buf.resize(static_cast<std::size_t>(P.size()) * D);
  for (int p = 0; p < P.size(); ++p)
    for (int k = 0; k < D; ++k) buf[static_cast<std::size_t>(p) * D + k] = P.x[p][k] - P.X[p][k];
  return {buf.data(), D};
}

#define OTMPM_GETTERS(F) F<1>, F<2>, F<3>
const std::array kFields{
    OutputField{"x", "position x_p", OTMPM_GETTERS(position)},
    OutputField{"v", "velocity v_p", OTMPM_GETTERS(velocity)},
    OutputField{"a", "acceleration a_p (npc)", OTMPM_GETTERS(acceleration)},
    OutputField{"stress", "Cauchy stress sigma_p (D x D, row-major)", OTMPM_GETTERS(stress)},
    OutputField{"strain", "small strain eps_p, or sym(F_p) - I for finite strain", OTMPM_GETTERS(strain)},
    OutputField{"F", "deformation gradient F_p", OTMPM_GETTERS(deformation)},
    OutputField{"density", "density rho_p", OTMPM_GETTERS(density)},
    OutputField{"volume", "volume V_p", OTMPM_GETTERS(volume)},
    OutputField{"mass", "mass m_p", OTMPM_GETTERS(mass)},
    OutputField{"displacement", "displacement x_p - X_p", OTMPM_GETTERS(displacement)},
};
#undef OTMPM_GETTERS

} // namespace

std::span<const OutputField> output_fields() { return kFields; }

bool is_symmetric_tensor_field(std::string_view name) { return name == "stress" || name == "strain"; }

std::string_view symmetric_components(int D) {
  require<std::invalid_argument>(D >= 1 && D <= 3, "symmetric_components: dimension must be 1, 2 or 3, got ", D);
  return D == 3 ? "xx xy xz yy yz zz" : D == 2 ? "xx xy yy" : "xx";
}

void pack_symmetric(const double* full, std::size_t rows, int D, std::vector<double>& out) {
  require<std::invalid_argument>(D >= 1 && D <= 3, "pack_symmetric: dimension must be 1, 2 or 3, got ", D);
  const auto d = static_cast<std::size_t>(D);
  const std::size_t cols = d * (d + 1) / 2;
  out.resize(rows * cols);
  parallel_chunks(static_cast<long long>(rows), [&](long long begin, long long end) {
    for (auto p = static_cast<std::size_t>(begin); p < static_cast<std::size_t>(end); ++p) {
      std::size_t c = 0;
      for (std::size_t i = 0; i < d; ++i)
        for (std::size_t j = i; j < d; ++j) out[p * cols + c++] = full[p * d * d + i * d + j];
    }
  });
}

std::string_view plane_stress_components() { return "xx xy yy zz"; }

void pack_plane_stress(const double* full, const double* zz, std::size_t rows, std::vector<double>& out) {
  out.resize(rows * 4);
  parallel_chunks(static_cast<long long>(rows), [&](long long begin, long long end) {
    for (auto p = static_cast<std::size_t>(begin); p < static_cast<std::size_t>(end); ++p) {
      out[p * 4 + 0] = full[p * 4 + 0];
      out[p * 4 + 1] = full[p * 4 + 1];
      out[p * 4 + 2] = full[p * 4 + 3];
      out[p * 4 + 3] = zz[p];
    }
  });
}

template <int D> FieldData output_field_data(std::string_view name, const Particles<D>& P, std::vector<double>& buffer) {
  FieldData d;
  const auto it = std::find_if(kFields.begin(), kFields.end(), [&](const OutputField& f) { return f.name == name; });
  if (it != kFields.end()) {
    if constexpr (D == 1) d = it->get1(P, buffer);
    else if constexpr (D == 2) d = it->get2(P, buffer);
    else d = it->get3(P, buffer);
  } else if (const StateField* s = P.find_state(name)) {
    d = {s->values.data(), s->width};
  }
  require<std::invalid_argument>(d.data != nullptr || P.size() == 0, "output_field_data: the particles have no field '",
                                 std::string(name), "'");
  return d;
}

template FieldData output_field_data<1>(std::string_view, const Particles<1>&, std::vector<double>&);
template FieldData output_field_data<2>(std::string_view, const Particles<2>&, std::vector<double>&);
template FieldData output_field_data<3>(std::string_view, const Particles<3>&, std::vector<double>&);

} // namespace otmpm
