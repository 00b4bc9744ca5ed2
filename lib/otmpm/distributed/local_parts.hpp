#pragma once
/// \file local_parts.hpp
/// The engine parts of one rank of a distributed run: the scene is
/// assembled as a whole on every rank (the same parts everywhere, so a bad
/// scene fails on every rank alike), the cells are decomposed by RCB over
/// the particles' home cells, and the parts are cut to this rank's share -
/// the particles of its cells in global order, the basis on its window of
/// the point lattice, the Dirichlet entries and traction particles inside
/// it - with the Domain that ties the ranks together. With one rank the
/// scene's parts are returned unchanged (a serial run, bit for bit).
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
