#pragma once
/// \file text.hpp
/// The text rules every layer shares: well-formed UTF-8, control characters
/// shown printable, exact numbers, and the names a result file can hold.
#include <string>
#include <string_view>

namespace otmpm {

namespace text {

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

} // namespace text

/// Why `name` cannot name a field, probe, series or attribute in the result
/// file, or "" when it can: it must be non-empty, at most 255 bytes, without
/// '/' (an HDF5 path separator), '.' ('.' and '..' are HDF5 path components,
/// and '.' separates the parts of a --set key), control characters (NUL
/// included), and without a leading or trailing space. The scene reader and
/// validate_scene apply the same rule to probe names.
std::string invalid_name_reason(const std::string& name);

} // namespace otmpm
