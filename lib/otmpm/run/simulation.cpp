/// \file simulation.cpp
/// Simulation (simulation.hpp): the engine built by the assembler, stepped
/// one step at a time, with the Recorder (recorder.hpp) that writes the
/// result file and the checkpoints; how a run stops on an instability, an
/// output error, memory running out or an interruption.
#include "otmpm/run/simulation.hpp"

#include "otmpm/assembly/assembler.hpp"
#include "otmpm/assembly/exact_solutions.hpp"
#include "otmpm/distributed/global_view.hpp"
#include "otmpm/interrupt.hpp"
#include "otmpm/run/initial_equilibrium.hpp"
#include "otmpm/run/recorder.hpp"
#include "otmpm/run/restart.hpp"
#include "otmpm/run/run_common.hpp"
#include "otmpm/scene/resources.hpp"
#include "otmpm/scene/validate.hpp"

#include <chrono>
#include <memory>
#include <new>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

namespace otmpm {

namespace {

/// What a run that ran out of memory had been told it could use: otmpm's
/// estimate (scene/resources.hpp) and the limit the estimate passed.
std::string memory_note(const Scene& scene) {
  const bool set = scene.simulation.memory_limit > 0;
  const int ranks = distributed::Comm::world().size();
  return "otmpm's estimate was about " + format_bytes(estimate_even_share(scene, ranks).bytes) +
         (ranks > 1 ? " per rank (an even share of " + std::to_string(ranks) + ")" : "") + " against a limit of " +
         format_bytes(memory_limit(scene)) +
         (set ? " set by simulation.memory_limit: more than this process could get" : " this process may use");
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// What every rank of a distributed run must share besides its scene: the
/// otmpm version, the options that change the run or its files, and the
/// checkpoint a restart continues.
std::string run_inputs(const RunOptions& opt, const Checkpoint* resume) {
  std::string s = "otmpm " OTMPM_VERSION "\nout_file = " + opt.out_file + "\nforce = " + (opt.force ? "1" : "0") +
                  "\nwrite_results = " + (opt.write_results ? "1" : "0") + "\n";
  if (resume) {
    const StateGroup& g = resume->group("engine");
    s += "checkpoint of run " + resume->run_id + " at step " + std::to_string(g.integer("step")) + "\n";
  }
  return s;
}

/// Every rank of a distributed run reads the scene (or checkpoint) itself:
/// they must have read the same one, with the same options, before they
/// set anything up together (distributed::require_same).
void require_same_inputs(const Scene& scene, const RunOptions& opt, const Checkpoint* resume) {
  const auto& comm = distributed::Comm::world();
  if (comm.size() == 1) return;
  const char* why = "every rank must run the same scene with the same options: does the scene file differ between "
                    "nodes, was it rewritten while the job started, or do the ranks' command lines differ?";
  distributed::require_same(comm, "the resolved scene (after --set)", scene.text.empty() ? to_toml(scene) : scene.text,
                            why);
  distributed::require_same(comm, "the set of run options", run_inputs(opt, resume), why);
}

} // namespace

/// The dimension-independent face of a simulation.
struct Simulation::Runner {
  virtual ~Runner() = default;
  Scene scene;
  RunSummary summary;
  bool finished = false;
  bool closed = false; ///< finish() has run: the result file is complete and closed
  virtual int dimension() const = 0;
  virtual double time() const = 0;
  virtual long steps() const = 0;
  virtual void step() = 0;
  virtual void write_frame() = 0;
  virtual void interrupt() = 0;
  virtual void finish() = 0;
};

/// A simulation in D dimensions: the engine, its exact solution (if any)
/// and the recorder of its result file.
template <int D> struct Simulation::DimRunner final : Simulation::Runner {
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  RunOptions options;
  /// A distributed restart: this rank's rows of the checkpoint, from build() to init().
  Checkpoint restart_rows;
  Engine<D> e;
  std::unique_ptr<ExactSolution<D>> exact;
  Recorder<D> rec;

  DimRunner(const Scene& s, const RunOptions& opt, const Checkpoint* resume)
      : options(opt), e(build(s, opt, resume, restart_rows)), exact(make_exact_solution<D>(s)),
        rec(init(s, resume), opt, e, exact.get(), resume) {
    const distributed::GlobalView<D> view(e);
    summary.mode = scene.simulation.mode;
    summary.integrator = scene.simulation.integrator;
    summary.basis = scene.basis.kind;
    summary.particles = view.particles();
    summary.nodes = view.nodes();
    summary.status = "running";
    if (resume) {
      summary.initial_equilibrium = rec.initial_equilibrium(); // how the interrupted run's phase ended
      return;
    }
    rec.set_initial_equilibrium(summary.initial_equilibrium); // its checkpoints carry it to a restart
    if (interrupt_requested(opt)) { // during the set-up: no initial frame, no checkpoint (nothing was run)
      stop_interrupted();
      return;
    }
    try { // an initial state that is not finite or cannot be written is a diagnosis too
      rec.sample_energy();
      rec.maybe_record(true);
    } catch (const InstabilityError& err) {
      stop_unstable(err);
    } catch (const OutputError& err) {
      stop_output_error(err);
    }
  }

  /// This rank's engine of the scene (the whole scene in a serial run); a
  /// distributed restart builds it from its rows of the checkpoint (`rows`).
  /// The run stops inside the seeding's loops when opt.interrupt is set
  /// (InterruptedError, before any file is created); in a distributed run
  /// the rank that got the signal tells the others (interrupt_peers), each
  /// leaves its loop, and the agreement after the loop stops them all.
  static Engine<D> build(const Scene& s, const RunOptions& opt, const Checkpoint* resume, Checkpoint& rows) {
    const auto& comm = distributed::Comm::world();
    std::optional<InterruptPolling> polling; // else the caller's (Python's signal handlers), if any
    if (opt.interrupt) polling.emplace(opt.interrupt, distributed::interrupt_peers());
    if (!resume || comm.size() == 1) return Engine<D>(distributed::rank_parts<D>(s, comm));
    return Engine<D>(distributed::restart_parts<D>(s, comm, *resume, rows));
  }

  /// Stores the scene and restores the checkpoint - or, for a new run,
  /// checks the step count on the seeded particles' first step - before
  /// the recorder is built.
  const Scene& init(const Scene& s, const Checkpoint* resume) {
    scene = s;
    if (resume) e.restore_state(distributed::local_checkpoint(e, *resume, std::exchange(restart_rows, {})));
    else if (const auto& q = scene.simulation.initial_equilibrium) {
      if (distributed::Comm::world().size() > 1)
        input_error(scene.locate("simulation.initial_equilibrium"), "runs in a serial run only (one rank)");
      std::optional<InterruptPolling> polling; // as in the set-up (build): SIGINT stops the phase
      if (options.interrupt) polling.emplace(options.interrupt);
      summary.initial_equilibrium = settle<D>(scene, e).describe(q->tolerance);
    }
    if (!resume) check_first_step(scene, e.stable_dt(), e.wave_speed());
    return scene;
  }

  int dimension() const override { return D; }
  double time() const override { return e.time(); }
  long steps() const override { return e.steps(); }

  void step() override {
    const double t_end = scene.simulation.t_end;
    stopping_on_failure([&] {
      e.step();
      rec.sample_energy();
      const bool last = e.time() >= t_end * (1.0 - time_slack);
      rec.maybe_record(last);
      rec.maybe_checkpoint(seconds_since(start), last);
      finished = last;
    });
    if (options.progress) options.progress(e.time(), t_end, e.steps());
  }

  /// Runs `f` (a step, a frame); an instability, an output error or memory
  /// running out ends the run with its status and is rethrown. In a
  /// distributed run an allocation that fails on one rank ends every rank
  /// with the same DeferredOutOfMemory: inside a stage of a step the rank
  /// defers it to the next reduction; anywhere else (a halo or migration
  /// buffer, a frame's rows, a sum) it tells the others at once
  /// (stop_every_rank), which leave the operation they wait in.
  template <class F> void stopping_on_failure(F&& f) {
    try {
      try {
        f();
      } catch (const std::bad_alloc&) {
        if (distributed::Comm::world().size() == 1) throw;
        const std::string what = "rank " + std::to_string(distributed::Comm::world().rank()) +
                                 " could not get the memory it needed";
        throw DeferredOutOfMemory(distributed::stop_every_rank(diagnosis(what, e.steps(), e.time())));
      }
    } catch (const InstabilityError& err) {
      stop_unstable(err);
      throw;
    } catch (const OutputError& err) {
      stop_output_error(err);
      throw;
    } catch (const DeferredOutOfMemory& err) {
      stop(kOutOfMemoryStatus + (": " + diagnosis(err.what(), e.steps(), e.time()) + " (" + memory_note(scene) + ")"),
           kOutputErrorExit);
      throw;
    } catch (const std::bad_alloc&) {
      if (distributed::Comm::world().size() == 1)
        stop(kOutOfMemoryStatus + (": " + diagnosis("the run needed more memory than this process could get (" +
                                               memory_note(scene) + ")", e.steps(), e.time())),
             kOutputErrorExit);
      throw;
    }
  }

  /// Ends the run on an instability: status "unstable: step N, t = T: ...", exit code 1.
  void stop_unstable(const InstabilityError& err) {
    rec.sample_energy(); // a runaway stop has the energy that tripped the monitor
    stop("unstable: " + diagnosis(err.what(), e.steps(), e.time()), 1);
  }

  /// Ends the run on a result or checkpoint that could not be written: status
  /// "output error: step N, t = T: ...", exit code kOutputErrorExit; the
  /// result file keeps what was written before.
  void stop_output_error(const OutputError& err) {
    stop("output error: " + diagnosis(err.what(), e.steps(), e.time()), kOutputErrorExit);
  }

  void stop(const std::string& status, int exit_code) {
    summary.status = status;
    summary.exit_code = exit_code;
    rec.set_status(summary.status);
    finished = true;
  }

  void write_frame() override {
    stopping_on_failure([&] { rec.maybe_record(true); });
  }

  void interrupt() override {
    try {
      rec.checkpoint(seconds_since(start));
    } catch (const OutputError& err) {
      stop_output_error(err);
      return;
    } catch (const InstabilityError& err) { // reported by the writer thread
      stop_unstable(err);
      return;
    }
    stop_interrupted();
  }

  /// Ends the run as interrupted: status "interrupted", kInterruptedExit.
  void stop_interrupted() {
    stop("interrupted", kInterruptedExit);
    summary.interrupted = true;
  }

  void finish() override {
    try { // the last output time may still be in flight on the writer thread
      rec.wait_for_output();
    } catch (const InstabilityError& err) {
      if (summary.exit_code == 0) stop_unstable(err);
    } catch (const OutputError& err) {
      if (summary.exit_code == 0) stop_output_error(err);
    }
    if (summary.exit_code == 0 && distributed::Comm::world().size() == 1) {
      try { // every step ends checked; a state changed by hand since (a writable view) is checked here
        e.check_particles_inside();
      } catch (const InstabilityError& err) {
        stop_unstable(err);
      }
    }
    if (summary.exit_code == 0) summary.status = "ok";
    summary.steps = e.steps();
    summary.time = e.time();
    summary.timers = e.timers();
    summary.wall_seconds = rec.wall_before() + seconds_since(start);
    const distributed::GlobalView<D> view(e); // the slowest rank's times (the same on every rank)
    summary.wall_seconds = view.max(summary.wall_seconds);
    for (double& t : summary.timers.seconds) t = view.max(t);
    rec.finish(summary);
    finished = true;
    closed = true;
  }
};

std::unique_ptr<Simulation::Runner> Simulation::make(const Scene& scene, const RunOptions& options,
                                                     const Checkpoint* resume) {
  const int dim = scene.simulation.dimension;
  require_same_inputs(scene, options, resume);
  // A Scene built in code meets the reader's checks too; the ranks agree
  // (the memory a process may use can differ from node to node).
  if (dim >= 1 && dim <= 3)
    distributed::agree_on(distributed::Comm::world(),
                          [&] { check_before_allocating(scene, dim, distributed::Comm::world().size()); });
  try {
    switch (scene.simulation.dimension) {
    case 1: return std::make_unique<DimRunner<1>>(scene, options, resume);
    case 2: return std::make_unique<DimRunner<2>>(scene, options, resume);
    case 3: return std::make_unique<DimRunner<3>>(scene, options, resume);
    default: break;
    }
  } catch (const std::bad_alloc&) { // the estimate let it start, the machine could not give it
    throw InputError(shortened(scene.file) + ": out of memory while setting up the run (" + memory_note(scene) + ")");
  }
  input_error(scene.locate("simulation.dimension"),
              "dimension must be 1, 2 or 3, got " + std::to_string(scene.simulation.dimension));
}

Simulation::Simulation(const Scene& scene, const RunOptions& options) : run_(make(scene, options, nullptr)) {}
Simulation::Simulation(const Checkpoint& checkpoint, const RunOptions& options)
    : run_(make(checkpoint_scene(checkpoint), options, &checkpoint)) {}
Simulation::Simulation(Simulation&&) noexcept = default;
Simulation& Simulation::operator=(Simulation&&) noexcept = default;
Simulation::~Simulation() {
  // A run dropped without finish() (an exception, a forgotten call) gets a
  // final status, as finish() after interrupt() gives it, instead of keeping
  // "running" for ever. Not in a distributed run: the other ranks may not be here.
  if (!run_ || run_->closed || distributed::Comm::world().size() > 1) return;
  try {
    if (!finished()) run_->interrupt();
    run_->finish();
  } catch (const std::exception&) { // nothing can be reported from a destructor; the status is what it could be
  }
}

const Scene& Simulation::scene() const { return run_->scene; }
int Simulation::dimension() const { return run_->dimension(); }
double Simulation::time() const { return run_->time(); }
double Simulation::t_end() const { return run_->scene.simulation.t_end; }
long Simulation::steps() const { return run_->steps(); }
bool Simulation::finished() const { return run_->finished || time() >= t_end() * (1.0 - time_slack); }
bool Simulation::unstable() const { return run_->summary.exit_code == 1; }
const std::string& Simulation::status() const { return run_->summary.status; }

void Simulation::step() {
  if (finished()) throw std::logic_error("Simulation::step: the run is finished (" + status() + ")");
  run_->step();
}

void Simulation::advance_to(double t) {
  while (!finished() && time() < t * (1.0 - time_slack)) step();
}

void Simulation::require_open(const char* what) const {
  if (run_->closed)
    throw std::logic_error(std::string("Simulation::") + what +
                           ": the run is finished (finish() was called)");
}

void Simulation::write_frame() {
  require_open("write_frame");
  run_->write_frame();
}

void Simulation::interrupt() {
  require_open("interrupt");
  if (finished()) throw std::logic_error("Simulation::interrupt: the run is finished (" + status() + ")");
  run_->interrupt();
}

RunSummary Simulation::finish() {
  require_open("finish");
  run_->finish();
  return run_->summary;
}

template <int D> Engine<D>& Simulation::engine() {
  auto* r = dynamic_cast<DimRunner<D>*>(run_.get());
  require<std::invalid_argument>(r != nullptr, "Simulation::engine<", D, ">: the run is ", dimension(), "D");
  return r->e;
}
template <int D> const Engine<D>& Simulation::engine() const { return const_cast<Simulation*>(this)->engine<D>(); }

template Engine<1>& Simulation::engine<1>();
template Engine<2>& Simulation::engine<2>();
template Engine<3>& Simulation::engine<3>();
template const Engine<1>& Simulation::engine<1>() const;
template const Engine<2>& Simulation::engine<2>() const;
template const Engine<3>& Simulation::engine<3>() const;

} // namespace otmpm
