/// \file particles.cpp
/// Particle storage (particles.hpp).
#include "otmpm/particles/particles.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace otmpm {

template <int D> void Particles<D>::resize(int n) {
  require<std::invalid_argument>(n >= 0, "Particles::resize: n must be >= 0, got ", n);
  x.assign(n, Vec<D>::Zero());
  X = v = length0 = x;
  m.assign(n, 0.0);
  V = V0 = rho = m;
  eps.assign(n, Mat<D>::Zero());
  sigma = eps;
  material.assign(n, 0);
  body.assign(n, 0);
  a.clear(), F.clear(), x_prev.clear(), state.clear();
}

template <int D> void Particles<D>::allocate_optional(bool with_a, bool with_F) {
  const auto n = static_cast<std::size_t>(size());
  if (with_a) a.assign(n, Vec<D>::Zero());
  if (with_F) F.assign(n, Mat<D>::Identity());
}

template <int D> StateField& Particles<D>::add_state(const std::string& name, int width, const double* initial) {
  require<std::invalid_argument>(width >= 1, "Particles::add_state: '", name, "' needs width >= 1, got ", width);
  if (StateField* f = find_state(name)) {
    require<std::invalid_argument>(f->width == width, "Particles::add_state: '", name, "' exists with width ",
                                   f->width, ", asked for ", width);
    return *f;
  }
  StateField f{name, width, std::vector<double>(static_cast<std::size_t>(size()) * width)};
  for (int p = 0; p < size(); ++p) std::copy(initial, initial + width, f.row(p));
  state.push_back(std::move(f));
  return state.back();
}

template <int D> StateField* Particles<D>::find_state(std::string_view name) {
  const auto it = std::find_if(state.begin(), state.end(), [&](const StateField& f) { return f.name == name; });
  return it == state.end() ? nullptr : &*it;
}

template <int D> const StateField* Particles<D>::find_state(std::string_view name) const {
  return const_cast<Particles*>(this)->find_state(name);
}

template struct Particles<1>;
template struct Particles<2>;
template struct Particles<3>;

} // namespace otmpm
