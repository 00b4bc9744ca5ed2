#pragma once
/// \file stl.hpp
/// Triangulated surfaces from STL files (`[[body]] shape = "stl"`), ASCII
/// or binary. The reader returns the triangles as the file lists them; the
/// checks of the surface itself (closed, not self-intersecting) are those of
/// TriangleSurface (geometry/triangle_surface.hpp).
#include "otmpm/core.hpp"

#include <array>
#include <string>
#include <vector>

namespace otmpm {

/// One triangle of an STL file: its three vertices in the file's order (the
/// facet normal of the file is not used: the orientation is taken from the
/// vertex order and made consistent by TriangleSurface).
using StlTriangle = std::array<Vec<3>, 3>;

/// Reads an STL file: binary when its size is 84 + 50 n bytes for the n its
/// header gives, else ASCII (`solid ... facet normal ... outer loop vertex
/// x y z (x3) endloop endfacet ... endsolid`). InputError naming the file
/// and the triangle (counting from 1; with its line in an ASCII file) for a
/// missing or unreadable file, a malformed facet, a coordinate that is not
/// a finite number, or no triangle at all.
std::vector<StlTriangle> read_stl(const std::string& path);

} // namespace otmpm
