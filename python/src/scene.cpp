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

/// A Python value converted to TOML.
using TomlValue = std::variant<bool, std::int64_t, double, std::string, toml::array, toml::table>;

TomlValue convert(py::handle v, const std::string& file, const std::string& path, bool inline_tables);

/// The dict `dict` as a TOML table (string keys only).
toml::table table_from(py::handle dict, const std::string& file, const std::string& path, bool inline_tables) {
  toml::table t;
  t.is_inline(inline_tables);
  for (auto [k, v] : py::reinterpret_borrow<py::dict>(dict)) {
    if (!py::isinstance<py::str>(k))
      input_error({file, 0, path}, "keys must be strings, got " + py::repr(k).cast<std::string>());
    const std::string key = k.cast<std::string>();
    std::visit([&](auto&& x) { t.insert(key, std::move(x)); }, convert(v, file, child_path(path, key), inline_tables));
  }
  return t;
}

/// Converts the Python value `v` at `path` to TOML: bool, int (64 bit),
/// float, str, list/tuple (array), dict (table); NumPy scalars and arrays
/// through their tolist(). Anything else is an InputError naming the key.
TomlValue convert(py::handle v, const std::string& file, const std::string& path, bool inline_tables) {
  py::object o = py::reinterpret_borrow<py::object>(v);
  if (!py::isinstance<py::str>(o) && py::hasattr(o, "tolist")) o = o.attr("tolist")();
  if (py::isinstance<py::bool_>(o)) return o.cast<bool>();
  if (py::isinstance<py::int_>(o)) {
    int overflow = 0;
    const long long i = PyLong_AsLongLongAndOverflow(o.ptr(), &overflow);
    if (overflow != 0) input_error({file, 0, path}, "integer " + py::str(o).cast<std::string>() + " out of range");
    return static_cast<std::int64_t>(i);
  }
  if (py::isinstance<py::float_>(o)) return o.cast<double>();
  if (py::isinstance<py::str>(o)) return o.cast<std::string>();
  if (py::isinstance<py::dict>(o)) return table_from(o, file, path, inline_tables);
  if (py::isinstance<py::list>(o) || py::isinstance<py::tuple>(o)) {
    // Arrays of tables are [[headers]] at the top level, inline below it
    // (probes = [{ name = "A", ... }]), as the scene files write them.
    const bool nested = inline_tables || path.find('.') != std::string::npos;
    toml::array a;
    std::size_t i = 0;
    for (py::handle item : o)
      std::visit([&](auto&& x) { a.push_back(std::move(x)); },
                 convert(item, file, child_path(path, std::to_string(i++)), nested));
    return a;
  }
  input_error({file, 0, path}, "a " + py::str(o.get_type().attr("__name__")).cast<std::string>() +
                                   " cannot be a scene value (expected bool, int, float, str, list or dict)");
}

/// The overrides as the command line's --set strings: a dict {KEY: value}
/// (each value written as TOML, so "fe" stays a string) or a list of
/// "KEY=VALUE" strings (read exactly as --set reads them).
std::vector<std::string> override_strings(const py::object& overrides) {
  std::vector<std::string> sets;
  if (overrides.is_none()) return sets;
  if (py::isinstance<py::dict>(overrides)) {
    for (auto [k, v] : py::reinterpret_borrow<py::dict>(overrides)) {
      const std::string key = py::str(k).cast<std::string>();
      toml::table t;
      std::visit([&](auto&& x) { t.insert("v", std::move(x)); }, convert(v, "", key, true));
      std::ostringstream os;
      os << t; // "v = VALUE"
      sets.push_back(key + "=" + os.str().substr(4));
    }
    return sets;
  }
  for (py::handle s : overrides) {
    if (!py::isinstance<py::str>(s))
      throw py::type_error("overrides: expected a dict or a list of \"KEY=VALUE\" strings, got an item " +
                           py::repr(s).cast<std::string>());
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
            return load_scene(path.string(), override_strings(overrides));
          },
          py::arg("path"), py::arg("overrides") = py::none(), kFromTomlDoc)
      .def_static(
          "from_dict",
          [](const py::dict& d, const py::object& overrides, const std::string& name) {
            std::ostringstream os;
            os << table_from(d, name, "", false) << "\n";
            return parse_scene(os.str(), name, override_strings(overrides));
          },
          py::arg("d"), py::arg("overrides") = py::none(), py::arg("name") = "<dict>", kFromDictDoc)
      .def(
          "with_overrides",
          [](const Scene& s, const py::object& overrides) {
            return parse_scene(s.text, s.file, override_strings(overrides));
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
