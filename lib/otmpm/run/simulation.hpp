#pragma once
/// \file simulation.hpp
/// A run in progress, stepped by hand: the engine of a scene with its result
/// file, probes, energy series and checkpoints - everything run_scene()
/// does, one step at a time, so that a C++ driver (or the Python package)
/// can look at the state between steps, add its own diagnostics and write
/// frames when it likes. run_scene() is a loop over Simulation::step().
#include "otmpm/engine/engine.hpp"
#include "otmpm/run/run.hpp"

#include <memory>

namespace otmpm {

struct Checkpoint;

class Simulation {
public:
  /// Builds the engine of `scene` (assemble) and, unless
  /// options.write_results is false, opens the result file and writes the
  /// frame at t = 0. InputError (exit 2) for a scene that cannot run or
  /// output files it may not write (io/output_files.hpp); OutputError when
  /// the result file cannot even be created. An instability or an output
  /// error at t = 0 finishes the simulation at once (status() says why).
  explicit Simulation(const Scene& scene, const RunOptions& options = {});
  /// Continues the run saved in a checkpoint: its own scene, its state, and
  /// the frames written before it copied into the result file (restart_run).
  Simulation(const Checkpoint& checkpoint, const RunOptions& options);
  Simulation(Simulation&&) noexcept;
  Simulation& operator=(Simulation&&) noexcept;
  /// A simulation destroyed before finish() (an exception, a forgotten call)
  /// is completed as interrupt() and finish() would complete it - its result
  /// file gets status "interrupted" (or its final one) and otmpm's lock files
  /// go - so that no file keeps status "running" after its run is gone.
  /// Not in a distributed run (the other ranks may not be destroying theirs).
  ~Simulation();

  const Scene& scene() const;
  int dimension() const;
  double time() const;
  double t_end() const;
  long steps() const;
  /// True once t_end is reached or the run became unstable.
  bool finished() const;
  /// True when the run stopped on an instability (status() says why).
  bool unstable() const;
  /// "running", "ok" after finish(), "unstable: ...", "output error: ..." or
  /// "interrupted" (the result file's status).
  const std::string& status() const;

  /// One step, then what a run does after it: the energy sample, a frame at
  /// an output time (and at t_end), a checkpoint every
  /// output.checkpoint_every steps, the progress callback. An instability
  /// is written into the result file's status and rethrown
  /// (InstabilityError), and so is a result or checkpoint that cannot be
  /// written (OutputError, status "output error: ...", exit code
  /// kOutputErrorExit) and memory running out (std::bad_alloc, status "out
  /// of memory: ...", kOutputErrorExit); the simulation is then finished.
  /// std::logic_error when finished() already.
  void step();
  /// Steps until time() >= t (at most to t_end).
  void advance_to(double t);
  /// Writes a frame (and probe samples) of the current state into the result
  /// file now (also after t_end, an instability or interrupt(); a state that
  /// is not finite ends the run as step() does). std::logic_error after finish().
  void write_frame();
  /// Stops the run before t_end at the user's request: a last checkpoint
  /// when checkpoints are on, status "interrupted" (exit code
  /// kInterruptedExit) in the result file; finish() then completes it.
  /// std::logic_error when finished() already.
  void interrupt();
  /// The final errors, attributes and status of the result file, and the
  /// summary; closes the result file and releases otmpm's locks on the run's
  /// files. Call once, after the last step (also after an instability or an
  /// interruption); std::logic_error the second time.
  RunSummary finish();

  /// The engine; D must be dimension() (std::invalid_argument otherwise).
  template <int D> Engine<D>& engine();
  template <int D> const Engine<D>& engine() const;

private:
  /// std::logic_error naming `what` once finish() has run.
  void require_open(const char* what) const;
  struct Runner;
  template <int D> struct DimRunner;
  static std::unique_ptr<Runner> make(const Scene& scene, const RunOptions& options, const Checkpoint* resume);
  std::unique_ptr<Runner> run_;
};

} // namespace otmpm
