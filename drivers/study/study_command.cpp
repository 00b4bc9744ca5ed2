// `otmpm study STUDY.toml`: sweeps a base scene over mesh sizes and variants,
// runs every (variant, mesh) pair as a child `otmpm run` process (several at a
// time), and appends one CSV row per run. Resumable: rows already in the CSV
// are skipped. At the end it draws the work-precision and convergence plots
// with scripts/plot_study.py (Debian's matplotlib) when python3 is available.
//
// Study file:
//   scene = "../dyka.toml"            # base scene, relative to the study file
//   csv = "dyka_study.csv"            # relative to the study file
//   results = "dyka_study"            # folder for the .h5 files (optional)
//   jobs = 2                          # runs at a time (default: number of cores)
//   error = "rms_velocity_error"      # the error drawn in the plots
//   set = ["output.every=2e-6"]       # overrides applied to every run
//   [sweep]                           # cartesian product of --set values
//   "simulation.integrator" = ["fe", "npc"]
//   [[variant]]                       # and/or explicit variants
//   name = "ul-lme4-npc"
//   set = ["simulation.mode=ul", "basis.kind=lme"]
//   [[mesh]]
//   name = "n13"
//   h = 0.010254
//   set = ["grid.cells=[15]", "grid.lower=[-0.020508]"]
//   [stability]                       # optional: a stability study
//   band = 0.05                       # stable: exit 0 and max_energy_ratio <= 1 + band
//   key = "simulation.cfl"            # the swept parameter on the map's x axis (default)
//
// Every row has the run's max_energy_ratio and energy_drift (RunSummary's
// EnergySummary, read from the result file). With [stability] the rows also
// get `stable` (1 or 0) and `stability` (stable, energy_growth, blown_up,
// refused, failed), and the plot is the stability map of
// scripts/plot_stability.py instead of the work-precision plots.
#include "commands.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/results.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace fs = std::filesystem;

namespace otmpm::cli {

namespace {

/// One run of the study: a variant at a mesh size.
struct StudyRun {
  std::string variant, mesh;
  double h = 0.0;
  std::vector<std::string> sets;      ///< all overrides, in order
  std::vector<std::pair<std::string, std::string>> params; ///< variant parameters (for CSV columns)
};

/// The [stability] section: a run is stable when it exits 0 and its
/// max_energy_ratio is at most 1 + band.
struct StabilityCriterion {
  bool enabled = false;
  double band = 0.0;
  std::string key = "simulation.cfl";
};

struct Study {
  fs::path file, scene, csv, results;
  int jobs = 1;
  std::string error = "rms_velocity_error";
  StabilityCriterion stability;
  std::vector<StudyRun> runs;
  std::vector<std::string> param_keys;
};

[[noreturn]] void study_error(const fs::path& file, const toml::node* n, const std::string& key, const std::string& msg) {
  const int line = n ? static_cast<int>(n->source().begin.line) : 0;
  throw InputError(file.string() + ":" + std::to_string(line) + ": key '" + key + "': " + msg);
}

std::vector<std::string> string_list(const fs::path& file, const toml::table& t, const std::string& key,
                                     const std::string& path) {
  std::vector<std::string> out;
  const toml::node* n = t.get(key);
  if (!n) return out;
  const toml::array* a = n->as_array();
  if (!a) study_error(file, n, path, "expected an array of strings");
  for (const toml::node& e : *a) {
    if (!e.is_string()) study_error(file, &e, path, "expected an array of strings");
    out.push_back(*e.value<std::string>());
  }
  return out;
}

void only_keys(const fs::path& file, const toml::table& t, const std::string& prefix, std::set<std::string> allowed) {
  for (const auto& [k, v] : t)
    if (!allowed.count(std::string(k.str())))
      study_error(file, &v, prefix + std::string(k.str()), "unknown key");
}

/// TOML value -> the text of a --set value.
std::string set_value(const fs::path& file, const toml::node& n, const std::string& key) {
  if (auto s = n.value<std::string>(); s && n.is_string()) return *s;
  if (n.is_integer()) return std::to_string(*n.value<std::int64_t>());
  if (n.is_floating_point()) { // the shortest text that reads back as the same double: 0.1, not 0.10000000000000001
    const double v = *n.value<double>();
    char b[40];
    for (int digits = 1; digits <= 17; ++digits) {
      std::snprintf(b, sizeof b, "%.*g", digits, v);
      if (std::strtod(b, nullptr) == v) break;
    }
    return b;
  }
  if (n.is_boolean()) return *n.value<bool>() ? "true" : "false";
  std::ostringstream os;
  if (const toml::array* a = n.as_array()) {
    os << *a;
    return os.str();
  }
  study_error(file, &n, key, "unsupported value type in [sweep]");
}

struct Variant {
  std::string name;
  std::vector<std::string> sets;
  std::vector<std::pair<std::string, std::string>> params;
};

std::vector<Variant> read_variants(const fs::path& file, const toml::table& root, std::vector<std::string>& keys) {
  std::vector<Variant> base{{"", {}, {}}};
  if (const toml::node* n = root.get("variant")) {
    const toml::array* a = n->as_array();
    if (!a) study_error(file, n, "variant", "expected [[variant]] tables");
    base.clear();
    for (const toml::node& e : *a) {
      const toml::table* t = e.as_table();
      if (!t) study_error(file, &e, "variant", "expected [[variant]] tables");
      only_keys(file, *t, "variant.", {"name", "set"});
      Variant v;
      v.name = t->get("name") ? t->get("name")->value_or<std::string>("") : "";
      if (v.name.empty()) study_error(file, &e, "variant.name", "every [[variant]] needs a name");
      v.sets = string_list(file, *t, "set", "variant.set");
      for (const std::string& s : v.sets) {
        const auto eq = s.find('=');
        if (eq == std::string::npos) study_error(file, &e, "variant.set", "'" + s + "' is not KEY=VALUE");
        v.params.emplace_back(s.substr(0, eq), s.substr(eq + 1));
      }
      base.push_back(v);
    }
  }
  if (const toml::node* n = root.get("sweep")) {
    const toml::table* t = n->as_table();
    if (!t) study_error(file, n, "sweep", "expected a table");
    for (const auto& [k, values] : *t) {
      const std::string key(k.str());
      const toml::array* a = values.as_array();
      if (!a || a->empty()) study_error(file, &values, "sweep." + key, "expected a non-empty array of values");
      std::vector<Variant> next;
      for (const Variant& v : base)
        for (const toml::node& val : *a) {
          Variant w = v;
          const std::string text = set_value(file, val, "sweep." + key);
          w.sets.push_back(key + "=" + text);
          w.params.emplace_back(key, text);
          w.name += (w.name.empty() ? "" : "/") + text;
          next.push_back(w);
        }
      base = next;
    }
  }
  for (const Variant& v : base)
    for (const auto& [k, val] : v.params)
      if (std::find(keys.begin(), keys.end(), k) == keys.end()) keys.push_back(k);
  return base;
}

Study read_study(const fs::path& file) {
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    throw InputError(file.string() + ":" + std::to_string(e.source().begin.line) + ":" +
                     std::to_string(e.source().begin.column) + ": syntax error: " + std::string(e.description()));
  }
  only_keys(file, root, "",
            {"scene", "csv", "results", "jobs", "error", "set", "sweep", "variant", "mesh", "stability"});
  Study s;
  s.file = file;
  const fs::path dir = file.parent_path();
  auto str = [&](const char* key, const std::string& fallback, bool required) {
    const toml::node* n = root.get(key);
    if (!n) {
      if (required) study_error(file, nullptr, key, "missing required key");
      return fallback;
    }
    if (!n->is_string()) study_error(file, n, key, "expected a string");
    return *n->value<std::string>();
  };
  s.scene = dir / str("scene", "", true);
  s.csv = dir / str("csv", file.stem().string() + ".csv", false);
  const std::string results = str("results", "", false);
  s.results = results.empty() ? s.csv.parent_path() / (s.csv.stem().string() + "_results") : dir / results;
  s.error = str("error", s.error, false);
  s.jobs = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (const toml::node* n = root.get("jobs")) {
    if (!n->is_integer() || *n->value<std::int64_t>() < 1) study_error(file, n, "jobs", "expected an integer >= 1");
    s.jobs = static_cast<int>(*n->value<std::int64_t>());
  }
  if (const toml::node* n = root.get("stability")) {
    const toml::table* t = n->as_table();
    if (!t) study_error(file, n, "stability", "expected a table");
    only_keys(file, *t, "stability.", {"band", "key"});
    const toml::node* band = t->get("band");
    if (!band || !band->is_number() || !(band->value<double>().value_or(0.0) > 0.0))
      study_error(file, band ? band : n, "stability.band", "expected a number > 0 (the allowed energy growth, e.g. 0.05)");
    s.stability.enabled = true;
    s.stability.band = *band->value<double>();
    if (const toml::node* k = t->get("key")) {
      if (!k->is_string()) study_error(file, k, "stability.key", "expected a string");
      s.stability.key = *k->value<std::string>();
    }
  }
  const std::vector<std::string> common = string_list(file, root, "set", "set");
  const std::vector<Variant> variants = read_variants(file, root, s.param_keys);
  const toml::node* meshes = root.get("mesh");
  const toml::array* ma = meshes ? meshes->as_array() : nullptr;
  if (!ma || ma->empty()) study_error(file, meshes, "mesh", "expected at least one [[mesh]] table");
  for (const toml::node& e : *ma) {
    const toml::table* t = e.as_table();
    if (!t) study_error(file, &e, "mesh", "expected [[mesh]] tables");
    only_keys(file, *t, "mesh.", {"name", "h", "set"});
    const toml::node* hn = t->get("h");
    if (!hn || !(hn->is_number()) || !(hn->value<double>().value_or(0.0) > 0.0))
      study_error(file, hn ? hn : &e, "mesh.h", "every [[mesh]] needs h > 0 (the mesh size used in the plots)");
    const double h = *hn->value<double>();
    std::string name = t->get("name") ? t->get("name")->value_or<std::string>("") : "";
    if (name.empty()) name = "h" + std::to_string(h);
    const std::vector<std::string> msets = string_list(file, *t, "set", "mesh.set");
    for (const Variant& v : variants) {
      StudyRun r;
      r.variant = v.name.empty() ? "base" : v.name;
      r.mesh = name;
      r.h = h;
      r.sets = common;
      r.sets.insert(r.sets.end(), msets.begin(), msets.end());
      r.sets.insert(r.sets.end(), v.sets.begin(), v.sets.end());
      r.params = v.params;
      s.runs.push_back(r);
    }
  }
  if (s.stability.enabled &&
      std::find(s.param_keys.begin(), s.param_keys.end(), s.stability.key) == s.param_keys.end())
    study_error(file, root.get("stability"), "stability.key",
                "'" + s.stability.key + "' is not swept: add it to [sweep] or to the variants' set");
  return s;
}

const std::vector<std::string> error_columns{"rms_velocity_error", "rms_displacement_error", "rms_stress_error",
                                             "history_error"};

std::string csv_escape(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

/// Energy columns: attributes of the result file, after the error columns.
const std::vector<std::string> energy_columns{"max_energy_ratio", "energy_drift"};

/// The header without the energy and stability columns: CSVs written before
/// those columns existed start with it and are extended in place.
std::string legacy_header(const Study& s) {
  std::string h = "variant,mesh,h";
  for (const std::string& k : s.param_keys) h += "," + csv_escape(k);
  h += ",status,exit_code,steps,wall_seconds,particles,nodes,particle_steps_per_second";
  for (const std::string& e : error_columns) h += "," + e;
  return h;
}

std::string header(const Study& s) {
  std::string h = legacy_header(s);
  for (const std::string& e : energy_columns) h += "," + e;
  if (s.stability.enabled) h += ",stable,stability";
  return h;
}

/// Rewrites a CSV whose header is legacy_header(s) with header(s), the rows
/// padded with empty cells for the new columns (they were not measured).
void upgrade_csv(const Study& s) {
  std::ifstream in(s.csv);
  std::string line;
  if (!std::getline(in, line) || line != legacy_header(s)) return;
  const std::string now = header(s);
  const std::string pad(static_cast<std::size_t>(std::count(now.begin(), now.end(), ',') -
                                                 std::count(line.begin(), line.end(), ',')),
                        ',');
  std::string text = now + "\n";
  while (std::getline(in, line)) text += line + pad + "\n";
  in.close();
  std::ofstream(s.csv, std::ios::trunc) << text;
  std::printf("%s: added the columns of this version (empty for the rows already there)\n", s.csv.c_str());
}

/// The (variant, mesh) pairs already in the CSV (first two columns).
std::set<std::pair<std::string, std::string>> done_runs(const Study& s) {
  std::set<std::pair<std::string, std::string>> done;
  std::ifstream in(s.csv);
  std::string line;
  if (!std::getline(in, line)) return done;
  if (line != header(s))
    throw InputError(s.csv.string() + ": the CSV header does not match this study (delete the file or use another csv)");
  while (std::getline(in, line)) {
    // variant and mesh never contain quotes in practice; split on the first two commas outside quotes
    std::vector<std::string> cols;
    std::string cur;
    bool q = false;
    for (char c : line) {
      if (c == '"') q = !q;
      else if (c == ',' && !q) { cols.push_back(cur); cur.clear(); if (cols.size() == 2) break; }
      else cur += c;
    }
    if (cols.size() == 2) done.insert({cols[0], cols[1]});
  }
  return done;
}

std::string self_path() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("otmpm") : p.string();
}

/// Starts `otmpm run` for one study run; returns the child pid.
pid_t start_run(const Study& s, const StudyRun& r, const fs::path& out, const fs::path& log) {
  std::vector<std::string> argv{self_path(), "run", s.scene.string(), "--quiet", "--out", out.string()};
  for (const std::string& set : r.sets) {
    argv.push_back("--set");
    argv.push_back(set);
  }
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error(std::string("fork failed: ") + std::strerror(errno));
  if (pid == 0) {
    std::FILE* f = std::freopen(log.c_str(), "w", stdout);
    if (f) dup2(fileno(stdout), STDERR_FILENO);
    setenv("OMP_NUM_THREADS", "1", 1);
    std::vector<char*> cargv;
    for (std::string& a : argv) cargv.push_back(a.data());
    cargv.push_back(nullptr);
    execv(cargv[0], cargv.data());
    _exit(127);
  }
  return pid;
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

/// The stability class of a run: stable (exit 0, max_energy_ratio <= 1 +
/// band), energy_growth (exit 0 but more energy than that), blown_up (exit 1:
/// NaN, runaway energy, det F <= 0, ...), refused (exit 2: the scene does not
/// allow the combination) or failed (anything else).
std::string stability_class(const StabilityCriterion& c, int exit_code, double max_energy_ratio) {
  if (exit_code == 0) {
    if (!std::isfinite(max_energy_ratio)) return "failed";
    return max_energy_ratio <= 1.0 + c.band ? "stable" : "energy_growth";
  }
  if (exit_code == 1) return "blown_up";
  if (exit_code == 2) return "refused";
  return "failed";
}

/// One CSV row from the finished child's result file (or its log if it failed early).
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
  try {
    status = read_string_attribute(out.string(), "status");
    steps = read_double_attribute(out.string(), "steps");
    wall = read_double_attribute(out.string(), "wall_seconds");
    particles = read_double_attribute(out.string(), "particles");
    nodes = read_double_attribute(out.string(), "nodes");
    for (const std::string& e : error_columns) {
      try {
        errors[e] = read_double_attribute(out.string(), e == "history_error" ? "history_error_A" : e);
      } catch (const InputError&) {
      }
    }
    for (const std::string& e : energy_columns) energy[e] = read_double_attribute(out.string(), e);
  } catch (const InputError&) {
    status = exit_code == 2 ? "input error: " + last_line(log) : "failed: " + last_line(log);
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
  return row;
}

std::string safe_name(std::string s) {
  for (char& c : s)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '.') c = '_';
  return s;
}

void draw_plots(const Study& s) {
  const std::string name = s.stability.enabled ? "plot_stability.py" : "plot_study.py";
  const fs::path script = fs::path(OTMPM_SOURCE_DIR) / "scripts" / name;
  const std::string args = s.stability.enabled
                               ? " --band " + number(s.stability.band) + " --key '" + s.stability.key + "'"
                               : " --error " + s.error;
  if (!fs::exists(script) || !fs::exists("/usr/bin/python3")) {
    std::printf("plots: run python3 scripts/%s %s%s\n", name.c_str(), s.csv.c_str(), args.c_str());
    return;
  }
  const std::string cmd = "/usr/bin/python3 '" + script.string() + "' '" + s.csv.string() + "'" + args;
  if (std::system(cmd.c_str()) != 0) std::fprintf(stderr, "otmpm: plot script failed: %s\n", cmd.c_str());
}

} // namespace

int study_command(const std::vector<std::string>& args) {
  if (args.size() != 1) throw InputError("usage: otmpm study STUDY.toml");
  if (!fs::exists(args[0])) throw InputError(args[0] + ": no such study file");
  const Study s = read_study(args[0]);
  if (!fs::exists(s.scene)) throw InputError(s.file.string() + ": key 'scene': no such file " + s.scene.string());
  fs::create_directories(s.results);
  upgrade_csv(s);
  const auto done = done_runs(s);
  const bool fresh = !fs::exists(s.csv) || fs::file_size(s.csv) == 0;
  std::ofstream csv(s.csv, std::ios::app);
  if (!csv) throw InputError("cannot write " + s.csv.string());
  if (fresh) csv << header(s) << "\n" << std::flush;
  std::vector<const StudyRun*> todo;
  for (const StudyRun& r : s.runs)
    if (!done.count({r.variant, r.mesh})) todo.push_back(&r);
  std::printf("study %s: %zu runs, %zu already in %s, %zu to do, %d at a time\n", s.file.c_str(), s.runs.size(),
              s.runs.size() - todo.size(), s.csv.c_str(), todo.size(), s.jobs);
  std::fflush(stdout);
  std::map<pid_t, const StudyRun*> running;
  std::size_t next = 0, finished = 0;
  auto paths = [&](const StudyRun& r) {
    const std::string base = safe_name(r.variant + "_" + r.mesh);
    return std::make_pair(s.results / (base + ".h5"), s.results / (base + ".log"));
  };
  while (next < todo.size() || !running.empty()) {
    while (next < todo.size() && static_cast<int>(running.size()) < s.jobs) {
      const auto [out, log] = paths(*todo[next]);
      running[start_run(s, *todo[next], out, log)] = todo[next];
      ++next;
    }
    int wstatus = 0;
    const pid_t pid = waitpid(-1, &wstatus, 0);
    if (pid < 0) break;
    const StudyRun* r = running.at(pid);
    running.erase(pid);
    const int code = WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : 128 + WTERMSIG(wstatus);
    const auto [out, log] = paths(*r);
    csv << result_row(s, *r, code, out, log) << "\n" << std::flush;
    std::printf("[%zu/%zu] %s %s: exit %d\n", ++finished, todo.size(), r->variant.c_str(), r->mesh.c_str(), code);
    std::fflush(stdout);
  }
  csv.close();
  draw_plots(s);
  return 0;
}

} // namespace otmpm::cli
