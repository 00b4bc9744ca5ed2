#pragma once
/// \file toml_reader.hpp
/// Internal (not installed: it needs toml++): the TOML reading idiom of the
/// scene reader, shared with the study-file reader of `otmpm study`. A
/// TableReader reads the keys of one TOML table, checks names, types and
/// presence, and reports every problem as an InputError "FILE:LINE: key 'K':
/// message" (SourceRef::describe), also for values written by --set.
#include "otmpm/text.hpp"
#include "otmpm/scene/scene.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace otmpm::toml_input {

/// SourceRef::line of a value that came from a --set override.
constexpr int kCommandLineLine = -1;
/// Largest edit distance for which an unknown key gets a "did you mean".
constexpr std::size_t kSuggestDistance = 3;

using Names = std::initializer_list<std::string_view>;

inline std::string quoted_list(std::span<const std::string_view> names) {
  std::string s;
  for (auto n : names) s += (s.empty() ? "\"" : ", \"") + std::string(n) + "\"";
  return s;
}

/// The message of a value that is not one of `allowed`: TableReader::choice's,
/// and the scene validator's (scene_rules::choice).
inline std::string choice_message(std::span<const std::string_view> allowed, std::string_view value) {
  return "must be one of " + quoted_list(allowed) + " (got \"" + std::string(value) + "\")";
}

inline std::string join_path(const std::string& prefix, std::string_view key) {
  return prefix.empty() ? std::string(key) : prefix + "." + std::string(key);
}

inline std::string type_name(const toml::node& n) {
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
inline std::size_t edit_distance(std::string_view a, std::string_view b) {
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

inline std::string suggestion(std::string_view key, std::span<const std::string_view> allowed) {
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
  /// The processes the scene is read for (0: not known): a particle file of
  /// more rows than they may hold (kMaxRankParticles each) is refused as
  /// soon as its row count is read.
  int processes = 0;
  std::map<std::string, std::string> overridden;
  std::map<std::string, SourceRef> where;

  /// Where `path` came from: the --set that wrote it (or a table above it:
  /// then `path` is the SourceRef's field), else the node's line in the
  /// file, else `fallback_line`.
  SourceRef ref(const std::string& path, const toml::node* node, int fallback_line) const {
    for (std::size_t pos = 0; pos != std::string::npos;) {
      pos = path.find('.', pos + 1);
      auto it = overridden.find(path.substr(0, pos));
      if (it != overridden.end())
        return SourceRef{file, kCommandLineLine, it->second, pos == std::string::npos ? "" : path};
    }
    int line = node ? static_cast<int>(node->source().begin.line) : 0;
    return SourceRef{file, line > 0 ? line : fallback_line, path};
  }
};

template <class T> T convert(const toml::node& n, const SourceRef& r);

template <> inline double convert<double>(const toml::node& n, const SourceRef& r) {
  double v = 0;
  if (auto i = n.as_integer()) v = static_cast<double>(i->get());
  else if (auto f = n.as_floating_point()) v = f->get();
  else input_error(r, "expected a number, got " + type_name(n));
  if (!std::isfinite(v)) input_error(r, "must be a finite number (got " + format_number(v) + ")"); // as ParameterSpec::check
  return v;
}
template <> inline int convert<int>(const toml::node& n, const SourceRef& r) {
  auto i = n.as_integer();
  if (!i) input_error(r, "expected an integer, got " + type_name(n));
  const std::int64_t v = i->get();
  if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max())
    input_error(r, "integer out of range");
  return static_cast<int>(v);
}
template <> inline std::int64_t convert<std::int64_t>(const toml::node& n, const SourceRef& r) {
  auto i = n.as_integer();
  if (!i) input_error(r, "expected an integer, got " + type_name(n));
  return i->get();
}
template <> inline std::string convert<std::string>(const toml::node& n, const SourceRef& r) {
  auto s = n.as_string();
  if (!s) input_error(r, "expected a string, got " + type_name(n));
  return s->get();
}
template <> inline bool convert<bool>(const toml::node& n, const SourceRef& r) {
  auto b = n.as_boolean();
  if (!b) input_error(r, "expected a boolean, got " + type_name(n));
  return b->get();
}

/// Reads the keys of one TOML table, checking names, types and presence.
/// Every key read is recorded in Context::where under its dotted path.
class TableReader {
public:
  const Context& context() const { return *ctx_; }
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
  void only(Names allowed) const { only(std::span<const std::string_view>(allowed.begin(), allowed.size())); }
  void only(std::span<const std::string_view> allowed) const {
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
    input_error(r, what); // in a table written by --set, r names the key inside it (SourceRef::field)
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
    return choice(key, std::move(fallback), std::span<const std::string_view>(allowed.begin(), allowed.size()));
  }
  std::string choice(std::string_view key, std::string fallback, std::span<const std::string_view> allowed) const {
    std::string v = get<std::string>(key, fallback);
    if (std::find(allowed.begin(), allowed.end(), v) == allowed.end())
      input_error(ref(key), choice_message(allowed, v));
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

  /// An array of strings, if present (e.g. a list of "KEY=VALUE" overrides).
  std::optional<std::vector<std::string>> strings(std::string_view key) const {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    const SourceRef r = ref(key);
    const toml::array* a = n->as_array();
    if (!a) input_error(r, "expected an array of strings, got " + type_name(*n));
    std::vector<std::string> out;
    for (const toml::node& el : *a) out.push_back(convert<std::string>(el, r));
    return out;
  }

  /// Calls visit(key, node, SourceRef) for every key of the table, in file order
  /// (a table whose keys are data, e.g. the swept parameters of a study).
  template <class Visit> void for_each(Visit&& visit) const {
    if (!table_) return;
    std::vector<std::pair<std::string, const toml::node*>> keys;
    for (auto&& [k, v] : *table_) keys.emplace_back(std::string(k.str()), &v);
    std::stable_sort(keys.begin(), keys.end(), [](const auto& a, const auto& b) {
      return a.second->source().begin.line < b.second->source().begin.line;
    });
    for (const auto& [k, v] : keys) visit(k, *v, ref(k));
  }

  /// The name an element is addressed by; control characters (which no
  /// valid name has) are shown as \\xHH so that messages stay printable.
  static std::string element_name(const toml::node& el, std::size_t index) {
    if (const toml::table* t = el.as_table())
      if (auto name = t->get_as<std::string>("name")) return printable(name->get());
    return std::to_string(index);
  }

  /// `s` with control characters shown as \\xHH (text::printable).
  static std::string printable(const std::string& s) { return text::printable(s); }

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

/// The whole content of a text file; InputError naming the file and `what`
/// ("scene file", "study file") when it is a directory, missing or unreadable.
std::string read_text_file(const std::string& path, const std::string& what);
/// Reads a TOML file: its root table, or an InputError "FILE:LINE:COLUMN:
/// syntax error: ..." (also for a file that cannot be opened or a directory).
toml::table parse_toml_file(const std::string& path, const std::string& what);
/// The same from text (`name` is the file name in messages).
toml::table parse_toml_text(const std::string& text, const std::string& name);

} // namespace otmpm::toml_input
