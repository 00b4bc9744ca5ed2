#pragma once
/// \file particle_rows.hpp
/// Every per-particle array of a run seen as rows of bytes, so that
/// particles move between ranks (and into global order for output) without
/// any code that names a field: the arrays of Particles (for_each_field),
/// the materials' state arrays, the basis' per-point state (LME multipliers,
/// their slopes and histories, cell hints) and the arrays of the distributed run itself (global ids,
/// traction shares). A field added to any of them moves with the particles.
#include "otmpm/basis/basis.hpp"
#include "otmpm/distributed/comm.hpp"
#include "otmpm/particles/particles.hpp"

#include <cstring>
#include <functional>
#include <vector>

namespace otmpm::distributed {

/// One per-particle array: `bytes` per particle.
struct Column {
  std::size_t bytes = 0;
  std::function<char*()> data;
  std::function<void(std::size_t)> resize;
};

/// A column over a std::vector-like array of trivially copyable elements
/// (`width` elements per particle).
template <class Array> Column column_of(Array& a, std::size_t width = 1) {
  return {sizeof(typename Array::value_type) * width, [&a] { return reinterpret_cast<char*>(a.data()); },
          [&a, width](std::size_t n) { a.resize(n * width); }};
}

/// The columns of the particles' own arrays (the non-empty ones), their
/// state arrays and the basis' per-point state.
template <int D> std::vector<Column> particle_columns(Particles<D>& P, PointState<D>& basis_state) {
  std::vector<Column> c;
  P.for_each_field([&](const char*, auto& field) {
    if (!field.empty()) c.push_back(column_of(field));
  });
  for (StateField& f : P.state) c.push_back(column_of(f.values, static_cast<std::size_t>(f.width)));
  if (!basis_state.lambda.empty()) c.push_back(column_of(basis_state.lambda));
  if (!basis_state.slope.empty()) c.push_back(column_of(basis_state.slope));
  if (!basis_state.history.empty()) c.push_back(column_of(basis_state.history));
  if (!basis_state.cell_hint.empty()) c.push_back(column_of(basis_state.cell_hint));
  return c;
}

/// Bytes of one row over all columns.
inline std::size_t row_bytes(const std::vector<Column>& columns) {
  std::size_t n = 0;
  for (const Column& c : columns) n += c.bytes;
  return n;
}

/// Appends row p of every column to `out`.
inline void pack_row(const std::vector<Column>& columns, std::size_t p, Bytes& out) {
  for (const Column& c : columns) put_bytes(out, c.data() + p * c.bytes, c.bytes);
}

/// Keeps the rows with keep[p] != 0 in their order; `n` rows before.
inline void keep_rows(const std::vector<Column>& columns, const std::vector<char>& keep, std::size_t n) {
  std::size_t kept = 0;
  for (std::size_t p = 0; p < n; ++p) kept += keep[p] != 0;
  for (const Column& c : columns) {
    char* d = c.data();
    std::size_t w = 0;
    for (std::size_t p = 0; p < n; ++p)
      if (keep[p]) {
        if (w != p) std::memmove(d + w * c.bytes, d + p * c.bytes, c.bytes);
        ++w;
      }
    c.resize(kept);
  }
}

/// Appends the rows packed in `in` (whole rows of these columns) after the
/// `n` rows already there; returns the new row count.
inline std::size_t append_rows(const std::vector<Column>& columns, const Bytes& in, std::size_t n) {
  const std::size_t width = row_bytes(columns);
  const std::size_t rows = width ? in.size() / width : 0;
  for (const Column& c : columns) c.resize(n + rows);
  const char* src = in.data();
  for (std::size_t r = 0; r < rows; ++r)
    for (const Column& c : columns) {
      std::memcpy(c.data() + (n + r) * c.bytes, src, c.bytes);
      src += c.bytes;
    }
  return n + rows;
}

} // namespace otmpm::distributed
