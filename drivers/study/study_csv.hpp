#pragma once
/// \file study_csv.hpp
/// The CSV of a study: one row per finished run - variant, mesh, h, the swept
/// parameters, status, exit code, steps, wall time, particles, nodes,
/// particle-steps per second, the errors against the exact solution,
/// max_energy_ratio and energy_drift, and with [stability] the columns
/// `stable` (1/0) and `stability` (stable, energy_growth, blown_up, refused,
/// failed). Rows are appended as runs finish; the (variant, mesh) pairs in
/// the file are the runs a resumed study skips.
#include "study_file.hpp"

#include <filesystem>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace otmpm::study {

/// (variant, mesh) of the runs already in the CSV.
using DoneRuns = std::set<std::pair<std::string, std::string>>;

/// Makes the CSV ready for appending and returns the runs it holds: a new
/// file gets the header; a file written before the energy columns existed
/// is extended in place (empty cells); a last row cut off by a kill (no
/// final newline) and any row without the header's number of cells are
/// dropped, so that run is done again and the next row starts on its own
/// line. InputError if the header belongs to another study.
DoneRuns prepare_csv(const Study& s);

/// The CSV row of a finished run, from its result file (or, when the run
/// failed before writing one, the last line of its log).
std::string result_row(const Study& s, const StudyRun& r, int exit_code, const std::filesystem::path& out,
                       const std::filesystem::path& log);

/// Appends one row (and a newline) and flushes it to the file.
void append_row(const Study& s, const std::string& row);

/// The cells of one CSV line (RFC 4180: "a, ""b""" is one cell).
std::vector<std::string> csv_cells(const std::string& line);

/// The stability class of a run: stable (exit 0, max_energy_ratio <= 1 +
/// band), energy_growth (exit 0 but more energy than that), blown_up (exit 1:
/// NaN, runaway energy, det F <= 0, ...), refused (exit 2: the scene does not
/// allow the combination) or failed (anything else).
std::string stability_class(const StabilityCriterion& c, int exit_code, double max_energy_ratio);

} // namespace otmpm::study
