#pragma once
/// \file local_parts.hpp
/// The engine parts of one rank of a distributed run: every rank runs the
/// assembler (so a bad scene fails on every rank alike) but seeds only the
/// particles of its own cells - a counting pass over the seeding gives the
/// particles per cell for the RCB of the cells, a second pass keeps the
/// particles of this rank's cells, in global order (their index in the
/// serial seeding) - then the basis is built on its window of the point
/// lattice only (never the whole lattice: a probe on a few cells tells the
/// family's reach) with the Dirichlet entries found on the window's points,
/// and the Domain that ties the ranks together. Traction loads act on surface particles found
/// among all particles in the counting pass. With one rank the scene's
/// parts are returned unchanged (a serial run, bit for bit).
#include "otmpm/distributed/domain.hpp"
#include "otmpm/scene/scene.hpp"
#include "otmpm/state.hpp"

namespace otmpm::distributed {

/// This rank's parts of `scene`. InputError for a scene that cannot run, or
/// that cannot be split over the ranks, or when a rank's share would need
/// more memory than it may use (check_rank_resources: checked once the
/// decomposition is known, before the particles are kept).
template <int D> EngineParts<D> rank_parts(const Scene& scene, const Comm& comm);
/// rank_parts with a Domain also on one rank (where rank_parts gives the
/// serial parts): such an engine counts the halo exchanges and reductions a
/// step of a distributed run makes (DomainStats), on one process.
template <int D> EngineParts<D> seeded_parts(const Scene& scene, const Comm& comm);

/// What one rank of a distributed run holds, known from the decomposition
/// before anything is allocated.
struct RankShare {
  long long particles = 0; ///< its particles (counted while seeding, before any is kept)
  long long points = 0;    ///< the lattice points of its window: its own and its ghosts
  long long ghosts = 0;    ///< of them, the points other ranks own
  /// Points whose values it sends in one nodal exchange: its ghosts'
  /// partial sums to their owners, then its own points' totals to the
  /// ranks that hold them as ghosts (halo.hpp).
  long long halo = 0;
  int neighbours = 0; ///< ranks it exchanges nodal values with
};

/// A neighbour in the nodal exchange and the points sent to it: in the
/// first round the ghosts it owns, in the second the own points it holds as
/// ghosts (halo.hpp).
struct HaloLink {
  int rank = 0;
  long long ghosts = 0, shared = 0;
};

/// The decomposition of a run: its particles and lattice points, and each rank's share.
struct RankPlan {
  long long particles = 0; ///< of all ranks
  long long points = 0;    ///< of the whole lattice
  std::vector<RankShare> ranks;
  std::vector<HaloLink> links; ///< this rank's neighbours, ascending
};

/// The shares of `scene` on the ranks of `comm` as a run divides it - the
/// seeding's counting pass, the bisection and the basis' point lattice
/// (from a probe of a few cells) - without seeding a particle or building
/// a node (`otmpm run --check` under mpirun). Collective; InputError as the
/// run's set-up makes it up to that point, on every rank alike (a rank's
/// memory too: check_rank_resources).
template <int D> RankPlan plan_ranks(const Scene& scene, const Comm& comm);

/// This rank's parts of a restart of `scene` from checkpoint `ck` (its head
/// with its open file, or all of it in memory), seeding nothing: on as
/// many ranks as the checkpoint's run, that run's decomposition and each
/// rank its own rows of the file (the same bits as the run would have
/// given); on another rank count, the cells bisected afresh from the
/// particles' home cells, each rank reading 1/N of the rows and sending
/// them to their owners. `rows` gets the checkpoint's head and this rank's
/// particle rows, in the order of its particles (for local_checkpoint).
/// Collective; InputError for a checkpoint that does not fit the scene.
template <int D>
EngineParts<D> restart_parts(const Scene& scene, const Comm& comm, const Checkpoint& ck, Checkpoint& rows);

/// InputError naming checkpoint `ck` when its run laid the nodes out anew
/// (simulation.node_reset) on another number of ranks than `ranks` (1: a
/// serial run) and `rows`, its particle rows, hold no home cells
/// (nodes/home_cell): a checkpoint of an older otmpm, whose F-bar patches
/// are numbered per rank and whose particles cannot be divided afresh.
template <int D> void require_reset_homes(const Checkpoint& ck, const Checkpoint& rows, int ranks);

/// The Domain of an engine, or null for a serial engine.
template <int D> const Domain<D>* domain_of(const Engine<D>& e) {
  return dynamic_cast<const Domain<D>*>(e.distribution());
}

} // namespace otmpm::distributed
