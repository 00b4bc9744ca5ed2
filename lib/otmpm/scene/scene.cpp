// Scene file reader: TOML text -> Scene, with errors that name file, line and
// key (interfaces.md "Scene file"). The TOML is parsed with toml++, --set
// overrides are applied to the parsed table, and only then is every value
// read and checked, so that overrides meet exactly the same checks as the file.
#include "otmpm/scene/scene.hpp"

#include "otmpm/io/results.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

namespace otmpm {

namespace {

/// SourceRef::line of a value that came from a --set override.
constexpr int kCommandLineLine = -1;
/// A grid node lies in a box when it is inside up to this fraction of h.
constexpr double kNodeTolerance = 1e-9;
/// grid.h must divide (upper - lower) into an integer to this relative accuracy.
constexpr double kCellsTolerance = 1e-6;
/// Largest edit distance for which an unknown key gets a "did you mean".
constexpr std::size_t kSuggestDistance = 3;

using Names = std::initializer_list<std::string_view>;

const std::set<std::string, std::less<>> kTableArrays = {"material", "body", "initial_velocity", "boundary",
                                                         "traction", "probes"};

std::string fmt(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", x);
  return buf;
}

std::string quoted_list(Names names) {
  std::string s;
  for (auto n : names) s += (s.empty() ? "\"" : ", \"") + std::string(n) + "\"";
  return s;
}

std::string join_path(const std::string& prefix, std::string_view key) {
  return prefix.empty() ? std::string(key) : prefix + "." + std::string(key);
}

std::string type_name(const toml::node& n) {
  switch (n.type()) {
  case toml::node_type::table: return "a table";
  case toml::node_type::array: return "an array";
  case toml::node_type::string: return "a string";
  case toml::node_type::integer: return "an integer";
  case toml::node_type::floating_point: return "a float";
  case toml::node_type::boolean: return "a boolean";
  default: return "a date/time";
  }
}

/// Levenshtein distance, for "did you mean" suggestions.
std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

std::string suggestion(std::string_view key, Names allowed) {
  std::string_view best;
  std::size_t best_d = kSuggestDistance + 1;
  for (auto a : allowed) {
    const std::size_t d = edit_distance(key, a);
    if (d < best_d) { best_d = d; best = a; }
  }
  if (!best.empty() && best_d < key.size()) return " (did you mean '" + std::string(best) + "'?)";
  return " (allowed: " + quoted_list(allowed) + ")";
}

/// State shared by all readers of one scene: file name, which paths --set
/// wrote (dotted path -> the KEY typed on the command line) and every key read.
struct Context {
  std::string file;
  std::map<std::string, std::string> overridden;
  std::map<std::string, SourceRef> where;

  /// Where `path` came from: the --set that wrote it (or a table above it),
  /// else the node's line in the file, else `fallback_line`.
  SourceRef ref(const std::string& path, const toml::node* node, int fallback_line) const {
    for (std::size_t pos = 0; pos != std::string::npos;) {
      pos = path.find('.', pos + 1);
      auto it = overridden.find(path.substr(0, pos));
      if (it != overridden.end()) return SourceRef{file, kCommandLineLine, it->second};
    }
    int line = node ? static_cast<int>(node->source().begin.line) : 0;
    return SourceRef{file, line > 0 ? line : fallback_line, path};
  }
};

template <class T> T convert(const toml::node& n, const SourceRef& r);

template <> double convert<double>(const toml::node& n, const SourceRef& r) {
  double v = 0;
  if (auto i = n.as_integer()) v = static_cast<double>(i->get());
  else if (auto f = n.as_floating_point()) v = f->get();
  else input_error(r, "expected a number, got " + type_name(n));
  if (!std::isfinite(v)) input_error(r, "must be a finite number");
  return v;
}
template <> int convert<int>(const toml::node& n, const SourceRef& r) {
  auto i = n.as_integer();
  if (!i) input_error(r, "expected an integer, got " + type_name(n));
  const std::int64_t v = i->get();
  if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max())
    input_error(r, "integer out of range");
  return static_cast<int>(v);
}
template <> std::int64_t convert<std::int64_t>(const toml::node& n, const SourceRef& r) {
  auto i = n.as_integer();
  if (!i) input_error(r, "expected an integer, got " + type_name(n));
  return i->get();
}
template <> std::string convert<std::string>(const toml::node& n, const SourceRef& r) {
  auto s = n.as_string();
  if (!s) input_error(r, "expected a string, got " + type_name(n));
  return s->get();
}
template <> bool convert<bool>(const toml::node& n, const SourceRef& r) {
  auto b = n.as_boolean();
  if (!b) input_error(r, "expected a boolean, got " + type_name(n));
  return b->get();
}

/// Reads the keys of one TOML table, checking names, types and presence.
/// Every key read is recorded in Context::where under its dotted path.
class TableReader {
public:
  TableReader(Context& ctx, const toml::table* table, std::string path, SourceRef self)
      : ctx_(&ctx), table_(table), path_(std::move(path)), self_(std::move(self)) {
    if (!path_.empty()) ctx_->where[path_] = self_;
  }

  const SourceRef& self() const { return self_; }
  const std::string& path() const { return path_; }
  std::string key_path(std::string_view key) const { return join_path(path_, key); }
  bool has(std::string_view key) const { return node(key) != nullptr; }
  const toml::node* node(std::string_view key) const { return table_ ? table_->get(key) : nullptr; }

  /// The SourceRef of `key` (its own line, or the table's line when absent).
  SourceRef ref(std::string_view key) const {
    const std::string p = key_path(key);
    SourceRef r = ctx_->ref(p, node(key), self_.line);
    if (r.line == kCommandLineLine || node(key)) ctx_->where[p] = r;
    return r;
  }

  /// Unknown keys are errors; the first one in file order (or from --set) is reported.
  void only(Names allowed) const {
    if (!table_) return;
    const toml::key* first = nullptr;
    for (auto&& [k, v] : *table_) {
      if (std::find(allowed.begin(), allowed.end(), k.str()) != allowed.end()) continue;
      if (!first || k.source().begin.line < first->source().begin.line) first = &k;
    }
    if (first) input_error(ref(first->str()), "unknown key" + suggestion(first->str(), allowed));
  }

  [[noreturn]] void missing(std::string_view key, const std::string& what = "required key is missing") const {
    SourceRef r = ctx_->ref(key_path(key), nullptr, self_.line);
    if (r.line == 0) r.line = 1;
    // A table written by --set: r names the --set KEY, so say which key inside it is missing.
    if (r.line == kCommandLineLine) input_error(r, what + " ('" + key_path(key) + "')");
    input_error(r, what);
  }

  template <class T> std::optional<T> get(std::string_view key) const {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    return convert<T>(*n, ref(key));
  }
  template <class T> T get(std::string_view key, T fallback) const {
    auto v = get<T>(key);
    return v ? *v : fallback;
  }
  template <class T> T require(std::string_view key) const {
    auto v = get<T>(key);
    if (!v) missing(key);
    return *v;
  }

  /// A string that must be one of `allowed`.
  std::string choice(std::string_view key, std::string fallback, Names allowed) const {
    std::string v = get<std::string>(key, fallback);
    if (std::find(allowed.begin(), allowed.end(), v) == allowed.end())
      input_error(ref(key), "must be one of " + quoted_list(allowed) + " (got \"" + v + "\")");
    return v;
  }

  /// An array of `dim` numbers (or, if `scalar_ok`, one number for all axes).
  std::optional<Vec3> vec(std::string_view key, int dim, bool scalar_ok = false) const {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    const SourceRef r = ref(key);
    Vec3 out{0, 0, 0};
    if (scalar_ok && !n->is_array()) {
      const double s = convert<double>(*n, r);
      for (int k = 0; k < dim; ++k) out[k] = s;
      return out;
    }
    const toml::array& a = array_of_length(*n, r, dim, "numbers");
    for (int k = 0; k < dim; ++k) out[k] = convert<double>(a[static_cast<std::size_t>(k)], r);
    return out;
  }
  Vec3 require_vec(std::string_view key, int dim) const {
    auto v = vec(key, dim);
    if (!v) missing(key);
    return *v;
  }

  std::optional<std::array<bool, 3>> bools(std::string_view key, int dim) const {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    const SourceRef r = ref(key);
    const toml::array& a = array_of_length(*n, r, dim, "booleans");
    std::array<bool, 3> out{false, false, false};
    for (int k = 0; k < dim; ++k) out[k] = convert<bool>(a[static_cast<std::size_t>(k)], r);
    return out;
  }

  /// A sub-table (a [header] table or an inline table), if present.
  std::optional<TableReader> table(std::string_view key) const {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    const SourceRef r = ref(key);
    if (!n->is_table()) input_error(r, "expected a table, got " + type_name(*n));
    return TableReader(*ctx_, n->as_table(), key_path(key), with_line(r));
  }
  TableReader require_table(std::string_view key) const {
    auto t = table(key);
    if (!t) missing(key, "required table [" + key_path(key) + "] is missing");
    return *t;
  }

  /// The elements of an array of tables ([[key]] or key = [{...}]). Each is
  /// named "key.NAME" when it has a string `name`, else "key.INDEX".
  std::vector<TableReader> tables(std::string_view key) const {
    std::vector<TableReader> out;
    const toml::node* n = node(key);
    if (!n) return out;
    const SourceRef r = ref(key);
    if (!n->is_array()) input_error(r, "expected an array of tables ([[" + key_path(key) + "]]), got " + type_name(*n));
    std::size_t i = 0;
    for (const toml::node& el : *n->as_array()) {
      const std::string p = key_path(key) + "." + element_name(el, i++);
      const SourceRef er = ctx_->ref(p, &el, r.line);
      if (!el.is_table()) input_error(er, "expected a table, got " + type_name(el));
      out.emplace_back(*ctx_, el.as_table(), p, er);
    }
    return out;
  }

  /// The name an element is addressed by; control characters (which no
  /// valid name has) are shown as \\xHH so that messages stay printable.
  static std::string element_name(const toml::node& el, std::size_t index) {
    if (const toml::table* t = el.as_table())
      if (auto name = t->get_as<std::string>("name")) return printable(name->get());
    return std::to_string(index);
  }

  static std::string printable(const std::string& s) {
    std::string out;
    for (unsigned char c : s) {
      if (c >= 0x20 && c != 0x7f) {
        out += static_cast<char>(c);
        continue;
      }
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    }
    return out;
  }

private:
  SourceRef with_line(SourceRef r) const {
    if (r.line == 0) r.line = self_.line;
    return r;
  }
  static const toml::array& array_of_length(const toml::node& n, const SourceRef& r, int dim,
                                            const char* what) {
    const toml::array* a = n.as_array();
    if (!a) input_error(r, "expected an array of " + std::to_string(dim) + " " + what + ", got " + type_name(n));
    if (static_cast<int>(a->size()) != dim)
      input_error(r, "has " + std::to_string(a->size()) + " components but simulation.dimension = " +
                         std::to_string(dim));
    return *a;
  }

  Context* ctx_;
  const toml::table* table_;
  std::string path_;
  SourceRef self_;
};

void check(bool ok, const SourceRef& r, const std::string& message) {
  if (!ok) input_error(r, message);
}

/// A positive number, or absent (fallback).
double positive(const TableReader& t, std::string_view key, double fallback) {
  const double v = t.get<double>(key, fallback);
  check(v > 0, t.ref(key), "must be > 0 (got " + fmt(v) + ")");
  return v;
}

/// Every component of upper strictly (or not) above lower.
void check_box(const TableReader& t, const Vec3& lo, const Vec3& hi, int dim, bool strict) {
  for (int k = 0; k < dim; ++k) {
    const bool ok = strict ? lo[k] < hi[k] : lo[k] <= hi[k];
    check(ok, t.ref("upper"), std::string("must be ") + (strict ? ">" : ">=") + " lower in every component (axis " +
                                  std::to_string(k) + ": lower " + fmt(lo[k]) + ", upper " + fmt(hi[k]) + ")");
  }
}

// ---------------------------------------------------------------- sections

SimulationSection read_simulation(const TableReader& t) {
  t.only({"dimension", "mode", "integrator", "gamma", "mass", "t_end", "cfl", "dt", "mass_tolerance",
          "energy_limit", "max_steps", "memory_limit"});
  SimulationSection s;
  s.where = t.self();
  s.dimension = t.require<int>("dimension");
  check(s.dimension >= 1 && s.dimension <= 3, t.ref("dimension"),
        "must be 1, 2 or 3 (got " + std::to_string(s.dimension) + ")");
  s.mode = t.choice("mode", s.mode, {"mpm", "ul"});
  s.integrator = t.choice("integrator", s.integrator, {"fe", "musl", "npc", "otm", "unified"});
  check(!(s.mode == "mpm" && (s.integrator == "otm" || s.integrator == "unified")), t.ref("integrator"),
        "integrator \"" + s.integrator + "\" needs advected nodes: use simulation.mode = \"ul\"");
  s.gamma = t.get<double>("gamma", s.gamma);
  check(s.gamma > 0 && s.gamma <= 1, t.ref("gamma"), "must be in (0, 1] (got " + fmt(s.gamma) + ")");
  // Default: the mass matrix of each algorithm's listing - lumped for fe, musl
  // and npc; consistent for otm (wobbes eq. 48) and unified (Algorithm 3).
  const bool consistent_default = s.integrator == "otm" || s.integrator == "unified";
  s.mass = t.choice("mass", consistent_default ? "consistent" : "lumped", {"lumped", "consistent"});
  check(!(s.integrator == "unified" && s.mass == "lumped"), t.ref("mass"),
        "integrator \"unified\" uses the consistent mass matrix (wobbes Algorithm 3): remove mass = \"lumped\"");
  s.t_end = t.require<double>("t_end");
  check(s.t_end > 0, t.ref("t_end"), "must be > 0 (got " + fmt(s.t_end) + ")");
  check(!(t.has("cfl") && t.has("dt")), t.ref("dt"), "give either simulation.cfl or simulation.dt, not both");
  s.cfl = positive(t, "cfl", s.cfl);
  if (t.has("dt")) s.dt = positive(t, "dt", 1.0);
  s.mass_tolerance = t.get<double>("mass_tolerance", s.mass_tolerance);
  check(s.mass_tolerance >= 0 && s.mass_tolerance < 1, t.ref("mass_tolerance"),
        "must be in [0, 1) (got " + fmt(s.mass_tolerance) + ")");
  s.energy_limit = t.get<double>("energy_limit", s.energy_limit);
  check(s.energy_limit >= 1, t.ref("energy_limit"),
        "must be >= 1 (a multiple of the larger of initial energy and work; got " + fmt(s.energy_limit) + ")");
  s.max_steps = t.get<double>("max_steps", s.max_steps);
  check(s.max_steps >= 1, t.ref("max_steps"), "must be >= 1 (the most steps a run may take; got " + fmt(s.max_steps) + ")");
  s.memory_limit = t.get<double>("memory_limit", s.memory_limit);
  check(s.memory_limit >= 0, t.ref("memory_limit"),
        "must be >= 0 (bytes; 0: the memory this process may use; got " + fmt(s.memory_limit) + ")");
  return s;
}

BasisOptions read_basis(const TableReader& t) {
  t.only({"kind", "gamma_lme", "tolerance", "d_max", "newton_tolerance", "max_newton_iterations"});
  BasisOptions b;
  if (!t.has("kind")) t.missing("kind");
  b.kind = t.choice("kind", b.kind, {"linear", "ugimp", "bspline2", "bspline3", "lme", "maxent"});
  b.gamma_lme = positive(t, "gamma_lme", b.gamma_lme);
  b.tolerance = t.get<double>("tolerance", b.tolerance);
  check(b.tolerance > 0 && b.tolerance < 1, t.ref("tolerance"), "must be in (0, 1) (got " + fmt(b.tolerance) + ")");
  b.d_max = positive(t, "d_max", b.d_max);
  b.newton_tolerance = t.get<double>("newton_tolerance", b.newton_tolerance);
  check(b.newton_tolerance > 0 && b.newton_tolerance < 1, t.ref("newton_tolerance"),
        "must be in (0, 1) (got " + fmt(b.newton_tolerance) + ")");
  b.max_newton_iterations = t.get<int>("max_newton_iterations", b.max_newton_iterations);
  check(b.max_newton_iterations >= 1, t.ref("max_newton_iterations"), "must be >= 1");
  return b;
}

/// grid.cells, or grid.h converted to cells (must divide the box evenly).
std::array<int, 3> read_cells(const TableReader& t, const GridSection& g, int dim) {
  std::array<int, 3> cells{1, 1, 1};
  check(!(t.has("cells") && t.has("h")), t.ref("h"), "give either grid.cells or grid.h, not both");
  if (t.has("h")) {
    const Vec3 h = *t.vec("h", dim, true);
    for (int k = 0; k < dim; ++k) {
      check(h[k] > 0, t.ref("h"), "must be > 0 (got " + fmt(h[k]) + ")");
      const double n = (g.upper[k] - g.lower[k]) / h[k];
      check(n <= kMaxSceneNodes, t.ref("h"),
            "gives " + fmt(n) + " cells on axis " + std::to_string(k) + "; at most " + fmt(kMaxSceneNodes) +
                " nodes are allowed");
      cells[k] = static_cast<int>(std::lround(n));
      check(cells[k] >= 1 && std::abs(n - cells[k]) <= kCellsTolerance * n, t.ref("h"),
            "does not divide the grid box into whole cells on axis " + std::to_string(k) + " ((upper - lower) / h = " +
                fmt(n) + ")");
    }
    return cells;
  }
  const toml::node* n = t.node("cells");
  if (!n) t.missing("cells", "required key is missing (give grid.cells or grid.h)");
  const SourceRef r = t.ref("cells");
  if (n->is_array()) {
    const toml::array& a = *n->as_array();
    check(static_cast<int>(a.size()) == dim, r,
          "has " + std::to_string(a.size()) + " components but simulation.dimension = " + std::to_string(dim));
    for (int k = 0; k < dim; ++k) cells[k] = convert<int>(a[static_cast<std::size_t>(k)], r);
  } else {
    const int c = convert<int>(*n, r);
    for (int k = 0; k < dim; ++k) cells[k] = c;
  }
  for (int k = 0; k < dim; ++k) check(cells[k] >= 1, r, "must be >= 1 (got " + std::to_string(cells[k]) + ")");
  return cells;
}

GridSection read_grid(const TableReader& t, int dim) {
  t.only({"kind", "lower", "upper", "cells", "h", "perturbation", "seed"});
  GridSection g;
  g.where = t.self();
  g.kind = t.choice("kind", g.kind, {"cartesian", "perturbed"});
  g.lower = t.require_vec("lower", dim);
  g.upper = t.require_vec("upper", dim);
  check_box(t, g.lower, g.upper, dim, true);
  for (int k = 0; k < dim; ++k)
    check(std::isfinite(g.upper[k] - g.lower[k]), t.ref("upper"),
          "upper - lower overflows on axis " + std::to_string(k) + " (lower " + fmt(g.lower[k]) + ", upper " +
              fmt(g.upper[k]) + ")");
  g.cells = read_cells(t, g, dim);
  g.perturbation = t.get<double>("perturbation", g.perturbation);
  check(g.perturbation >= 0 && g.perturbation < 0.5, t.ref("perturbation"),
        "must be in [0, 0.5) (a fraction of h; got " + fmt(g.perturbation) + ")");
  const std::int64_t seed = t.get<std::int64_t>("seed", g.seed);
  check(seed >= 0 && seed <= std::numeric_limits<unsigned>::max(), t.ref("seed"), "must be a non-negative 32-bit integer");
  g.seed = static_cast<unsigned>(seed);
  return g;
}

double spacing(const GridSection& g, int k) { return (g.upper[k] - g.lower[k]) / g.cells[k]; }

/// Cells of size h over an extent, rounded as the engine rounds them (at least one).
double cells_over(double extent, double h) { return std::max(1.0, std::round(extent / h)); }

/// The cells seed_particles fills in body `b` (see SceneSize).
double body_cells(const BodySection& b, const GridSection& g, int dim) {
  double n = 1;
  for (int k = 0; k < dim; ++k) n *= cells_over(b.upper[k] - b.lower[k], spacing(g, k));
  return n;
}

/// The particles seed_particles puts into body `b` (see SceneSize).
double body_particles(const BodySection& b, const GridSection& g, int dim) {
  return body_cells(b, g, dim) * std::pow(b.particles_per_cell, dim);
}

/// The nodes of the engine's node set (see SceneSize).
double node_count(const Scene& s) {
  double n = 1;
  for (int k = 0; k < s.simulation.dimension; ++k) {
    double cells = s.grid.cells[k];
    if (s.simulation.mode == "ul" && !s.bodies.empty()) {
      double lo = s.bodies.front().lower[k], hi = s.bodies.front().upper[k];
      for (const BodySection& b : s.bodies) {
        lo = std::min(lo, b.lower[k]);
        hi = std::max(hi, b.upper[k]);
      }
      cells = cells_over(hi - lo, spacing(s.grid, k));
    }
    n *= cells + 1;
  }
  return n;
}

/// Reads a required non-empty `name` (or returns the default) and checks uniqueness.
std::string read_name(const TableReader& t, bool required, const std::string& fallback, std::set<std::string>& seen) {
  std::string name = required ? t.require<std::string>("name") : t.get<std::string>("name", fallback);
  check(!name.empty(), t.ref("name"), "must not be empty");
  check(seen.insert(name).second, t.has("name") ? t.ref("name") : t.self(), "duplicate name \"" + name + "\"");
  return name;
}

std::vector<MaterialSection> read_materials(const TableReader& root) {
  auto tables = root.tables("material");
  if (tables.empty()) root.missing("material", "at least one [[material]] is required");
  std::vector<MaterialSection> out;
  std::set<std::string> names;
  for (const TableReader& t : tables) {
    t.only({"name", "model", "density", "young", "poisson"});
    MaterialSection m;
    m.where = t.self();
    m.name = read_name(t, true, "", names);
    if (!t.has("model")) t.missing("model");
    m.model = t.choice("model", m.model, {"linear_elastic", "linear_elastic_finite", "neo_hookean"});
    m.density = t.require<double>("density");
    check(m.density > 0, t.ref("density"), "must be > 0 (got " + fmt(m.density) + ")");
    m.young = t.require<double>("young");
    check(m.young > 0, t.ref("young"), "must be > 0 (got " + fmt(m.young) + ")");
    m.poisson = t.require<double>("poisson");
    check(m.poisson > -1 && m.poisson < 0.5, t.ref("poisson"),
          "must be in (-1, 0.5) (got " + fmt(m.poisson) + ")");
    out.push_back(std::move(m));
  }
  return out;
}

/// The SourceRef of a box: the --set that changed it, else the table's line.
SourceRef box_ref(const TableReader& t) {
  for (const char* key : {"lower", "upper"}) {
    SourceRef r = t.ref(key);
    if (r.line == kCommandLineLine) return r;
  }
  return t.self();
}

void check_body_in_grid(const TableReader& t, const BodySection& b, const GridSection& g, int dim) {
  for (int k = 0; k < dim; ++k) {
    const double tol = kNodeTolerance * spacing(g, k);
    check(b.lower[k] >= g.lower[k] - tol && b.upper[k] <= g.upper[k] + tol, box_ref(t),
          "body \"" + b.name + "\" [" + fmt(b.lower[k]) + ", " + fmt(b.upper[k]) + "] on axis " + std::to_string(k) +
              " is not inside the grid [" + fmt(g.lower[k]) + ", " + fmt(g.upper[k]) + "] (mpm mode)");
  }
}

std::vector<BodySection> read_bodies(const TableReader& root, const Scene& s) {
  auto tables = root.tables("body");
  if (tables.empty()) root.missing("body", "at least one [[body]] is required");
  const int dim = s.simulation.dimension;
  std::vector<BodySection> out;
  std::set<std::string> names;
  double particles = 0;
  for (const TableReader& t : tables) {
    t.only({"name", "material", "lower", "upper", "particles_per_cell", "placement", "velocity", "velocity_profile"});
    BodySection b;
    b.where = t.self();
    b.name = read_name(t, false, "body" + std::to_string(out.size()), names);
    b.material = t.require<std::string>("material");
    const bool known = std::any_of(s.materials.begin(), s.materials.end(),
                                   [&](const MaterialSection& m) { return m.name == b.material; });
    check(known, t.ref("material"), "no [[material]] named \"" + b.material + "\"");
    b.lower = t.require_vec("lower", dim);
    b.upper = t.require_vec("upper", dim);
    check_box(t, b.lower, b.upper, dim, true);
    b.particles_per_cell = t.get<int>("particles_per_cell", b.particles_per_cell);
    check(b.particles_per_cell >= 1 && b.particles_per_cell <= kMaxParticlesPerCell, t.ref("particles_per_cell"),
          "must be in [1, " + std::to_string(kMaxParticlesPerCell) + "] (got " +
              std::to_string(b.particles_per_cell) + ")");
    b.placement = t.choice("placement", b.placement, {"gauss", "cell_centres"});
    b.velocity = t.vec("velocity", dim).value_or(b.velocity);
    if (t.has("velocity_profile")) b.velocity_profile = t.choice("velocity_profile", "", {"sin_x"});
    if (s.simulation.mode == "mpm") check_body_in_grid(t, b, s.grid, dim);
    particles += body_particles(b, s.grid, dim);
    check(particles <= kMaxSceneParticles, box_ref(t),
          "body \"" + b.name + "\" brings the particle count to " + fmt(particles) + " (" +
              fmt(body_cells(b, s.grid, dim)) + " cells of the grid spacing, " +
              fmt(std::pow(b.particles_per_cell, dim)) + " particles each); at most " + fmt(kMaxSceneParticles) +
              " are allowed");
    out.push_back(std::move(b));
  }
  return out;
}

std::vector<InitialVelocitySection> read_initial_velocities(const TableReader& root, int dim) {
  std::vector<InitialVelocitySection> out;
  for (const TableReader& t : root.tables("initial_velocity")) {
    t.only({"lower", "upper", "velocity"});
    InitialVelocitySection iv;
    iv.where = t.self();
    iv.lower = t.require_vec("lower", dim);
    iv.upper = t.require_vec("upper", dim);
    check_box(t, iv.lower, iv.upper, dim, false);
    iv.velocity = t.require_vec("velocity", dim);
    out.push_back(iv);
  }
  return out;
}

/// True when some node of the Cartesian grid lies in [lo, hi] (tolerance 1e-9 h).
bool box_selects_node(const GridSection& g, const Vec3& lo, const Vec3& hi, int dim) {
  for (int k = 0; k < dim; ++k) {
    const double h = spacing(g, k), tol = kNodeTolerance * h;
    const double first = std::max(0.0, std::ceil((lo[k] - tol - g.lower[k]) / h));
    const double last = std::min(static_cast<double>(g.cells[k]), std::floor((hi[k] + tol - g.lower[k]) / h));
    if (first > last) return false;
  }
  return true;
}

std::vector<BoundarySection> read_boundaries(const TableReader& root, const GridSection& g, int dim) {
  std::vector<BoundarySection> out;
  std::set<std::string> names;
  for (const TableReader& t : root.tables("boundary")) {
    t.only({"name", "lower", "upper", "fix", "value"});
    BoundarySection b;
    b.where = t.self();
    b.name = read_name(t, false, "boundary" + std::to_string(out.size()), names);
    b.lower = t.require_vec("lower", dim);
    b.upper = t.require_vec("upper", dim);
    check_box(t, b.lower, b.upper, dim, false);
    auto fix = t.bools("fix", dim);
    if (!fix) t.missing("fix");
    b.fix = *fix;
    b.value = t.vec("value", dim).value_or(b.value);
    check(box_selects_node(g, b.lower, b.upper, dim), box_ref(t),
          "boundary \"" + b.name + "\" selects no grid node (nodes are at grid.lower + i h)");
    out.push_back(std::move(b));
  }
  return out;
}

TimeFunction read_time(const TableReader& parent) {
  TimeFunction f;
  auto t = parent.table("time");
  if (!t) return f;
  t->only({"kind", "period"});
  f.kind = t->choice("kind", f.kind, {"constant", "ramp"});
  if (f.kind == "ramp" && !t->has("period")) t->missing("period", "required key is missing (kind = \"ramp\")");
  f.period = t->has("period") ? positive(*t, "period", 1.0) : 0.0;
  return f;
}

std::optional<BodyForceSection> read_body_force(const TableReader& root, int dim) {
  auto t = root.table("body_force");
  if (!t) return std::nullopt;
  t->only({"value", "time"});
  BodyForceSection b;
  b.where = t->self();
  b.value = t->require_vec("value", dim);
  b.time = read_time(*t);
  return b;
}

std::vector<TractionSection> read_tractions(const TableReader& root, int dim) {
  std::vector<TractionSection> out;
  for (const TableReader& t : root.tables("traction")) {
    t.only({"lower", "upper", "value", "time", "function"});
    TractionSection tr;
    tr.where = t.self();
    tr.lower = t.require_vec("lower", dim);
    tr.upper = t.require_vec("upper", dim);
    check_box(t, tr.lower, tr.upper, dim, false);
    if (t.has("function")) tr.function = t.choice("function", "", {"wobbes_traction_bar"});
    if (tr.function.empty()) tr.value = t.require_vec("value", dim);
    else tr.value = t.vec("value", dim).value_or(tr.value);
    tr.time = read_time(t);
    out.push_back(tr);
  }
  return out;
}

std::vector<ProbeSection> read_probes(const TableReader& out_table, int dim) {
  std::vector<ProbeSection> out;
  std::set<std::string> names;
  for (const TableReader& t : out_table.tables("probes")) {
    t.only({"name", "particle", "at"});
    ProbeSection p;
    p.where = t.self();
    p.name = read_name(t, true, "", names);
    const std::string why = invalid_name_reason(p.name);
    check(why.empty(), t.ref("name"),
          "\"" + TableReader::printable(p.name) + "\" cannot name a probe in the result file: " + why);
    p.particle = t.choice("particle", p.particle, {"leftmost", "rightmost", "nearest"});
    if (p.particle == "nearest" && !t.has("at")) t.missing("at", "required key is missing (particle = \"nearest\")");
    p.at = t.vec("at", dim).value_or(p.at);
    out.push_back(std::move(p));
  }
  return out;
}

/// Particle fields a frame can hold (what the engine's recorder writes).
const Names kOutputFields = {"x", "v", "a", "stress", "strain", "F", "density", "volume", "mass", "displacement"};

/// output.fields: known, distinct particle field names.
std::vector<std::string> read_fields(const TableReader& t, std::string_view key, std::vector<std::string> fallback) {
  const toml::node* n = t.node(key);
  if (!n) return fallback;
  const SourceRef r = t.ref(key);
  const toml::array* a = n->as_array();
  if (!a) input_error(r, "expected an array of strings, got " + type_name(*n));
  std::vector<std::string> out;
  for (const toml::node& el : *a) {
    out.push_back(convert<std::string>(el, r));
    check(std::find(kOutputFields.begin(), kOutputFields.end(), out.back()) != kOutputFields.end(), r,
          "unknown field \"" + out.back() + "\"" + suggestion(out.back(), kOutputFields));
    check(std::count(out.begin(), out.end(), out.back()) == 1, r, "names \"" + out.back() + "\" twice");
  }
  return out;
}

/// Values of output.format.
const Names kOutputFormats = {"hdf5", "vtp", "vtu"};

/// output.format: "hdf5" (required) and at most one of "vtp", "vtu"; a
/// string is a list of one.
std::vector<std::string> read_formats(const TableReader& t) {
  const toml::node* n = t.node("format");
  if (!n) return {"hdf5"};
  const SourceRef r = t.ref("format");
  std::vector<std::string> out;
  if (n->is_string()) out.push_back(convert<std::string>(*n, r));
  else if (const toml::array* a = n->as_array())
    for (const toml::node& el : *a) out.push_back(convert<std::string>(el, r));
  else input_error(r, "expected an array of strings, got " + type_name(*n));
  const Names known = kOutputFormats;
  for (const std::string& f : out) {
    check(std::find(known.begin(), known.end(), f) != known.end(), r,
          "unknown format \"" + f + "\"" + suggestion(f, known));
    check(std::count(out.begin(), out.end(), f) == 1, r, "names \"" + f + "\" twice");
  }
  check(std::count(out.begin(), out.end(), "hdf5") == 1, r,
        "must contain \"hdf5\": the HDF5 result file is always written (e.g. [\"hdf5\", \"vtp\"])");
  check(!(std::count(out.begin(), out.end(), "vtp") && std::count(out.begin(), out.end(), "vtu")), r,
        "choose one of \"vtp\" and \"vtu\" (both would be listed by the same .pvd)");
  return out;
}

/// output.checkpoint_every (steps, >= 0) and output.checkpoint_file.
void read_checkpoint_keys(const TableReader& t, OutputSection& o) {
  const std::int64_t every = t.get<std::int64_t>("checkpoint_every", 0);
  check(every >= 0 && every <= std::numeric_limits<long>::max(), t.ref("checkpoint_every"),
        "must be an integer >= 0 (steps between checkpoints; 0: none; got " + std::to_string(every) + ")");
  o.checkpoint_every = static_cast<long>(every);
  o.checkpoint_file = t.get<std::string>("checkpoint_file", "");
  check(!t.has("checkpoint_file") || !o.checkpoint_file.empty(), t.ref("checkpoint_file"), "must not be empty");
  check(o.checkpoint_file != o.file, t.ref("checkpoint_file"), "must differ from output.file");
}

OutputSection read_output(const TableReader& root, int dim) {
  OutputSection o;
  auto t = root.table("output");
  if (!t) return o;
  t->only({"file", "every", "fields", "probes", "checkpoint_every", "checkpoint_file", "format"});
  o.where = t->self();
  o.file = t->get<std::string>("file", o.file);
  check(!o.file.empty(), t->ref("file"), "must not be empty");
  o.every = t->get<double>("every", o.every);
  check(o.every >= 0, t->ref("every"), "must be >= 0 (got " + fmt(o.every) + ")");
  o.fields = read_fields(*t, "fields", o.fields);
  o.probes = read_probes(*t, dim);
  read_checkpoint_keys(*t, o);
  o.formats = read_formats(*t);
  return o;
}

ReferenceSection read_reference(const TableReader& root) {
  ReferenceSection r;
  auto t = root.table("reference");
  if (!t) return r;
  t->only({"solution"});
  r.where = t->self();
  r.solution = t->choice("solution", "", {"", "dyka", "fixed_bar", "traction_bar", "mms_plate"});
  return r;
}

/// The node set must stay within kMaxSceneNodes: the grid in mpm mode, the
/// bodies' bounding box in ul mode (both in cells of grid.h).
void check_node_count(const TableReader& grid, const Scene& s) {
  const double n = node_count(s);
  check(n <= kMaxSceneNodes, grid.ref(grid.has("h") ? "h" : "cells"),
        "the node set would have " + fmt(n) + " nodes" +
            (s.simulation.mode == "ul" ? " (the bodies' bounding box in cells of the grid spacing)" : "") +
            "; at most " + fmt(kMaxSceneNodes) + " are allowed");
}

/// Checks that involve several sections, and derived basis parameters.
void finish_basis(Scene& s, const TableReader& basis) {
  if (s.basis.kind != "ugimp") return;
  check(s.grid.kind == "cartesian", basis.ref("kind"),
        "uGIMP needs an unperturbed Cartesian grid; this scene has grid.kind = \"" + s.grid.kind + "\"");
  const int ppc = s.bodies.front().particles_per_cell;
  for (int k = 0; k < s.simulation.dimension; ++k) s.basis.ugimp_half_width[k] = spacing(s.grid, k) / (2.0 * ppc);
}

Scene read_scene(const toml::table& root, Context& ctx) {
  TableReader r(ctx, &root, "", SourceRef{ctx.file, 1, ""});
  r.only({"simulation", "basis", "grid", "material", "body", "initial_velocity", "boundary", "body_force", "traction",
          "output", "reference"});
  Scene s;
  s.file = ctx.file;
  s.simulation = read_simulation(r.require_table("simulation"));
  const int dim = s.simulation.dimension;
  const TableReader basis = r.require_table("basis");
  s.basis = read_basis(basis);
  s.basis_where = basis.self();
  const TableReader grid = r.require_table("grid");
  s.grid = read_grid(grid, dim);
  const bool ul = s.simulation.mode == "ul";
  if (!ul) check_node_count(grid, s);
  s.materials = read_materials(r);
  s.bodies = read_bodies(r, s);
  if (ul) check_node_count(grid, s);
  s.initial_velocities = read_initial_velocities(r, dim);
  s.boundaries = read_boundaries(r, s.grid, dim);
  s.body_force = read_body_force(r, dim);
  s.tractions = read_tractions(r, dim);
  s.output = read_output(r, dim);
  s.reference = read_reference(r);
  finish_basis(s, basis);
  return s;
}

// ---------------------------------------------------------------- --set

/// Keys that exclude each other: setting one on the command line drops the other.
const std::map<std::string, std::string> kExclusive = {
    {"grid.h", "grid.cells"}, {"grid.cells", "grid.h"}, {"simulation.dt", "simulation.cfl"},
    {"simulation.cfl", "simulation.dt"}};

std::vector<std::string> split_key(const std::string& key, const std::string& what) {
  std::vector<std::string> segs;
  std::size_t start = 0;
  for (;;) {
    const std::size_t dot = key.find('.', start);
    segs.push_back(key.substr(start, dot - start));
    if (segs.back().empty()) throw InputError("--set " + what + ": empty key segment");
    if (dot == std::string::npos) return segs;
    start = dot + 1;
  }
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

/// True when `s` is well-formed UTF-8 (RFC 3629: shortest form, no surrogates,
/// at most U+10FFFF), as TOML requires of every string.
bool valid_utf8(std::string_view s) {
  constexpr char32_t kMinimum[] = {0, 0x80, 0x800, 0x10000}; // smallest code point per continuation count
  for (std::size_t i = 0; i < s.size();) {
    const auto lead = static_cast<unsigned char>(s[i]);
    std::size_t more = 0;
    char32_t cp = lead;
    if (lead >= 0xF0 && lead < 0xF8) more = 3, cp = lead & 0x07u;
    else if (lead >= 0xE0 && lead < 0xF0) more = 2, cp = lead & 0x0Fu;
    else if (lead >= 0xC0 && lead < 0xE0) more = 1, cp = lead & 0x1Fu;
    else if (lead >= 0x80) return false;
    if (s.size() - i <= more) return false;
    for (std::size_t j = 1; j <= more; ++j) {
      const auto byte = static_cast<unsigned char>(s[i + j]);
      if ((byte & 0xC0u) != 0x80u) return false;
      cp = (cp << 6) | (byte & 0x3Fu);
    }
    if (cp < kMinimum[more] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return false;
    i += more + 1;
  }
  return true;
}

/// VALUE as a TOML value; a bare word that is not valid TOML is a string
/// (if it is valid UTF-8: otherwise the resolved scene text would not read back).
toml::table parse_value(const std::string& key, const std::string& value) {
  try {
    const std::string doc = "v = " + value + "\n";
    return toml::parse(std::string_view(doc), std::string_view("--set"));
  } catch (const toml::parse_error& e) {
    const bool bare = !value.empty() && std::string("[{\"'").find(value.front()) == std::string::npos;
    if (!bare) throw InputError("--set " + key + ": cannot read '" + value + "' as a TOML value: " +
                                std::string(e.description()));
    if (!valid_utf8(value)) throw InputError("--set " + key + ": the value is not valid UTF-8 text");
    toml::table t;
    t.insert("v", value);
    return t;
  }
}

/// Finds the element of an array of tables named `seg` (or with index `seg`).
toml::table* find_element(toml::array& a, const std::string& seg, std::string& canonical) {
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!a[i].is_table()) continue;
    const std::string name = TableReader::element_name(a[i], i);
    if (name == seg || std::to_string(i) == seg) {
      canonical = name;
      return a[i].as_table();
    }
  }
  return nullptr;
}

void apply_override(toml::table& root, const std::string& text, Context& ctx) {
  const std::size_t eq = text.find('=');
  if (eq == std::string::npos) throw InputError("--set " + text + ": expected KEY=VALUE");
  const std::string key = trim(text.substr(0, eq));
  const std::vector<std::string> segs = split_key(key, text);
  toml::table parsed = parse_value(key, trim(text.substr(eq + 1)));
  toml::table* cur = &root;
  std::string path;
  for (std::size_t i = 0; i + 1 < segs.size(); ++i) {
    toml::node* n = cur->get(segs[i]);
    path = join_path(path, segs[i]);
    if (!n) {
      if (kTableArrays.count(segs[i])) throw InputError("--set " + key + ": the scene has no [[" + path + "]]");
      n = &cur->insert(segs[i], toml::table{}).first->second;
      ctx.overridden.emplace(path, key);
    }
    if (toml::array* a = n->as_array(); a && i + 2 < segs.size()) {
      std::string name;
      cur = find_element(*a, segs[++i], name);
      if (!cur) throw InputError("--set " + key + ": no element '" + segs[i] + "' in [[" + path + "]]");
      path += "." + name;
    } else if (!(cur = n->as_table())) {
      throw InputError("--set " + key + ": '" + path + "' is not a table");
    }
  }
  path = join_path(path, segs.back());
  cur->insert_or_assign(segs.back(), *parsed.get("v"));
  ctx.overridden[path] = key;
  if (auto ex = kExclusive.find(path); ex != kExclusive.end())
    cur->erase(ex->second.substr(ex->second.find('.') + 1));
}

} // namespace

// ---------------------------------------------------------------- public

std::string SourceRef::describe() const {
  if (line == kCommandLineLine) return "--set " + key;
  if (file.empty() && line <= 0) return "key '" + key + "'"; // a Scene built in code
  std::string s = file;
  if (line > 0) s += ":" + std::to_string(line);
  return s + ": key '" + key + "'";
}

void input_error(const SourceRef& where, const std::string& message) {
  throw InputError(where.describe() + ": " + message);
}

SourceRef Scene::locate(const std::string& key) const {
  auto it = where.find(key);
  if (it != where.end()) return it->second;
  return SourceRef{file, 0, key};
}

Scene parse_scene(const std::string& text, const std::string& name, const std::vector<std::string>& overrides) {
  toml::table root;
  try {
    root = toml::parse(std::string_view(text), std::string_view(name));
  } catch (const toml::parse_error& e) {
    const auto& pos = e.source().begin;
    throw InputError(name + ":" + std::to_string(pos.line) + ":" + std::to_string(pos.column) +
                     ": syntax error: " + std::string(e.description()));
  }
  Context ctx;
  ctx.file = name;
  for (const std::string& o : overrides) apply_override(root, o, ctx);
  Scene s = read_scene(root, ctx);
  s.where = std::move(ctx.where);
  std::ostringstream os;
  os << root << "\n";
  s.text = os.str();
  return s;
}

bool is_output_field(const std::string& name) {
  return std::find(kOutputFields.begin(), kOutputFields.end(), name) != kOutputFields.end();
}

bool is_output_format(const std::string& format) {
  return std::find(kOutputFormats.begin(), kOutputFormats.end(), format) != kOutputFormats.end();
}

std::string vtk_format(const OutputSection& output) {
  for (const std::string& f : output.formats)
    if (f == "vtp" || f == "vtu") return f;
  return "";
}

SceneSize scene_size(const Scene& scene) {
  SceneSize n;
  for (const BodySection& b : scene.bodies) n.particles += body_particles(b, scene.grid, scene.simulation.dimension);
  n.nodes = node_count(scene);
  return n;
}

Scene load_scene(const std::string& path, const std::vector<std::string>& overrides) {
  if (path.empty()) throw InputError("load_scene: the scene file path is empty");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open the scene file");
  std::ostringstream buf;
  buf << in.rdbuf();
  return parse_scene(buf.str(), path, overrides);
}

} // namespace otmpm
