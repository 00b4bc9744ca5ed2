#pragma once
/// \file study_file.hpp
/// The study file of `otmpm study` and its reader. A study sweeps a base
/// scene over mesh sizes and variants; every (variant, mesh) pair is one run.
///
///   scene = "../dyka.toml"            # base scene, relative to the study file
///   csv = "dyka_study.csv"            # relative to the study file (default: STEM.csv)
///   results = "dyka_study"            # folder for the .h5 files (default: CSVSTEM_results)
///   jobs = 2                          # runs at a time (default: number of cores)
///   error = "rms_velocity_error"      # the error drawn in the plots
///   set = ["output.every=2e-6"]       # overrides applied to every run
///   [sweep]                           # cartesian product of --set values
///   "simulation.integrator" = ["fe", "npc"]
///   [[variant]]                       # and/or explicit variants
///   name = "ul-lme4-npc"
///   set = ["simulation.mode=ul", "basis.kind=lme"]
///   [[mesh]]
///   name = "n13"
///   h = 0.010254
///   set = ["grid.cells=[15]", "grid.lower=[-0.020508]"]
///   [reference]                       # optional: errors against a reference run
///   variant = "mpm-linear-npc"        # its finest run (default: each variant's own finest run)
///   file = "reference.h5"             # or a given result file (relative to the study file)
///   [[measure]]                       # what is compared (otmpm.convergence: extent, footprint, field, energy)
///   name = "length"
///   kind = "extent"
///   axis = 2
///   [stability]                       # optional: a stability study
///   band = 0.05                       # stable: exit 0 and max_energy_ratio <= 1 + band
///   key = "simulation.cfl"            # the swept parameter on the map's x axis (default)
///
/// The file is read with the scene reader's idiom (toml_reader.hpp): every
/// mistake is an InputError "FILE:LINE: key 'K': message". Variant names, mesh
/// names and the result files they map to must be distinct (also ignoring
/// case); the common and the mesh `set` entries are applied to the base
/// scene when the file is read, so a bad key or value there stops the study
/// before any run.
#include "otmpm/scene/scene.hpp"

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace otmpm::study {

/// One run of the study: a variant at a mesh size.
struct StudyRun {
  std::string variant, mesh;
  double h = 0.0;
  std::vector<std::string> sets;                           ///< all overrides, in order: common, mesh, variant
  std::vector<std::pair<std::string, std::string>> params; ///< variant parameters (for CSV columns)
  std::string file_stem;                                   ///< result and log file name, without extension
};

/// The [stability] section: a run is stable when it exits 0 and its
/// max_energy_ratio is at most 1 + band.
struct StabilityCriterion {
  bool enabled = false;
  double band = 0.0;
  std::string key = "simulation.cfl";
  SourceRef where; ///< stability.key (or the table): where an unswept key is reported
};

/// One [[measure]] of a study: its name and kind (the other keys are read
/// by otmpm.convergence, which computes it from the result files).
struct Measure {
  std::string name, kind;
};

/// A study as read from its file: paths resolved against the study file's
/// folder, every (variant, mesh) run with its overrides.
struct Study {
  std::filesystem::path file, scene, csv, results;
  SourceRef results_where; ///< the `results` key (or the file): where a results folder problem is reported
  int jobs = 1;
  std::string error = "rms_velocity_error";
  StabilityCriterion stability;
  std::vector<Measure> measures;       ///< [[measure]]: errors against the reference run after the runs
  std::filesystem::path reference;     ///< [reference] file (empty: a run of the study)
  std::string reference_variant;       ///< [reference] variant (empty: each variant's finest run)
  std::vector<StudyRun> runs;
  std::vector<std::string> param_keys; ///< the swept keys, in order of first appearance
};

/// Reads and checks a study file (InputError naming file, line and key;
/// also for a directory, a missing file, a scene or results path that is not
/// what it should be, colliding result files, and a common or mesh `set`
/// entry the base scene refuses).
Study read_study(const std::filesystem::path& file);

/// The file name a run's result and log get: variant and mesh joined by '_',
/// every character other than letters, digits, '-' and '.' replaced by '_'.
std::string file_stem(const std::string& variant, const std::string& mesh);

} // namespace otmpm::study
