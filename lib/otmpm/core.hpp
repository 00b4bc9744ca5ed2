#pragma once
/// \file core.hpp
/// Types shared by every part of otmpm: fixed-size Eigen vectors templated on
/// the spatial dimension D (1, 2, 3), the kinds of error that the command
/// line turns into exit statuses (InputError -> 2, InstabilityError -> 1,
/// OutputError -> 4),
/// and require(), the one-line argument check that throws them with context.
///
/// Which exception means what (docs/architecture.md, "Errors and argument checks"):
///  - InputError: a value that cannot be used (a scene value, an option, a
///    physical parameter, a non-finite coordinate given to a factory), whether
///    it came from a file or from code.
///  - std::invalid_argument: the calling code broke the interface (arrays
///    whose sizes must agree do not, a null data pointer, an index out of
///    range, a call out of order). A bug in the caller, never a user mistake;
///    the command line reports it as an internal error (exit 3).
///  - BasisError: a basis cannot be evaluated at a point (also a non-finite one).
///  - InstabilityError: the state of a run stopped making sense (NaN/Inf,
///    det F <= 0, an inverted knot vector, runaway energy).
///  - OutputError: a result or checkpoint file could not be written (disk
///    full, file size limit, quota, I/O error); a run stops with exit code 4.
#include <Eigen/Core>
#include <Eigen/LU>
#include <Eigen/StdVector>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
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

/// An open box of positions: lo < x < hi on every axis (bounds may be
/// infinite; NaN is never inside). Tested without a branch per axis: it
/// runs for every particle after every step (NodeMode, the staying box of
/// a distributed run).
template <int D> struct PositionBox {
  Vec<D> lo = Vec<D>::Zero(), hi = Vec<D>::Zero();
  bool contains(const Vec<D>& x) const {
    bool in = true;
    for (int k = 0; k < D; ++k) {
      in &= x[k] > lo[k];
      in &= x[k] < hi[k];
    }
    return in;
  }
};

/// Where a bad input value came from: the file ("" when not from a file),
/// the line (> 0 in a file, -1 for a --set override, 0 unknown) and the key
/// ("" when the error concerns no single key, e.g. a TOML syntax error).
struct InputSource {
  std::string file;
  int line = 0;
  std::string key;
};

/// Longest piece of user text (a name, key, value or path) a message quotes whole.
inline constexpr std::size_t kQuotedTextBytes = 80;
/// Longest message of an InputError: a longer one keeps its start and its end.
inline constexpr std::size_t kMaxMessageBytes = 2048;

namespace detail {
/// True for a UTF-8 continuation byte (10xxxxxx): a cut must not fall before one.
inline bool utf8_continuation(char c) { return (static_cast<unsigned char>(c) & 0xC0u) == 0x80u; }
} // namespace detail

/// `s` as a message quotes it: whole when it has at most `limit` bytes, else
/// its first bytes (cut at a UTF-8 character boundary) and "... (N bytes)",
/// so that a 10 MB name never makes a 10 MB message.
inline std::string shortened(std::string_view s, std::size_t limit = kQuotedTextBytes) {
  if (s.size() <= limit) return std::string(s);
  std::size_t keep = limit * 3 / 4;
  while (keep > 0 && detail::utf8_continuation(s[keep])) --keep;
  return std::string(s.substr(0, keep)) + "... (" + std::to_string(s.size()) + " bytes)";
}

namespace detail {
/// `what` when it has at most kMaxMessageBytes, else its first and last
/// bytes around "[... N bytes in all ...]" (a thrower that quoted user text whole).
inline std::string bounded_message(const std::string& what) {
  if (what.size() <= kMaxMessageBytes) return what;
  std::size_t head = kMaxMessageBytes * 3 / 4, tail = what.size() - kMaxMessageBytes / 4;
  while (head > 0 && utf8_continuation(what[head])) --head;
  while (tail < what.size() && utf8_continuation(what[tail])) ++tail;
  return what.substr(0, head) + " [... " + std::to_string(what.size()) + " bytes in all ...] " + what.substr(tail);
}
} // namespace detail

/// Bad input: a scene value, a command-line option or a library argument that
/// cannot be used. Carries where it came from (file, line, key) when known:
/// in the message ("FILE:LINE: key 'KEY': ...") and, for the errors of the
/// scene reader, as an InputSource (the Python package's InputError.file,
/// .line, .key). The command line reports it and exits with status 2. The
/// message is at most about kMaxMessageBytes long (detail::bounded_message).
class InputError : public std::runtime_error {
public:
  explicit InputError(const std::string& what) : std::runtime_error(detail::bounded_message(what)) {}
  InputError(const std::string& what, InputSource source)
      : std::runtime_error(detail::bounded_message(what)),
        source_(std::make_shared<const InputSource>(std::move(source))) {}
  /// The source of the bad value, or null when the thrower did not give one.
  const InputSource* source() const { return source_.get(); }

private:
  std::shared_ptr<const InputSource> source_; ///< shared: copying an exception must not throw
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

/// The results could not be written: no space left on the device, a file
/// size limit (`ulimit -f`), a disk quota or an I/O error. The message names
/// the file and the cause. A run stops at the output that failed and reports
/// exit code 4 (RunSummary::exit_code); everything written before is kept.
class OutputError : public std::runtime_error {
public:
  explicit OutputError(const std::string& what) : std::runtime_error(what) {}
};

/// An allocation that failed on one rank of a distributed run (std::bad_alloc),
/// thrown on every rank by the reduction or wait that found it, so that every
/// rank ends the run "out of memory" with the same message (the failed rank's).
class DeferredOutOfMemory : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

/// Formats a number with nine significant digits ("%.9g") for error messages.
inline std::string format_number(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", x);
  return buf;
}

/// Formats a point as "(x, y, z)" for error messages.
template <int D> std::string format_point(const Vec<D>& x) {
  std::string s = "(";
  for (int k = 0; k < D; ++k) {
    if (k) s += ", ";
    s += format_number(x[k]);
  }
  return s + ")";
}

namespace detail {
inline void append_part(std::string& s, std::string_view part) { s += part; }
inline void append_part(std::string& s, const char* part) { s += part; }
inline void append_part(std::string& s, const std::string& part) { s += part; }
template <class T>
  requires std::is_arithmetic_v<T>
void append_part(std::string& s, T value) {
  if constexpr (std::is_same_v<T, bool>) s += value ? "true" : "false";
  else if constexpr (std::is_floating_point_v<T>) s += format_number(value);
  else s += std::to_string(value);
}
template <int D> void append_part(std::string& s, const Vec<D>& x) { s += format_point<D>(x); }
} // namespace detail

/// Concatenates the parts of an error message: strings as they are, numbers
/// by format_number (integers exactly), points by format_point.
template <class... Parts> std::string error_message(const Parts&... parts) {
  std::string s;
  (detail::append_part(s, parts), ...);
  return s;
}

/// Throws Error(error_message(parts...)) unless `ok`. The message is only built
/// on failure, so a check that passes costs one branch. Usage:
///   require(h > 0, "NodeSet::cloud: spacing must be > 0, got ", h);
///   require<std::invalid_argument>(a.size() == b.size(), "f: ", a.size(), " values for ", b.size(), " points");
template <class Error = InputError, class... Parts> void require(bool ok, const Parts&... parts) {
  if (!ok) [[unlikely]]
    throw Error(error_message(parts...));
}

/// True when `value` is finite and > 0 (false for NaN).
inline bool finite_positive(double value) { return std::isfinite(value) && value > 0.0; }

/// True when `v` gives a direction (a wall's normal, a cylinder's axis):
/// finite and not zero, however large or small its components - its unit
/// vector is v.stableNormalized(), which scales by the largest component
/// first (v.normalized() is the zero vector when |v|^2 overflows or underflows).
template <int D> bool is_direction(const Vec<D>& v) { return v.allFinite() && v.cwiseAbs().maxCoeff() > 0.0; }

} // namespace otmpm
