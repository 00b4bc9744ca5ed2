#pragma once
/// \file text_files.hpp
/// Internal helpers of the XML outputs (the XDMF sidecar, the VTK files):
/// escaping and the atomic replacement of a file. The text rules they share
/// with the other layers (UTF-8, control characters, exact numbers) are in
/// text.hpp.
#include "otmpm/text.hpp"

#include <string>

namespace otmpm::text {

/// `s` with &, <, > and " replaced by XML entities.
std::string xml_escape(const std::string& s);

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
