/// \file loads.cpp
/// External loads (loads.hpp).
#include "otmpm/engine/loads.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace otmpm {

template <int D> Vec<D> Loads<D>::body_force_at(double t) const {
  return body_force ? Vec<D>(body_force->value * time_function(body_force->time, t)) : Vec<D>::Zero();
}

template <int D>
template <class Visit>
void Loads<D>::for_each_force(double t, const Particles<D>& P, Visit&& visit) const {
  if (body_force) {
    const Vec<D> b = body_force_at(t);
    const auto& field = body_force->field;
    for (int p = 0; p < P.size(); ++p) visit(p, Vec<D>(P.m[p] * (field ? Vec<D>(b + field(P.X[p], t)) : b)));
  }
  for (const Traction<D>& load : tractions) {
    const Vec<D> traction = traction_at(load, t);
    for (std::size_t i = 0; i < load.particle.size(); ++i) visit(load.particle[i], Vec<D>(traction * load.area[i]));
  }
}

template <int D> Vec<D> Loads<D>::traction_at(const Traction<D>& load, double t) const {
  Vec<D> traction = load.value * time_function(load.time, t);
  if (load.history) traction[load.axis] = load.history(t);
  return traction;
}

template <int D>
void Loads<D>::particle_forces(double t, const Particles<D>& P, AlignedVector<Vec<D>>& fext) const {
  fext.assign(static_cast<std::size_t>(P.size()), Vec<D>::Zero());
  for_each_force(t, P, [&](int p, const Vec<D>& force) { fext[p] += force; });
}

template <int D> double Loads<D>::power(double t, const Particles<D>& P, const Vec<D>& momentum) const {
  if (!body_force) return 0.0;
  const Vec<D> b = body_force_at(t);
  if (!body_force->field) return b.dot(momentum); // sum_p m_p b(t) . v_p = b(t) . sum_p m_p v_p
  double power = 0.0;
  for (int p = 0; p < P.size(); ++p) power += Vec<D>(P.m[p] * Vec<D>(b + body_force->field(P.X[p], t))).dot(P.v[p]);
  return power;
}

template <int D> void Loads<D>::traction_positions(const Particles<D>& P, AlignedVector<Vec<D>>& x0) const {
  x0.clear();
  for (const Traction<D>& load : tractions)
    for (int p : load.particle) x0.push_back(P.x[p]);
}

template <int D>
double Loads<D>::traction_work(double t0, double t1, const Particles<D>& P, const AlignedVector<Vec<D>>& x0) const {
  double work = 0.0;
  std::size_t j = 0;
  for (const Traction<D>& load : tractions) {
    const Vec<D> mean = 0.5 * (traction_at(load, t0) + traction_at(load, t1));
    for (std::size_t i = 0; i < load.particle.size(); ++i, ++j)
      work += load.area[i] * mean.dot(P.x[load.particle[i]] - x0[j]);
  }
  return work;
}

template <int D> double Loads<D>::unresolved_work(double t, const Particles<D>& P) const {
  double work = 0.0;
  for (const Traction<D>& load : tractions) {
    const double traction = traction_at(load, t).template lpNorm<1>();
    for (std::size_t i = 0; i < load.particle.size(); ++i)
      work += traction * load.area[i] * P.x[load.particle[i]].template lpNorm<Eigen::Infinity>();
  }
  return std::numeric_limits<double>::epsilon() * work;
}

template <int D> void Loads<D>::check(int n) const {
  if (body_force)
    require<std::invalid_argument>(body_force->value.allFinite(), "Loads: body force ", body_force->value,
                                   " is not finite");
  for (std::size_t i = 0; i < tractions.size(); ++i) {
    const Traction<D>& tr = tractions[i];
    require<std::invalid_argument>(tr.axis >= 0 && tr.axis < D, "Loads: traction ", i, ": axis ", tr.axis,
                                   " out of range");
    require<std::invalid_argument>(tr.value.allFinite(), "Loads: traction ", i, ": value is not finite");
    require<std::invalid_argument>(tr.area.size() == tr.particle.size(), "Loads: traction ", i, ": ",
                                   tr.particle.size(), " particles but ", tr.area.size(), " areas");
    for (std::size_t j = 0; j < tr.particle.size(); ++j) {
      const int p = tr.particle[j];
      require<std::invalid_argument>(p >= 0 && p < n, "Loads: traction ", i, ": particle ", p, " out of range [0, ",
                                     n, ")");
      require<std::invalid_argument>(std::isfinite(tr.area[j]) && tr.area[j] >= 0.0, "Loads: traction ", i,
                                     ": particle ", p, ": area ", tr.area[j], " is not finite and >= 0");
    }
  }
}

template class Loads<1>;
template class Loads<2>;
template class Loads<3>;

} // namespace otmpm
