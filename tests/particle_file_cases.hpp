// Faulty particle files and the messages the reader gives for them
// (tests/test_particle_stream.cpp). Each file has one fault, several of them
// past the first rows, so that a reader in blocks of a few rows meets it in a
// later block. The messages are those of the reader before it read in blocks
// (checked by linking a small driver against that library).
#pragma once

#include "h5_support.hpp"

#include <fstream>
#include <limits>
#include <string>
#include <vector>

namespace otmpm::test {

/// A faulty particle file: its name, how to write it, and the message's end
/// (the message is the file's path followed by it).
struct FaultyFile {
  std::string name;
  std::string csv;                  ///< the content of a CSV file, or "" for HDF5
  std::vector<Dataset> datasets;    ///< the datasets of an HDF5 file
  std::string message;              ///< after the path
};

/// The header x, y, volume (and a column `a` when `a`), six valid 2D rows, then `after`.
inline std::string csv_rows(bool a, const std::string& after) {
  std::string s = a ? "x, y, volume, a\n" : "x, y, volume\n";
  for (int r = 0; r < 6; ++r) s += std::to_string(0.1 * r) + ", 0.5, 0.01" + (a ? ", 1" : "") + "\n";
  return s + after;
}

/// Positions (n x 2) of n valid rows.
inline std::vector<double> positions(int n) {
  std::vector<double> x;
  for (int r = 0; r < n; ++r) x.push_back(0.1 * r), x.push_back(0.5);
  return x;
}

/// n volumes of 0.01, the one at `bad` (if any) replaced by `value`.
inline std::vector<double> volumes(int n, int bad = -1, double value = 0.0) {
  std::vector<double> v(static_cast<std::size_t>(n), 0.01);
  if (bad >= 0) v[static_cast<std::size_t>(bad)] = value;
  return v;
}

inline std::vector<FaultyFile> faulty_files() {
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> x_inf = positions(7), field_nan(7, 1.0);
  x_inf[11] = inf; // row 5, y
  field_nan[6] = nan;
  return {
      {"header.csv", "# comment\nx, y\n0, 0, 1\n", {}, ":2: the header has no column 'volume'"},
      {"number.csv", csv_rows(false, "0.7, zero, 0.01\n"), {}, ":8: column 'y': expected a finite number, got 'zero'"},
      {"inf.csv", csv_rows(false, "0.7, inf, 0.01\n"), {}, ":8: column 'y': expected a finite number, got 'inf'"},
      {"volume.csv", csv_rows(false, "0.7, 0.5, -1\n"), {}, ":8: column 'volume': must be > 0 (got -1)"},
      {"ragged.csv", csv_rows(false, "0.7, 0.5\n"), {}, ":8: 2 values, the header has 3 columns"},
      {"extra.csv", csv_rows(true, "0.7, 0.5, 0.01, nan\n"), {}, ":8: column 'a': expected a finite number, got 'nan'"},
      {"velocity.csv", "x, y, volume, vx\n0, 0, 1, 0\n", {}, ":1: give all of vx, vy, vz (the first 2) or none"},
      {"unnamed.csv", "x, y, volume, \n0, 0, 1, 0\n", {}, ":1: column 4 has no name"},
      {"empty.csv", "x, y, volume\n# no rows\n", {}, ": no particles"},
      {"no_x.h5", "", {{"volume", 2, 0, volumes(2)}}, ": no dataset 'x'"},
      {"no_volume.h5", "", {{"x", 2, 2, positions(2)}}, ": no dataset 'volume'"},
      {"columns.h5", "", {{"x", 2, 3, std::vector<double>(6, 0.5)}, {"volume", 2, 0, volumes(2)}},
       ": dataset 'x' has 3 columns, expected 2"},
      {"field_nan.h5", "", {{"x", 7, 2, positions(7)}, {"volume", 7, 0, volumes(7)}, {"a", 7, 0, field_nan}},
       ": dataset 'a' row 6: not finite"},
      {"sizes.h5", "", {{"x", 7, 2, positions(7)}, {"volume", 6, 0, volumes(6)}}, ": 7 positions but 6 volumes"},
      {"x_inf.h5", "", {{"x", 7, 2, x_inf}, {"volume", 7, 0, volumes(7)}}, ": dataset 'x' row 5: not finite"},
      {"volume0.h5", "", {{"x", 7, 2, positions(7)}, {"volume", 7, 0, volumes(7, 4)}},
       ": dataset 'volume' row 4: must be > 0 (got 0)"},
      {"field_rows.h5", "", {{"x", 7, 2, positions(7)}, {"volume", 7, 0, volumes(7)}, {"a", 6, 0, std::vector<double>(6, 1.0)}},
       ": dataset 'a' has 6 rows, expected 7"},
      {"v.h5", "", {{"x", 7, 2, positions(7)}, {"volume", 7, 0, volumes(7)}, {"v", 7, 0, std::vector<double>(7, 1.0)}},
       ": dataset 'v' has 1 columns, expected 2"},
      {"empty.h5", "", {{"x", 0, 2, {}}, {"volume", 0, 0, {}}}, ": no particles"},
  };
}

/// Writes the faulty file into `dir`; returns its path.
inline std::string write_faulty(const std::string& dir, const FaultyFile& f) {
  const std::string path = dir + "/" + f.name;
  if (f.datasets.empty()) std::ofstream(path) << f.csv;
  else write_datasets(path, f.datasets);
  return path;
}

} // namespace otmpm::test
