#pragma once
/// \file share_seeding.hpp
/// A rank's particles of a distributed run, seeded once and only in its
/// own cells (docs/architecture.md, "Distributed runs"):
///
/// 1. counting: the seeding cells of the bodies seeded cell by cell (boxes,
///    shapes on the lattice: assembly/seeding.hpp, BodyCells) are split
///    into N contiguous ranges, one per rank; each rank goes through its
///    range (with every check of the serial seeding: shapes, overlaps) and
///    counts the particles placed per seeding cell - kept as runs of equal
///    counts, shared by all ranks (CellRuns: a body of equal cells is one
///    run) - and per home cell (the weights of the bisection, as runs of
///    cells along axis 0); a run of cells whose particles all lie inside the
///    shape, in no earlier body and behind no wall (Shape::side,
///    WallSides::clear) is counted without generating its particles
///    (TakeRun: their home cells from their coordinates axis by axis), the
///    cells cutting a boundary particle by particle - the same counts; a
///    file or mesh body is read by every rank, which counts 1/N of its rows;
/// 2. the traction loads' surface particles (only with traction loads): the
///    ranks visit their ranges again, now numbered, and merge the columns;
/// 3. keeping: each rank generates the seeding cells near its own cells and
///    keeps the particles whose home cell it owns, with their global ids
///    (their index in the serial seeding order) from the runs.
///
/// The first error in the serial seeding order is the one every rank
/// reports, whichever rank met it.
#include "otmpm/assembly/seeding.hpp"
#include "otmpm/distributed/decomposition.hpp"

#include <exception>
#include <functional>

namespace otmpm::distributed {

/// What share_seeding gives besides the particles: the decomposition of the
/// cells (or the error that the bisection raised, deferred: it is raised
/// after the assembly, as when the whole scene was assembled first), the
/// particles of all ranks and, per rank, its particle count.
template <int D> struct ShareSeeding {
  Decomposition<D> decomposition;
  std::exception_ptr deferred;
  long long particles = 0;
  std::vector<std::int64_t> per_rank;
};

/// Called on every rank once the decomposition and the particles per rank
/// are known (ShareSeeding), before anything is kept: a check of each
/// rank's share (its memory), or the report of a decomposition that stops
/// there (false: nothing is seeded).
template <int D> using BeforeKeeping = std::function<bool(const ShareSeeding<D>&)>;

/// How the counting pass counts: runs of cells whose particles are all
/// placed at once (`runs`), or every particle generated (`seeds`: the
/// reference the runs must equal, for tests).
enum class CountBy { runs, seeds };

/// This rank's particles of `scene` (cells of spacing h, the node lattice
/// `lattice`; SeededBodies::ids their global ids, SeededBodies::surfaces the traction
/// loads' surface particles). Collective; InputError (on every rank alike)
/// for a scene that cannot be seeded, and when a rank would hold more than
/// kMaxRankParticles. `before_keeping` (when given): see BeforeKeeping;
/// it is not called when the bisection failed (ShareSeeding::deferred).
template <int D>
SeededBodies<D> share_seeding(const Scene& scene, const Comm& comm, const Vec<D>& h, const CartesianGrid<D>& lattice,
                              ShareSeeding<D>& out, const BeforeKeeping<D>& before_keeping = nullptr,
                              CountBy count_by = CountBy::runs);

} // namespace otmpm::distributed
