/// \file particle_file.cpp
/// Particle files (particle_file.hpp): CSV and HDF5 readers with messages
/// that name the file, the line and column, or the dataset.
#include "otmpm/io/particle_file.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/interrupt.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <utility>

namespace otmpm {

namespace {

constexpr const char* kAxes[] = {"x", "y", "z"};
constexpr const char* kVelocities[] = {"vx", "vy", "vz"};
/// The range of every particle's volume.
constexpr ParameterSpec kVolume{"volume", "particle volume", std::nullopt, 0.0, true};

/// The rule of further column `name`: null without rules; InputError
/// "`where` 'NAME' is not one of ..." when the rules have none for it.
const ParameterSpec* column_rule(const ParticleFileRules* rules, const std::string& name, const std::string& where) {
  if (!rules) return nullptr;
  const auto it = rules->columns.find(name);
  require(it != rules->columns.end(), where, " '", name, "' is not one of the columns a particle file may have here (",
          rules->known, ")");
  return &it->second;
}

/// InputError "WHERE: must be > 0 (got -1)" when `value` is out of the range
/// of `spec` (none: any); where() names the value (called on failure only).
template <class Where> void check_value(const ParameterSpec* spec, double value, Where&& where) {
  if (!spec) return;
  if (const std::string why = spec->check(value); !why.empty()) throw InputError(where() + ": " + why);
}

/// InputError "`where`: N rows; at most CAP particles are allowed" when a file
/// of `rows` rows (`more`: more than rows - 1, a CSV file read so far) exceeds the rules' cap.
void check_rows(const ParticleFileRules* rules, long long rows, bool more, const std::string& where) {
  if (!rules || rules->max_rows < 0 || rows <= rules->max_rows) return;
  const std::string cap = format_number(static_cast<double>(rules->max_rows));
  throw InputError(where + ": " + (more ? "more than " + cap : std::to_string(rows)) + " rows; at most " + cap +
                   " particles are allowed");
}

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

using Each = std::function<void(const ParticleColumns&, const ParticleRows&)>;

/// Hands the rows gathered so far to `each` and starts the next block.
void flush(const ParticleColumns& columns, ParticleRows& rows, const Each& each) {
  if (rows.size() == 0) return;
  each(columns, rows);
  rows.first += rows.size();
  rows.x.clear();
  rows.volume.clear();
  rows.v.clear();
  for (std::vector<double>& f : rows.fields) f.clear();
}

/// A CSV header: the columns of the positions, volume, velocities and of
/// the further fields (field[c]: its index in ParticleColumns::fields, or -1).
struct CsvHeader {
  std::vector<std::string> names;
  int pos[3] = {0, 0, 0}, vel[3] = {-1, -1, -1}, vol = 0;
  std::vector<int> field;
  std::vector<const ParameterSpec*> rule; ///< per ParticleColumns::fields: its range (null: any finite value)
};

/// Reads the header line (after comment lines) and checks it.
CsvHeader read_header(std::istream& in, const std::string& path, int D, int& lineno, ParticleColumns& columns,
                      const ParticleFileRules* rules) {
  std::string line;
  while (std::getline(in, line) && (line.empty() || line[0] == '#')) ++lineno; // comments before the header
  ++lineno;
  CsvHeader h;
  h.names = split_csv(line);
  const auto need = [&](const std::string& name) {
    const int c = column(h.names, name);
    require(c >= 0, path, ":", lineno, ": the header has no column '", name, "'");
    return c;
  };
  for (int k = 0; k < D; ++k) h.pos[k] = need(kAxes[k]);
  h.vol = need("volume");
  for (int k = 0; k < D; ++k) h.vel[k] = column(h.names, kVelocities[k]);
  columns.velocity = h.vel[0] >= 0;
  for (int k = 0; k < D; ++k)
    require((h.vel[k] >= 0) == columns.velocity, path, ":", lineno, ": give all of vx, vy, vz (the first ", D,
            ") or none");
  for (int c = 0; c < static_cast<int>(h.names.size()); ++c) {
    require(!h.names[c].empty(), path, ":", lineno, ": column ", c + 1, " has no name");
    require(column(h.names, h.names[c]) == c, path, ":", lineno, ": column '", h.names[c], "' appears twice");
    const bool known = c == h.vol || std::find(h.pos, h.pos + D, c) != h.pos + D ||
                       std::find(h.vel, h.vel + D, c) != h.vel + D;
    if (!known) columns.fields.push_back(h.names[c]);
  }
  std::sort(columns.fields.begin(), columns.fields.end());
  for (const std::string& name : h.names) {
    const auto it = std::find(columns.fields.begin(), columns.fields.end(), name);
    h.field.push_back(it == columns.fields.end() ? -1 : static_cast<int>(it - columns.fields.begin()));
  }
  for (const std::string& name : columns.fields)
    h.rule.push_back(column_rule(rules, name, path + ":" + std::to_string(lineno) + ": column"));
  return h;
}

/// Appends one data line's values to `rows` (values checked in the header's order of the kinds).
void read_line(const std::string& line, const std::string& path, int lineno, const CsvHeader& h, int D,
               ParticleRows& rows) {
  const std::vector<std::string> cells = split_csv(line);
  require(cells.size() == h.names.size(), path, ":", lineno, ": ", cells.size(), " values, the header has ",
          h.names.size(), " columns");
  const auto where = [&](int c) { return path + ":" + std::to_string(lineno) + ": column '" + h.names[c] + "'"; };
  auto value = [&](int c) { return number(cells[c], where(c)); };
  for (int k = 0; k < D; ++k) rows.x.push_back(value(h.pos[k]));
  rows.volume.push_back(value(h.vol));
  check_value(&kVolume, rows.volume.back(), [&] { return where(h.vol); });
  if (h.vel[0] >= 0)
    for (int k = 0; k < D; ++k) rows.v.push_back(value(h.vel[k]));
  for (std::size_t c = 0; c < h.names.size(); ++c) {
    const int f = h.field[c];
    if (f < 0) continue;
    rows.fields[static_cast<std::size_t>(f)].push_back(value(static_cast<int>(c)));
    check_value(h.rule[static_cast<std::size_t>(f)], rows.fields[static_cast<std::size_t>(f)].back(),
                [&] { return where(static_cast<int>(c)); });
  }
}

/// Skips the UTF-8 byte-order mark a CSV file may start with (spreadsheet
/// programs write one); InputError for a UTF-16 file, which no column name matches.
void skip_byte_order_mark(std::istream& in, const std::string& path) {
  std::string start(3, '\0');
  in.read(start.data(), 3);
  start.resize(static_cast<std::size_t>(in.gcount()));
  if (start == "\xEF\xBB\xBF") return;
  require(!start.starts_with("\xFF\xFE") && !start.starts_with("\xFE\xFF"), path,
          ": the file is UTF-16 text (it starts with a UTF-16 byte-order mark); save it as UTF-8 or ASCII CSV");
  in.clear();
  in.seekg(0);
}

void stream_csv(const std::string& path, int D, const Each& each, std::size_t chunk, const ParticleFileRules* rules) {
  std::ifstream in(path, std::ios::binary);
  require(in.good(), path, ": cannot open the particle file");
  skip_byte_order_mark(in, path);
  ParticleColumns columns{path, D, false, {}, -1};
  int lineno = 0;
  const CsvHeader header = read_header(in, path, D, lineno, columns, rules);
  ParticleRows rows;
  rows.fields.resize(columns.fields.size());
  std::string line;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.empty() || line[0] == '#') continue;
    check_rows(rules, rows.first + rows.size() + 1, true, path + ":" + std::to_string(lineno));
    read_line(line, path, lineno, header, D, rows);
    if (static_cast<std::size_t>(rows.size()) >= chunk) flush(columns, rows, each);
  }
  flush(columns, rows, each);
  require(rows.first > 0, path, ": no particles");
}

/// The datasets of an HDF5 particle file, opened and checked for their
/// shapes before any row is read.
struct Hdf5Layout {
  std::vector<std::string> names; ///< x, volume, then the others in name order
  std::vector<h5::DoubleRows> sets;
  std::vector<const ParameterSpec*> rules; ///< per set: the range of its values (null: any finite value)
  hsize_t rows = 0;
};

/// Opens dataset `name` of `cols` columns.
h5::DoubleRows open_dataset(hid_t id, const std::string& path, const std::string& name, hsize_t cols) {
  require(h5::has_link(id, name), path, ": no dataset '", name, "'");
  try {
    h5::DoubleRows set(id, name, path);
    require(set.cols() == cols, path, ": dataset '", name, "' has ", set.cols(), " columns, expected ", cols);
    return set;
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(path + ": dataset '" + name + "' is not a matrix of numbers (" + e.what() + ")");
  }
}

Hdf5Layout open_layout(hid_t id, const std::string& path, int D, ParticleColumns& columns,
                       const ParticleFileRules* rules) {
  Hdf5Layout l;
  l.names = {"x", "volume"};
  l.rules = {nullptr, &kVolume};
  l.sets.push_back(open_dataset(id, path, "x", static_cast<hsize_t>(D)));
  l.sets.push_back(open_dataset(id, path, "volume", 1));
  l.rows = l.sets[0].rows();
  check_rows(rules, static_cast<long long>(l.rows), false, path + ": dataset 'x'");
  require(l.sets[1].rows() == l.rows, path, ": ", l.rows, " positions but ", l.sets[1].rows(), " volumes");
  for (const std::string& name : h5::link_names(id, path)) {
    if (name == "x" || name == "volume") continue;
    l.rules.push_back(name == "v" ? nullptr : column_rule(rules, name, path + ": dataset"));
    l.sets.push_back(open_dataset(id, path, name, name == "v" ? static_cast<hsize_t>(D) : 1));
    require(l.sets.back().rows() == l.rows, path, ": dataset '", name, "' has ", l.sets.back().rows(),
            " rows, expected ", l.rows);
    l.names.push_back(name);
    if (name == "v") columns.velocity = true;
    else columns.fields.push_back(name);
  }
  std::sort(columns.fields.begin(), columns.fields.end());
  columns.rows = static_cast<long long>(l.rows);
  return l;
}

/// Reads rows [first, first + count) of dataset `name` into out and checks they are finite.
void read_block(const h5::DoubleRows& set, const std::string& path, const std::string& name, hsize_t first,
                hsize_t count, std::vector<double>& out) {
  out.resize(static_cast<std::size_t>(count * set.cols()));
  try {
    set.read(first, count, out.data());
  } catch (const std::exception& e) {
    throw InputError(path + ": dataset '" + name + "' is not a matrix of numbers (" + e.what() + ")");
  }
  for (std::size_t i = 0; i < out.size(); ++i)
    require(std::isfinite(out[i]), path, ": dataset '", name, "' row ", first + i / set.cols(), ": not finite");
}

/// The rows' vector that dataset `name` goes to.
std::vector<double>& target(const std::string& name, const ParticleColumns& columns, ParticleRows& rows) {
  if (name == "x") return rows.x;
  if (name == "volume") return rows.volume;
  if (name == "v") return rows.v;
  const auto it = std::find(columns.fields.begin(), columns.fields.end(), name);
  return rows.fields[static_cast<std::size_t>(it - columns.fields.begin())];
}

void stream_hdf5(const std::string& path, int D, const Each& each, std::size_t chunk, const ParticleFileRules* rules) {
  h5::silence();
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  require(id >= 0, path, ": cannot open the particle file (not HDF5? CSV files must end in .csv)");
  const h5::Handle file(id, H5Fclose);
  ParticleColumns columns{path, D, false, {}, -1};
  const Hdf5Layout layout = open_layout(id, path, D, columns, rules);
  ParticleRows rows;
  rows.fields.resize(columns.fields.size());
  for (hsize_t first = 0; first < layout.rows; first += chunk) {
    const hsize_t count = std::min<hsize_t>(chunk, layout.rows - first);
    rows.first = static_cast<long long>(first);
    for (std::size_t s = 0; s < layout.sets.size(); ++s) {
      std::vector<double>& out = target(layout.names[s], columns, rows);
      read_block(layout.sets[s], path, layout.names[s], first, count, out);
      if (layout.rules[s])
        for (std::size_t p = 0; p < out.size(); ++p)
          check_value(layout.rules[s], out[p],
                      [&] { return path + ": dataset '" + layout.names[s] + "' row " + std::to_string(first + p); });
    }
    each(columns, rows);
  }
  require(layout.rows > 0, path, ": no particles");
}

/// The passes begun per path (particle_file_passes), under their mutex.
struct PassCount {
  std::mutex mutex;
  std::map<std::string, long long> passes;
};

/// The process's pass counts.
PassCount& pass_count() {
  static PassCount count;
  return count;
}

/// Counts a pass begun over the file `path`.
void count_pass(const std::string& path) {
  PassCount& c = pass_count();
  const std::lock_guard<std::mutex> lock(c.mutex);
  ++c.passes[path];
}

} // namespace

long long particle_file_passes(const std::string& path) {
  PassCount& c = pass_count();
  const std::lock_guard<std::mutex> lock(c.mutex);
  const auto it = c.passes.find(path);
  return it == c.passes.end() ? 0 : it->second;
}

void stream_particle_file(const std::string& path, int dimension, const Each& each, std::size_t chunk,
                          const ParticleFileRules* rules) {
  require<std::invalid_argument>(dimension >= 1 && dimension <= 3, "read_particle_file: dimension ", dimension);
  require<std::invalid_argument>(chunk > 0, "stream_particle_file: chunk of 0 rows");
  std::error_code ec;
  const std::string kind = special_file(path);
  require(kind.empty(), path, ": is ", kind, ", not a particle file");
  require(!std::filesystem::is_directory(path, ec), path, ": is a directory, not a particle file");
  require(std::filesystem::is_regular_file(path, ec), path, ": no such particle file");
  count_pass(path);
  const Each polled = [&each](const ParticleColumns& columns, const ParticleRows& rows) {
    interrupt_point("reading a particle file"); // once per block: a file of 1e8 rows stops at once
    each(columns, rows);
  };
  if (path.size() > 4 && path.ends_with(".csv")) stream_csv(path, dimension, polled, chunk, rules);
  else stream_hdf5(path, dimension, polled, chunk, rules);
}

ParticleFile read_particle_file(const std::string& path, int dimension, long long expected_rows,
                                const ParticleFileRules* rules) {
  ParticleFile f{path, dimension, {}, {}, {}, {}};
  const auto each = [&f, expected_rows](const ParticleColumns& columns, const ParticleRows& rows) {
    const long long known = columns.rows > 0 ? columns.rows : expected_rows;
    if (rows.first == 0 && known > 0) { // no growth by doubling (peak memory)
      const std::size_t n = static_cast<std::size_t>(known), D = static_cast<std::size_t>(columns.dimension);
      f.x.reserve(n * D);
      f.volume.reserve(n);
      if (columns.velocity) f.v.reserve(n * D);
      for (const std::string& name : columns.fields) f.fields[name].reserve(n);
    }
    f.x.insert(f.x.end(), rows.x.begin(), rows.x.end());
    f.volume.insert(f.volume.end(), rows.volume.begin(), rows.volume.end());
    f.v.insert(f.v.end(), rows.v.begin(), rows.v.end());
    for (std::size_t i = 0; i < columns.fields.size(); ++i) {
      std::vector<double>& to = f.fields[columns.fields[i]];
      to.insert(to.end(), rows.fields[i].begin(), rows.fields[i].end());
    }
  };
  stream_particle_file(path, dimension, each, kParticleChunk, rules);
  return f;
}

} // namespace otmpm
