/// \file text.cpp
/// The shared text rules (text.hpp).
#include "otmpm/text.hpp"

#include <cstdio>

namespace otmpm {

namespace {
/// Longest name of a field, probe or series.
constexpr std::size_t kMaxNameBytes = 255;
} // namespace

namespace text {

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

namespace {
bool is_control(unsigned char c) {
  constexpr unsigned char kFirstPrintable = 0x20, kDelete = 0x7f;
  return c < kFirstPrintable || c == kDelete;
}
} // namespace

std::string printable(std::string_view s) {
  std::string out;
  for (const unsigned char c : s) {
    if (!is_control(c)) {
      out += static_cast<char>(c);
      continue;
    }
    char buf[8];
    std::snprintf(buf, sizeof buf, "\\x%02x", c);
    out += buf;
  }
  return out;
}

std::string control_character(std::string_view s) {
  for (const unsigned char c : s)
    if (is_control(c)) return "a control character (code " + std::to_string(c) + ")";
  return "";
}

std::string exact(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

} // namespace text

std::string invalid_name_reason(const std::string& name) {
  if (name.empty()) return "it is empty";
  if (name.size() > kMaxNameBytes) return "it is longer than " + std::to_string(kMaxNameBytes) + " bytes";
  if (const std::string c = text::control_character(name); !c.empty()) return "it contains " + c;
  if (name.find('/') != std::string::npos) return "it contains '/' (an HDF5 path separator)";
  if (name.find('.') != std::string::npos)
    return "it contains '.' (a --set key separator; '.' and '..' are HDF5 path components)";
  if (name.front() == ' ' || name.back() == ' ') return "it starts or ends with a space";
  return "";
}

} // namespace otmpm
