// check_scene() (run.hpp): what `otmpm run --check` prints about a scene
// without running it, after the checks a run makes, in the run's order.
#include "otmpm/assembly/assembler.hpp"
#include "otmpm/assembly/seeding.hpp"
#include "otmpm/distributed/global_view.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/scene/file_bodies.hpp"
#include "otmpm/scene/resources.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

namespace otmpm {

namespace {

using Clock = std::chrono::steady_clock;

/// Particles of the calibration block (StepTime), about: as many as the
/// busiest rank holds (the cost per particle grows once the particles no
/// longer fit in the caches), within these bounds.
constexpr double kCalibrationMin = 512, kCalibrationMax = 32768;
/// The calibration steps: two not timed (the first basis evaluation, the
/// warm starts), then timed until kCalibrationSeconds have passed, at least
/// kCalibrationMinSteps and at most kCalibrationMaxSteps.
constexpr int kCalibrationWarmup = 2, kCalibrationMinSteps = 5, kCalibrationMaxSteps = 200;
constexpr double kCalibrationSeconds = 0.2;
/// t_end of the calibration block: never reached.
constexpr double kCalibrationEnd = 1e300;
/// Rounds of a step's communication timed (StepTime::comm_rounds).
constexpr int kCommRounds = 20;

double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

/// The calibration block of `s` (StepTime), of about `particles` particles
/// (at least two cells per axis): the dimension, mode, integrator, basis,
/// mass, materials and grid spacing of `s`; one box body of the first
/// body's material and particles per cell (2 for a file or mesh body) with
/// two spare cells on each side, deforming from a smooth initial velocity
/// along axis 0 (profile sin_x, 0.1 % of the fastest wave speed).
Scene calibration_scene(const Scene& s, double particles) {
  Scene c;
  c.file = s.file;
  c.simulation = s.simulation;
  c.simulation.t_end = kCalibrationEnd;
  c.simulation.memory_limit = 0.0;          // a small block: the process's own limit
  c.simulation.energy_limit = kCalibrationEnd; // its cost is timed, not its physics
  c.basis = s.basis;
  c.basis_where = s.basis_where;
  c.materials = s.materials;
  c.grid = s.grid;
  const int dim = s.simulation.dimension;
  const BodySection& first = s.bodies.front();
  BodySection b;
  b.name = "calibration";
  b.material = first.material;
  const bool lattice = first.shape != "file" && first.shape != "mesh";
  b.particles_per_cell = lattice ? first.particles_per_cell : 2;
  b.placement = lattice ? first.placement : "gauss";
  const double cells = std::max(2.0, std::round(std::pow(particles / std::pow(b.particles_per_cell, dim), 1.0 / dim)));
  for (int k = 0; k < dim; ++k) {
    const double h = (s.grid.upper[k] - s.grid.lower[k]) / s.grid.cells[k];
    c.grid.cells[k] = static_cast<int>(cells) + 4;
    c.grid.upper[k] = c.grid.lower[k] + c.grid.cells[k] * h;
    b.lower[k] = c.grid.lower[k] + 2 * h;
    b.upper[k] = c.grid.lower[k] + (cells + 2) * h;
  }
  b.velocity[0] = 1e-3 * max_wave_speed(s);
  b.velocity_profile = "sin_x";
  c.bodies = {b};
  return c;
}

/// Times kCalibrationWarmup + n steps of the calibration block of about
/// `particles` particles on one rank with a Domain (which counts its
/// exchanges and reductions) into `t`.
template <int D> void time_block(const Scene& scene, double particles, StepTime& t) {
  particles = std::clamp(particles, kCalibrationMin, kCalibrationMax);
  Engine<D> e(distributed::seeded_parts<D>(calibration_scene(scene, particles), distributed::Comm::self()));
  for (int i = 0; i < kCalibrationWarmup; ++i) e.step();
  const distributed::DomainStats before = distributed::domain_of(e)->stats();
  const double nodal_before = e.timers()[Phase::nodal_update];
  const Clock::time_point start = Clock::now();
  int n = 0;
  while (n < kCalibrationMinSteps || (n < kCalibrationMaxSteps && seconds_since(start) < kCalibrationSeconds)) {
    e.step();
    ++n;
  }
  const double wall = seconds_since(start), nodal = e.timers()[Phase::nodal_update] - nodal_before;
  const distributed::DomainStats& after = distributed::domain_of(e)->stats();
  t.calibration_particles = e.particles().size();
  t.calibration_steps = n;
  t.per_particle = (wall - nodal) / (n * static_cast<double>(e.particles().size()));
  t.per_node = nodal / (n * static_cast<double>(e.basis().nodes().size()));
  t.exchanges = static_cast<double>(after.halo_exchanges - before.halo_exchanges) / n;
  t.reductions = static_cast<double>(after.reductions - before.reductions) / n;
}

/// Seconds per step of a step's communication on this rank: its nodal
/// exchanges with its neighbours (`links`, `width` doubles per point) and
/// its reductions, done kCommRounds times (collective); the slowest rank's.
double time_communication(const distributed::Comm& comm, const std::vector<distributed::HaloLink>& links, int width,
                          const StepTime& t) {
  std::vector<int> first, second; // the ranks this rank sends to in each round (and receives from in the other)
  std::vector<distributed::Bytes> ghosts, shared;
  for (const distributed::HaloLink& l : links) {
    const auto bytes = [&](long long points) { return distributed::Bytes(static_cast<std::size_t>(points * width) * 8); };
    if (l.ghosts > 0) first.push_back(l.rank), ghosts.push_back(bytes(l.ghosts));
    if (l.shared > 0) second.push_back(l.rank), shared.push_back(bytes(l.shared));
  }
  const int exchanges = static_cast<int>(std::ceil(t.exchanges)), reductions = static_cast<int>(std::ceil(t.reductions));
  comm.barrier();
  const Clock::time_point start = Clock::now();
  for (int round = 0; round < kCommRounds; ++round) {
    for (int i = 0; i < exchanges; ++i) {
      comm.exchange(first, ghosts, second);
      comm.exchange(second, shared, first);
    }
    for (int i = 0; i < reductions; ++i) {
      double sums[8] = {}, maxima[4] = {};
      comm.reduce(sums, maxima);
    }
  }
  return comm.max(seconds_since(start) / kCommRounds);
}

/// The expected step time of the run that `plan` divides (StepTime;
/// collective). A calibration that fails is reported, not thrown.
template <int D> StepTime step_time(const Scene& scene, const distributed::RankPlan& plan) {
  const distributed::Comm& comm = distributed::Comm::world();
  StepTime t;
  std::string error;
  double busiest = 0.0;
  for (const distributed::RankShare& r : plan.ranks) busiest = std::max(busiest, static_cast<double>(r.particles));
  try {
    time_block<D>(scene, busiest, t);
  } catch (const std::exception& e) {
    error = e.what();
  }
  const int failed = static_cast<int>(comm.min(static_cast<std::int64_t>(error.empty() ? comm.size() : comm.rank())));
  if (failed < comm.size()) {
    t.why_not = "rank " + std::to_string(failed) + ": " + comm.broadcast(error, failed);
    return t;
  }
  const distributed::RankShare& mine = plan.ranks[static_cast<std::size_t>(comm.rank())];
  const double compute = t.per_particle * mine.particles + t.per_node * mine.points;
  t.compute = comm.max(compute);
  t.busiest = static_cast<int>(comm.min(static_cast<std::int64_t>(compute == t.compute ? comm.rank() : comm.size())));
  double rates[2] = {t.per_particle, t.per_node};
  comm.broadcast(rates, sizeof rates, t.busiest);
  t.per_particle = rates[0], t.per_node = rates[1];
  t.comm_rounds = kCommRounds;
  t.communication = time_communication(comm, plan.links, 1 + 2 * D, t);
  t.seconds = t.compute + t.communication;
  t.calibrated = true;
  return t;
}

/// The decomposition `plan` of the scene over `ranks` ranks and each
/// rank's estimates in `c` (SceneCheck::ranks).
template <int D> void report_plan(const Scene& scene, const distributed::RankPlan& plan, int ranks, SceneCheck& c) {
  const ResourceEstimate whole = estimate_resources(scene);
  c.dt = whole.dt;
  c.particles = plan.particles;
  c.nodes = plan.points;
  c.estimated_steps = whole.steps;
  c.memory_bytes = 0.0;
  for (const distributed::RankShare& r : plan.ranks) {
    SceneSize share;
    share.particles = static_cast<double>(r.particles), share.nodes = static_cast<double>(r.points);
    const double bytes = estimate_resources(scene, share, ranks).bytes;
    c.ranks.push_back({r.particles, r.points, r.ghosts, r.neighbours, 8.0 * (1 + 2 * D) * r.halo, bytes});
    c.memory_bytes += bytes;
  }
}

/// The compute part of the step time of the run that `plan` divides, from
/// one calibration in this process (StepTime with comm_rounds 0: the
/// communication is not timed without the ranks). A calibration that
/// fails is reported, not thrown.
template <int D> StepTime planned_step_time(const Scene& scene, const distributed::RankPlan& plan) {
  StepTime t;
  double busiest = 0.0;
  for (const distributed::RankShare& r : plan.ranks) busiest = std::max(busiest, static_cast<double>(r.particles));
  try {
    time_block<D>(scene, busiest, t);
  } catch (const std::exception& e) {
    t.why_not = e.what();
    return t;
  }
  for (std::size_t r = 0; r < plan.ranks.size(); ++r) {
    const double compute = t.per_particle * plan.ranks[r].particles + t.per_node * plan.ranks[r].points;
    if (compute > t.compute) t.compute = compute, t.busiest = static_cast<int>(r);
  }
  t.seconds = t.compute;
  t.calibrated = true;
  return t;
}

/// run --check under mpirun: the decomposition and the estimates of each
/// rank, nothing allocated (SceneCheck).
template <int D> SceneCheck check_ranks(const Scene& scene, SceneCheck c) {
  const distributed::Comm& comm = distributed::Comm::world();
  const distributed::RankPlan plan = distributed::plan_ranks<D>(scene, comm);
  report_plan<D>(scene, plan, comm.size(), c);
  c.step_time = step_time<D>(scene, plan);
  return c;
}

/// run --check --ranks N in one process: the decomposition a run on
/// `ranks` ranks computes, found by `ranks` ranks played in this process
/// (Comm::run_local: fibers on a few threads, each with one OpenMP thread), nothing allocated;
/// the step time from one calibration here, without the communication.
template <int D> SceneCheck check_planned_ranks(const Scene& scene, SceneCheck c, int ranks) {
  distributed::RankPlan plan;
  distributed::Comm::run_local(ranks, [&](const distributed::Comm& comm) {
#ifdef OTMPM_HAVE_OPENMP
    omp_set_num_threads(1); // the threads play the ranks: no OpenMP team inside a rank
#endif
    distributed::RankPlan mine = distributed::plan_ranks<D>(scene, comm);
    if (comm.root()) plan = std::move(mine);
  });
  report_plan<D>(scene, plan, ranks, c);
  c.step_time = planned_step_time<D>(scene, plan);
  return c;
}

/// The set-up of this rank's engine (the whole scene in one process), as
/// the run sets it up, and the step-count check on its first step.
template <int D> SceneCheck check_dim(const Scene& scene, SceneCheck c) {
  const Engine<D> e(distributed::rank_parts<D>(scene, distributed::Comm::world()));
  const distributed::GlobalView<D> view(e);
  c.dt = e.stable_dt();
  check_first_step(scene, c.dt, e.wave_speed());
  c.particles = view.particles();
  c.nodes = view.nodes();
  c.estimated_steps = std::ceil(c.t_end / c.dt * (1.0 - 1e-9));
  if (const auto& q = scene.simulation.initial_equilibrium) c.phase_steps = std::ceil(q->time / c.dt * (1.0 - 1e-9));
  c.volumes = body_volumes<D>(scene, e);
  return c;
}

} // namespace

template <int D> std::vector<BodyVolume> body_volumes(const Scene& scene, const Engine<D>& e) {
  std::vector<double> seeded(scene.bodies.size(), 0.0);
  const Particles<D>& P = e.particles();
  for (int p = 0; p < P.size(); ++p) seeded[static_cast<std::size_t>(P.body[p])] += P.V0[p];
  if (Distribution<D>* d = e.distribution()) d->sum(seeded);
  std::vector<BodyVolume> out;
  for (std::size_t b = 0; b < scene.bodies.size(); ++b)
    out.push_back({scene.bodies[b].name, scene.bodies[b].shape, seeded[b], body_measure<D>(scene.bodies[b])});
  return out;
}

template std::vector<BodyVolume> body_volumes<1>(const Scene&, const Engine<1>&);
template std::vector<BodyVolume> body_volumes<2>(const Scene&, const Engine<2>&);
template std::vector<BodyVolume> body_volumes<3>(const Scene&, const Engine<3>&);

SceneCheck check_scene(const Scene& scene, int planned_ranks) {
  const int D = scene.simulation.dimension;
  if (D < 1 || D > 3)
    input_error(scene.locate("simulation.dimension"), "dimension must be 1, 2 or 3, got " + std::to_string(D));
  // the run's checks, before anything is allocated (the ranks agree, as in the run)
  const int world = distributed::Comm::world().size();
  if (planned_ranks > 0 && world > 1 && planned_ranks != world)
    throw InputError("--ranks " + std::to_string(planned_ranks) + " under mpirun with " + std::to_string(world) +
                     " ranks: under mpirun run --check divides the scene over the ranks it runs on (leave --ranks "
                     "out, or run without mpirun)");
  const int ranks = world > 1 ? world : std::max(planned_ranks, 1);
  distributed::agree_on(distributed::Comm::world(), [&] { check_before_allocating(scene, D, ranks); });
  SceneCheck c;
  c.dimension = D;
  c.mode = scene.simulation.mode;
  c.integrator = scene.simulation.integrator;
  c.basis = scene.basis.kind;
  c.t_end = scene.simulation.t_end;
  c.memory_bytes = estimate_resources(scene).bytes;
  c.memory_limit = memory_limit(scene);
  c.out_file = scene.output.file;
  if (world > 1) switch (D) {
    case 1: return check_ranks<1>(scene, c);
    case 2: return check_ranks<2>(scene, c);
    default: return check_ranks<3>(scene, c);
    }
  if (ranks > 1) switch (D) {
    case 1: return check_planned_ranks<1>(scene, c, ranks);
    case 2: return check_planned_ranks<2>(scene, c, ranks);
    default: return check_planned_ranks<3>(scene, c, ranks);
    }
  switch (D) {
  case 1: return check_dim<1>(scene, c);
  case 2: return check_dim<2>(scene, c);
  default: return check_dim<3>(scene, c);
  }
}

} // namespace otmpm
