/// \file scene.cpp
/// otmpm.Scene: a scene read from a TOML file or built from a Python dict
/// (converted to TOML text with toml++ and read by the same parser as the
/// command line, so that every value meets the same checks and errors
/// carry the same messages).
#include "bindings.hpp"

#include "otmpm/scene/scene.hpp"

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>
#include <toml++/toml.h>

#include <algorithm>
#include <filesystem>
#include <sstream>
#include <stdexcept>
#include <variant>

namespace otmpm::python {

namespace {

/// The TOML key path of `key` under `parent` ("material.0.young").
std::string child_path(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}

/// The name of the type of `o` ("list"): messages never repr() a value,
/// which may be nested too deep to print or be megabytes long.
std::string type_name(py::handle o) { return py::str(py::type::handle_of(o).attr("__name__")).cast<std::string>(); }

/// A Python value converted to TOML.
using TomlValue = std::variant<bool, std::int64_t, double, std::string, toml::array, toml::table>;

/// Deepest nesting of lists and dicts a scene value may have: the limit of the
/// TOML parser the converted text goes through.
constexpr std::size_t kMaxDepth = 256;

/// Where a conversion is: the file name of its errors and the containers on
/// the path from the top (their ids: a container met again contains itself).
struct Conversion {
  std::string file;
  std::vector<const PyObject*> path;
};

TomlValue convert(py::handle v, Conversion& c, const std::string& key, bool inline_tables);

/// Enters the container `o` at `key`: InputError naming the key when it is
/// already on the path (a dict or list that contains itself) or the nesting
/// is deeper than kMaxDepth. Leaves it on destruction.
class Enter {
public:
  Enter(Conversion& c, const py::handle& o, const std::string& key) : c_(c) {
    if (std::find(c.path.begin(), c.path.end(), o.ptr()) != c.path.end())
      input_error({c.file, 0, key}, "the value contains itself (a dict or list that refers to itself)");
    if (c.path.size() >= kMaxDepth)
      input_error({c.file, 0, key}, "lists and dicts nested deeper than " + std::to_string(kMaxDepth) + " levels");
    c.path.push_back(o.ptr());
  }
  ~Enter() { c_.path.pop_back(); }
  Enter(const Enter&) = delete;
  Enter& operator=(const Enter&) = delete;

private:
  Conversion& c_;
};

/// The dict `dict` as a TOML table (string keys only).
toml::table table_from(py::handle dict, Conversion& c, const std::string& path, bool inline_tables) {
  const Enter enter(c, dict, path);
  toml::table t;
  t.is_inline(inline_tables);
  for (auto [k, v] : py::reinterpret_borrow<py::dict>(dict)) {
    if (!py::isinstance<py::str>(k)) input_error({c.file, 0, path}, "keys must be strings, got a " + type_name(k));
    const std::string key = k.cast<std::string>();
    std::visit([&](auto&& x) { t.insert(key, std::move(x)); }, convert(v, c, child_path(path, key), inline_tables));
  }
  return t;
}

/// Converts the Python value `v` at `path` to TOML: bool, int (64 bit),
/// float, str, list/tuple (array), dict (table); NumPy scalars and arrays
/// through their tolist(). Anything else, a container that contains itself
/// or nesting deeper than kMaxDepth is an InputError naming the key.
TomlValue convert(py::handle v, Conversion& c, const std::string& path, bool inline_tables) {
  py::object o = py::reinterpret_borrow<py::object>(v);
  if (!py::isinstance<py::str>(o) && py::hasattr(o, "tolist")) o = o.attr("tolist")();
  if (py::isinstance<py::bool_>(o)) return o.cast<bool>();
  if (py::isinstance<py::int_>(o)) {
    int overflow = 0;
    const long long i = PyLong_AsLongLongAndOverflow(o.ptr(), &overflow);
    if (overflow != 0) {
      // str() of an int of more than 4300 digits raises: a huge one is told by its size.
      const auto bits = o.attr("bit_length")().cast<long long>();
      const std::string value = bits <= 1000 ? shortened(py::str(o).cast<std::string>())
                                             : "of " + std::to_string(bits) + " bits";
      input_error({c.file, 0, path}, "integer " + value + " out of range");
    }
    return static_cast<std::int64_t>(i);
  }
  if (py::isinstance<py::float_>(o)) return o.cast<double>();
  if (py::isinstance<py::str>(o)) return o.cast<std::string>();
  if (py::isinstance<py::dict>(o)) return table_from(o, c, path, inline_tables);
  if (py::isinstance<py::list>(o) || py::isinstance<py::tuple>(o)) {
    const Enter enter(c, o, path);
    // Arrays of tables are [[headers]] at the top level, inline below it
    // (probes = [{ name = "A", ... }]), as the scene files write them.
    const bool nested = inline_tables || path.find('.') != std::string::npos;
    toml::array a;
    std::size_t i = 0;
    for (py::handle item : o)
      std::visit([&](auto&& x) { a.push_back(std::move(x)); },
                 convert(item, c, child_path(path, std::to_string(i++)), nested));
    return a;
  }
  input_error({c.file, 0, path},
              "a " + type_name(o) + " cannot be a scene value (expected bool, int, float, str, list or dict)");
}

/// A TOML value written on one line, as --set reads it: strings as basic
/// strings with escapes (never multi-line or literal: toml++ writes a literal
/// string with a raw line break), and the line breaks toml++ puts between the
/// elements of a long array (outside any string) made spaces.
std::string one_line(const toml::table& t) {
  constexpr auto flags = toml::format_flags::allow_unicode_strings;
  std::ostringstream os;
  os << toml::toml_formatter(t, flags); // "v = VALUE"
  std::string text = os.str().substr(4);
  std::replace(text.begin(), text.end(), '\n', ' ');
  return text;
}

/// The overrides as the command line's --set strings: a dict {KEY: value}
/// (each value written as TOML, so "fe" stays a string) or a list of
/// "KEY=VALUE" strings (read exactly as --set reads them).
std::vector<std::string> override_strings(const py::object& overrides) {
  std::vector<std::string> sets;
  if (overrides.is_none()) return sets;
  if (py::isinstance<py::dict>(overrides)) {
    for (auto [k, v] : py::reinterpret_borrow<py::dict>(overrides)) {
      if (!py::isinstance<py::str>(k))
        throw py::type_error("overrides: the keys must be strings (\"material.steel.young\"), got a " + type_name(k));
      const std::string key = k.cast<std::string>();
      Conversion c;
      toml::table t;
      std::visit([&](auto&& x) { t.insert("v", std::move(x)); }, convert(v, c, key, true));
      sets.push_back(key + "=" + one_line(t));
    }
    return sets;
  }
  for (py::handle s : overrides) {
    if (!py::isinstance<py::str>(s))
      throw py::type_error("overrides: expected a dict or a list of \"KEY=VALUE\" strings, got an item of type " +
                           type_name(s));
    sets.push_back(s.cast<std::string>());
  }
  return sets;
}

/// The scene's TOML text (Scene::text: the file after the overrides) with
/// the path of every body's file (particles, STL, mesh) made absolute, so that the text
/// reads back to the same scene from any directory (the reader takes a
/// relative path relative to the scene file, which a dict has not).
std::string portable_text(const Scene& s) {
  const bool has_file = std::any_of(s.bodies.begin(), s.bodies.end(), [](const BodySection& b) { return !b.file.empty(); });
  if (!has_file) return s.text;
  toml::table root = toml::parse(std::string_view(s.text), std::string_view(s.file));
  toml::array* bodies = root["body"].as_array();
  if (!bodies || bodies->size() != s.bodies.size()) throw std::logic_error("Scene.to_toml: [[body]] does not match the scene");
  for (std::size_t i = 0; i < s.bodies.size(); ++i)
    if (!s.bodies[i].file.empty())
      bodies->get(i)->as_table()->insert_or_assign("file", std::filesystem::absolute(s.bodies[i].file).string());
  std::ostringstream os;
  os << root << "\n";
  return os.str();
}

/// to_toml(full): the scene's own text, or with full every value (the
/// defaults too) as otmpm::to_toml() writes it.
std::string scene_text(const Scene& s, bool full) { return full ? to_toml(s) : portable_text(s); }

const char* kToTomlDoc = R"doc(The resolved scene (after overrides) as TOML text.

full=False: the keys the file or dict gave, as the result file stores them in
its `scene` attribute (a particle-file body's path made absolute, so that
the text reads back from any directory). full=True: every value, the
defaults included (integrator parameters, basis tolerances, body shapes,
walls, output), as otmpm::to_toml writes a scene built in code; it reads
back to the same scene and runs to the same bits.)doc";

const char* kSceneDoc = R"doc(A scene: everything a run needs (docs/user-guide.md, "The scene file").

Build one with Scene.from_toml(path, overrides) or Scene.from_dict(d). Every
value is checked as the command line checks it; bad input raises
otmpm.InputError with the command line's message, file, line and key. A Scene
is immutable: with_overrides() returns a changed copy.)doc";

const char* kFromTomlDoc = R"doc(Reads a scene file, as `otmpm run PATH --set KEY=VALUE ...` does.

overrides: a dict {"material.steel.young": 70e9, "simulation.integrator": "fe"}
(values written as TOML: str stays a string, lists are arrays, dicts inline
tables) or a list of "KEY=VALUE" strings read exactly as --set reads them.
Raises InputError (file, line, key) for anything the command line refuses.)doc";

const char* kFromDictDoc = R"doc(Builds a scene from a dict shaped like the TOML file.

d: {"simulation": {...}, "material": [{...}], ...} (arrays of tables are
lists of dicts); values bool, int, float, str, list, dict or NumPy
scalars/arrays. The dict is written as TOML text and read by the scene
parser, so it meets every check of a file. Errors name `name` as the file and
the key; their line is the line of to_toml() of the same dict.)doc";

} // namespace

void register_scene(py::module_& m) {
  py::class_<Scene>(m, "Scene", kSceneDoc)
      .def_static(
          "from_toml",
          [](const std::filesystem::path& path, const py::object& overrides) {
            return with_python_signals([&] { // Python runs in one process
              return load_scene(path.string(), override_strings(overrides), 1);
            });
          },
          py::arg("path"), py::arg("overrides") = py::none(), kFromTomlDoc)
      .def_static(
          "from_dict",
          [](const py::dict& d, const py::object& overrides, const std::string& name) {
            Conversion c{name, {}};
            std::ostringstream os;
            os << table_from(d, c, "", false) << "\n";
            return with_python_signals([&] { return parse_scene(os.str(), name, override_strings(overrides), 1); });
          },
          py::arg("d"), py::arg("overrides") = py::none(), py::arg("name") = "<dict>", kFromDictDoc)
      .def(
          "with_overrides",
          [](const Scene& s, const py::object& overrides) {
            return with_python_signals([&] { return parse_scene(s.text, s.file, override_strings(overrides), 1); });
          },
          py::arg("overrides"),
          "A new scene: this one with the overrides applied (as Scene.from_toml's overrides).")
      .def(
          "to_toml", [](const Scene& s, bool full) { return scene_text(s, full); }, py::arg("full") = false, kToTomlDoc)
      .def(
          "to_dict",
          [](const Scene& s, bool full) { return py::module_::import("tomllib").attr("loads")(scene_text(s, full)); },
          py::arg("full") = false,
          "The resolved scene as a dict: tomllib.loads(to_toml(full)); Scene.from_dict(scene.to_dict()) gives\n"
          "the same scene.")
      .def_property_readonly(
          "file", [](const Scene& s) { return s.file; }, "The file the scene was read from (or the name given to from_dict).")
      .def_property_readonly(
          "dimension", [](const Scene& s) { return s.simulation.dimension; }, "simulation.dimension (1, 2 or 3).")
      .def_property_readonly(
          "mode", [](const Scene& s) { return s.simulation.mode; }, "simulation.mode: \"mpm\" or \"ul\".")
      .def_property_readonly(
          "integrator", [](const Scene& s) { return s.simulation.integrator; }, "simulation.integrator.")
      .def_property_readonly(
          "basis", [](const Scene& s) { return s.basis.kind; }, "basis.kind.")
      .def_property_readonly(
          "t_end", [](const Scene& s) { return s.simulation.t_end; }, "simulation.t_end [s].")
      .def_property_readonly(
          "output_file", [](const Scene& s) { return s.output.file; }, "output.file: where a run writes its results.")
      .def("__repr__", [](const Scene& s) {
        return "<otmpm.Scene '" + s.file + "': " + std::to_string(s.simulation.dimension) + "D " + s.simulation.mode +
               " " + s.simulation.integrator + " " + s.basis.kind + ", t_end = " + format_number(s.simulation.t_end) +
               ">";
      });
}

} // namespace otmpm::python
