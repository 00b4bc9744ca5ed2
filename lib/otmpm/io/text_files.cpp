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
