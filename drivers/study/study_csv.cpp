#include "study_csv.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/results.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

namespace fs = std::filesystem;

namespace otmpm::study {

namespace {

const std::vector<std::string> error_columns{"rms_velocity_error", "rms_displacement_error", "rms_stress_error",
                                             "history_error"};
/// Energy columns: attributes of the result file, after the error columns.
const std::vector<std::string> energy_columns{"max_energy_ratio", "energy_drift"};
/// The errors of a saturated body's pore pressure, at the end of a row (after
/// the stability columns: CSVs written before them are extended in place).
const std::vector<std::string> pore_pressure_columns{"rms_pore_pressure_error", "max_pore_pressure_error"};

std::string csv_escape(std::string s) {
  std::replace(s.begin(), s.end(), '\n', ' '); // one row per line
  if (s.find_first_of(",\"") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

/// The header without the energy and stability columns: CSVs written before
/// those columns existed start with it and are extended in place.
std::string legacy_header(const Study& s) {
  std::string h = "variant,mesh,h";
  for (const std::string& k : s.param_keys) h += "," + csv_escape(k);
  h += ",status,exit_code,steps,wall_seconds,particles,nodes,particle_steps_per_second";
  for (const std::string& e : error_columns) h += "," + e;
  return h;
}

/// The header without the pore-pressure columns (CSVs written before them).
std::string header_before_pore_pressure(const Study& s) {
  std::string h = legacy_header(s);
  for (const std::string& e : energy_columns) h += "," + e;
  if (s.stability.enabled) h += ",stable,stability";
  return h;
}

std::string header(const Study& s) {
  std::string h = header_before_pore_pressure(s);
  for (const std::string& e : pore_pressure_columns) h += "," + e;
  return h;
}

std::string number(double v) {
  if (!std::isfinite(v)) return "";
  char b[40];
  std::snprintf(b, sizeof b, "%.8g", v);
  return b;
}

std::string last_line(const fs::path& log) {
  std::ifstream in(log);
  std::string line, last;
  while (std::getline(in, line))
    if (!line.empty()) last = line;
  return last;
}

/// Replaces the file's content (written beside it, then renamed over it).
void rewrite(const fs::path& file, const std::string& text) {
  const fs::path tmp = file.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << text;
    if (!out.flush()) throw InputError("cannot write " + tmp.string());
  }
  fs::rename(tmp, file);
}

} // namespace

std::vector<std::string> csv_cells(const std::string& line) {
  std::vector<std::string> cells(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (c == '"' && quoted && i + 1 < line.size() && line[i + 1] == '"') cells.back() += line[++i];
    else if (c == '"') quoted = !quoted;
    else if (c == ',' && !quoted) cells.emplace_back();
    else cells.back() += c;
  }
  return cells;
}

DoneRuns prepare_csv(const Study& s) {
  DoneRuns done;
  std::ifstream in(s.csv, std::ios::binary);
  std::stringstream buf;
  buf << in.rdbuf();
  in.close();
  const std::string text = buf.str();
  const std::string head = header(s);
  if (text.empty()) {
    rewrite(s.csv, head + "\n");
    return done;
  }
  std::vector<std::string> lines;
  std::stringstream split(text);
  for (std::string line; std::getline(split, line);) lines.push_back(line);
  bool changed = false;
  if (text.back() != '\n') {
    std::printf("%s: the last row was cut off (the study was killed while writing it): dropped, that run is done "
                "again\n", s.csv.c_str());
    lines.pop_back();
    changed = true;
  }
  if (lines.empty()) {
    rewrite(s.csv, head + "\n");
    return done;
  }
  std::string pad;
  if (lines.front() == legacy_header(s) || lines.front() == header_before_pore_pressure(s)) {
    pad.assign(csv_cells(head).size() - csv_cells(lines.front()).size(), ',');
    lines.front() = head;
    changed = true;
    std::printf("%s: added the columns of this version (empty for the rows already there)\n", s.csv.c_str());
  }
  if (lines.front() != head)
    throw InputError(s.csv.string() + ": the CSV header does not match this study (delete the file or use another csv)");
  const std::size_t width = csv_cells(head).size();
  std::string kept = head + "\n";
  for (std::size_t i = 1; i < lines.size(); ++i) {
    if (lines[i].empty()) { // a blank line: nothing to keep
      changed = true;
      continue;
    }
    const std::string row = lines[i] + pad;
    const std::vector<std::string> cells = csv_cells(row);
    if (cells.size() != width) {
      std::printf("%s: row %zu has %zu cells instead of %zu: dropped, that run is done again\n", s.csv.c_str(), i + 1,
                  cells.size(), width);
      changed = true;
      continue;
    }
    done.insert({cells[0], cells[1]});
    kept += row + "\n";
  }
  if (changed) rewrite(s.csv, kept);
  return done;
}

void append_row(const Study& s, const std::string& row) {
  std::ofstream csv(s.csv, std::ios::app);
  csv << row << "\n" << std::flush;
  if (!csv) throw InputError("cannot write " + s.csv.string());
}

std::string stability_class(const StabilityCriterion& c, int exit_code, double max_energy_ratio) {
  if (exit_code == 0) {
    if (!std::isfinite(max_energy_ratio)) return "failed";
    return max_energy_ratio <= 1.0 + c.band ? "stable" : "energy_growth";
  }
  if (exit_code == 1) return "blown_up";
  if (exit_code == 2) return "refused";
  return "failed";
}

std::string result_row(const Study& s, const StudyRun& r, int exit_code, const fs::path& out, const fs::path& log) {
  std::string row = csv_escape(r.variant) + "," + csv_escape(r.mesh) + "," + number(r.h);
  for (const std::string& k : s.param_keys) {
    std::string v;
    for (const auto& [pk, pv] : r.params)
      if (pk == k) v = pv;
    row += "," + csv_escape(v);
  }
  std::string status = "ok";
  double steps = NAN, wall = NAN, particles = NAN, nodes = NAN;
  std::map<std::string, double> errors, energy;
  const std::string refused = exit_code == 2 ? "input error: " + last_line(log) : "failed: " + last_line(log);
  // A run refused or failed (any status but 0 and 1) stopped before its
  // result file or without finishing it: whatever file is at its path may
  // be an earlier run's, so nothing is read from it.
  if (exit_code != 0 && exit_code != 1) status = refused;
  else try {
    status = read_string_attribute(out.string(), "status");
    steps = read_double_attribute(out.string(), "steps");
    wall = read_double_attribute(out.string(), "wall_seconds");
    particles = read_double_attribute(out.string(), "particles");
    nodes = read_double_attribute(out.string(), "nodes");
    for (const std::vector<std::string>* columns : {&error_columns, &pore_pressure_columns})
      for (const std::string& e : *columns) {
        try {
          errors[e] = read_double_attribute(out.string(), e == "history_error" ? "history_error_A" : e);
        } catch (const InputError&) { // not a run with that error
        }
      }
    for (const std::string& e : energy_columns) energy[e] = read_double_attribute(out.string(), e);
  } catch (const InputError&) {
    status = refused;
  }
  if (exit_code == 1 && status == "ok") status = "unstable";
  const double psps = (wall > 0) ? particles * steps / wall : NAN;
  row += "," + csv_escape(status) + "," + std::to_string(exit_code) + "," + number(steps) + "," + number(wall) + "," +
         number(particles) + "," + number(nodes) + "," + number(psps);
  for (const std::string& e : error_columns) row += "," + (errors.count(e) ? number(errors[e]) : std::string());
  for (const std::string& e : energy_columns) row += "," + (energy.count(e) ? number(energy[e]) : std::string());
  if (s.stability.enabled) {
    const double ratio = energy.count("max_energy_ratio") ? energy["max_energy_ratio"] : NAN;
    const std::string verdict = stability_class(s.stability, exit_code, ratio);
    row += "," + std::string(verdict == "stable" ? "1" : "0") + "," + verdict;
  }
  for (const std::string& e : pore_pressure_columns) row += "," + (errors.count(e) ? number(errors[e]) : std::string());
  return row;
}

} // namespace otmpm::study
