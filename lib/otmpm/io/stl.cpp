/// \file stl.cpp
/// The STL reader (stl.hpp).
#include "otmpm/io/stl.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>

namespace otmpm {

namespace {

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  require(static_cast<bool>(in), path, ": cannot open the STL file");
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  require(!in.bad(), path, ": cannot read the STL file");
  return bytes;
}

std::uint32_t little_u32(const char* p) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(p[i]);
  return v;
}

float little_float(const char* p) {
  const std::uint32_t bits = little_u32(p);
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

/// The triangle count of a binary STL file, or -1 when the bytes are not one.
long long binary_count(const std::string& bytes) {
  if (bytes.size() < 84) return -1;
  const long long n = little_u32(bytes.data() + 80);
  return static_cast<long long>(bytes.size()) == 84 + 50 * n ? n : -1;
}

std::vector<StlTriangle> read_binary(const std::string& path, const std::string& bytes, long long n) {
  std::vector<StlTriangle> out(static_cast<std::size_t>(n));
  for (long long t = 0; t < n; ++t) {
    const char* p = bytes.data() + 84 + 50 * t + 12; // past the facet normal
    for (int v = 0; v < 3; ++v)
      for (int k = 0; k < 3; ++k) {
        const double x = little_float(p + 12 * v + 4 * k);
        require(std::isfinite(x), path, ": triangle ", t + 1, ": a coordinate is not a finite number");
        out[static_cast<std::size_t>(t)][static_cast<std::size_t>(v)][k] = x;
      }
  }
  return out;
}

/// Whitespace-separated words of an ASCII STL file with their line numbers.
class Words {
public:
  Words(const std::string& path, const std::string& text) : path_(path), in_(text) {}

  /// The next word, or "" at the end of the file.
  std::string next() {
    std::string w;
    for (;;) {
      if (words_ >> w) return w;
      std::string line;
      if (!std::getline(in_, line)) return "";
      ++line_;
      words_.clear();
      words_.str(line);
    }
  }

  /// Throws unless the next word is `expected`.
  void expect(std::string_view expected, long long triangle) {
    const std::string w = next();
    require(w == expected, path_, ":", line_, ": triangle ", triangle, ": expected '", std::string(expected),
            "', found ", w.empty() ? std::string("the end of the file") : "'" + w + "'");
  }

  double number(long long triangle) {
    const std::string w = next();
    char* end = nullptr;
    const double x = std::strtod(w.c_str(), &end);
    require(!w.empty() && end == w.c_str() + w.size() && std::isfinite(x), path_, ":", line_, ": triangle ", triangle,
            ": expected a finite number, found '", w, "'");
    return x;
  }

  /// The line of the last word read.
  long long line() const { return line_; }

private:
  std::string path_;
  std::istringstream in_;
  std::istringstream words_;
  long long line_ = 0;
};

std::vector<StlTriangle> read_ascii(const std::string& path, const std::string& text) {
  Words words(path, text);
  require(words.next() == "solid", path, ": not an STL file (neither binary nor starting with 'solid')");
  const long long first_line = words.line();
  std::vector<StlTriangle> out;
  for (std::string w = words.next(); w != "endsolid"; w = words.next()) {
    const long long t = static_cast<long long>(out.size()) + 1;
    if (w != "facet") {
      if (words.line() == first_line) continue; // the rest of the 'solid' line: the solid's name
      require(false, path, ":", words.line(), ": triangle ", t, ": expected 'facet' or 'endsolid', found ",
              w.empty() ? std::string("the end of the file") : "'" + w + "'");
    }
    words.expect("normal", t);
    for (int k = 0; k < 3; ++k) words.number(t);
    words.expect("outer", t);
    words.expect("loop", t);
    StlTriangle tri;
    for (auto& v : tri) {
      words.expect("vertex", t);
      for (int k = 0; k < 3; ++k) v[k] = words.number(t);
    }
    words.expect("endloop", t);
    words.expect("endfacet", t);
    out.push_back(tri);
  }
  return out;
}

} // namespace

std::vector<StlTriangle> read_stl(const std::string& path) {
  const std::string bytes = read_bytes(path);
  const long long n = binary_count(bytes);
  std::vector<StlTriangle> out = n >= 0 ? read_binary(path, bytes, n) : read_ascii(path, bytes);
  require(!out.empty(), path, ": the STL file holds no triangle");
  return out;
}

} // namespace otmpm
