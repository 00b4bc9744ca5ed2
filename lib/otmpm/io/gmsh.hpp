#pragma once
/// \file gmsh.hpp
/// Meshes from Gmsh's .msh files, format 4.1, ASCII or binary
/// (`[[body]] shape = "mesh"`): nodes, the elements of the kinds otmpm
/// seeds or selects with (points, lines, triangles, quadrangles, tetrahedra,
/// hexahedra: first order), and the physical groups of the entities.
#include "otmpm/core.hpp"

#include <array>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace otmpm {

/// The element types of the Gmsh format that the reader accepts.
enum class GmshElementType : int { line = 1, triangle = 2, quadrangle = 3, tetrahedron = 4, hexahedron = 5, point = 15 };

/// The number of nodes of a type, and its dimension.
int gmsh_type_nodes(GmshElementType type);
int gmsh_type_dimension(GmshElementType type);

/// One element: its tag, type, entity (dimension, tag) and its nodes (as
/// indices into GmshMesh::nodes, in Gmsh's order).
struct GmshElement {
  long long tag = 0;
  GmshElementType type = GmshElementType::point;
  int entity = 0;
  std::array<int, 8> node{};
  int dimension() const { return gmsh_type_dimension(type); }
  int nodes() const { return gmsh_type_nodes(type); }
};

/// The content of a .msh file that otmpm uses.
struct GmshMesh {
  std::string path;
  std::vector<Vec<3>> nodes;       ///< positions, in file order
  std::vector<long long> node_tag; ///< per node, its tag
  std::vector<GmshElement> elements;
  /// (dimension, entity tag) -> the physical tags of that entity
  std::map<std::pair<int, int>, std::vector<int>> entity_physicals;
  /// (dimension, physical tag) -> its name ("" when it has none)
  std::map<std::pair<int, int>, std::string> physical_names;

  /// The physical tag of dimension `dim` that `group` names (its name, or
  /// its number written in decimal); InputError naming the file and the
  /// groups it has otherwise.
  int physical_tag(int dim, const std::string& group) const;
  /// Whether an element belongs to a physical tag (through its entity).
  bool in_group(const GmshElement& e, int tag) const;
};

/// Reads a Gmsh .msh file of format 4.1 (ASCII or binary, either byte
/// order). InputError naming the file, and the line (ASCII) or the element
/// or node tag, for a missing file, another format version, a truncated
/// or malformed section, a coordinate that is not finite, an element type
/// other than the first-order ones above, or a node tag that $Nodes lacks.
GmshMesh read_gmsh(const std::string& path);

} // namespace otmpm
