#include "otmpm/scene/toml_reader.hpp"

#include "otmpm/io/output_files.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>

namespace otmpm::toml_input {

toml::table parse_toml_text(const std::string& text, const std::string& name) {
  try {
    return toml::parse(std::string_view(text), std::string_view(name));
  } catch (const toml::parse_error& e) {
    const auto& pos = e.source().begin;
    throw InputError(name + ":" + std::to_string(pos.line) + ":" + std::to_string(pos.column) +
                         ": syntax error: " + std::string(e.description()),
                     {name, static_cast<int>(pos.line), ""});
  }
}

std::string read_text_file(const std::string& path, const std::string& what) {
  if (path.empty()) throw InputError("the " + what + " path is empty");
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw InputError(path + ": is a directory, not a " + what + " (give the .toml file inside it)", {path, 0, ""});
  if (const std::string kind = special_file(path); !kind.empty())
    throw InputError(path + ": is " + kind + ", not a " + what, {path, 0, ""});
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw InputError(path + ": cannot open the " + what + (std::filesystem::exists(path, ec) ? "" : " (no such file)"),
                     {path, 0, ""});
  std::ostringstream buf;
  buf << in.rdbuf();
  if (in.bad()) throw InputError(path + ": cannot read the " + what, {path, 0, ""});
  return buf.str();
}

toml::table parse_toml_file(const std::string& path, const std::string& what) {
  return parse_toml_text(read_text_file(path, what), path);
}

} // namespace otmpm::toml_input
