// Memory and step-count estimates of a scene, and the limits a run checks
// before it allocates anything (see resources.hpp).
#include "otmpm/scene/resources.hpp"

#include "otmpm/basis/kinds.hpp"
#include "otmpm/materials/elasticity.hpp"
#include "otmpm/scene/validate.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <string>

namespace otmpm {

namespace {

/// Bytes per particle (kParticleBytes, per dimension D - 1) and per entry of
/// its stencil (kStencilEntryBytes), and per node, fitted to the peak
/// resident memory of `otmpm run` with the linear and LME bases, 1e5 to 4e6
/// particles and 1e4 to 1e6 nodes (docs/stability.md, "What a run may
/// cost"); the estimate multiplies them by kSafety.
constexpr std::array<double, 3> kParticleBytes = {70, 115, 245};
constexpr double kStencilEntryBytes = 60;
constexpr double kNodeBytes = 260;
/// Bytes per entry of a step's scatter plan over compact rows: at most the
/// dense blocked scatter's buffers (14 B per entry in 3D) or the column
/// gather's transposed nodes and particles (8 B; engine/scatter.hpp).
constexpr double kPlanEntryBytes = 14;
/// Bytes per entry of the LDL^T factor of the consistent mass matrix.
constexpr double kFactorEntryBytes = 12;
/// Nodal vectors of D doubles of the conjugate gradients that solve the
/// consistent mass of a distributed run (mask, solution, residual,
/// preconditioned residual, direction, product: Domain::solve_consistent_mass).
constexpr double kCgVectors = 6;
/// The footprint of the process before the scene (libraries, HDF5, buffers).
constexpr double kBaseBytes = 30e6;
/// Factor on the fitted costs: the estimate stays above what was measured.
constexpr double kSafety = 1.25;

/// The support radius, in units of h, of a basis family whose particles
/// see `stencil` lattice nodes: half the width of the cube of a tensor-product
/// family (1 linear, 1.5 quadratic, 2 cubic), the radius of the D-ball of a
/// family that searches the nodes within a radius (lme, lme_box, maxent).
double support_radius(const BasisKind& kind, double stencil, int dim) {
  if (!kind.searches_nodes) return 0.5 * std::pow(stencil, 1.0 / dim);
  return dim == 1 ? 0.5 * stencil
         : dim == 2 ? std::sqrt(stencil / std::numbers::pi)
                    : std::cbrt(3.0 * stencil / (4.0 * std::numbers::pi));
}

/// Entries of the LDL^T factor of the consistent mass matrix: n nodes times
/// the profile of a lattice ordered row by row (n^(1 - 1/D) nodes per layer
/// times the 2 r + 1 layers a node couples to). Measured fill stays below it.
double factor_entries(double nodes, double radius, int dim) {
  const double band = std::pow(nodes, 1.0 - 1.0 / dim) * (2 * radius + 1);
  return nodes * std::min(nodes, band);
}

/// The bytes per particle of the compact rows a run of the scene in `ranks`
/// processes keeps instead of a basis table (BasisKind::compact_row_bytes),
/// or 0: on a Cartesian lattice, where no pass reads a table (TableReaders).
double compact_row_bytes(const Scene& s, const BasisKind& kind, int ranks) {
  const TableReaders readers{.nodes_move = s.simulation.nodes_move(),
                             .ranks = ranks > 1,
                             .contact = s.contact.has_value(),
                             .two_phase = saturated(s),
                             .fbar = volumetric_treatment(s) != "none",
                             .consistent_mass = uses_consistent_mass(s),
                             .side_walls = s.channel.has_value()};
  if (!kind.compact_row_bytes || s.grid.kind != "cartesian" || !readers.none()) return 0.0;
  return kind.compact_row_bytes(s.basis, s.simulation.dimension);
}

/// Smallest grid spacing over the scene's axes.
double min_spacing(const Scene& s) {
  double h = INFINITY;
  for (int k = 0; k < s.simulation.dimension; ++k) h = std::min(h, (s.grid.upper[k] - s.grid.lower[k]) / s.grid.cells[k]);
  return h;
}

/// The square of the first `dim` components of v, or 0 when it overflows:
/// such a state is not a long run but an instability at t = 0, which the run reports.
double speed2(const Vec3& v, int dim) {
  double v2 = 0;
  for (int k = 0; k < dim; ++k) v2 += v[k] * v[k];
  return std::isfinite(v2) ? v2 : 0.0;
}

/// The steps of a run whose steps are `dt` (INFINITY when dt underflowed to 0 or c overflowed).
double step_count(const Scene& s, double dt) {
  const double steps = std::ceil(s.simulation.t_end / dt);
  return std::isfinite(steps) ? steps : INFINITY;
}

/// InputError when `steps` exceed simulation.max_steps: `dt` is the step
/// they come from, `origin` what gave it (", from ..." or "").
void check_steps(const Scene& s, double steps, double dt, const std::string& origin) {
  if (steps <= s.simulation.max_steps) return;
  const bool fixed = s.simulation.dt.has_value();
  input_error(s.locate(fixed ? "simulation.dt" : "simulation.cfl"),
              "the run would take about " + format_number(steps) + " steps (t_end = " +
                  format_number(s.simulation.t_end) + " s over a " + (fixed ? "fixed" : "first CFL") +
                  " step dt = " + format_number(dt) + " s" + origin + "), more than simulation.max_steps = " +
                  format_number(s.simulation.max_steps) + " (set it higher to run anyway)");
}

/// The cgroup v2 memory limit of this process in bytes, or INFINITY.
double cgroup_limit() {
  std::ifstream in("/sys/fs/cgroup/memory.max");
  std::string value;
  if (!(in >> value) || value == "max") return INFINITY;
  try {
    return std::stod(value);
  } catch (const std::exception&) {
    return INFINITY;
  }
}

/// InputError when estimate `e` exceeds memory_limit(scene): "WHO about X of
/// memory (WHAT: the particles and nodes with their costs; ALL), more than the limit ...".
void refuse_memory(const Scene& scene, const ResourceEstimate& e, const std::string& who, const std::string& what = "",
                   const std::string& all = "") {
  const double limit = memory_limit(scene);
  if (e.bytes <= limit) return;
  const bool set = scene.simulation.memory_limit > 0;
  input_error(scene.locate("simulation.memory_limit"),
              who + " about " + format_bytes(e.bytes) + " of memory (" + what + format_number(e.particles) +
                  " particles x " + format_bytes(e.bytes_per_particle) + " with the " + scene.basis.kind + " basis, " +
                  format_number(e.nodes) + " nodes x " + format_bytes(e.bytes_per_node) + all + "), more than the limit of " + format_bytes(limit) +
                  (set ? " set by simulation.memory_limit"
                       : " this process may use (physical memory; set simulation.memory_limit in bytes to override)"));
}

} // namespace

double max_wave_speed(const Scene& s) {
  const int dim = s.simulation.dimension;
  double c2 = 0;
  for (const MaterialSection& ms : s.materials) {
    const ElasticConstants m = ms.elastic();
    c2 = std::max(c2, m.p_modulus(dim) / m.density);
  }
  for (const BodySection& b : s.bodies) {
    c2 = std::max({c2, speed2(b.velocity, dim), b.file_max_speed * b.file_max_speed});
    if (!(b.file_min_density > 0)) continue;
    for (const MaterialSection& ms : s.materials)
      if (ms.name == b.material) c2 = std::max(c2, ms.elastic().p_modulus(dim) / b.file_min_density);
  }
  for (const InitialVelocitySection& iv : s.initial_velocities) c2 = std::max(c2, speed2(iv.velocity, dim));
  return std::sqrt(c2);
}

ResourceEstimate estimate_resources(const Scene& scene) { return estimate_resources(scene, scene_size(scene)); }

ResourceEstimate estimate_resources(const Scene& scene, const SceneSize& share, int ranks) {
  const int dim = scene.simulation.dimension;
  const std::size_t d = static_cast<std::size_t>(std::clamp(dim, 1, 3) - 1);
  ResourceEstimate e;
  e.particles = share.particles;
  e.nodes = share.nodes;
  const BasisKind& kind = basis_kind(scene.basis.kind);
  e.stencil = kind.stencil_nodes(scene.basis, dim);
  const double compact = compact_row_bytes(scene, kind, ranks);
  e.bytes_per_particle = kSafety * (kParticleBytes[d] + (compact > 0 ? compact + e.stencil * kPlanEntryBytes
                                                                     : e.stencil * kStencilEntryBytes));
  e.bytes_per_node = kSafety * kNodeBytes;
  if (uses_consistent_mass(scene) && ranks > 1)
    e.bytes_per_node += kSafety * kCgVectors * dim * sizeof(double);
  else if (uses_consistent_mass(scene) && e.nodes > 0)
    e.bytes_per_node += kFactorEntryBytes * factor_entries(e.nodes, support_radius(kind, e.stencil, dim), dim) / e.nodes;
  e.bytes = kBaseBytes + e.particles * e.bytes_per_particle + e.nodes * e.bytes_per_node;
  // A gravity-loading phase runs its own engine beside the run's (run/initial_equilibrium.hpp).
  if (scene.simulation.initial_equilibrium) e.bytes += e.particles * e.bytes_per_particle + e.nodes * e.bytes_per_node;
  e.wave_speed = max_wave_speed(scene);
  e.dt = scene.simulation.dt ? *scene.simulation.dt : scene.simulation.cfl * min_spacing(scene) / e.wave_speed;
  e.steps = step_count(scene, e.dt);
  return e;
}

double available_memory() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  double limit = pages > 0 && page > 0 ? static_cast<double>(pages) * static_cast<double>(page) : INFINITY;
  limit = std::min(limit, cgroup_limit());
  struct rlimit as {};
  if (::getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY)
    limit = std::min(limit, static_cast<double>(as.rlim_cur));
  return limit;
}

double memory_limit(const Scene& scene) {
  return scene.simulation.memory_limit > 0 ? scene.simulation.memory_limit : available_memory();
}

std::string format_bytes(double bytes) {
  const char* units[] = {"B", "kB", "MB", "GB", "TB", "PB"};
  int u = 0;
  while (bytes >= 1000 && u < 5) {
    bytes /= 1000;
    ++u;
  }
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.3g %s", bytes, units[u]);
  return buf;
}

ResourceEstimate estimate_even_share(const Scene& scene, int processes) {
  const int P = std::max(processes, 1);
  SceneSize even = scene_size(scene);
  even.particles = std::ceil(even.particles / P), even.nodes = std::ceil(even.nodes / P);
  return estimate_resources(scene, even, P);
}

void check_resources(const Scene& scene, int processes) {
  const int P = std::max(processes, 1);
  const ResourceEstimate whole = estimate_resources(scene);
  const ResourceEstimate e = P > 1 ? estimate_even_share(scene, P) : whole;
  if (P == 1) refuse_memory(scene, e, "the run would need");
  else
    refuse_memory(scene, e, "each of the " + std::to_string(P) + " ranks would need at least",
                  "1/" + std::to_string(P) + " of the scene: ",
                  "; all ranks together at least " + format_bytes(P * e.bytes));
  check_steps(scene, whole.steps, whole.dt,
              scene.simulation.dt ? "" : ", from the fastest wave speed " + format_number(whole.wave_speed) + " m/s");
}

void check_rank_resources(const Scene& scene, const SceneSize& share, int rank, int ranks, double total_bytes) {
  refuse_memory(scene, estimate_resources(scene, share, ranks),
                "rank " + std::to_string(rank) + " of " + std::to_string(ranks) + " would need",
                "its share of the decomposition: ",
                " with its ghosts; all ranks together about " + format_bytes(total_bytes));
}

void check_before_allocating(const Scene& scene, int dimension, int processes) {
  validate_scene(scene, dimension, processes);
  check_resources(scene, processes);
}

void check_first_step(const Scene& scene, double dt, double c) {
  if (!(dt > 0.0) || !std::isfinite(c)) return; // not a long run: the first step reports the instability
  check_steps(scene, step_count(scene, dt), dt,
              c > 0 ? ", from the seeded particles' fastest wave or particle speed " + format_number(c) + " m/s" : "");
}

void check_node_count(double nodes, const std::string& what) {
  constexpr double kBytesPerNode = 1000;
  if (!(nodes <= kMaxRankNodes))
    throw InputError(what + " gives " + format_number(nodes) + " nodes, more than " + format_number(kMaxRankNodes));
  if (nodes * kBytesPerNode > available_memory())
    throw InputError(what + " needs about " + format_bytes(nodes * kBytesPerNode) + " of memory; " +
                     format_bytes(available_memory()) + " are available");
}

} // namespace otmpm
