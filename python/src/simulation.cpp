/// \file simulation.cpp
/// otmpm.Simulation and otmpm.run: a run of a scene (run/simulation.hpp)
/// stepped from Python with the GIL released, NumPy views of the engine's
/// particle and node arrays, a per-step Python callback, and Ctrl-C
/// (KeyboardInterrupt) between steps.
#include "bindings.hpp"

#include "otmpm/run/simulation.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <chrono>
#include <filesystem>
#include <limits>
#include <new>
#include <set>

namespace otmpm::python {

namespace {

using Clock = std::chrono::steady_clock;

/// How often a loop of steps (step(n), advance_to, run) takes the GIL back
/// to run Python's signal handlers: Ctrl-C is seen within this time plus one step.
constexpr auto kSignalPoll = std::chrono::milliseconds(10);
/// Relative slack of advance_to(t), as Simulation::advance_to.
constexpr double kTimeSlack = 1e-9;

/// RunOptions from the Python arguments: out None = the scene's output.file;
/// force as `otmpm run --force`.
RunOptions run_options(const py::object& out, bool write_results, bool force) {
  RunOptions opt;
  opt.write_results = write_results;
  opt.force = force;
  if (out.is_none()) return opt;
  try {
    opt.out_file = py::cast<std::filesystem::path>(out).string();
  } catch (const py::cast_error&) {
    throw py::type_error("out: expected a path (str or os.PathLike) or None, got a " +
                         py::str(out.get_type().attr("__name__")).cast<std::string>());
  }
  return opt;
}

/// Runs Python's signal handlers (Ctrl-C raises KeyboardInterrupt); the GIL must be held.
void check_signals() {
  if (PyErr_CheckSignals() != 0) throw py::error_already_set();
}

/// The otmpm.Summary (a dict-like object, otmpm/summary.py) of a finished run.
py::object summary_object(const RunSummary& s) {
  py::dict errors, phases, diagnostics;
  for (const auto& [name, value] : s.errors) errors[py::str(name)] = value;
  for (const auto& [name, value] : s.diagnostics) diagnostics[py::str(name)] = value;
  for (std::size_t i = 0; i < phase_names.size(); ++i) phases[py::str(std::string(phase_names[i]))] = s.timers.seconds[i];
  py::dict d;
  d["status"] = s.status;
  d["exit_code"] = s.exit_code;
  d["interrupted"] = s.interrupted;
  d["mode"] = s.mode;
  d["integrator"] = s.integrator;
  d["basis"] = s.basis;
  d["steps"] = s.steps;
  d["time"] = s.time;
  d["wall_seconds"] = s.wall_seconds;
  d["particles"] = s.particles;
  d["nodes"] = s.nodes;
  d["particle_steps_per_second"] = s.particle_steps_per_second();
  d["errors"] = errors;
  d["max_energy_ratio"] = s.energy.max_energy_ratio();
  d["energy_drift"] = s.energy.energy_drift();
  d["phases"] = phases;
  d["diagnostics"] = diagnostics;
  d["initial_equilibrium"] =
      s.initial_equilibrium.empty() ? py::object(py::none()) : py::object(py::str(s.initial_equilibrium));
  d["out_file"] = s.out_file.empty() ? py::object(py::none()) : py::object(py::str(s.out_file));
  return py::module_::import("otmpm.summary").attr("Summary")(d, summary_line(s));
}

/// A run in progress, owned by the Python Simulation object. One dropped
/// without finish() is completed by ~Simulation (status "interrupted"), and
/// the ones still alive when the interpreter exits by finish_all() (atexit).
class PySimulation {
public:
  PySimulation(const Scene& scene, const py::object& out, bool write_results, bool force, std::optional<int> threads)
      : threads_(checked_threads(threads)), sim_(build(scene, run_options(out, write_results, force), threads_)) {
    live().insert(this);
  }
  ~PySimulation() { live().erase(this); }
  PySimulation(const PySimulation&) = delete;
  PySimulation& operator=(const PySimulation&) = delete;

  /// Completes every simulation not finished yet (registered with atexit:
  /// objects the interpreter never frees keep no status "running").
  static void finish_all() {
    for (PySimulation* s : std::set<PySimulation*>(live()))
      if (!s->finish_called_ && !s->busy_) {
        s->finish_called_ = true;
        try {
          if (!s->sim_.finished()) s->sim_.interrupt();
          s->sim_.finish();
        } catch (const std::exception&) { // at exit nothing more can be done; the status is what it could be
        }
      }
  }

  /// The simulation for `what`, a method that changes the run: RuntimeError
  /// once finish() was called (the views and properties stay readable).
  Simulation& open(const char* what) {
    if (finish_called_)
      throw std::runtime_error(std::string("Simulation.") + what +
                               ": the run is finished (finish() was called; status " + sim_.status() + ")");
    return sim();
  }

  /// The simulation; RuntimeError while another Python thread is stepping it
  /// (its steps run with the GIL released).
  Simulation& sim() {
    if (busy_) throw std::runtime_error("Simulation: another thread is stepping this simulation");
    return sim_;
  }
  /// The per-step callback: None or a callable (TypeError otherwise, when it is set).
  const py::object& callback() const { return callback_; }
  void set_callback(const py::object& f) {
    if (!f.is_none() && !PyCallable_Check(f.ptr()))
      throw py::type_error("Simulation.callback: expected a callable or None, got a " +
                           py::str(f.get_type().attr("__name__")).cast<std::string>());
    callback_ = f;
  }

  /// Steps while more(simulation) holds (more must not touch Python). Without a
  /// callback the steps run with the GIL released, which is taken back
  /// every kSignalPoll for Ctrl-C; with one, the callback runs after every
  /// step (GIL held) and the signals are checked after it. An
  /// InstabilityError or a Python exception (KeyboardInterrupt, the
  /// callback's) leaves the run between two steps.
  template <class More> void steps_while(py::handle self, More&& more) {
    sim(); // RuntimeError while another thread steps it
    auto next_poll = Clock::now() + kSignalPoll;
    while (more(sim_)) {
      if (callback_.is_none()) {
        bool poll = false;
        {
          Busy busy(busy_);
          py::gil_scoped_release nogil;
          ThreadScope scope(threads_);
          while (!poll && more(sim_)) {
            sim_.step();
            poll = Clock::now() >= next_poll;
          }
        }
        if (poll) {
          check_signals();
          next_poll = Clock::now() + kSignalPoll;
        }
      } else {
        {
          Busy busy(busy_);
          py::gil_scoped_release nogil;
          ThreadScope scope(threads_);
          sim_.step();
        }
        callback_(self);
        check_signals();
      }
    }
  }

  /// Steps to t_end; an instability, an output error or memory running out
  /// ends the run (its status is in the summary, as run_scene's).
  void run_to_end(py::handle self) {
    try {
      steps_while(self, [](const Simulation& s) { return !s.finished(); });
    } catch (const InstabilityError&) { // run_scene's rule: the diagnosis is the status
    } catch (const OutputError&) {
    } catch (const std::bad_alloc&) {
    }
  }

  /// Simulation::interrupt() (status "interrupted"); RuntimeError once finished.
  void interrupt() {
    Simulation& s = open("interrupt");
    if (s.finished()) throw std::runtime_error("Simulation.interrupt: the run is finished (" + s.status() + ")");
    s.interrupt();
  }

  /// Simulation::finish() as an otmpm.Summary; RuntimeError the second time.
  py::object finish() {
    if (finish_called_) throw std::runtime_error("Simulation.finish: already called");
    Simulation& s = sim();
    finish_called_ = true;
    return summary_object(s.finish());
  }
  bool finish_called() const { return finish_called_; }

  /// Finishes a run left by an exception (`with` block, KeyboardInterrupt in
  /// run()): interrupted when it had not reached t_end, then finish().
  py::object abandon() {
    if (!sim().finished()) sim_.interrupt();
    return finish();
  }

private:
  /// The simulation, built without the GIL; Ctrl-C during its set-up raises
  /// KeyboardInterrupt (with_python_signals) and leaves no object.
  static Simulation build(const Scene& scene, const RunOptions& options, std::optional<int> threads) {
    return with_python_signals([&] {
      py::gil_scoped_release nogil;
      ThreadScope scope(threads);
      return Simulation(scene, options);
    });
  }
  static std::set<PySimulation*>& live() {
    static std::set<PySimulation*> all; // touched with the GIL held only
    return all;
  }

  /// Marks the simulation busy (set and cleared with the GIL held) while its
  /// steps run without the GIL.
  class Busy {
  public:
    explicit Busy(bool& flag) : flag_(flag) { flag_ = true; }
    ~Busy() { flag_ = false; }
    Busy(const Busy&) = delete;
    Busy& operator=(const Busy&) = delete;

  private:
    bool& flag_;
  };

  py::object callback_ = py::none();
  std::optional<int> threads_;
  Simulation sim_;
  bool finish_called_ = false;
  bool busy_ = false;
};

/// Calls f(engine) with the engine of the simulation's dimension.
template <class F> py::object visit_engine(Simulation& sim, F&& f) {
  switch (sim.dimension()) {
  case 1: return f(sim.engine<1>());
  case 2: return f(sim.engine<2>());
  default: return f(sim.engine<3>());
  }
}

/// A NumPy array over `data` (no copy) with the given shape and byte
/// strides whose base is `owner` (the Python Simulation, kept alive by the
/// array); read-only unless `writable`. None for a field not allocated.
template <class T>
py::object view(const T* data, std::vector<py::ssize_t> shape, std::vector<py::ssize_t> strides, py::handle owner,
                bool writable = false) {
  if (data == nullptr) return py::none();
  py::array a(py::dtype::of<T>(), std::move(shape), std::move(strides), data, owner);
  if (!writable) a.attr("setflags")(py::arg("write") = false);
  return a;
}

/// (n, D) view of an array of Vec<D>.
template <int D> py::object vectors(const AlignedVector<Vec<D>>& v, py::handle owner, bool writable = false) {
  static_assert(sizeof(Vec<D>) == D * sizeof(double), "Vec<D> must be D contiguous doubles");
  const auto n = static_cast<py::ssize_t>(v.size());
  return view(v.empty() ? nullptr : v.data()->data(), {n, D}, {sizeof(Vec<D>), sizeof(double)}, owner, writable);
}

/// (n, D, D) view of an array of Mat<D>: [p, i, j] = A_p(i, j) (column-major inside each particle).
template <int D> py::object tensors(const AlignedVector<Mat<D>>& A, py::handle owner) {
  static_assert(sizeof(Mat<D>) == D * D * sizeof(double), "Mat<D> must be D*D contiguous doubles");
  const auto n = static_cast<py::ssize_t>(A.size());
  return view(A.empty() ? nullptr : A.data()->data(), {n, D, D},
              {sizeof(Mat<D>), sizeof(double), D * static_cast<py::ssize_t>(sizeof(double))}, owner);
}

/// (n,) view of a per-particle or per-node scalar array.
template <class T> py::object scalars(const std::vector<T>& v, py::handle owner) {
  return view(v.empty() ? nullptr : v.data(), {static_cast<py::ssize_t>(v.size())}, {sizeof(T)}, owner);
}

/// Plane strain's out-of-plane Cauchy stress sigma_zz of every particle of a
/// 2D engine, (n,) read-only - a new array, not a view: the materials derive
/// it from what they keep (Material::out_of_plane_stress), as the result
/// file's stress_zz is derived when a frame is written. None in 1D and 3D.
template <int D> py::object out_of_plane_stress(const Engine<D>& e) {
  if constexpr (D != 2) {
    (void)e;
    return py::none();
  } else {
    const Particles<D>& P = e.particles();
    py::array_t<double> zz(static_cast<py::ssize_t>(P.size()));
    double* out = zz.mutable_data();
    for (int first = 0, last = 0; first < P.size(); first = last) { // runs of particles of one material
      while (last < P.size() && P.material[last] == P.material[first]) ++last;
      e.material(P.material[first]).out_of_plane_stress(P, first, last, out + first);
    }
    zz.attr("setflags")(py::arg("write") = false);
    return zz;
  }
}

/// sim.particles: views of the engine's particle arrays.
struct ParticleViews {
  py::object owner; ///< the Python Simulation
  Simulation& sim() { return owner.cast<PySimulation&>().sim(); }
  template <class F> py::object get(F&& f) {
    return visit_engine(sim(), [&](auto& e) { return f(e.particles()); });
  }
};

/// sim.nodes: views of the node positions and the nodal fields of the last step.
struct NodeViews {
  py::object owner;
  Simulation& sim() { return owner.cast<PySimulation&>().sim(); }
  template <class F> py::object get(F&& f) {
    return visit_engine(sim(), [&](auto& e) { return f(e); });
  }
};

/// The material state arrays by name: (n,) for one value per particle, (n, width) otherwise.
template <int D> py::dict state_views(const Particles<D>& P, py::handle owner) {
  py::dict d;
  for (const StateField& s : P.state) {
    const auto n = static_cast<py::ssize_t>(P.size());
    const auto w = static_cast<py::ssize_t>(s.width);
    const auto row = w * static_cast<py::ssize_t>(sizeof(double));
    d[py::str(s.name)] = s.width == 1 ? view(s.values.data(), {n}, {row}, owner)
                                      : view(s.values.data(), {n, w}, {row, sizeof(double)}, owner);
  }
  return d;
}

py::dict energy_dict(const EnergyBalance& E) {
  py::dict d;
  d["kinetic"] = E.kinetic;
  d["strain"] = E.strain;
  d["dissipated"] = E.dissipated;
  d["friction"] = E.friction;
  d["impact"] = E.impact;
  d["darcy"] = E.darcy;
  d["pressure_average"] = E.pressure_average;
  d["relaxation"] = E.relaxation;
  d["external_work"] = E.external_work;
  d["reaction_work"] = E.reaction_work;
  d["initial"] = E.initial;
  d["total"] = E.total();
  d["work"] = E.work();
  d["balance_error"] = E.balance_error();
  return d;
}

PySimulation& cast(const py::object& self) { return self.cast<PySimulation&>(); }

const char* kSimulationDoc = R"doc(A run of a scene stepped by hand (the engine behind `otmpm run`).

Simulation(scene, out=None, write_results=True, threads=None, callback=None, force=False)

out: the result file (None: the scene's output.file); write_results=False
writes none; force=True replaces an existing result file (otmpm run --force). threads: OpenMP threads for the steps (None: OMP_NUM_THREADS).
callback: called as callback(sim) after every step (see `callback`).

The frame at t = 0 is written on construction; frames at the scene's output
times, probes, energy series and checkpoints follow as in `otmpm run`. Use
it as a context manager (or call finish()) so that the result file gets its
final status and summary attributes:

    with otmpm.Simulation(scene) as sim:
        sim.advance_to(5e-5)
        print(sim.particles.v[:3])

particles and nodes give NumPy views of the engine's arrays (no copy);
stepping changes what they show. Steps run with the GIL released; Ctrl-C
stops a loop of steps between two steps with KeyboardInterrupt.)doc";

void register_views(py::module_& m) {
  py::class_<ParticleViews>(m, "ParticleViews",
                            "NumPy views of the engine's particle arrays (no copy): each stays valid and shows\n"
                            "the current state for the life of its Simulation (the arrays are never\n"
                            "reallocated during a run). All are read-only except v. None for a field the\n"
                            "run does not allocate (a: npc only; F: finite strain, ul mode or output).\n"
                            "stress_zz (2D) is no view: a new array computed on each access.")
      .def("__len__", [](ParticleViews& p) { return p.get([](auto& P) -> py::object { return py::int_(P.size()); }); })
      .def_property_readonly(
          "x", [](ParticleViews& p) { return p.get([&](auto& P) { return vectors(P.x, p.owner); }); },
          "Positions x_p, (n, D).")
      .def_property_readonly(
          "X", [](ParticleViews& p) { return p.get([&](auto& P) { return vectors(P.X, p.owner); }); },
          "Initial positions X_p (the material coordinates of the exact solutions), (n, D).")
      .def_property_readonly(
          "v", [](ParticleViews& p) { return p.get([&](auto& P) { return vectors(P.v, p.owner, true); }); },
          "Velocities v_p, (n, D) - WRITABLE between steps: the next step starts from what you write\n"
          "(fe, musl, npc, unified; otm recomputes v_p from the positions at every step after its first).\n"
          "NaN or Inf written here is reported by the next step as an InstabilityError.")
      .def_property_readonly(
          "a", [](ParticleViews& p) { return p.get([&](auto& P) { return vectors(P.a, p.owner); }); },
          "Accelerations a_p (npc), (n, D), or None.")
      .def_property_readonly(
          "stress", [](ParticleViews& p) { return p.get([&](auto& P) { return tensors(P.sigma, p.owner); }); },
          "Cauchy stress sigma_p, (n, D, D): stress[p, i, j] = sigma_ij.")
      .def_property_readonly(
          "stress_zz",
          [](ParticleViews& p) { return visit_engine(p.sim(), [](auto& e) { return out_of_plane_stress(e); }); },
          "2D: plane strain's out-of-plane Cauchy stress sigma_zz, (n,) - computed on access from the\n"
          "materials' state (a new read-only array, not a view), the values the result file's\n"
          "stress_zz holds at a frame. None in 1D and 3D (3D: stress[:, 2, 2]).")
      .def_property_readonly(
          "strain", [](ParticleViews& p) { return p.get([&](auto& P) { return tensors(P.eps, p.owner); }); },
          "Strain eps_p (small strain, or sym(F_p) - I for finite strain), (n, D, D).")
      .def_property_readonly(
          "F", [](ParticleViews& p) { return p.get([&](auto& P) { return tensors(P.F, p.owner); }); },
          "Deformation gradient F_p, (n, D, D), or None.")
      .def_property_readonly(
          "volume", [](ParticleViews& p) { return p.get([&](auto& P) { return scalars(P.V, p.owner); }); },
          "Volumes V_p, (n,).")
      .def_property_readonly(
          "mass", [](ParticleViews& p) { return p.get([&](auto& P) { return scalars(P.m, p.owner); }); },
          "Masses m_p, (n,).")
      .def_property_readonly(
          "density", [](ParticleViews& p) { return p.get([&](auto& P) { return scalars(P.rho, p.owner); }); },
          "Densities rho_p, (n,).")
      .def_property_readonly(
          "material", [](ParticleViews& p) { return p.get([&](auto& P) { return scalars(P.material, p.owner); }); },
          "Material index of each particle (order of the scene's [[material]]), (n,) int32.")
      .def_property_readonly(
          "body", [](ParticleViews& p) { return p.get([&](auto& P) { return scalars(P.body, p.owner); }); },
          "Body index of each particle (order of the scene's [[body]]), (n,) int32.")
      .def_property_readonly(
          "state",
          [](ParticleViews& p) { return p.get([&](auto& P) -> py::object { return state_views(P, p.owner); }); },
          "The materials' internal variables by name: a dict of read-only views, (n,) or (n, width).");

  py::class_<NodeViews>(m, "NodeViews",
                        "NumPy views of the nodes (no copy), read-only: positions x_I (advected in ul\n"
                        "mode; B-splines: the control points) and the nodal fields of the last step.")
      .def("__len__", [](NodeViews& n) { return n.get([](auto& e) -> py::object { return py::int_(e.basis().nodes().size()); }); })
      .def_property_readonly(
          "x", [](NodeViews& n) { return n.get([&](auto& e) { return vectors(e.basis().nodes().positions(), n.owner); }); },
          "Node positions x_I, (m, D).")
      .def_property_readonly(
          "v", [](NodeViews& n) { return n.get([&](auto& e) { return vectors(e.nodal().v, n.owner); }); },
          "Nodal velocities v_I of the last step, (m, D).")
      .def_property_readonly(
          "m", [](NodeViews& n) { return n.get([&](auto& e) { return scalars(e.nodal().m, n.owner); }); },
          "Lumped nodal masses m_I of the last step, (m,).");
}

} // namespace

void register_simulation(py::module_& m) {
  register_views(m);
  py::module_::import("atexit").attr("register")(py::cpp_function([] { PySimulation::finish_all(); }));
  py::class_<PySimulation>(m, "Simulation", kSimulationDoc)
      .def(py::init([](const Scene& scene, const py::object& out, bool write_results,
                       std::optional<int> threads, const py::object& callback, bool force) {
             auto s = std::make_unique<PySimulation>(scene, out, write_results, force, threads);
             s->set_callback(callback);
             return s;
           }),
           py::arg("scene"), py::arg("out") = py::none(), py::arg("write_results") = true,
           py::arg("threads") = py::none(), py::arg("callback") = py::none(), py::arg("force") = false)
      .def(
          "step",
          [](const py::object& self, long n) {
            PySimulation& s = cast(self);
            if (n < 0) throw py::value_error("Simulation.step: n must be >= 0, got " + std::to_string(n));
            if (s.open("step").finished()) s.sim().step(); // raises: the run is finished
            const long done = s.sim().steps();
            const long target =
                n > std::numeric_limits<long>::max() - done ? std::numeric_limits<long>::max() : done + n;
            s.steps_while(self, [&](const Simulation& m) { return m.steps() < target && !m.finished(); });
          },
          py::arg("n") = 1,
          "Takes n steps (fewer if the run reaches t_end). Raises InstabilityError when the run becomes\n"
          "unstable (the result file gets the diagnosis as its status; the run is then finished) and\n"
          "RuntimeError when the run is already finished.")
      .def(
          "advance_to",
          [](const py::object& self, double t) {
            PySimulation& s = cast(self);
            s.open("advance_to");
            s.steps_while(self, [&](const Simulation& m) { return !m.finished() && m.time() < t * (1.0 - kTimeSlack); });
          },
          py::arg("t"), "Steps until sim.t >= t (at most to t_end): the first step at or past t.")
      .def(
          "write_frame", [](PySimulation& s) { s.open("write_frame").write_frame(); },
          "Writes a frame (and probe and energy samples) of the current state into the result file now.\n"
          "RuntimeError after finish().")
      .def(
          "interrupt", [](PySimulation& s) { s.interrupt(); },
          "Stops the run before t_end: a last checkpoint (when output.checkpoint_every is set) and status\n"
          "\"interrupted\" in the result file; finish() then completes it.")
      .def(
          "finish", [](PySimulation& s) { return s.finish(); },
          "Completes the result file (final status, errors against the exact solution, summary\n"
          "attributes) and returns the otmpm.Summary. Call once, after the last step.")
      .def(
          "energy",
          [](PySimulation& s) {
            return visit_engine(s.sim(), [](auto& e) -> py::object { return energy_dict(e.energy()); });
          },
          "The energy balance after the last step [J]: kinetic, strain, dissipated (plastic work), friction\n"
          "(dissipated at walls, in body contact and at a channel's side walls), impact (taken by impacts on "
          "walls and between bodies), darcy (dissipated by the drag of a saturated body's pore\n"
          "liquid), pressure_average (the pore pressure's work on the increments its cell average leaves "
          "out), relaxation (the kinetic\n"
          "energy the PIC relaxation took: simulation.pic_relaxation_time), external_work, reaction_work, "
          "initial (E(0)),\n"
          "total (kinetic + strain), work, balance_error.")
      .def_property_readonly(
          "particles", [](const py::object& self) { return ParticleViews{self}; },
          "The particles (ParticleViews).")
      .def_property_readonly(
          "nodes", [](const py::object& self) { return NodeViews{self}; }, "The nodes (NodeViews).")
      .def_property_readonly(
          "t", [](PySimulation& s) { return s.sim().time(); }, "Simulated time [s].")
      .def_property_readonly(
          "dt",
          [](PySimulation& s) {
            return visit_engine(s.sim(), [](auto& e) { return py::float_(e.last_dt()); });
          },
          "Size of the last step [s] (0 before the first).")
      .def_property_readonly(
          "next_dt",
          [](PySimulation& s) {
            return visit_engine(s.sim(), [](auto& e) { return py::float_(e.stable_dt()); });
          },
          "Size of the next step [s] (CFL rule or the fixed dt, at most t_end - t).")
      .def_property_readonly(
          "steps", [](PySimulation& s) { return s.sim().steps(); }, "Steps taken.")
      .def_property_readonly(
          "t_end", [](PySimulation& s) { return s.sim().t_end(); }, "simulation.t_end [s].")
      .def_property_readonly(
          "dimension", [](PySimulation& s) { return s.sim().dimension(); }, "1, 2 or 3.")
      .def_property_readonly(
          "finished", [](PySimulation& s) { return s.sim().finished(); },
          "True once t_end is reached, the run became unstable or was interrupted.")
      .def_property_readonly(
          "status", [](PySimulation& s) { return s.sim().status(); },
          "\"running\", \"ok\" after finish(), \"interrupted\" or \"unstable: ...\" (the result file's "
          "status).")
      .def_property_readonly(
          "scene", [](PySimulation& s) { return s.sim().scene(); }, "The scene (a copy).")
      .def_property(
          "callback", &PySimulation::callback, &PySimulation::set_callback,
          "Called as callback(sim) after every step taken by step(), advance_to() (None: no\n"
          "callback; TypeError for anything not callable). It may read the views; an exception\n"
          "it raises stops the loop and propagates. Loops with a callback hold the GIL between steps.")
      .def("__enter__", [](const py::object& self) { return self; })
      .def(
          "__exit__",
          [](PySimulation& s, const py::object& type, const py::object&, const py::object&) {
            if (s.finish_called()) return false;
            if (type.is_none())
              s.finish();
            else
              s.abandon();
            return false;
          },
          "Finishes the run (status \"interrupted\" when an exception left the block before t_end).");

  m.def(
      "run",
      [](const Scene& scene, const py::object& out, std::optional<int> threads, bool write_results, bool force) {
        PySimulation s(scene, out, write_results, force, threads);
        try {
          s.run_to_end(py::none());
        } catch (py::error_already_set&) { // KeyboardInterrupt: a valid file with status "interrupted"
          s.abandon();
          throw;
        }
        return s.finish();
      },
      py::arg("scene"), py::arg("out") = py::none(), py::arg("threads") = py::none(), py::arg("write_results") = true,
      py::arg("force") = false,
      R"doc(Runs a scene to t_end, as `otmpm run` does, and returns its otmpm.Summary.

out: the result file (None: the scene's output.file). threads: OpenMP threads
(None: OMP_NUM_THREADS). force=True replaces an existing result file, as
`otmpm run --force` (RunOptions::force). The GIL is released while it runs. An instability
ends the run with exit_code 1 and the diagnosis as status (no exception, as
the command line). Ctrl-C raises KeyboardInterrupt after the current step and
leaves the result file valid with status "interrupted".)doc");
}

} // namespace otmpm::python
