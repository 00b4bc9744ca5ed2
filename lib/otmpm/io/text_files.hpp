#pragma once
/// \file text_files.hpp
/// Internal helpers of the XML outputs (the XDMF sidecar, the VTK files):
/// escaping, exact number formatting, and the atomic replacement of a file.
#include <string>

namespace otmpm::text {

/// `s` with &, <, > and " replaced by XML entities.
std::string xml_escape(const std::string& s);

/// A double with 17 significant digits ("%.17g"): reads back to the same bits.
std::string exact(double x);

/// The XML comment that records the run id and the result file's name in
/// otmpm's VTK outputs (`<!-- otmpm_run_id Value="ID" otmpm_result
/// Value="NAME" -->`, read by xml_run_id and xml_result in output_files.hpp).
std::string run_id_comment(const std::string& run_id, const std::string& result_name);

/// Writes `content` to `path` + ".tmp", flushes it and renames it over
/// `path`, so readers never see half a file. OutputError naming the file and
/// the system error when it cannot (the previous file at `path` stays).
void replace_file(const std::string& path, const std::string& content, const std::string& what);

} // namespace otmpm::text
