#pragma once
/// \file seeding.hpp
/// The particles of a scene's bodies (seeding.cpp). Internal to assembly/.
#include "otmpm/nodes/node_set.hpp"
#include "otmpm/particles/particles.hpp"
#include "otmpm/scene/scene.hpp"

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
};

/// Seeds every body of the scene (assembler.hpp, seed_particles): boxes on
/// cells of the spacing `h`, other shapes on the cells of `lattice`.
template <int D> SeededBodies<D> seed_bodies(const Scene& scene, const Vec<D>& h, const CartesianGrid<D>& lattice);

} // namespace otmpm
