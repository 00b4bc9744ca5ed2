// XML helpers of the sidecar and VTK outputs (see text_files.hpp).
#include "otmpm/io/text_files.hpp"

#include "otmpm/core.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>

namespace otmpm::text {

std::string xml_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
    case '&': out += "&amp;"; break;
    case '<': out += "&lt;"; break;
    case '>': out += "&gt;"; break;
    case '"': out += "&quot;"; break;
    default: out += c;
    }
  }
  return out;
}

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

std::string run_id_attributes(const std::string& run_id, const std::string& result_name) {
  return " otmpm_run_id=\"" + xml_escape(run_id) + "\" otmpm_result=\"" + xml_escape(result_name) + "\"";
}

void replace_file(const std::string& path, const std::string& content, const std::string& what) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << content;
    if (!out.flush()) {
      const std::string cause = std::strerror(errno);
      out.close();
      std::remove(tmp.c_str());
      throw OutputError(tmp + ": cannot write the " + what + ": " + cause);
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    throw OutputError(path + ": cannot move the " + what + " into place: " + std::strerror(errno));
}

} // namespace otmpm::text
