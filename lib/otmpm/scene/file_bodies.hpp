#pragma once
/// \file file_bodies.hpp
/// The bodies whose shape a geometry file gives (`shape = "stl"`: a closed
/// surface; `shape = "mesh"`: the elements of a Gmsh mesh), read by the
/// scene reader (bounds, particle count, the file's checks), the assembler
/// (their shape and particles) and run --check (their volumes).
#include "otmpm/basis/mesh_elements.hpp"
#include "otmpm/scene/file_shapes.hpp"
#include "otmpm/scene/scene.hpp"

#include <functional>
#include <memory>

namespace otmpm {

/// Whether the body's shape is read from a geometry file (stl or mesh).
inline bool geometry_file_body(const BodySection& b) { return b.shape == "stl" || b.shape == "mesh"; }

/// Whether the scene's nodes are its mesh bodies' vertices (a body with
/// nodes = "mesh"; validate_scene then requires it of every body).
inline bool mesh_nodes(const Scene& s) {
  for (const BodySection& b : s.bodies)
    if (b.nodes == "mesh") return true;
  return false;
}

/// The nodes of a scene whose bodies give their mesh's vertices as nodes
/// (nodes = "mesh"): the bodies' vertices, each position once (two bodies
/// of one mesh share the vertices of their interface), in body and file
/// order; `spacing` h = (V / n)^(1/D), V the bodies' volume and n the
/// vertices - the spacing of a lattice with as many nodes per volume; the
/// bodies' elements on these nodes.
template <int D> struct MeshNodes {
  AlignedVector<Vec<D>> x;
  double spacing = 0.0;
  std::vector<ElementNodes> elements;
};
template <int D> MeshNodes<D> mesh_body_nodes(const std::vector<BodySection>& bodies);

/// The body's scale, rotate and translate keys.
Placement body_placement(const BodySection& b);

/// The surface of an stl body, placed (read_stl_surface).
std::unique_ptr<TriangleSurface> stl_body_surface(const BodySection& b);

/// The shape of a mesh body: the union of the elements it takes (read_mesh_body).
template <int D> std::unique_ptr<ElementUnion<D>> mesh_body_shape(const BodySection& b);

/// The material points of a mesh body's elements (element_points: one per
/// element, or per quadrature point with seeding = "quadrature"), in
/// element order: emit(x, V).
template <int D>
void seed_mesh_body(const BodySection& b, const ElementUnion<D>& shape,
                    const std::function<void(const Vec<D>& x, double V)>& emit);

/// Reads the geometry file of an stl or mesh body of a `dim`-dimensional
/// scene and sets its bounds (lower, upper) and, for a mesh, the number of
/// its material points (file_particles). InputError naming the file and
/// the bad triangle, element or node.
void read_geometry_file(BodySection& b, int dim);

} // namespace otmpm
