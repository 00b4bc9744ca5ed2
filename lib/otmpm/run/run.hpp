#pragma once
/// \file run.hpp
/// Runs a whole scene: builds the engine for the scene's dimension, steps to
/// t_end, writes the HDF5 result file (frames, probes, errors against the
/// exact solution) and returns a summary. Used by `otmpm run` and `otmpm pair`.
#include "otmpm/engine/timers.hpp"
#include "otmpm/scene/scene.hpp"

#include <atomic>
#include <functional>
#include <map>
#include <string>

namespace otmpm {

struct Checkpoint;

/// RunSummary::exit_code of a run whose results could not be written (disk
/// full, file size limit, quota, I/O error) or that ran out of memory while
/// stepping: the `otmpm` exit status 4 (a resource ran out; the result file
/// keeps what was written before).
inline constexpr int kOutputErrorExit = 4;
/// The start of the status of a run that ran out of memory while stepping
/// ("out of memory: step N, t = T s: ..."; exit code kOutputErrorExit).
inline constexpr const char* kOutOfMemoryStatus = "out of memory";

struct RunOptions {
  std::string out_file;  ///< overrides output.file when not empty
  bool write_results = true;
  /// Replace existing output files that do not belong to this run (see
  /// io/output_files.hpp claim_outputs; `otmpm run --force`). Without it an
  /// existing result file is replaced only when it holds the results of the
  /// identical scene from the same otmpm version, and its sidecar,
  /// checkpoint and VTK files only when they belong to it (same run id).
  bool force = false;
  /// Called after every step with (t, t_end, steps) - e.g. a progress bar.
  std::function<void(double, double, long)> progress;
  /// When not null, read once per step: once true, the run stops after the
  /// current step, writes a last checkpoint (if output.checkpoint_every > 0),
  /// sets the result file's status to "interrupted" and returns a summary
  /// with interrupted = true (otmpm run on SIGINT/SIGTERM). The result file
  /// stays valid and the checkpoint can be continued with restart_run().
  const std::atomic<bool>* interrupt = nullptr;
  /// Write the frames and history samples on a writer thread while the
  /// engine steps on (serial runs only; a distributed run writes its file
  /// collectively on the stepping thread). Each output time's values are
  /// copied and checked (NaN, Inf, the single-precision range) before the run
  /// steps on; the writing of one output time overlaps the steps to the next,
  /// which waits for it first. The file is the same as without the thread; a
  /// write error is reported at the next output time, checkpoint or the end
  /// (OutputError, exit 4). `otmpm run` and `otmpm pair` turn it on when
  /// the OpenMP threads leave a core free (a writer thread that shares a
  /// core with the OpenMP team slows each parallel loop more than it saves).
  bool background_output = false;
};

/// The energy balance of a run, sampled after every step (docs/theory.md
/// eq. 11.2): E = kinetic + strain energy, W_s = the energy spent (plastic
/// work, friction, impacts and Darcy drag), W = work of the external loads, of the
/// Dirichlet reactions and of the walls since t = 0 (Engine's EnergyBalance).
struct EnergySummary {
  double initial = 0.0;           ///< E(0)
  double max_energy = 0.0;        ///< max_t E(t) + W_s(t) (W_s = W_p + W_f + W_i + W_d: the energy spent, EnergyBalance::spent)
  double max_work = 0.0;          ///< max_t |W(t)|
  double max_balance_error = 0.0; ///< max_t |E(t) + W_s(t) - E(0) - W(t)|
  /// Takes one sample; non-finite values are ignored (the run stops on them anyway).
  void sample(double energy, double work, double balance_error);
  /// E(0) + max_t |W(t)|: the most energy the body can hold without a spurious source.
  double reference() const;
  /// max_t (E(t) + W_s(t)) / reference(): at most 1 when the scheme creates no energy.
  double max_energy_ratio() const;
  /// max_t |E(t) + W_s(t) - E(0) - W(t)| / reference(): the relative energy error.
  double energy_drift() const;
};

/// RunSummary::exit_code of a run stopped at the user's request (128 + SIGINT).
inline constexpr int kInterruptedExit = 130;

/// What a run reports (docs/theory.md sect. 12).
struct RunSummary {
  /// "ok", "unstable: DIAGNOSIS", "output error: MESSAGE", "out of memory: MESSAGE" or "interrupted"
  std::string status = "ok";
  /// 0 ok, 1 unstable, kOutputErrorExit the results could not be written or memory ran out,
  /// kInterruptedExit interrupted
  int exit_code = 0;
  bool interrupted = false;  ///< stopped early (Simulation::interrupt, RunOptions::interrupt); status "interrupted"
  std::string mode, integrator, basis;
  long steps = 0;
  double time = 0.0;         ///< simulated time reached
  double wall_seconds = 0.0;
  long particles = 0, nodes = 0;
  std::map<std::string, double> errors; ///< rms_velocity_error, history_error_A, ...
  /// `ul` mode with a max-ent basis: widened_supports and moved_points since
  /// t = 0 (docs/theory.md sect. 4.8; also the series /diagnostics)
  std::map<std::string, double> diagnostics;
  EnergySummary energy;                 ///< max_energy_ratio, energy_drift
  /// The energy impacts on walls and between bodies took since t = 0 (W_i,
  /// docs/theory.md eq. 6.5); 0 without walls or [contact]
  double impact = 0.0;
  PhaseTimers timers;
  /// How the gravity-loading phase of simulation.initial_equilibrium ended
  /// (EquilibriumReport::describe); empty without one. A restart carries the
  /// interrupted run's (stored in its checkpoints).
  std::string initial_equilibrium;
  std::string out_file;
  double particle_steps_per_second() const { return wall_seconds > 0 ? particles * steps / wall_seconds : 0.0; }
};

/// Runs the scene. InputError propagates (exit 2): among others, before
/// anything is allocated or written, a scene whose memory or step count
/// estimate exceeds its limits (scene/resources.hpp), output paths that
/// collide, are locked by another run, or hold files the run may not replace
/// (io/output_files.hpp). An instability (also at t = 0) is caught, written
/// into the result file's status, and reported with exit_code 1; an output
/// that cannot be written (OutputError) likewise with kOutputErrorExit, the
/// file keeping every frame written before. The status and step and time of
/// every diagnosis are in RunSummary::status.
/// With output.checkpoint_every = N a checkpoint (io/checkpoint.hpp) is
/// written after every N steps of a run that writes a result file.
RunSummary run_scene(const Scene& scene, const RunOptions& options = {});

/// Continues the run saved in a checkpoint (otmpm run --restart) to t_end:
/// the checkpoint's own scene, its state restored, and the result file
/// (options.out_file, else the interrupted run's) holding first the frames
/// and probe samples written before the checkpoint, copied from the
/// interrupted run's result file. The result equals, bit for bit, that of
/// the uninterrupted run. InputError (naming the file) when the checkpoint
/// does not fit or that result file is missing or not the checkpoint's run's
/// (its run id differs).
RunSummary restart_run(const Checkpoint& checkpoint, const RunOptions& options = {});

/// One line: "ok: 1234 steps, 0.52 s wall, rms_velocity_error = 0.01 ..."
/// ("INTERRUPTED: ...", "UNSTABLE: ...", "OUTPUT FAILED: ..." or "OUT OF MEMORY: ..." for a run that did not finish).
std::string summary_line(const RunSummary& s);

/// What `otmpm run --check` prints about a scene without running it.
template <int D> class Engine;

/// A body's volume (area, length) as seeded - the sum of its particles'
/// volumes at t = 0 - and its shape's exact one (a box's, sphere's,
/// cylinder's or polygon's; the surface's enclosed volume for stl; the sum
/// of the element volumes for a mesh; NaN for a file body).
struct BodyVolume {
  std::string name, shape;
  double seeded = 0.0, exact = 0.0;
};

/// The BodyVolume of every body of the scene, from the particles of an
/// engine built from it (all ranks' particles: collective in a distributed run).
template <int D> std::vector<BodyVolume> body_volumes(const Scene& scene, const Engine<D>& e);

/// One rank of a distributed run as `run --check` under mpirun reports it
/// (distributed::plan_ranks: known before anything is allocated).
struct RankCheck {
  long long particles = 0;
  long long nodes = 0;  ///< the lattice points of its window, ghosts included
  long long ghosts = 0; ///< of them, the points other ranks own
  int neighbours = 0;   ///< ranks it exchanges nodal values with
  /// Bytes it sends in one nodal exchange of the mass, momentum and force
  /// (1 + 2D doubles per point; halo.hpp: ghosts' partial sums, then totals).
  double halo_bytes = 0.0;
  double memory_bytes = 0.0; ///< its memory estimate (estimate_resources of its share)
};

/// The expected wall time of one step of a distributed run, calibrated on
/// the ranks `run --check` runs on (each rank for itself): the step of a
/// small block of the scene's kind (calibration_particles particles of its
/// dimension, mode, integrator, basis, mass and first body's material and
/// particles per cell, with its grid spacing; one rank with the run's
/// Domain, which counts the nodal exchanges and reductions of a step) timed
/// over calibration_steps steps: the nodal update phase gives the time per
/// node, the others the time per particle. The communication of a step -
/// its exchanges with this rank's neighbours at the planned sizes, its
/// reductions over all ranks - is timed by doing it `comm_rounds` times.
/// compute = max over ranks of (per_particle particles + per_node nodes).
struct StepTime {
  bool calibrated = false;
  std::string why_not;      ///< when not calibrated: the error the calibration met
  double seconds = 0.0;     ///< compute + communication
  double compute = 0.0;     ///< of the busiest rank
  int busiest = 0;          ///< that rank
  double communication = 0.0; ///< per step, the slowest rank's
  double per_particle = 0.0, per_node = 0.0; ///< seconds per particle-step and node-step (the busiest rank's)
  double exchanges = 0.0, reductions = 0.0;  ///< per step, counted on the calibration
  long calibration_particles = 0;
  int calibration_steps = 0, comm_rounds = 0;
};

struct SceneCheck {
  int dimension = 1;
  std::string mode, integrator, basis;
  long particles = 0, nodes = 0; ///< of all ranks
  double dt = 0.0;           ///< the first time step (cfl rule at t = 0, or simulation.dt), as the engine takes it
  double t_end = 0.0;
  /// t_end / dt, rounded up: the step count if dt stayed as at t = 0 (with
  /// the cfl rule dt follows the wave and particle speeds, so it is an estimate).
  double estimated_steps = 0.0;
  /// simulation.initial_equilibrium's time / dt, rounded up: the most steps
  /// its gravity-loading phase takes before t = 0 (0: the scene has none).
  double phase_steps = 0.0;
  /// the run's own memory estimate (estimate_resources, scene/resources.hpp);
  /// under mpirun the sum of the ranks' estimates
  double memory_bytes = 0.0;
  double memory_limit = 0.0; ///< what the estimate is checked against (memory_limit(scene)), per process
  std::string out_file;      ///< output.file
  std::vector<BodyVolume> volumes; ///< per body (in one process only)
  std::vector<RankCheck> ranks; ///< under mpirun or with planned ranks: per rank (else empty)
  StepTime step_time;           ///< under mpirun or with planned ranks
};

/// Checks the scene as a run does, in the run's order: first, before
/// anything is allocated, every check of the reader and the run's memory
/// and step estimates (check_before_allocating: a scene whose estimate
/// exceeds its limits is refused in a moment, whatever its size); then, in
/// one process, the set-up of the engine as the run makes it (particles
/// seeded, nodes and basis built, Dirichlet boxes and tractions matched)
/// and the step-count check on its first step. Under mpirun (collective)
/// it allocates no share of the scene: the decomposition as the run finds
/// it (the seeding's counting pass, the bisection, the basis' reach) with
/// each rank's memory checked (RankCheck), the first step from the scene's
/// wave speeds, and the expected step time (StepTime). Reports the size,
/// first time step, estimated steps and the run's memory estimate, without
/// stepping. InputError as run_scene().
///
/// `planned_ranks` > 1 in one process (`run --check --ranks N`): the
/// decomposition a run on that many ranks would compute, found as under
/// mpirun by ranks played in this process (Comm::run_local) (nothing of the
/// scene allocated; the step time's compute part from one calibration
/// here, its communication not timed: StepTime::comm_rounds 0). Under
/// mpirun it must be the rank count or 0 (InputError otherwise).
SceneCheck check_scene(const Scene& scene, int planned_ranks = 0);

/// The run's rules on its output files applied without touching them
/// (`otmpm run --check`): the paths derived from `out_file` ("": the
/// scene's output.file) and the scene's checkpoint and VTK keys, each a
/// usable name and all different files (checked_output_files). InputError
/// as the run gives before writing; nothing when the scene writes no result
/// file.
void check_output_names(const Scene& scene, const std::string& out_file);

} // namespace otmpm
