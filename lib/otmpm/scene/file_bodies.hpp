#pragma once
/// \file file_bodies.hpp
/// The bodies whose shape a geometry file gives (`shape = "stl"`: a closed
/// surface; `shape = "mesh"`: the elements of a Gmsh mesh), read by the
/// scene reader (bounds, particle count, the file's checks), the assembler
/// (their shape and particles) and run --check (their volumes).
#include "otmpm/geometry/file_shapes.hpp"
#include "otmpm/scene/scene.hpp"

#include <functional>
#include <memory>

namespace otmpm {

/// Whether the body's shape is read from a geometry file (stl or mesh).
inline bool geometry_file_body(const BodySection& b) { return b.shape == "stl" || b.shape == "mesh"; }

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
