#pragma once
/// \file seeding.hpp
/// The particles of a scene's bodies (seeding.cpp). Internal to assembly/ and
/// the distributed set-up (distributed/local_parts.cpp, which seeds a rank's share).
#include "otmpm/nodes/node_set.hpp"
#include "otmpm/particles/particles.hpp"
#include "otmpm/scene/scene.hpp"

#include <array>
#include <cmath>
#include <functional>
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

/// Seeds every body of the scene (assembler.hpp, seed_particles): boxes on
/// cells of the spacing `h`, other shapes on the cells of `lattice`.
template <int D> SeededBodies<D> seed_bodies(const Scene& scene, const Vec<D>& h, const CartesianGrid<D>& lattice);

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
