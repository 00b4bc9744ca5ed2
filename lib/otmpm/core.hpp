#pragma once
/// \file core.hpp
/// Types shared by every part of otmpm: fixed-size Eigen vectors templated on
/// the spatial dimension D (1, 2, 3), and the three kinds of error that the
/// command line turns into exit statuses (InputError -> 2, InstabilityError -> 1).
#include <Eigen/Core>
#include <Eigen/LU>
#include <Eigen/StdVector>
#include <array>
#include <cstddef>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

namespace otmpm {

/// A point or vector in D dimensions.
template <int D> using Vec = Eigen::Matrix<double, D, 1>;
/// A D x D tensor (velocity gradient, deformation gradient, stress, strain).
template <int D> using Mat = Eigen::Matrix<double, D, D>;
/// Contiguous storage of fixed-size Eigen objects (aligned where it matters).
template <class T> using AlignedVector = std::vector<T, Eigen::aligned_allocator<T>>;

/// Integer index triple/pair/single of a structured node set.
template <int D> using Index = std::array<int, D>;

/// Bad input: a scene value, a command-line option or a library argument that
/// cannot be used. Carries where it came from (file, line, key) when known.
/// The command line reports it and exits with status 2.
class InputError : public std::runtime_error {
public:
  explicit InputError(const std::string& what) : std::runtime_error(what) {}
};

/// A basis function that cannot be evaluated at a point (outside the convex
/// hull of its support, too few nodes, singular Hessian, no convergence).
/// The message names the point (and the particle, when the engine adds it).
class BasisError : public std::runtime_error {
public:
  explicit BasisError(const std::string& what) : std::runtime_error(what) {}
};

/// The simulation became unstable (NaN/Inf, det F <= 0, runaway energy, a
/// particle leaving the grid). The message names particle, step and time.
/// The command line reports it and exits with status 1.
class InstabilityError : public std::runtime_error {
public:
  explicit InstabilityError(const std::string& what) : std::runtime_error(what) {}
};

/// Formats a point as "(x, y, z)" for error messages.
template <int D> std::string format_point(const Vec<D>& x) {
  std::string s = "(";
  for (int k = 0; k < D; ++k) {
    if (k) s += ", ";
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.9g", x[k]);
    s += buf;
  }
  return s + ")";
}

} // namespace otmpm
