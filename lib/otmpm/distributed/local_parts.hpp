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

namespace otmpm::distributed {

/// This rank's parts of `scene`. `positions`, when given, are the current
/// positions of all particles in global order (a restart: they decide the
/// home cells in `mpm` mode instead of the seeded positions). InputError
/// for a scene that cannot run, or that cannot be split over the ranks.
template <int D>
EngineParts<D> rank_parts(const Scene& scene, const Comm& comm, const AlignedVector<Vec<D>>* positions = nullptr);

/// The Domain of an engine, or null for a serial engine.
template <int D> const Domain<D>* domain_of(const Engine<D>& e) {
  return dynamic_cast<const Domain<D>*>(e.distribution());
}

} // namespace otmpm::distributed
