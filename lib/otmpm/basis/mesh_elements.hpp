#pragma once
/// \file mesh_elements.hpp
/// The `linear` family on a mesh's own elements (a body with nodes = "mesh"):
/// the nodes are the mesh's vertices, and the shape functions of a point are
/// those of the first-order element that holds it - N_a(xi(x)) of the
/// triangle, quadrangle, tetrahedron or hexahedron (xi by the inverse of the
/// element map, affine for the simplices, by Newton for the multilinear
/// ones), grad N_a = J^{-T} dN_a/dxi (the standard isoparametric finite
/// element, docs/theory.md sect. 4). Partition of unity and linear
/// completeness hold to round-off inside every element.
#include "otmpm/basis/basis.hpp"

#include <array>
#include <memory>
#include <vector>

namespace otmpm {

/// One first-order element on the nodes of a node set: its corner count
/// (2D: 3 triangle, 4 quadrangle; 3D: 4 tetrahedron, 8 hexahedron) and its
/// corners' node ids, in Gmsh's order (quadrangle and hexahedron corners
/// counter-clockwise, the hexahedron's bottom face first).
struct ElementNodes {
  int corners = 0;
  std::array<int, 8> node{};
};

/// The linear family on `elements` over `nodes` (a cloud of the mesh's
/// vertices). A point is evaluated in the element of its cell hint when it
/// lies there (a particle stays in its element while the nodes move with
/// it), else in the element a walk over the elements that share a node
/// reaches, else in the first element of the mesh that holds it; a point
/// a little outside every element (at most kElementSlack of the reference
/// element: the surface moved by the walls or the light nodes) takes the
/// nearest one's functions. InputError for an element with a node id
/// outside the node set or a corner count that is not one of D's.
template <int D>
std::unique_ptr<Basis<D>> make_element_basis(NodeSet<D> nodes, std::vector<ElementNodes> elements);

/// How far outside its element (in the reference element's coordinates) a
/// point may lie and still be evaluated there; farther is a BasisError.
inline constexpr double kElementSlack = 0.05;

} // namespace otmpm
