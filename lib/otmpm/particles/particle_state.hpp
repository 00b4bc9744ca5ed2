#pragma once
/// \file particle_state.hpp
/// The particles as checkpoint arrays (state.hpp): every field of
/// Particles (for_each_field) and every state array, one row per particle,
/// element by element in memory order - doubles as doubles, integers as
/// 64-bit integers - so that a state read back is the same bits. Used by
/// Engine::save_state / restore_state and by a distributed restart, which
/// builds a rank's particles from its rows of a checkpoint.
#include "otmpm/particles/particles.hpp"
#include "otmpm/state.hpp"

#include <array>
#include <type_traits>

namespace otmpm {

/// How one element of a particle field is stored: as `cols` values of type
/// Stored (double, or int64 for integers) starting at begin(element).
template <class T> struct FieldLayout;
template <> struct FieldLayout<double> {
  using Stored = double;
  static constexpr std::size_t cols = 1;
  template <class E> static auto* begin(E& e) { return &e; }
};
template <> struct FieldLayout<int> {
  using Stored = std::int64_t;
  static constexpr std::size_t cols = 1;
  template <class E> static auto* begin(E& e) { return &e; }
};
template <int R, int C, int O, int MR, int MC> struct FieldLayout<Eigen::Matrix<double, R, C, O, MR, MC>> {
  using Stored = double;
  static constexpr std::size_t cols = static_cast<std::size_t>(R * C);
  template <class E> static auto* begin(E& e) { return e.data(); }
};
template <std::size_t N> struct FieldLayout<std::array<int, N>> {
  using Stored = std::int64_t;
  static constexpr std::size_t cols = N;
  template <class E> static auto* begin(E& e) { return e.data(); }
};

/// The arrays of `g` that hold values of type T (real or integer arrays).
template <class T> auto& arrays_of(StateGroup& g) {
  if constexpr (std::is_same_v<T, double>) return g.real_arrays;
  else return g.integer_arrays;
}
template <class T>
const StateArray<T>& array_of(const StateGroup& g, const std::string& name, std::size_t rows, std::size_t cols) {
  if constexpr (std::is_same_v<T, double>) return g.real_array(name, rows, cols);
  else return g.integer_array(name, rows, cols);
}

/// Stores a per-particle (or per-node) array, element by element in memory order.
template <class Field> void save_field(StateGroup& g, const std::string& name, const Field& field) {
  using L = FieldLayout<typename Field::value_type>;
  StateArray<typename L::Stored>& a = arrays_of<typename L::Stored>(g)[name];
  a.cols = L::cols;
  a.values.clear();
  a.values.reserve(field.size() * L::cols);
  for (const auto& e : field) a.values.insert(a.values.end(), L::begin(e), L::begin(e) + L::cols);
}

/// Restores an array of n elements. A field the checkpoint does not hold
/// must be one this run leaves empty as well.
template <class Field> void restore_field(const StateGroup& g, const std::string& name, Field& field, std::size_t n) {
  using L = FieldLayout<typename Field::value_type>;
  if (!g.has_array(name)) {
    if (!field.empty()) g.error("missing particle field '" + name + "'");
    return;
  }
  const auto& values = array_of<typename L::Stored>(g, name, n, L::cols).values;
  field.resize(n);
  for (std::size_t p = 0; p < n; ++p) {
    auto* out = L::begin(field[p]);
    for (std::size_t c = 0; c < L::cols; ++c) {
      const auto v = values[p * L::cols + c];
      out[c] = static_cast<std::remove_reference_t<decltype(*out)>>(v);
      if constexpr (!std::is_same_v<typename L::Stored, double>)
        if (out[c] != v) g.error("particle field '" + name + "': integer out of range");
    }
  }
}

/// Stores every non-empty field of P and its state arrays ("state_NAME") in g.
template <int D> void save_particles(StateGroup& g, const Particles<D>& P) {
  P.for_each_field([&](const char* name, const auto& field) {
    if (!field.empty()) save_field(g, name, field);
  });
  for (const StateField& f : P.state)
    g.real_arrays["state_" + f.name] = {static_cast<std::size_t>(f.width), f.values};
}

/// Restores n particles into P from g: every field g holds (the others must
/// be empty in P) and P's state arrays (InputError naming the array when
/// one is missing or misshapen).
template <int D> void restore_particles(const StateGroup& g, Particles<D>& P, std::size_t n) {
  P.for_each_field([&](const char* name, auto& field) { restore_field(g, name, field, n); });
  for (StateField& f : P.state)
    f.values = g.real_array("state_" + f.name, n, static_cast<std::size_t>(f.width)).values;
}

} // namespace otmpm
