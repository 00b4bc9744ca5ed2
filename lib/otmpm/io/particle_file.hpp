#pragma once
/// \file particle_file.hpp
/// Particles of a body read from a file (`[[body]] shape = "file"`): CSV with
/// a header line, or HDF5. Columns / datasets:
///  - positions: CSV `x`, `y`, `z` (the first D); HDF5 `x` (n x D);
///  - volumes: `volume` (n), > 0;
///  - optional velocities: CSV `vx`, `vy`, `vz`; HDF5 `v` (n x D);
///  - optional further scalar fields by name (CSV columns, HDF5 rank-1
///    datasets of n values): `density` (overrides the material's for the
///    particle's mass) or the name of a material state variable (its
///    initial value, e.g. `plastic_strain`).
#include <map>
#include <string>
#include <vector>

namespace otmpm {

/// The content of a particle file, positions and velocities row-major (n x D).
struct ParticleFile {
  std::string path;
  int dimension = 0;
  std::vector<double> x;
  std::vector<double> volume;
  std::vector<double> v; ///< empty when the file has none
  std::map<std::string, std::vector<double>> fields;
  int size() const { return static_cast<int>(volume.size()); }
};

/// Reads a particle file (CSV when the name ends in .csv, else HDF5).
/// Throws InputError naming the file and the line and column (CSV) or the
/// dataset (HDF5) for a missing column, a value that is not a finite
/// number, a volume <= 0, ragged rows or no particles.
ParticleFile read_particle_file(const std::string& path, int dimension);

} // namespace otmpm
