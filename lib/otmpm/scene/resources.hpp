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
/// refuses runs; estimate_memory_bytes() (run/run.hpp), which `otmpm run
/// --check` prints, is a point estimate within a factor 2 either way.
///
/// Limits: memory - simulation.memory_limit in bytes when set, else the
/// memory this process may use (physical memory, lowered by a cgroup limit
/// or RLIMIT_AS when there is one); steps - simulation.max_steps
/// (default kDefaultMaxSteps).
#include "otmpm/scene/scene.hpp"

#include <string>

namespace otmpm {

/// An estimate of what a run of a scene costs.
struct ResourceEstimate {
  double particles = 0;           ///< scene_size(scene).particles
  double nodes = 0;               ///< scene_size(scene).nodes
  double stencil = 0;             ///< nodes per particle of the basis family (its support)
  double bytes_per_particle = 0;  ///< particle fields, basis table and scatter plan
  double bytes_per_node = 0;      ///< nodal fields (and the mass matrix, when consistent)
  double bytes = 0;               ///< the total, with the process's fixed footprint
  double dt = 0;                  ///< simulation.dt, or the first CFL step
  double steps = 0;               ///< t_end / dt, rounded up
};

/// The estimate for a scene that validate_scene accepts.
ResourceEstimate estimate_resources(const Scene& scene);

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
/// exceed simulation.max_steps.
void check_resources(const Scene& scene);

/// Throws InputError, naming `what` (the option that gives the nodes, e.g.
/// "--cells 5000 in 3D"), when a node set built outside a scene (`otmpm
/// basis`, the Python otmpm.basis) would have more than kMaxSceneNodes nodes
/// or not fit in available_memory() at about 1 kB per node (the nodes with
/// the basis' neighbour search, generously): the scene's cap, before anything
/// is allocated.
void check_node_count(double nodes, const std::string& what);

} // namespace otmpm
