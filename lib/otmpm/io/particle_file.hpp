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
#include "otmpm/parameters.hpp"

#include <cstddef>
#include <functional>
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

/// What a particle file holds besides positions and volumes, known before
/// its rows (stream_particle_file).
struct ParticleColumns {
  std::string path;
  int dimension = 0;
  bool velocity = false;           ///< whether it gives velocities
  std::vector<std::string> fields; ///< its further scalar fields, in name order
  long long rows = -1;             ///< its number of rows when known before reading them (HDF5), else -1
};

/// What the rows of a particle file must satisfy beyond finite numbers and
/// volumes > 0, so that its values meet the checks of the scene keys of the
/// same quantity: the range of each further column (ParameterSpec: the row
/// that checks the scene key, e.g. material.NAME.density for `density`, or
/// a state variable's StateSpec range), with the message form of those keys
/// ("FILE:LINE: column 'density': must be > 0 (got -1)"). A further column
/// without a rule is refused when the file's layout is read (`known` says
/// which columns the file may have), and so is a file of more than
/// `max_rows` rows (-1: no cap) - as soon as its row count is known.
struct ParticleFileRules {
  std::map<std::string, ParameterSpec, std::less<>> columns;
  std::string known; ///< "x, y, volume, vx, vy, density or plastic_strain": the columns allowed
  long long max_rows = -1;
};

/// Consecutive rows [first, first + size()) of a particle file, laid out as
/// in ParticleFile (positions and velocities row-major, size() x D).
struct ParticleRows {
  long long first = 0;
  std::vector<double> x, volume;
  std::vector<double> v;                   ///< empty when the file has none
  std::vector<std::vector<double>> fields; ///< per ParticleColumns::fields
  int size() const { return static_cast<int>(volume.size()); }
};

/// The rows stream_particle_file hands over at once by default.
inline constexpr std::size_t kParticleChunk = 65536;

/// Reads a particle file (CSV when the name ends in .csv, else HDF5) `chunk`
/// rows at a time (CSV line by line, HDF5 in hyperslabs of every dataset),
/// calling each(columns, rows) for every block of rows in file order: at
/// most `chunk` rows are held at once. The checks and messages are those of
/// read_particle_file; the blocks before the one holding a bad row have been
/// handed over when it throws. The file's layout (columns, datasets and
/// their sizes; with `rules`, its further columns and an HDF5 file's row
/// count) is checked before any row is handed over; with `rules`, every row
/// is checked against them before its block is handed over.
void stream_particle_file(const std::string& path, int dimension,
                          const std::function<void(const ParticleColumns&, const ParticleRows&)>& each,
                          std::size_t chunk = kParticleChunk, const ParticleFileRules* rules = nullptr);

/// Reads a whole particle file (CSV when the name ends in .csv, else HDF5).
/// Throws InputError naming the file and the line and column (CSV) or the
/// dataset (HDF5) for a missing column, a value that is not a finite
/// number, a volume <= 0, ragged rows or no particles. A file with several
/// such faults is refused for one of them: the first in the file's layout
/// (header, datasets and their sizes), else a bad row - in a CSV file the
/// first; in an HDF5 file the first of the first dataset found faulty in the
/// first block of rows holding a fault (the order of the checks within a
/// block: positions, volumes, velocities, the further fields). Its vectors
/// are reserved for the file's rows up front when they are known before
/// reading them: an HDF5 file's extent, else `expected_rows` when > 0 (a
/// hint, e.g. the count the scene reader found; a CSV file may hold more).
/// `rules`: as for stream_particle_file.
ParticleFile read_particle_file(const std::string& path, int dimension, long long expected_rows = -1,
                                const ParticleFileRules* rules = nullptr);

/// How many passes over the particle file `path` (as spelt by the caller)
/// stream_particle_file - and so read_particle_file - has begun in this
/// process: a pass is counted when the file exists and its reading starts,
/// also when a bad row or layout ends it. For tests that check how often
/// set-up reads a file (once per seeding pass).
long long particle_file_passes(const std::string& path);

} // namespace otmpm
