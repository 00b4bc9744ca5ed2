#pragma once
/// \file seeding.hpp
/// The particles of a scene's bodies (seeding.cpp). Internal to assembly/ and
/// the distributed set-up (distributed/local_parts.cpp, which seeds a rank's share).
#include "otmpm/nodes/node_set.hpp"
#include "otmpm/particles/particles.hpp"
#include "otmpm/scene/scene.hpp"

#include <functional>
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
/// variable of that name, for the particles of `body` (row = file_row[p]).
struct FileState {
  std::string name;
  int body = 0;
  std::vector<double> values;
};

/// The seeded particles and what their particle files give beyond them.
template <int D> struct SeededBodies {
  Particles<D> particles;
  std::vector<int> file_row; ///< per particle: its row in its body's file, or -1
  std::vector<FileState> file_state;
  /// seed_bodies_where: per particle, its index in seed_bodies' order (its global id)
  std::vector<long long> ids;
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
/// result->ids; particle files are still read whole (their extra columns go
/// to result->file_state whole). Returns the number of particles of the
/// scene. Without `result`, a counting pass: nothing is stored.
template <int D>
long long seed_bodies_where(const Scene& scene, const Vec<D>& h, const CartesianGrid<D>& lattice,
                            const std::function<bool(long long, const Vec<D>&)>& keep, SeededBodies<D>* result);

} // namespace otmpm
