/// \file module.cpp
/// The module otmpm._otmpm: the error types and the registration of its parts.
#include "bindings.hpp"

#include "otmpm/io/output_files.hpp"

#include "otmpm/core.hpp"

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

namespace otmpm::python {

namespace {

// The Python exception types, created once when the module is imported and
// kept for the life of the interpreter (never released: the translator may
// run until the interpreter shuts down).
PyObject* g_input_error = nullptr;
PyObject* g_instability_error = nullptr;
PyObject* g_basis_error = nullptr;

/// Raises otmpm.InputError with the message of `e` and its source: `file`
/// and `line` (None when unknown, and for a --set override), `key` (None
/// when the error names no key), `override` (True when the bad value came
/// from an override).
void raise_input_error(const InputError& e) {
  py::object file = py::none(), line = py::none(), key = py::none();
  bool from_override = false;
  if (const InputSource* s = e.source()) {
    from_override = s->line < 0;
    if (!s->file.empty() && !from_override) file = py::str(s->file);
    if (s->line > 0) line = py::int_(s->line);
    if (!s->key.empty()) key = py::str(s->key);
  }
  py::object error = py::reinterpret_borrow<py::object>(g_input_error)(e.what());
  error.attr("file") = file;
  error.attr("line") = line;
  error.attr("key") = key;
  error.attr("override") = py::bool_(from_override);
  PyErr_SetObject(g_input_error, error.ptr());
}

/// A new exception type otmpm.NAME derived from `base`, with a docstring
/// and class attributes (defaults for the instance attributes).
PyObject* new_error(py::module_& m, const char* name, PyObject* base, const char* doc) {
  const std::string qualified = std::string("otmpm.") + name;
  PyObject* type = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, base, nullptr);
  if (!type) throw py::error_already_set();
  m.add_object(name, py::handle(type)); // the module holds a second reference
  return type;
}

} // namespace

bool PythonSignals::check() {
  if (PyErr_CheckSignals() == 0) return false;
  raised_.emplace(); // fetches the handler's exception
  return true;
}

bool PythonSignals::told() {
  if (raised_) return true;
  const auto now = std::chrono::steady_clock::now();
  if (now < next_) return false;
  next_ = now + std::chrono::milliseconds(10);
  if (PyGILState_Check()) return check();
  const py::gil_scoped_acquire gil;
  return check();
}

void PythonSignals::rethrow() {
  if (!raised_) return;
  py::error_already_set e = std::move(*raised_);
  raised_.reset();
  throw e;
}

void register_errors(py::module_& m) {
  g_input_error = new_error(m, "InputError", PyExc_ValueError,
                            "Bad input: a scene value, an override or an argument that cannot be used.\n\n"
                            "str(error) is the message of the command line (\"FILE:LINE: key 'KEY': message\", or\n"
                            "\"--set KEY: message\" for an override). Attributes: file (str or None), line (int or\n"
                            "None), key (str or None), override (True when the bad value came from an override).");
  for (const char* attr : {"file", "line", "key"}) PyObject_SetAttrString(g_input_error, attr, Py_None);
  PyObject_SetAttrString(g_input_error, "override", Py_False);
  g_instability_error = new_error(m, "InstabilityError", PyExc_RuntimeError,
                                  "The simulation became unstable (NaN/Inf, det F <= 0, a particle leaving the grid,\n"
                                  "runaway energy). The message names particle, step and time; the result file keeps\n"
                                  "everything written so far, with its status set to the diagnosis.");
  g_basis_error = new_error(m, "BasisError", PyExc_ValueError,
                            "A basis cannot be evaluated at a point (outside the nodes' hull, too few nodes, no\n"
                            "convergence, a non-finite point). The message names the point.");
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      raise_input_error(e);
    } catch (const InstabilityError& e) {
      PyErr_SetString(g_instability_error, e.what());
    } catch (const BasisError& e) {
      PyErr_SetString(g_basis_error, e.what());
    } catch (const OutputError& e) { // the results could not be written: an I/O error
      PyErr_SetString(PyExc_OSError, e.what());
    }
  });
}

std::optional<int> checked_threads(std::optional<int> threads) {
  if (threads && *threads < 1) throw py::value_error("threads must be >= 1 (or None), got " + std::to_string(*threads));
  return threads;
}

ThreadScope::ThreadScope(std::optional<int> threads) {
#ifdef OTMPM_HAVE_OPENMP
  if (!threads) return;
  previous_ = omp_get_max_threads();
  omp_set_num_threads(*threads);
#else
  (void)threads;
#endif
}

ThreadScope::~ThreadScope() {
#ifdef OTMPM_HAVE_OPENMP
  if (previous_ > 0) omp_set_num_threads(previous_);
#endif
}

} // namespace otmpm::python

PYBIND11_MODULE(_otmpm, m) {
  m.doc() = "The compiled part of the otmpm Python package; use it through `import otmpm` (docs/python.md).";
  m.attr("__version__") = OTMPM_PYTHON_VERSION;
  otmpm::python::register_errors(m);
  otmpm::python::register_scene(m);
  otmpm::python::register_simulation(m);
  otmpm::python::register_basis(m);
  m.def("_roll_back_interrupted_flush", &otmpm::roll_back_interrupted_flush, pybind11::arg("path"),
        "Restores a result file whose writer was killed inside a flush to its last flushed state (what otmpm's "
        "own readers do before they open it); nothing while its writer runs.");
}
