#pragma once
/// \file text_files.hpp
/// Internal helpers of the XML outputs (the XDMF sidecar, the VTK files):
/// escaping, the text they can hold, exact number formatting, and the atomic
/// replacement of a file.
#include <string>
#include <string_view>

namespace otmpm::text {

/// `s` with &, <, > and " replaced by XML entities.
std::string xml_escape(const std::string& s);

/// True when `s` is well-formed UTF-8 (RFC 3629: shortest form, no
/// surrogates, at most U+10FFFF), as TOML and XML require of their text.
bool valid_utf8(std::string_view s);

/// `s` with its control characters shown as \\xHH, so that a message quoting it stays printable.
std::string printable(std::string_view s);

/// "a control character (code N)" for the first control character of `s`
/// (codes 0 to 31 and 127, NUL included), "" when it has none: such text
/// cannot be in an XML file, and NUL would end the path the system sees.
std::string control_character(std::string_view s);

/// A double with 17 significant digits ("%.17g"): reads back to the same bits.
std::string exact(double x);

/// The attributes of the root element (VTKFile) that record the run id and
/// the result file's name in otmpm's VTK outputs (` otmpm_run_id="ID"
/// otmpm_result="NAME"`, escaped; read by xml_run_id and xml_result in
/// output_files.hpp). Attributes, not a comment: a comment cannot hold "--"
/// and nothing in it is unescaped, so a name like "run--2.h5" would make the
/// file ill-formed.
std::string run_id_attributes(const std::string& run_id, const std::string& result_name);

/// Writes `content` to `path` + ".tmp", flushes it and renames it over
/// `path`, so readers never see half a file. OutputError naming the file and
/// the system error when it cannot (the previous file at `path` stays).
void replace_file(const std::string& path, const std::string& content, const std::string& what);

} // namespace otmpm::text
