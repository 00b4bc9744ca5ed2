/// \file file_bodies.cpp
/// Bodies from geometry files (file_bodies.hpp).
#include "otmpm/scene/file_bodies.hpp"

#include "otmpm/interrupt.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>

namespace otmpm {

Placement body_placement(const BodySection& b) {
  Placement p;
  for (int k = 0; k < 3; ++k) p.scale[k] = b.scale[k], p.rotate[k] = b.rotate[k], p.translate[k] = b.translate[k];
  return p;
}

std::unique_ptr<TriangleSurface> stl_body_surface(const BodySection& b) {
  return read_stl_surface(b.file, body_placement(b));
}

template <int D> std::unique_ptr<ElementUnion<D>> mesh_body_shape(const BodySection& b) {
  return std::make_unique<ElementUnion<D>>(read_mesh_body<D>(b.file, b.physical, body_placement(b)).elements);
}

template <int D>
void seed_mesh_body(const BodySection& b, const ElementUnion<D>& shape,
                    const std::function<void(const Vec<D>& x, double V)>& emit) {
  for (const MeshElement<D>& e : shape.elements()) {
    interrupt_point("seeding a mesh body");
    for (const ElementPoint<D>& p : element_points<D>(e, b.seeding == "quadrature")) emit(p.x, p.volume);
  }
}

namespace {

template <int D> void read_mesh(BodySection& b) {
  MeshBody<D> mesh = read_mesh_body<D>(b.file, b.physical, body_placement(b));
  b.file_vertices = static_cast<long long>(mesh.vertices.size());
  const auto shape = std::make_unique<ElementUnion<D>>(std::move(mesh.elements));
  Vec<D> lo, hi;
  shape->bounds(lo, hi);
  for (int k = 0; k < D; ++k) b.lower[k] = lo[k], b.upper[k] = hi[k];
  long long points = 0;
  for (const MeshElement<D>& e : shape->elements())
    points += b.seeding == "quadrature" ? static_cast<long long>(element_points<D>(e, true).size()) : 1;
  b.file_particles = points;
}

} // namespace

template <int D> MeshNodes<D> mesh_body_nodes(const std::vector<BodySection>& bodies) {
  MeshNodes<D> out;
  std::map<std::array<double, D>, int> seen; // a position -> its node
  double volume = 0.0;
  for (const BodySection& b : bodies) {
    const MeshBody<D> mesh = read_mesh_body<D>(b.file, b.physical, body_placement(b));
    std::vector<int> node(mesh.vertices.size()); // vertex -> node
    for (std::size_t v = 0; v < node.size(); ++v) {
      const Vec<D>& x = mesh.vertices[v];
      std::array<double, D> key;
      for (int k = 0; k < D; ++k) key[static_cast<std::size_t>(k)] = x[k];
      const auto [it, fresh] = seen.try_emplace(key, static_cast<int>(out.x.size()));
      if (fresh) out.x.push_back(x);
      node[v] = it->second;
    }
    for (std::size_t e = 0; e < mesh.elements.size(); ++e) {
      volume += element_points<D>(mesh.elements[e], false).front().volume;
      ElementNodes el;
      el.corners = element_corners(mesh.elements[e].kind);
      for (int a = 0; a < el.corners; ++a)
        el.node[static_cast<std::size_t>(a)] = node[static_cast<std::size_t>(mesh.corners[e][static_cast<std::size_t>(a)])];
      out.elements.push_back(el);
    }
  }
  out.spacing = std::pow(volume / static_cast<double>(out.x.size()), 1.0 / D);
  return out;
}

void read_geometry_file(BodySection& b, int dim) {
  if (b.shape == "stl") {
    require(dim == 3, "shape \"stl\" is three-dimensional (simulation.dimension = ", dim, ")");
    Vec<3> lo, hi;
    stl_body_surface(b)->bounds(lo, hi);
    for (int k = 0; k < 3; ++k) b.lower[k] = lo[k], b.upper[k] = hi[k];
  } else {
    require(dim == 2 || dim == 3, "shape \"mesh\" is two- or three-dimensional (simulation.dimension = ", dim, ")");
    if (dim == 2) read_mesh<2>(b);
    else read_mesh<3>(b);
  }
  b.file_read = b.file;
}

template std::unique_ptr<ElementUnion<2>> mesh_body_shape<2>(const BodySection&);
template std::unique_ptr<ElementUnion<3>> mesh_body_shape<3>(const BodySection&);
template MeshNodes<2> mesh_body_nodes<2>(const std::vector<BodySection>&);
template MeshNodes<3> mesh_body_nodes<3>(const std::vector<BodySection>&);
template void seed_mesh_body<2>(const BodySection&, const ElementUnion<2>&,
                                const std::function<void(const Vec<2>&, double)>&);
template void seed_mesh_body<3>(const BodySection&, const ElementUnion<3>&,
                                const std::function<void(const Vec<3>&, double)>&);

} // namespace otmpm
