/// \file particle_file.cpp
/// Particle files (particle_file.hpp): CSV and HDF5 readers with messages
/// that name the file, the line and column, or the dataset.
#include "otmpm/io/particle_file.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/hdf5.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace otmpm {

namespace {

constexpr const char* kAxes[] = {"x", "y", "z"};
constexpr const char* kVelocities[] = {"vx", "vy", "vz"};

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, ',')) {
    const auto b = cell.find_first_not_of(" \t\r");
    const auto e = cell.find_last_not_of(" \t\r");
    out.push_back(b == std::string::npos ? std::string() : cell.substr(b, e - b + 1));
  }
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

/// A finite number, or InputError naming file, line and column.
double number(const std::string& text, const std::string& where) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  require(!text.empty() && end && *end == '\0' && errno != ERANGE && std::isfinite(v), where,
          ": expected a finite number, got '", text, "'");
  return v;
}

/// The index of column `name` in the header, or -1.
int column(const std::vector<std::string>& header, const std::string& name) {
  const auto it = std::find(header.begin(), header.end(), name);
  return it == header.end() ? -1 : static_cast<int>(it - header.begin());
}

ParticleFile read_csv(const std::string& path, int D) {
  std::ifstream in(path);
  require(in.good(), path, ": cannot open the particle file");
  ParticleFile f{path, D, {}, {}, {}, {}};
  std::string line;
  int lineno = 0;
  while (std::getline(in, line) && (line.empty() || line[0] == '#')) ++lineno; // comments before the header
  ++lineno;
  const std::vector<std::string> header = split_csv(line);
  const auto need = [&](const std::string& name) {
    const int c = column(header, name);
    require(c >= 0, path, ":", lineno, ": the header has no column '", name, "'");
    return c;
  };
  int pos[3] = {0, 0, 0}, vel[3] = {-1, -1, -1};
  for (int k = 0; k < D; ++k) pos[k] = need(kAxes[k]);
  const int vol = need("volume");
  for (int k = 0; k < D; ++k) vel[k] = column(header, kVelocities[k]);
  const bool has_v = vel[0] >= 0;
  for (int k = 0; k < D; ++k)
    require((vel[k] >= 0) == has_v, path, ":", lineno, ": give all of vx, vy, vz (the first ", D, ") or none");
  std::vector<int> extra;
  for (int c = 0; c < static_cast<int>(header.size()); ++c) {
    require(!header[c].empty(), path, ":", lineno, ": column ", c + 1, " has no name");
    const bool known = c == vol || std::find(pos, pos + D, c) != pos + D || std::find(vel, vel + D, c) != vel + D;
    if (!known) extra.push_back(c);
  }
  while (std::getline(in, line)) {
    ++lineno;
    if (line.empty() || line[0] == '#') continue;
    const std::vector<std::string> cells = split_csv(line);
    require(cells.size() == header.size(), path, ":", lineno, ": ", cells.size(), " values, the header has ",
            header.size(), " columns");
    auto value = [&](int c) { return number(cells[c], path + ":" + std::to_string(lineno) + ": column '" + header[c] + "'"); };
    for (int k = 0; k < D; ++k) f.x.push_back(value(pos[k]));
    f.volume.push_back(value(vol));
    require(f.volume.back() > 0.0, path, ":", lineno, ": volume must be > 0, got ", f.volume.back());
    if (has_v)
      for (int k = 0; k < D; ++k) f.v.push_back(value(vel[k]));
    for (int c : extra) f.fields[header[c]].push_back(value(c));
  }
  require(f.size() > 0, path, ": no particles");
  return f;
}

ParticleFile read_hdf5(const std::string& path, int D) {
  h5::silence();
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  require(id >= 0, path, ": cannot open the particle file (not HDF5? CSV files must end in .csv)");
  const h5::Handle file(id, H5Fclose);
  ParticleFile f{path, D, {}, {}, {}, {}};
  auto matrix = [&](const std::string& name, hsize_t cols) {
    require(h5::has_link(id, name), path, ": no dataset '", name, "'");
    h5::Matrix<double> m;
    try {
      m = h5::read_double_matrix(id, name, path);
    } catch (const std::exception& e) {
      throw InputError(path + ": dataset '" + name + "' is not a matrix of numbers (" + e.what() + ")");
    }
    require(m.cols == cols, path, ": dataset '", name, "' has ", m.cols, " columns, expected ", cols);
    for (std::size_t i = 0; i < m.values.size(); ++i)
      require(std::isfinite(m.values[i]), path, ": dataset '", name, "' row ", i / cols, ": not finite");
    return m;
  };
  const h5::Matrix<double> x = matrix("x", static_cast<hsize_t>(D));
  f.x = x.values;
  f.volume = matrix("volume", 1).values;
  require(f.volume.size() == x.rows, path, ": ", x.rows, " positions but ", f.volume.size(), " volumes");
  for (std::size_t p = 0; p < f.volume.size(); ++p)
    require(f.volume[p] > 0.0, path, ": dataset 'volume' row ", p, ": must be > 0, got ", f.volume[p]);
  for (const std::string& name : h5::link_names(id, path)) {
    if (name == "x" || name == "volume") continue;
    const h5::Matrix<double> m = matrix(name, name == "v" ? static_cast<hsize_t>(D) : 1);
    require(m.rows == x.rows, path, ": dataset '", name, "' has ", m.rows, " rows, expected ", x.rows);
    if (name == "v") f.v = m.values;
    else f.fields[name] = m.values;
  }
  require(f.size() > 0, path, ": no particles");
  return f;
}

} // namespace

ParticleFile read_particle_file(const std::string& path, int dimension) {
  require<std::invalid_argument>(dimension >= 1 && dimension <= 3, "read_particle_file: dimension ", dimension);
  std::error_code ec;
  require(std::filesystem::is_regular_file(path, ec), path, ": no such particle file");
  return path.size() > 4 && path.ends_with(".csv") ? read_csv(path, dimension) : read_hdf5(path, dimension);
}

} // namespace otmpm
