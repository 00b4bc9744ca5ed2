#pragma once
/// \file resources.hpp
/// What a scene will cost before anything is allocated: memory (particles
/// and nodes, for the scene's dimension, basis family and integrator) and
/// time steps (t_end over the first step, simulation.dt or the CFL step
/// cfl h / c with c the fastest P-wave or initial particle speed). run_scene()
/// refuses a scene whose estimate exceeds a limit with an InputError naming
/// the estimate, the limit and the key that raises it, instead of running out
/// of memory (std::bad_alloc) or running for ever at 0 % progress.
///
/// The memory estimate here is an upper bound, fitted to measured peaks and
/// kept above them (docs/stability.md, "What a run may cost"), because it
/// refuses runs; `otmpm run --check` prints the same estimate (check_scene,
/// run/run.hpp). A run that keeps compact rows instead of a basis table
/// (BasisKind::compact_row_bytes) is counted with its rows.
///
/// Limits: memory - simulation.memory_limit in bytes when set, else the
/// memory this process may use (physical memory, lowered by a cgroup limit
/// or RLIMIT_AS when there is one); steps - simulation.max_steps
/// (default kDefaultMaxSteps).
#include "otmpm/scene/scene.hpp"

#include <string>

namespace otmpm {

/// An estimate of what a run of a scene costs in one process.
struct ResourceEstimate {
  double particles = 0;           ///< the particles the process holds (scene_size(scene).particles in one process)
  double nodes = 0;               ///< the nodes it holds (scene_size(scene).nodes in one process)
  double stencil = 0;             ///< nodes per particle of the basis family (its support)
  double bytes_per_particle = 0;  ///< particle fields, basis table (or compact rows) and scatter plan
  double bytes_per_node = 0;      ///< nodal fields (and the mass matrix, when consistent)
  double bytes = 0;               ///< the total, with the process's fixed footprint (and a gravity-loading phase's engine)
  double dt = 0;                  ///< simulation.dt, or the first CFL step
  double wave_speed = 0;          ///< the fastest signal at t = 0 the CFL step is taken from (max_wave_speed)
  double steps = 0;               ///< t_end / dt, rounded up
};

/// The estimate for a scene that validate_scene accepts, run in one process.
ResourceEstimate estimate_resources(const Scene& scene);
/// The estimate for the process that holds `share` of the scene's particles
/// and nodes: the memory is linear in them (30 MB of its own, bytes_per_particle
/// and bytes_per_node), so a decomposition known before anything is allocated
/// gives each rank of a distributed run its own estimate. With `ranks` > 1
/// the process is one rank of a distributed run, whose consistent mass is
/// solved by conjugate gradients over the basis table (no factor; the
/// solver's five nodal vectors instead).
ResourceEstimate estimate_resources(const Scene& scene, const SceneSize& share, int ranks = 1);

/// The estimate for one of `processes` ranks holding an even share of the
/// scene (1/processes of its particles and nodes, rounded up): the largest
/// rank of a decomposition holds at least that. One process: the whole
/// scene's.
ResourceEstimate estimate_even_share(const Scene& scene, int processes);

/// The fastest signal at t = 0: the P-wave speed sqrt(M / rho) of every
/// material - with the smallest density of a file body's `density` column
/// for that body (BodySection::file_min_density) - and the speed of every
/// initial velocity, a file body's velocity columns included.
double max_wave_speed(const Scene& scene);

/// The memory limit of a run of `scene`: simulation.memory_limit when set
/// (> 0), else available_memory().
double memory_limit(const Scene& scene);
/// The memory this process may use: physical memory, or less when a cgroup
/// (memory.max) or RLIMIT_AS limits it.
double available_memory();

/// "1.5 GB", "512 MB", "12 kB" (decimal units, 3 significant digits).
std::string format_bytes(double bytes);

/// Throws InputError naming the estimate, the limit and the key that raises
/// it when the memory estimate exceeds memory_limit(scene) or the steps
/// exceed simulation.max_steps. With `processes` > 1 (a distributed run) the
/// memory checked is that of an even share, 1/processes of the particles and
/// nodes: the largest rank holds at least that, so a scene refused here is
/// refused before its particles are counted; check_rank_resources checks
/// each rank's own share once the decomposition is known.
void check_resources(const Scene& scene, int processes = 1);

/// Throws InputError when rank `rank` of `ranks`, holding `share` (its
/// particles and the lattice points of its window, ghosts included), would
/// need more than memory_limit(scene): the message names the rank, its
/// particles, nodes and estimate, the estimate of all ranks together
/// (`total_bytes`) and the limit.
void check_rank_resources(const Scene& scene, const SceneSize& share, int rank, int ranks, double total_bytes);

/// What a run and `otmpm run --check` check of a scene in `dimension`
/// dimensions before anything is allocated, in this order: every check of
/// the reader (validate_scene, with the size per process of a run on
/// `processes` ranks), then its estimated memory (of an even share on
/// `processes` ranks) and steps (check_resources).
void check_before_allocating(const Scene& scene, int dimension, int processes = 1);

/// The step-count check once the particles are seeded: t_end / dt, with
/// dt the engine's first step (Engine::stable_dt: the particles' own
/// densities and velocities), must not exceed simulation.max_steps. Throws
/// InputError naming the step, the wave speed `c` it came from (0: a fixed
/// step) and the key that raises it. A step that is not > 0, or a speed
/// that is not finite, is no long run but an instability the first step
/// reports (exit status 1): not checked here.
void check_first_step(const Scene& scene, double dt, double c);

/// Throws InputError, naming `what` (the option that gives the nodes, e.g.
/// "--cells 5000 in 3D"), when a node set built outside a scene (`otmpm
/// basis`, the Python otmpm.basis) would have more than kMaxRankNodes nodes
/// or not fit in available_memory() at about 1 kB per node (the nodes with
/// the basis' neighbour search, generously): the cap of one process, before
/// anything is allocated.
void check_node_count(double nodes, const std::string& what);

} // namespace otmpm
