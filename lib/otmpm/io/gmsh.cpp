/// \file gmsh.cpp
/// The Gmsh .msh 4.1 reader (gmsh.hpp).
#include "otmpm/io/gmsh.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <unordered_map>

namespace otmpm {

namespace {

/// A read position in a .msh file: ASCII words (with their line) or, in the
/// binary sections, raw values of the file's byte order.
class Cursor {
public:
  Cursor(std::string path, std::string bytes) : path_(std::move(path)), bytes_(std::move(bytes)) {}

  bool binary = false;      ///< reading binary data now (inside a section of a binary file)
  bool binary_file = false; ///< the file's sections hold binary data (file-type 1)
  bool swap = false;        ///< the file's byte order differs from this machine's

  /// "FILE:LINE: " in ASCII, "FILE: " in binary sections.
  std::string where() const { return binary ? path_ + ": " : path_ + ":" + std::to_string(line_) + ": "; }

  /// The next whitespace-separated word, "" at the end.
  std::string word() {
    while (pos_ < bytes_.size() && std::isspace(static_cast<unsigned char>(bytes_[pos_])))
      line_ += bytes_[pos_++] == '\n';
    const std::size_t start = pos_;
    while (pos_ < bytes_.size() && !std::isspace(static_cast<unsigned char>(bytes_[pos_]))) ++pos_;
    return bytes_.substr(start, pos_ - start);
  }

  /// The rest of the current line (a quoted name), without the newline.
  std::string rest_of_line() {
    const std::size_t end = std::min(bytes_.find('\n', pos_), bytes_.size());
    std::string s = bytes_.substr(pos_, end - pos_);
    pos_ = end;
    return s;
  }

  /// Skips the single newline that ends an ASCII line before binary data.
  void end_line() {
    while (pos_ < bytes_.size() && bytes_[pos_] != '\n') ++pos_;
    if (pos_ < bytes_.size()) ++pos_, ++line_;
  }

  long long integer(const char* what) {
    const std::string w = word();
    char* end = nullptr;
    const long long v = std::strtoll(w.c_str(), &end, 10);
    require(!w.empty() && end == w.c_str() + w.size(), where(), "expected an integer (", what, "), found ",
            w.empty() ? std::string("the end of the file") : "'" + w + "'");
    return v;
  }

  double real(const char* what) {
    if (binary) return raw<double>(what);
    const std::string w = word();
    char* end = nullptr;
    const double v = std::strtod(w.c_str(), &end);
    require(!w.empty() && end == w.c_str() + w.size(), where(), "expected a number (", what, "), found ",
            w.empty() ? std::string("the end of the file") : "'" + w + "'");
    return v;
  }

  /// An int field of the format (an ASCII integer or a binary int).
  long long i32(const char* what) { return binary ? raw<std::int32_t>(what) : integer(what); }
  /// A size_t field of the format (an ASCII integer or a binary size_t).
  long long size(const char* what) {
    if (!binary) return integer(what);
    const std::uint64_t v = raw<std::uint64_t>(what);
    require(v < (std::uint64_t{1} << 62), where(), "a count (", what, ") of ", static_cast<double>(v),
            " is not plausible");
    return static_cast<long long>(v);
  }

  template <class T> T raw(const char* what) {
    require(pos_ + sizeof(T) <= bytes_.size(), where(), "the file ends inside its binary data (", what, ")");
    char b[sizeof(T)];
    std::memcpy(b, bytes_.data() + pos_, sizeof(T));
    if (swap) std::reverse(b, b + sizeof(T));
    pos_ += sizeof(T);
    T v;
    std::memcpy(&v, b, sizeof(T));
    return v;
  }

  /// Skips to the word `$EndNAME` (an unknown section).
  void skip_section(const std::string& name) {
    const std::string end = "$End" + name;
    const std::size_t at = bytes_.find(end, pos_);
    require(at != std::string::npos, where(), "section $", name, " has no ", end);
    line_ += std::count(bytes_.begin() + static_cast<std::ptrdiff_t>(pos_),
                        bytes_.begin() + static_cast<std::ptrdiff_t>(at), '\n');
    pos_ = at + end.size();
  }

  void expect(const std::string& w) {
    const std::string got = word();
    require(got == w, where(), "expected ", w, ", found ", got.empty() ? std::string("the end of the file") : "'" + got + "'");
  }

  /// Throws unless `n` further items of `bytes` each could still be in the file (a truncated count).
  void plausible(long long n, std::size_t bytes, const char* what) {
    require(n >= 0 && static_cast<double>(n) * static_cast<double>(bytes) <= static_cast<double>(bytes_.size() - pos_) + 1,
            where(), "the count of ", what, " (", n, ") exceeds what the rest of the file can hold");
  }

private:
  std::string path_;
  std::string bytes_;
  std::size_t pos_ = 0;
  long long line_ = 1;
};

void read_format(Cursor& c) {
  const std::string version = c.word();
  require(version == "4.1", c.where(), "Gmsh mesh format ", version,
          " is not supported (write format 4.1: gmsh -format msh41)");
  const long long type = c.integer("file-type"), size = c.integer("data-size");
  require(type == 0 || type == 1, c.where(), "file-type must be 0 (ASCII) or 1 (binary), found ", type);
  require(size == 8, c.where(), "data-size must be 8, found ", size);
  if (type == 1) {
    c.end_line();
    c.binary = c.binary_file = true;
    const auto one = c.raw<std::int32_t>("the byte-order mark");
    c.swap = one != 1;
    require(one == 1 || one == 0x01000000, c.where(), "the byte-order mark is neither 1 nor 1 byte-swapped");
    c.binary = false; // the section markers are ASCII
  }
  c.expect("$EndMeshFormat");
}

void read_physical_names(Cursor& c, GmshMesh& m) {
  const long long n = c.integer("number of physical names");
  for (long long i = 0; i < n; ++i) {
    const int dim = static_cast<int>(c.integer("dimension"));
    const int tag = static_cast<int>(c.integer("physical tag"));
    std::string name = c.rest_of_line();
    const std::size_t a = name.find('"'), b = name.rfind('"');
    require(a != std::string::npos && b > a, c.where(), "expected a quoted name of physical group ", tag);
    m.physical_names[{dim, tag}] = name.substr(a + 1, b - a - 1);
  }
  c.expect("$EndPhysicalNames");
}

/// One entity of $Entities: its tag, box (not for points), physical tags and bounding entities.
void read_entity(Cursor& c, int dim, GmshMesh& m) {
  const int tag = static_cast<int>(c.i32("entity tag"));
  for (int k = 0; k < (dim == 0 ? 3 : 6); ++k) c.real("entity box");
  const long long np = c.size("number of physical tags");
  c.plausible(np, 4, "physical tags");
  std::vector<int>& phys = m.entity_physicals[{dim, tag}];
  for (long long i = 0; i < np; ++i) phys.push_back(static_cast<int>(c.i32("physical tag")));
  if (dim == 0) return;
  const long long nb = c.size("number of bounding entities");
  c.plausible(nb, 4, "bounding entities");
  for (long long i = 0; i < nb; ++i) c.i32("bounding entity");
}

void read_entities(Cursor& c, GmshMesh& m, bool binary) {
  c.binary = binary;
  if (binary) c.end_line();
  long long count[4];
  for (auto& n : count) n = c.size("number of entities");
  for (int dim = 0; dim < 4; ++dim) {
    c.plausible(count[dim], 4, "entities");
    for (long long i = 0; i < count[dim]; ++i) read_entity(c, dim, m);
  }
  c.binary = false;
  c.expect("$EndEntities");
}

void read_nodes(Cursor& c, GmshMesh& m, bool binary) {
  c.binary = binary;
  if (binary) c.end_line();
  const long long blocks = c.size("number of node blocks"), total = c.size("number of nodes");
  c.size("smallest node tag"), c.size("largest node tag");
  c.plausible(total, binary ? 32 : 6, "nodes");
  m.nodes.reserve(static_cast<std::size_t>(total));
  m.node_tag.reserve(static_cast<std::size_t>(total));
  for (long long b = 0; b < blocks; ++b) {
    const long long dim = c.i32("entity dimension");
    c.i32("entity tag");
    const long long parametric = c.i32("parametric");
    const long long n = c.size("number of nodes in the block");
    c.plausible(n, binary ? 32 : 6, "nodes in a block");
    for (long long i = 0; i < n; ++i) m.node_tag.push_back(c.size("node tag"));
    for (long long i = 0; i < n; ++i) {
      Vec<3> x;
      for (int k = 0; k < 3; ++k) x[k] = c.real("node coordinate");
      const long long tag = m.node_tag[m.nodes.size()];
      require(x.allFinite(), c.where(), "node ", tag, ": a coordinate is not a finite number");
      for (long long p = 0; p < (parametric ? dim : 0); ++p) c.real("node parameter");
      m.nodes.push_back(x);
    }
  }
  require(static_cast<long long>(m.nodes.size()) == total, c.where(), "$Nodes announces ", total, " nodes but holds ",
          m.nodes.size());
  c.binary = false;
  c.expect("$EndNodes");
}

const char* type_name(long long type) {
  switch (type) {
  case 8: return " (3-node line)";
  case 9: return " (6-node triangle)";
  case 10: return " (9-node quadrangle)";
  case 11: return " (10-node tetrahedron)";
  case 12: return " (27-node hexahedron)";
  case 6: return " (prism)";
  case 7: return " (pyramid)";
  default: return "";
  }
}

void read_elements(Cursor& c, GmshMesh& m, bool binary) {
  c.binary = binary;
  if (binary) c.end_line();
  std::unordered_map<long long, int> index; // node tag -> index
  index.reserve(m.node_tag.size());
  for (std::size_t i = 0; i < m.node_tag.size(); ++i) index[m.node_tag[i]] = static_cast<int>(i);
  const long long blocks = c.size("number of element blocks"), total = c.size("number of elements");
  c.size("smallest element tag"), c.size("largest element tag");
  c.plausible(total, binary ? 16 : 4, "elements");
  m.elements.reserve(static_cast<std::size_t>(total));
  for (long long b = 0; b < blocks; ++b) {
    c.i32("entity dimension");
    const int entity = static_cast<int>(c.i32("entity tag"));
    const long long type = c.i32("element type");
    const long long n = c.size("number of elements in the block");
    c.plausible(n, binary ? 16 : 4, "elements in a block");
    const bool known = type == 1 || type == 2 || type == 3 || type == 4 || type == 5 || type == 15;
    for (long long i = 0; i < n; ++i) {
      GmshElement e;
      e.tag = c.size("element tag");
      require(known, c.where(), "element ", e.tag, ": type ", type, type_name(type),
              " is not supported (first-order points, lines, triangles, quadrangles, tetrahedra and hexahedra are)");
      e.type = static_cast<GmshElementType>(type);
      e.entity = entity;
      for (int k = 0; k < e.nodes(); ++k) {
        const long long tag = c.size("node tag");
        const auto it = index.find(tag);
        require(it != index.end(), c.where(), "element ", e.tag, ": node ", tag, " is not in $Nodes");
        e.node[static_cast<std::size_t>(k)] = it->second;
      }
      m.elements.push_back(e);
    }
  }
  c.binary = false;
  c.expect("$EndElements");
}

} // namespace

int gmsh_type_nodes(GmshElementType type) {
  switch (type) {
  case GmshElementType::point: return 1;
  case GmshElementType::line: return 2;
  case GmshElementType::triangle: return 3;
  case GmshElementType::quadrangle: return 4;
  case GmshElementType::tetrahedron: return 4;
  case GmshElementType::hexahedron: return 8;
  }
  return 0;
}

int gmsh_type_dimension(GmshElementType type) {
  switch (type) {
  case GmshElementType::point: return 0;
  case GmshElementType::line: return 1;
  case GmshElementType::triangle:
  case GmshElementType::quadrangle: return 2;
  case GmshElementType::tetrahedron:
  case GmshElementType::hexahedron: return 3;
  }
  return 0;
}

int GmshMesh::physical_tag(int dim, const std::string& group) const {
  std::string known;
  for (const auto& [key, name] : physical_names) {
    if (key.first != dim) continue;
    if (name == group || std::to_string(key.second) == group) return key.second;
    known += (known.empty() ? "" : ", ") + ("\"" + name + "\"");
  }
  for (const auto& [entity, tags] : entity_physicals) // unnamed groups, by number
    if (entity.first == dim)
      for (int t : tags)
        if (std::to_string(t) == group) return t;
  throw InputError(error_message(path, ": no physical group \"", group, "\" of dimension ", dim,
                                 known.empty() ? std::string(" (the file names none)") : " (it has " + known + ")"));
}

bool GmshMesh::in_group(const GmshElement& e, int tag) const {
  const auto it = entity_physicals.find({e.dimension(), e.entity});
  return it != entity_physicals.end() && std::find(it->second.begin(), it->second.end(), tag) != it->second.end();
}

GmshMesh read_gmsh(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  require(static_cast<bool>(in), path, ": cannot open the mesh file");
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  require(!in.bad(), path, ": cannot read the mesh file");
  GmshMesh m;
  m.path = path;
  Cursor c(path, std::move(bytes));
  c.expect("$MeshFormat");
  read_format(c);
  for (std::string w = c.word(); !w.empty(); w = c.word()) {
    require(w.size() > 1 && w[0] == '$', c.where(), "expected a section ($Name), found '", w, "'");
    const std::string name = w.substr(1);
    if (name == "PhysicalNames") read_physical_names(c, m);
    else if (name == "Entities") read_entities(c, m, c.binary_file);
    else if (name == "Nodes") read_nodes(c, m, c.binary_file);
    else if (name == "Elements") read_elements(c, m, c.binary_file);
    else c.skip_section(name);
  }
  require(!m.nodes.empty() && !m.elements.empty(), path, ": the mesh has no ", m.nodes.empty() ? "$Nodes" : "$Elements");
  return m;
}

} // namespace otmpm
