#pragma once
/// \file file_shapes.hpp
/// Body shapes read from files: a closed surface from an STL file
/// (`shape = "stl"`) and the elements of a Gmsh mesh (`shape = "mesh"`),
/// placed by a scale, a rotation and a translation.
#include "otmpm/geometry/triangle_surface.hpp"
#include "otmpm/geometry/volume_mesh.hpp"

#include <memory>
#include <string>
#include <vector>

namespace otmpm {

/// How a body read from a file is placed: x = R (scale .* x_file) +
/// translate, R the rotations about the x, then y, then z axis by the
/// angles of `rotate` in degrees.
struct Placement {
  Vec<3> scale = Vec<3>::Ones();
  Vec<3> rotate = Vec<3>::Zero();
  Vec<3> translate = Vec<3>::Zero();
  Vec<3> operator()(const Vec<3>& x) const;
};

/// The closed surface of an STL file, placed. InputError naming the file
/// (read_stl, TriangleSurface) and the first bad triangle.
std::unique_ptr<TriangleSurface> read_stl_surface(const std::string& path, const Placement& placement);

/// The part of a Gmsh mesh a body takes: its elements of dimension D (of
/// the physical group `group`, or all when it is empty), and the mesh
/// vertices they use with their connectivity - the nodes of the classic
/// OTM discretisation (vertices as nodes, material points in the elements).
template <int D> struct MeshBody {
  std::vector<MeshElement<D>> elements;
  std::vector<Vec<D>> vertices;               ///< the vertices the elements use, in the file's node order
  std::vector<std::array<int, 8>> corners;    ///< per element, its corners as indices into vertices
  std::vector<long long> vertex_tag;          ///< per vertex, its node tag in the file
};

/// Reads the mesh body of `path` (read_gmsh), placed. In 2D the mesh lies
/// in the plane z = 0. InputError naming the file and the node or element
/// tag: no element of dimension D (in the group), an unknown group, a 2D
/// node off z = 0, a degenerate or inverted element (element_points).
template <int D>
MeshBody<D> read_mesh_body(const std::string& path, const std::string& group, const Placement& placement);

/// The box [lower, upper] of the nodes of the elements of a physical group
/// of dimension D - 1 (a boundary: lines in 2D, faces in 3D) of a mesh, placed.
template <int D>
std::pair<Vec<D>, Vec<D>> mesh_group_box(const std::string& path, const std::string& group, const Placement& placement);

} // namespace otmpm
