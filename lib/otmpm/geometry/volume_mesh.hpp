#pragma once
/// \file volume_mesh.hpp
/// Bodies from volume meshes (`[[body]] shape = "mesh"`): first-order
/// triangles and quadrangles (2D), tetrahedra and hexahedra (3D) as
/// isoparametric maps x(xi) = sum_a N_a(xi) x_a of a reference element, with
/// their exact volumes and seeding points, and the union of a mesh's
/// elements as a body shape.
#include "otmpm/geometry/shapes.hpp"

#include <array>
#include <vector>

namespace otmpm {

/// The first-order element kinds (Gmsh's node order: quadrangle and
/// hexahedron corners counter-clockwise, the hexahedron's bottom face first).
enum class ElementKind { triangle, quadrangle, tetrahedron, hexahedron };

/// The number of corners of a kind and its dimension.
int element_corners(ElementKind kind);
int element_dimension(ElementKind kind);

/// One element of a volume mesh: its kind, corners and tag (for messages).
template <int D> struct MeshElement {
  ElementKind kind = ElementKind::triangle;
  std::array<Vec<D>, 8> x{};
  long long tag = 0;
};

/// A material point of an element: position and the volume it carries.
template <int D> struct ElementPoint {
  Vec<D> x;
  double volume = 0;
};

/// The material points of an element. `quadrature` false: one point at
/// the element's centroid carrying its volume V = int |det J| dxi; true:
/// one per point of its quadrature rule (triangle 3, quadrangle 2x2 Gauss,
/// tetrahedron 4, hexahedron 2x2x2 Gauss), at x(xi_q) with w_q |det J(xi_q)|.
/// The rules integrate det J and x det J of these maps exactly, so the
/// volumes add up to the element's exact volume and the one point sits at
/// its exact centroid. InputError naming the element's tag when det J is
/// zero or changes sign over the element (degenerate or inverted; an
/// element numbered clockwise throughout is accepted as it is).
template <int D> std::vector<ElementPoint<D>> element_points(const MeshElement<D>& e, bool quadrature);

/// The union of a mesh's elements (element_points' volumes): contains(x)
/// tests the elements near x (a bucket grid over their boxes; a quadrangle
/// as two triangles, a hexahedron as six tetrahedra: exact for planar
/// faces); measure() is the sum of the exact element volumes;
/// boundary_measure() the length (2D) or area (3D) of the element sides
/// that belong to one element only (quadrangle faces as two triangles).
template <int D> class ElementUnion final : public Shape<D> {
public:
  /// InputError for no element, or as element_points for a bad one.
  explicit ElementUnion(std::vector<MeshElement<D>> elements);
  bool contains(const Vec<D>& x) const override;
  void bounds(Vec<D>& lower, Vec<D>& upper) const override;
  double measure() const override { return volume_; }
  double boundary_measure() const override { return boundary_; }
  /// The elements, in the given order.
  const std::vector<MeshElement<D>>& elements() const { return elements_; }

private:
  long long bucket(const Index<D>& cell) const;
  std::vector<MeshElement<D>> elements_;
  Vec<D> lower_, upper_;
  Vec<D> cell_;
  Index<D> cells_;
  std::vector<std::vector<int>> buckets_; ///< per cell of the bucket grid, the elements whose box meets it
  double volume_ = 0, boundary_ = 0;
};

extern template class ElementUnion<2>;
extern template class ElementUnion<3>;

} // namespace otmpm
