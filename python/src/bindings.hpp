#pragma once
/// \file bindings.hpp
/// The compiled part of the Python package (`otmpm._otmpm`, docs/python.md):
/// one registration function per part, called from module.cpp.
#include "otmpm/interrupt.hpp"

#include <pybind11/pybind11.h>

#include <chrono>
#include <optional>

namespace otmpm::python {

namespace py = pybind11;

/// The exception types (InputError, InstabilityError, BasisError) and the
/// translator that raises them with the C++ message (and, for InputError,
/// its file, line and key).
void register_errors(py::module_& m);
/// otmpm.Scene: from_toml, from_dict, to_toml, to_dict, with_overrides.
void register_scene(py::module_& m);
/// otmpm.Simulation (with its particle and node views) and otmpm.run.
void register_simulation(py::module_& m);
/// The basis families on a grid or a node cloud (otmpm.basis).
void register_basis(py::module_& m);

/// Sets the number of OpenMP threads of the calling thread for its
/// lifetime (nothing for std::nullopt, or without OpenMP) and restores the
/// previous number afterwards. ValueError for a number < 1.
class ThreadScope {
public:
  explicit ThreadScope(std::optional<int> threads);
  ~ThreadScope();
  ThreadScope(const ThreadScope&) = delete;
  ThreadScope& operator=(const ThreadScope&) = delete;

private:
  int previous_ = 0;
};

/// Python's signal handlers seen from the loops of a set-up (a scene's
/// particle files, a body's seeding, a checkpoint: interrupt_point): at
/// most every 10 ms PyErr_CheckSignals runs (the GIL taken back when it was
/// released); when a handler raised (Ctrl-C: KeyboardInterrupt), the loop
/// stops with InterruptedError and rethrow() raises the Python exception.
class PythonSignals final : public InterruptPeers {
public:
  void tell() override {}
  bool told() override;
  /// Raises the exception a Python handler raised, if any (GIL held).
  void rethrow();

private:
  bool check();
  std::optional<py::error_already_set> raised_;
  std::chrono::steady_clock::time_point next_{};
};

/// Runs `f` (GIL held, or released inside it) with the loops of its set-up
/// watching Python's signal handlers: KeyboardInterrupt raised within
/// about 10 ms of Ctrl-C, nothing built.
template <class F> auto with_python_signals(F&& f) {
  PythonSignals signals;
  try {
    const InterruptPolling polling(nullptr, &signals);
    return f();
  } catch (const InterruptedError&) {
    signals.rethrow();
    throw;
  }
}

/// Throws ValueError unless `threads` is empty or >= 1 (checked where the
/// value is given, so that ThreadScope never throws in a released-GIL section).
std::optional<int> checked_threads(std::optional<int> threads);

} // namespace otmpm::python
