#include "study_file.hpp"

#include "otmpm/io/output_files.hpp"
#include "otmpm/scene/toml_reader.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <sstream>
#include <thread>

namespace fs = std::filesystem;

namespace otmpm::study {

using namespace toml_input;

namespace {

/// A variant before it meets the meshes; `where` is the [[variant]] table or
/// the [sweep] key that named it.
struct Variant {
  std::string name;
  SourceRef where;
  std::vector<std::string> sets;
  std::vector<std::pair<std::string, std::string>> params;
};

struct Mesh {
  std::string name;
  double h = 0.0;
  std::vector<std::string> sets;
  SourceRef where, set_where; ///< the [[mesh]] table, its `set`
};

/// `s` without leading and trailing blanks (as --set reads a key).
std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  return b == std::string::npos ? "" : s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

/// True when `key` is a dotted path of non-empty segments (what --set accepts).
bool valid_key(const std::string& key) {
  const std::string k = trim(key);
  return !k.empty() && k.front() != '.' && k.back() != '.' && k.find("..") == std::string::npos;
}

/// A list of "KEY=VALUE" overrides (the common `set`, a mesh's or a
/// variant's): each one is checked for its form here; the value itself is
/// checked by the scene reader of each run.
std::vector<std::string> overrides(const TableReader& t, std::string_view key) {
  std::vector<std::string> sets = t.strings(key).value_or(std::vector<std::string>{});
  for (const std::string& s : sets) {
    const auto eq = s.find('=');
    if (eq == std::string::npos || !valid_key(s.substr(0, eq)))
      input_error(t.ref(key), "'" + s + "' is not KEY=VALUE (a --set override, e.g. \"grid.cells=[40]\")");
  }
  return sets;
}

/// The (key, value) pairs of overrides, for the CSV's parameter columns.
std::vector<std::pair<std::string, std::string>> params_of(const std::vector<std::string>& sets) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const std::string& s : sets) out.emplace_back(s.substr(0, s.find('=')), s.substr(s.find('=') + 1));
  return out;
}

/// A [sweep] value as the text of a --set value: strings as they are, numbers
/// in the shortest form that reads back as the same double (0.1, not
/// 0.10000000000000001), booleans, arrays in TOML syntax.
std::string set_value(const toml::node& n, const SourceRef& where) {
  if (const auto* s = n.as_string()) return s->get();
  if (const auto* i = n.as_integer()) return std::to_string(i->get());
  if (const auto* f = n.as_floating_point()) {
    const double v = f->get();
    char b[40];
    for (int digits = 1; digits <= 17; ++digits) {
      std::snprintf(b, sizeof b, "%.*g", digits, v);
      if (std::strtod(b, nullptr) == v) break;
    }
    return b;
  }
  if (const auto* b = n.as_boolean()) return b->get() ? "true" : "false";
  if (const auto* a = n.as_array()) {
    std::ostringstream os;
    os << *a;
    return os.str();
  }
  input_error(where, "unsupported value type in [sweep] (" + type_name(n) + ")");
}

std::vector<Variant> read_variants(const TableReader& root) {
  std::vector<Variant> variants;
  for (const TableReader& t : root.tables("variant")) {
    t.only({"name", "set"});
    Variant v;
    v.where = t.self();
    v.name = t.require<std::string>("name");
    if (v.name.empty()) input_error(t.ref("name"), "must not be empty");
    v.sets = overrides(t, "set");
    v.params = params_of(v.sets);
    variants.push_back(std::move(v));
  }
  if (variants.empty()) variants.push_back({"", root.self(), {}, {}});
  if (auto sweep = root.table("sweep")) {
    sweep->for_each([&](const std::string& key, const toml::node& values, const SourceRef& where) {
      const toml::array* a = values.as_array();
      if (!a || a->empty()) input_error(where, "expected a non-empty array of values");
      std::vector<Variant> next;
      for (const Variant& v : variants)
        for (const toml::node& val : *a) {
          Variant w = v;
          const std::string text = set_value(val, where);
          w.sets.push_back(key + "=" + text);
          w.params.emplace_back(key, text);
          w.name += (w.name.empty() ? "" : "/") + text;
          w.where = where;
          next.push_back(std::move(w));
        }
      variants = std::move(next);
    });
  }
  return variants;
}

std::vector<Mesh> read_meshes(const TableReader& root) {
  std::vector<Mesh> meshes;
  for (const TableReader& t : root.tables("mesh")) {
    t.only({"name", "h", "set"});
    Mesh m;
    m.where = t.self();
    m.h = t.require<double>("h");
    if (!(m.h > 0)) input_error(t.ref("h"), "must be > 0 (the mesh size used in the plots)");
    m.name = t.get<std::string>("name", "h" + std::to_string(m.h));
    if (m.name.empty()) input_error(t.ref("name"), "must not be empty");
    m.sets = overrides(t, "set");
    m.set_where = t.has("set") ? t.ref("set") : t.self();
    meshes.push_back(std::move(m));
  }
  if (meshes.empty()) root.missing("mesh", "at least one [[mesh]] table is required");
  return meshes;
}

/// Refuses a name used twice: two runs would share a CSV row key and a result file.
void check_distinct(const std::vector<std::pair<std::string, SourceRef>>& named, const std::string& what) {
  std::map<std::string, SourceRef> seen;
  for (const auto& [name, where] : named) {
    auto [it, fresh] = seen.emplace(name, where);
    if (!fresh)
      input_error(where, what + " name \"" + name + "\" is used twice (also at " + it->second.describe() +
                             "): every " + what + " needs its own name");
  }
}

StabilityCriterion read_stability(const TableReader& root) {
  StabilityCriterion c;
  auto t = root.table("stability");
  if (!t) return c;
  t->only({"band", "key"});
  c.enabled = true;
  c.band = t->require<double>("band");
  if (!(c.band > 0)) input_error(t->ref("band"), "must be > 0 (the allowed energy growth, e.g. 0.05)");
  c.key = t->get<std::string>("key", c.key);
  c.where = t->has("key") ? t->ref("key") : t->self();
  return c;
}

/// The keys each kind of [[measure]] takes besides name and kind: required, then optional
/// (otmpm.convergence.KINDS, which computes them).
const std::map<std::string, std::pair<std::vector<std::string_view>, std::vector<std::string_view>>, std::less<>>
    kMeasureKinds = {{"extent", {{"axis"}, {"initial"}}},
                     {"footprint", {{"axis"}, {"layer", "center", "initial"}}},
                     {"field", {{"field"}, {"points", "grid", "probes"}}},
                     {"energy", {{"series"}, {}}}};

/// The [[measure]] tables: names distinct, kinds known, their keys present
/// (a field measure samples at `points`, a `grid` or `probes`: one of them).
std::vector<Measure> read_measures(const TableReader& root) {
  std::vector<Measure> out;
  std::vector<std::pair<std::string, SourceRef>> names;
  std::vector<std::string_view> kinds;
  for (const auto& [kind, keys] : kMeasureKinds) kinds.push_back(kind);
  for (const TableReader& t : root.tables("measure")) {
    Measure m;
    m.name = t.require<std::string>("name");
    if (m.name.empty() || m.name.find_first_of(",\"\n") != std::string::npos)
      input_error(t.ref("name"), "must be a non-empty name without commas, quotes or newlines (a CSV column)");
    m.kind = t.choice("kind", "", kinds);
    const auto& [required, optional] = kMeasureKinds.find(m.kind)->second;
    std::vector<std::string_view> allowed{"name", "kind"};
    allowed.insert(allowed.end(), required.begin(), required.end());
    allowed.insert(allowed.end(), optional.begin(), optional.end());
    t.only(allowed);
    for (std::string_view key : required)
      if (!t.has(key)) t.missing(key);
    if (m.kind == "field" && t.has("points") + t.has("grid") + t.has("probes") != 1)
      input_error(t.self(), "measure \"" + m.name + "\": give exactly one of points, grid and probes");
    if (t.has("axis") && (t.require<int>("axis") < 0 || t.require<int>("axis") > 2))
      input_error(t.ref("axis"), "must be 0, 1 or 2 (x, y, z)");
    names.emplace_back(m.name, t.self());
    out.push_back(m);
  }
  check_distinct(names, "measure");
  return out;
}

/// The [reference] table: a `variant` of the study or a result `file`.
void read_reference(const TableReader& root, const fs::path& dir, Study& s) {
  auto t = root.table("reference");
  if (!t) return;
  t->only({"variant", "file"});
  if (t->has("variant") && t->has("file")) input_error(t->self(), "give a variant or a file, not both");
  if (t->has("file")) {
    s.reference = dir / t->require<std::string>("file");
    if (!fs::is_regular_file(s.reference))
      input_error(t->ref("file"), "the reference result file " + s.reference.string() + " does not exist");
  }
  s.reference_variant = t->get<std::string>("variant", "");
  if (s.measures.empty()) input_error(t->self(), "a [reference] needs [[measure]] tables: what to compare");
}

/// The nearest existing one of `p` and its parent folders ("" if none exists).
fs::path existing_ancestor(fs::path p) {
  std::error_code ec;
  while (!p.empty() && !fs::exists(fs::symlink_status(p, ec))) {
    if (p == p.parent_path()) return {};
    p = p.parent_path();
  }
  return p;
}

/// InputError at `where` unless `path` is a directory or can be created as one.
void check_folder(const SourceRef& where, const fs::path& path, const std::string& what) {
  std::error_code ec;
  const fs::path ancestor = existing_ancestor(path);
  if (ancestor.empty() || fs::is_directory(ancestor, ec)) return;
  if (ancestor == path)
    input_error(where, path.string() + " exists and is not a directory (" + what + ")");
  input_error(where, path.string() + " cannot be created: " + ancestor.string() + " is a file, not a directory (" +
                         what + ")");
}

/// The scene must be a file; results a directory (or one that can be
/// created); csv a file (or absent) in an existing folder.
void check_paths(const TableReader& root, const Study& s) {
  std::error_code ec;
  if (fs::is_directory(s.scene, ec)) input_error(root.ref("scene"), s.scene.string() + " is a directory, not a scene file");
  if (const std::string kind = special_file(s.scene.string()); !kind.empty())
    input_error(root.ref("scene"), s.scene.string() + " is " + kind + ", not a scene file");
  if (!fs::exists(s.scene, ec)) input_error(root.ref("scene"), "no such file " + s.scene.string());
  check_folder(s.results_where, s.results, "the folder for the result files");
  const SourceRef csv = root.has("csv") ? root.ref("csv") : root.self();
  if (fs::is_directory(s.csv, ec)) input_error(csv, s.csv.string() + " is a directory, not a CSV file");
  if (const std::string kind = special_file(s.csv.string()); !kind.empty())
    input_error(csv, s.csv.string() + " is " + kind + ", not a CSV file");
  const fs::path folder = s.csv.parent_path().empty() ? fs::path(".") : s.csv.parent_path();
  if (!fs::is_directory(folder, ec))
    input_error(csv, "the folder of the CSV file " + s.csv.string() + " does not exist (create it first)");
}

/// A `set` list of the study file and where it is.
struct Overrides {
  std::vector<std::string> sets;
  SourceRef where;
};

/// The entry of `o` (the last one: it wins) that sets `key`, or nullptr.
const std::string* entry_setting(const Overrides& o, const std::string& key) {
  for (auto it = o.sets.rbegin(); it != o.sets.rend(); ++it)
    if (trim(it->substr(0, it->find('='))) == key) return &*it;
  return nullptr;
}

/// Applies the common `set` and each mesh's `set` to the base scene, before
/// any run starts: an entry the scene reader refuses (an unknown key, a value
/// of the wrong type or out of range) is an InputError at that entry.
/// Errors of the base scene itself are left to the runs (a variant may be
/// what makes the scene valid, and a refused variant is a result of a
/// stability study).
void check_overrides(const fs::path& scene, const Overrides& common, const std::vector<Mesh>& meshes) {
  for (const Mesh& m : meshes) {
    const Overrides mesh{m.sets, m.set_where};
    std::vector<std::string> sets = common.sets;
    sets.insert(sets.end(), m.sets.begin(), m.sets.end());
    try {
      (void)load_scene(scene.string(), sets);
    } catch (const InputError& e) {
      const InputSource* from = e.source();
      if (!from || from->line != kCommandLineLine) continue;
      for (const Overrides* o : {&mesh, &common})
        if (const std::string* entry = entry_setting(*o, from->key))
          input_error(o->where, "\"" + *entry + "\" does not apply to the scene " + scene.string() + ": " + e.what());
    }
  }
}

/// Longest result file stem: the lock file of NAME.xdmf, `.NAME.xdmf.otmpm-lock`,
/// must fit in the 255 bytes of a file name.
constexpr std::size_t kMaxStemBytes = 200;

/// `variant "NAME"` or `mesh "NAME"`, with where it is when `with_where`.
std::string named(const std::string& what, const std::string& name, const SourceRef& where, bool with_where) {
  return what + " \"" + name + "\"" + (with_where ? " (" + where.describe() + ")" : "");
}

/// InputError: run (v, m) has the result file of the earlier run (v0, m0),
/// reported at the variant or mesh that differs and naming both.
[[noreturn]] void collision(const std::string& file, const Variant& v, const Mesh& m, const Variant& v0,
                            const Mesh& m0) {
  const std::string why = " map to the same result file " + file +
                          " (names are compared as file names: characters other than letters, digits, '-' and "
                          "'.' become '_', and case does not count): rename one of them";
  if (&v == &v0)
    input_error(m.where, named("mesh", m.name, m.where, false) + " and " + named("mesh", m0.name, m0.where, true) +
                             why);
  const std::string at = &m == &m0 ? "" : " at mesh \"" + m.name + "\"";
  const std::string at0 = &m == &m0 ? "" : " at mesh \"" + m0.name + "\"";
  input_error(v.where, named("variant", v.name, v.where, false) + at + " and " +
                           named("variant", v0.name, v0.where, true) + at0 + why);
}

/// Refuses a run whose result file is another run's (compared without case,
/// as on the case-insensitive file systems of macOS and Windows) or whose
/// name is too long for a file name. `stems` holds the runs made so far.
void check_result_file(const Study& s, const StudyRun& r, const Variant& v, const Mesh& m,
                       std::map<std::string, std::pair<const Variant*, const Mesh*>>& stems) {
  if (r.file_stem.size() > kMaxStemBytes)
    input_error(v.where, named("variant", r.variant, v.where, false) + " at mesh \"" + m.name +
                             "\" gives a result file name of " + std::to_string(r.file_stem.size() + 3) +
                             " bytes; at most " + std::to_string(kMaxStemBytes + 3) + ": shorten the names");
  std::string key = r.file_stem;
  std::transform(key.begin(), key.end(), key.begin(), [](unsigned char c) { return std::tolower(c); });
  const auto [it, fresh] = stems.emplace(key, std::make_pair(&v, &m));
  if (!fresh) collision((s.results / (r.file_stem + ".h5")).string(), v, m, *it->second.first, *it->second.second);
}

/// The runs: every mesh with every variant, its overrides in the order
/// common, mesh, variant.
void make_runs(Study& s, const std::vector<std::string>& common, const std::vector<Variant>& variants,
               const std::vector<Mesh>& meshes) {
  std::map<std::string, std::pair<const Variant*, const Mesh*>> stems;
  for (const Mesh& m : meshes)
    for (const Variant& v : variants) {
      StudyRun r;
      r.variant = v.name.empty() ? "base" : v.name;
      r.mesh = m.name;
      r.h = m.h;
      r.sets = common;
      r.sets.insert(r.sets.end(), m.sets.begin(), m.sets.end());
      r.sets.insert(r.sets.end(), v.sets.begin(), v.sets.end());
      r.params = v.params;
      r.file_stem = file_stem(r.variant, r.mesh);
      check_result_file(s, r, v, m, stems);
      for (const auto& kv : v.params)
        if (std::find(s.param_keys.begin(), s.param_keys.end(), kv.first) == s.param_keys.end())
          s.param_keys.push_back(kv.first);
      s.runs.push_back(std::move(r));
    }
}

} // namespace

std::string file_stem(const std::string& variant, const std::string& mesh) {
  std::string s = variant + "_" + mesh;
  for (char& c : s)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '.') c = '_';
  return s;
}

Study read_study(const fs::path& file) {
  const toml::table table = parse_toml_file(file.string(), "study file");
  Context ctx;
  ctx.file = file.string();
  const TableReader root(ctx, &table, "", SourceRef{ctx.file, 1, ""});
  root.only({"scene", "csv", "results", "jobs", "error", "set", "sweep", "variant", "mesh", "stability", "reference",
             "measure"});
  Study s;
  s.file = file;
  const fs::path dir = file.parent_path();
  s.scene = dir / root.require<std::string>("scene");
  s.csv = dir / root.get<std::string>("csv", file.stem().string() + ".csv");
  s.results = root.has("results") ? dir / root.require<std::string>("results")
                                  : s.csv.parent_path() / (s.csv.stem().string() + "_results");
  s.results_where = root.has("results") ? root.ref("results") : root.self();
  check_paths(root, s);
  s.error = root.choice("error", s.error,
                        {"rms_velocity_error", "rms_displacement_error", "rms_stress_error", "history_error",
                         "rms_pore_pressure_error", "max_pore_pressure_error"});
  s.jobs = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  s.jobs = root.get<int>("jobs", s.jobs);
  if (s.jobs < 1) input_error(root.ref("jobs"), "must be an integer >= 1");
  s.stability = read_stability(root);
  s.measures = read_measures(root);
  read_reference(root, dir, s);
  const Overrides common{overrides(root, "set"), root.has("set") ? root.ref("set") : root.self()};
  const std::vector<Variant> variants = read_variants(root);
  const std::vector<Mesh> meshes = read_meshes(root);
  std::vector<std::pair<std::string, SourceRef>> names;
  for (const Variant& v : variants) names.emplace_back(v.name, v.where);
  check_distinct(names, "variant");
  names.clear();
  for (const Mesh& m : meshes) names.emplace_back(m.name, m.where);
  check_distinct(names, "mesh");
  check_overrides(s.scene, common, meshes);
  make_runs(s, common.sets, variants, meshes);
  if (!s.reference_variant.empty() &&
      std::none_of(s.runs.begin(), s.runs.end(), [&](const StudyRun& r) { return r.variant == s.reference_variant; }))
    input_error(root.table("reference")->ref("variant"), "no variant \"" + s.reference_variant + "\" in this study");
  if (s.stability.enabled &&
      std::find(s.param_keys.begin(), s.param_keys.end(), s.stability.key) == s.param_keys.end())
    input_error(s.stability.where,
                "'" + s.stability.key + "' is not swept: add it to [sweep] or to the variants' set");
  return s;
}

} // namespace otmpm::study
