#pragma once
/// \file seeding.hpp
/// The particles of a scene's bodies (seeding.cpp). Internal to assembly/ and
/// the distributed set-up (distributed/local_parts.cpp, which seeds a rank's share).
#include "otmpm/geometry/box_cells.hpp"
#include "otmpm/nodes/node_set.hpp"
#include "otmpm/particles/particles.hpp"
#include "otmpm/scene/scene.hpp"

#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace otmpm {

/// The first D components of a scene vector (scene values are stored with 3).
template <int D> Vec<D> scene_vec(const Vec3& v) {
  Vec<D> out;
  for (int k = 0; k < D; ++k) out[k] = v[k];
  return out;
}

/// Per-particle values of a particle file's column that is not a position,
/// volume, velocity or density: the initial value of a material state
/// variable of that name, for the particles of `body` (particle p's value:
/// values[file_row[p]]; seed_bodies holds every row of the file,
/// seed_bodies_where the rows of the particles it keeps only).
struct FileState {
  std::string name;
  int body = 0;
  std::vector<double> values;
};

/// The axis a traction load acts along (its faces' normal): `axis` when
/// given, 0 for wobbes_traction_bar, else the largest component of `value`.
template <int D> int traction_axis(const TractionSection& ts) {
  int axis = 0;
  scene_vec<D>(ts.value).cwiseAbs().maxCoeff(&axis);
  if (ts.function == "wobbes_traction_bar") axis = 0;
  if (ts.axis) axis = *ts.axis;
  return axis;
}

/// The column of a particle at X across `axis`: its other coordinates in
/// units of tol, so that particles seeded on one lattice line share it.
template <int D> std::array<long long, 2> column_key(const Vec<D>& X, int axis, double tol) {
  std::array<long long, 2> key{0, 0};
  for (int k = 0, j = 0; k < D; ++k)
    if (k != axis) key[static_cast<std::size_t>(j++)] = std::llround(X[k] / tol);
  return key;
}

/// The surface particles of the scene's traction loads - per load, the
/// first and the last particle of each column along its axis (the serial
/// rule of the assembler: smallest and largest coordinate, the earlier
/// particle on ties) - found one particle at a time in seeding order, so
/// that a rank that stores only a share of the particles knows which of
/// them are loaded. Holds one entry per column and load.
template <int D> class TractionSurfaces {
public:
  /// For the loads of `scene`, columns told apart at `tol`.
  TractionSurfaces(const Scene& scene, double tol);
  /// Particle `id` (the next in seeding order) at X.
  void visit(long long id, const Vec<D>& X);
  /// After every visit: per load, the ids of its surface particles, sorted.
  void finish();
  /// The columns' ends as bytes (before finish), and the ends of another
  /// share of the particles taken in, as visits of theirs would have been
  /// (the earlier id on ties): the ranks of a distributed run visit their
  /// own particles and then merge.
  std::string pack() const;
  void merge(const std::string& packed);
  /// Whether particle `id` is a surface particle of `load` (after finish).
  bool surface(std::size_t load, long long id) const;
  /// Whether some surface particle of `load` lies in the load's box.
  bool selects(std::size_t load) const { return selects_[load] != 0; }

private:
  struct End {
    long long first = 0, last = 0;
    Vec<D> x_first, x_last;
  };
  std::vector<TractionSection> loads_;
  std::vector<int> axis_;
  double tol_;
  std::vector<std::map<std::array<long long, 2>, End>> ends_;
  std::vector<std::vector<long long>> ids_;
  std::vector<char> selects_;
};

/// The particles that start behind a rigid wall - on the side its normal
/// points away from (docs/theory.md sect. 6.1: the normal points to the
/// material's side), by more than round-off (kBoxTolerance h) - counted per
/// wall and body as the particles are seeded, so that a body the wall would
/// push or hold from its first step is refused at set-up. Each particle
/// comes with its place in the seeding order (`Order`, compared as a pair),
/// so that shares counted apart (the ranks of a distributed run) merge into
/// the counts and first particles of the whole.
template <int D> class WallSides {
public:
  using Order = std::pair<long long, long long>;
  WallSides(const Scene& scene, const Vec<D>& h);
  /// A particle of body `body` at x, at place `at` of the seeding order.
  void visit(const Vec<D>& x, int body, const Order& at);
  /// True when visit() would count no particle in the box [lower, upper]:
  /// it lies on the material side of every wall, by more than rounding.
  bool clear(const Vec<D>& lower, const Vec<D>& upper) const;
  /// InputError at the first wall with particles behind it, naming the
  /// wall, the body, their count and the first of them.
  void refuse() const;
  /// The counts as bytes, and those of another share added in.
  std::string pack() const;
  void merge(const std::string& packed);

private:
  struct Behind {
    long long count = 0;
    Order at{0, 0};
    Vec<D> first = Vec<D>::Zero();
  };
  const Scene& scene_;
  double tol_;
  std::vector<std::pair<Vec<D>, Vec<D>>> walls_; ///< point, unit normal
  std::vector<Behind> behind_;                   ///< per wall and body
};

/// The seeded particles and what their particle files give beyond them.
template <int D> struct SeededBodies {
  Particles<D> particles;
  /// per particle: its index in its body's FileState values (seed_bodies: its row in the file), or -1
  std::vector<int> file_row;
  std::vector<FileState> file_state;
  /// seed_bodies_where: per particle, its index in seed_bodies' order (its global id)
  std::vector<long long> ids;
  /// seed_bodies_where with traction loads: their surface particles among all
  std::shared_ptr<const TractionSurfaces<D>> surfaces;
  /// Instead of `surfaces` (a distributed restart, which seeds nothing): per
  /// traction load, per particle, its share of the loaded area (< 0: not loaded).
  std::vector<std::vector<double>> traction_area;
};

/// The exact measure (volume; area in 2D; length in 1D) of a body's shape,
/// or NaN for a file body (whose particle volumes are its volume).
template <int D> double body_measure(const BodySection& body);

/// The factor that scales the particle volumes `seeded` (their sum) of a
/// body seeded on the lattice to its shape's exact measure `exact`, when
/// the body asks for it (volume = "exact"), else 1. Every shape seeded on
/// the lattice - the ones there are and any added - goes through it.
double volume_factor(const BodySection& body, double seeded, double exact);
/// volume_factor of a body whose placed particles have the volume `seeded`:
/// 1 for a box, a file or a body that keeps its seeded volume.
template <int D> double body_volume_factor(const BodySection& body, double seeded);

/// Seeds every body of the scene (assembler.hpp, seed_particles): boxes on
/// cells of the spacing `h`, other shapes on the cells of `lattice` (their
/// volumes scaled by volume_factor).
template <int D> SeededBodies<D> seed_bodies(const Scene& scene, const Vec<D>& h, const CartesianGrid<D>& lattice);

/// How a body is seeded: a box on cells of the spacing h and a sphere,
/// cylinder, polygon or STL surface on the cells of the node lattice that
/// meet its bounds are seeded cell by cell (`by_cells`: the box [lower,
/// upper] cut into `cells` seeding cells per axis of size `size`, numbered
/// axis 0 fastest; any cell alone gives the bits it gives among all); a
/// file or mesh body as a whole (one "cell").
template <int D> struct BodyCells {
  bool by_cells = false;
  Index<D> cells{};
  Vec<D> lower = Vec<D>::Zero(), upper = Vec<D>::Ones(), size = Vec<D>::Ones();
  /// Seeding cells (1 for a body seeded as a whole).
  long long count() const {
    long long n = 1;
    for (int k = 0; k < D && by_cells; ++k) n *= cells[k];
    return n;
  }
  /// The seeding cells [first, last) per axis whose particles may lie in
  /// the box [lo, hi) (a cell of margin on each side).
  std::pair<Index<D>, Index<D>> near(const Vec<D>& lo, const Vec<D>& hi) const;
};
/// The seeding cells of each body of the scene (as seed_bodies seeds them).
template <int D> std::vector<BodyCells<D>> body_cells(const Scene& scene, const Vec<D>& h, const CartesianGrid<D>& lattice);

/// The seeding cells of a body that a pass generates: those of the box
/// [lo, hi) whose number lies in [from, to).
template <int D> struct CellRange {
  Index<D> lo{}, hi{};
  long long from = 0, to = std::numeric_limits<long long>::max();
};

/// Where a particle of a pass over the bodies comes from: its body, its
/// seeding cell (BodyCells; 0 for a body seeded as a whole) and its index
/// among the particles placed in that cell (of that body).
struct SeedSpot {
  int body = 0;
  long long cell = 0, index = 0;
};

/// Per body of a pass: the particles it generated in the body's shape
/// (none in the whole body is an input error) and those it placed (not
/// dropped by an earlier body: overlap = "first").
struct BodyTally {
  long long generated = 0, placed = 0;
  /// the volume of the particles placed (before volume_factor); of the runs
  /// a pass takes whole (TakeRun), only where body_volume_factor uses it
  double seeded = 0.0;
};

/// A run of seeding cells along axis 0 of a body seeded by cells whose
/// every particle a counting pass places (all in the body's shape, none in
/// an earlier body's: Shape::side): the cells [first, first + cells) of the
/// body's numbering (BodyCells), the first of index `c`, `per_cell`
/// particles each, all of them in the box [lower, upper]; `box` gives
/// their coordinates (BoxCells::coordinate).
template <int D> struct CellRun {
  int body = 0;
  long long first = 0, cells = 0, per_cell = 0;
  Index<D> c{};
  Vec<D> lower = Vec<D>::Zero(), upper = Vec<D>::Zero();
  const BoxCells<D>* box = nullptr;
};

/// Takes the particles of a CellRun at once (true: they are counted as
/// placed, none generated), or leaves them to be generated one at a time
/// (false).
template <int D> using TakeRun = std::function<bool(const CellRun<D>&)>;

/// A pass over the bodies in seeding order that generates only some of
/// their particles: of a body seeded by cells, the cells `range(body)`
/// (all of them: every particle, in the serial order), a file or mesh body
/// whole (a file read in blocks of rows) - with the checks and errors of
/// seed_bodies, one particle at a time (the overlap with earlier bodies).
/// place(spot, x) is asked for every particle placed and returns its global
/// id to keep it (in `result`, with result->ids; null `result`: nothing is
/// stored) or -1. `at` follows the particle being checked (an error names
/// where it happened: spot.index is its index among the cell's generated
/// particles, -1 while a body's shape is built, max() for a body that
/// holds no particle). A body whose every cell the pass generates and that
/// holds no particle is an InputError at its end; of a body generated in
/// part, the caller adds the tallies of all parts (and counts the
/// particles behind walls: WallSides). With `take` (a counting pass: no
/// `result`), the cells of a run along axis 0 whose particles are all
/// placed are offered to it whole (TakeRun), and a run whose particles are
/// all outside the shape or dropped by an earlier body is skipped, with the
/// tallies of the particles one by one; the other runs are halved down to
/// single cells, generated particle by particle, in cell order. Returns the
/// tallies.
template <int D>
std::vector<BodyTally> seed_cells_where(const Scene& scene, const Vec<D>& h, const CartesianGrid<D>& lattice,
                                        const std::function<CellRange<D>(int)>& range,
                                        const std::function<long long(const SeedSpot&, const Vec<D>&)>& place,
                                        SeededBodies<D>* result, SeedSpot* at = nullptr,
                                        const std::vector<double>* factors = nullptr, const TakeRun<D>& take = nullptr);

/// The place of a particle in the seeding order (WallSides::Order).
inline std::pair<long long, long long> seeding_order(const SeedSpot& s) {
  return {(static_cast<long long>(s.body) << 40) + s.cell, s.index};
}

/// The input error of a body that holds no particle.
[[noreturn]] void no_particle(const BodySection& body);

/// Some of the particles of seed_bodies, without ever holding the others
/// (a rank's share in a distributed run, distributed/local_parts.cpp): the
/// bodies are seeded in the same order, one particle at a time, with the
/// same checks and errors, and keep(id, x) is asked for every particle (id:
/// its index in seed_bodies' order, x: its position). With `result`, the
/// particles it keeps are stored there, in that order, with their ids in
/// result->ids. Particle files are read in blocks of rows
/// (stream_particle_file), each in one pass over its rows per call (the
/// later bodies' boxes an earlier file body's shape is built on are their
/// shapes' bounds, a file body's the bounds the scene reader found; a later
/// file body's row outside them is an InputError: the file changed after
/// the scene was read): of a file, only the rows kept are stored (their
/// extra columns in result->file_state), and its body's shape (for the
/// overlap of later bodies) holds only the particles whose cells meet
/// where later bodies are seeded. Returns the number of particles of the
/// scene. Without `result`, a counting pass: nothing is stored.
template <int D>
long long seed_bodies_where(const Scene& scene, const Vec<D>& h, const CartesianGrid<D>& lattice,
                            const std::function<bool(long long, const Vec<D>&)>& keep, SeededBodies<D>* result);

} // namespace otmpm
