#include "study_file.hpp"

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
  SourceRef where;
};

/// True when `key` is a dotted path of non-empty segments (what --set accepts).
bool valid_key(const std::string& key) {
  const auto b = key.find_first_not_of(" \t"), e = key.find_last_not_of(" \t");
  if (b == std::string::npos) return false;
  const std::string k = key.substr(b, e - b + 1);
  return k.front() != '.' && k.back() != '.' && k.find("..") == std::string::npos;
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

/// The scene must be a file; results a directory (or absent); csv a file (or absent).
void check_paths(const TableReader& root, const Study& s) {
  std::error_code ec;
  if (fs::is_directory(s.scene, ec)) input_error(root.ref("scene"), s.scene.string() + " is a directory, not a scene file");
  if (!fs::exists(s.scene, ec)) input_error(root.ref("scene"), "no such file " + s.scene.string());
  if (fs::exists(s.results, ec) && !fs::is_directory(s.results, ec))
    input_error(root.has("results") ? root.ref("results") : root.self(),
                s.results.string() + " exists and is not a directory (the folder for the result files)");
  if (fs::is_directory(s.csv, ec))
    input_error(root.has("csv") ? root.ref("csv") : root.self(), s.csv.string() + " is a directory, not a CSV file");
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
  root.only({"scene", "csv", "results", "jobs", "error", "set", "sweep", "variant", "mesh", "stability"});
  Study s;
  s.file = file;
  const fs::path dir = file.parent_path();
  s.scene = dir / root.require<std::string>("scene");
  s.csv = dir / root.get<std::string>("csv", file.stem().string() + ".csv");
  s.results = root.has("results") ? dir / root.require<std::string>("results")
                                  : s.csv.parent_path() / (s.csv.stem().string() + "_results");
  check_paths(root, s);
  s.error = root.choice("error", s.error,
                        {"rms_velocity_error", "rms_displacement_error", "rms_stress_error", "history_error"});
  s.jobs = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  s.jobs = root.get<int>("jobs", s.jobs);
  if (s.jobs < 1) input_error(root.ref("jobs"), "must be an integer >= 1");
  s.stability = read_stability(root);
  const std::vector<std::string> common = overrides(root, "set");
  const std::vector<Variant> variants = read_variants(root);
  const std::vector<Mesh> meshes = read_meshes(root);
  std::vector<std::pair<std::string, SourceRef>> names;
  for (const Variant& v : variants) names.emplace_back(v.name, v.where);
  check_distinct(names, "variant");
  names.clear();
  for (const Mesh& m : meshes) names.emplace_back(m.name, m.where);
  check_distinct(names, "mesh");
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
      auto [it, fresh] = stems.emplace(r.file_stem, std::make_pair(&v, &m));
      if (!fresh) {
        const bool same_variant = it->second.first == &v;
        const SourceRef& other = same_variant ? it->second.second->where : it->second.first->where;
        input_error(same_variant ? m.where : v.where,
                    std::string(same_variant ? "mesh \"" + m.name : "variant \"" + v.name) +
                        "\" and the one at " + other.describe() + " map to the same result file " +
                        (s.results / (r.file_stem + ".h5")).string() + ": rename one of them");
      }
      for (const auto& kv : v.params)
        if (std::find(s.param_keys.begin(), s.param_keys.end(), kv.first) == s.param_keys.end())
          s.param_keys.push_back(kv.first);
      s.runs.push_back(std::move(r));
    }
  if (s.stability.enabled &&
      std::find(s.param_keys.begin(), s.param_keys.end(), s.stability.key) == s.param_keys.end())
    input_error(s.stability.where,
                "'" + s.stability.key + "' is not swept: add it to [sweep] or to the variants' set");
  return s;
}

} // namespace otmpm::study
