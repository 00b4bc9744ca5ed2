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
/// that cannot be split over the ranks.
template <int D> EngineParts<D> rank_parts(const Scene& scene, const Comm& comm);

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

/// The Domain of an engine, or null for a serial engine.
template <int D> const Domain<D>* domain_of(const Engine<D>& e) {
  return dynamic_cast<const Domain<D>*>(e.distribution());
}

} // namespace otmpm::distributed
