/// \file file_shapes.cpp
/// Body shapes read from files (file_shapes.hpp).
#include "otmpm/scene/file_shapes.hpp"

#include "otmpm/io/gmsh.hpp"
#include "otmpm/io/stl.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <numbers>

namespace otmpm {

namespace {

ElementKind kind_of(GmshElementType type) {
  switch (type) {
  case GmshElementType::triangle: return ElementKind::triangle;
  case GmshElementType::quadrangle: return ElementKind::quadrangle;
  case GmshElementType::tetrahedron: return ElementKind::tetrahedron;
  default: return ElementKind::hexahedron;
  }
}

/// A node of the mesh, placed, as a point of D dimensions (2D: on z = 0).
template <int D> Vec<D> node_at(const GmshMesh& m, int node, const Placement& placement) {
  const Vec<3> x = placement(m.nodes[static_cast<std::size_t>(node)]);
  if constexpr (D == 2)
    require(x[2] == 0.0, m.path, ": node ", m.node_tag[static_cast<std::size_t>(node)], ": z = ", x[2],
            " (a 2D mesh lies in the plane z = 0)");
  return x.head<D>();
}

/// The elements of dimension `dim` in the group (all without one).
std::vector<const GmshElement*> selected(const GmshMesh& m, int dim, const std::string& group) {
  const int tag = group.empty() ? 0 : m.physical_tag(dim, group);
  std::vector<const GmshElement*> out;
  for (const GmshElement& e : m.elements)
    if (e.dimension() == dim && (group.empty() || m.in_group(e, tag))) out.push_back(&e);
  require(!out.empty(), m.path, ": no element of dimension ", dim,
          group.empty() ? std::string() : " in physical group \"" + group + "\"");
  return out;
}

} // namespace

Vec<3> Placement::operator()(const Vec<3>& x) const {
  const Vec<3> a = rotate * (std::numbers::pi / 180.0);
  const Mat<3> Rx = Eigen::AngleAxisd(a[0], Vec<3>::UnitX()).toRotationMatrix();
  const Mat<3> Ry = Eigen::AngleAxisd(a[1], Vec<3>::UnitY()).toRotationMatrix();
  const Mat<3> Rz = Eigen::AngleAxisd(a[2], Vec<3>::UnitZ()).toRotationMatrix();
  const Vec<3> scaled = scale.cwiseProduct(x);
  const Vec<3> turned = rotate.isZero() ? scaled : Vec<3>(Rz * (Ry * (Rx * scaled)));
  return turned + translate;
}

std::unique_ptr<TriangleSurface> read_stl_surface(const std::string& path, const Placement& placement) {
  std::vector<StlTriangle> triangles = read_stl(path);
  for (StlTriangle& t : triangles)
    for (Vec<3>& x : t) x = placement(x);
  return std::make_unique<TriangleSurface>(triangles, path);
}

template <int D>
MeshBody<D> read_mesh_body(const std::string& path, const std::string& group, const Placement& placement) {
  const GmshMesh m = read_gmsh(path);
  MeshBody<D> body;
  std::vector<int> vertex(m.nodes.size(), -1); // node index -> vertex index
  const std::vector<const GmshElement*> elements = selected(m, D, group);
  for (const GmshElement* e : elements)
    for (int a = 0; a < e->nodes(); ++a) vertex[static_cast<std::size_t>(e->node[static_cast<std::size_t>(a)])] = 0;
  for (std::size_t i = 0; i < vertex.size(); ++i) {
    if (vertex[i] < 0) continue;
    vertex[i] = static_cast<int>(body.vertices.size());
    body.vertices.push_back(node_at<D>(m, static_cast<int>(i), placement));
    body.vertex_tag.push_back(m.node_tag[i]);
  }
  for (const GmshElement* e : elements) {
    MeshElement<D> me;
    me.kind = kind_of(e->type);
    me.tag = e->tag;
    std::array<int, 8> corners{};
    for (int a = 0; a < e->nodes(); ++a) {
      corners[static_cast<std::size_t>(a)] = vertex[static_cast<std::size_t>(e->node[static_cast<std::size_t>(a)])];
      me.x[static_cast<std::size_t>(a)] = body.vertices[static_cast<std::size_t>(corners[static_cast<std::size_t>(a)])];
    }
    try {
      element_points<D>(me, false); // checks the element
    } catch (const InputError& err) {
      throw InputError(path + ": " + err.what());
    }
    body.elements.push_back(me);
    body.corners.push_back(corners);
  }
  return body;
}

template <int D>
std::pair<Vec<D>, Vec<D>> mesh_group_box(const std::string& path, const std::string& group, const Placement& placement) {
  const GmshMesh m = read_gmsh(path);
  const std::vector<const GmshElement*> elements = selected(m, D - 1, group);
  Vec<D> lo = node_at<D>(m, elements[0]->node[0], placement), hi = lo;
  for (const GmshElement* e : elements)
    for (int a = 0; a < e->nodes(); ++a) {
      const Vec<D> x = node_at<D>(m, e->node[static_cast<std::size_t>(a)], placement);
      lo = lo.cwiseMin(x), hi = hi.cwiseMax(x);
    }
  return {lo, hi};
}

template MeshBody<2> read_mesh_body<2>(const std::string&, const std::string&, const Placement&);
template MeshBody<3> read_mesh_body<3>(const std::string&, const std::string&, const Placement&);
template std::pair<Vec<2>, Vec<2>> mesh_group_box<2>(const std::string&, const std::string&, const Placement&);
template std::pair<Vec<3>, Vec<3>> mesh_group_box<3>(const std::string&, const std::string&, const Placement&);

} // namespace otmpm
