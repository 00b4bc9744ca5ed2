/// \file file_bodies.cpp
/// Bodies from geometry files (file_bodies.hpp).
#include "otmpm/scene/file_bodies.hpp"

#include "otmpm/interrupt.hpp"

#include <algorithm>
#include <limits>

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
  const std::unique_ptr<ElementUnion<D>> shape = mesh_body_shape<D>(b);
  Vec<D> lo, hi;
  shape->bounds(lo, hi);
  for (int k = 0; k < D; ++k) b.lower[k] = lo[k], b.upper[k] = hi[k];
  long long points = 0;
  for (const MeshElement<D>& e : shape->elements())
    points += b.seeding == "quadrature" ? static_cast<long long>(element_points<D>(e, true).size()) : 1;
  b.file_particles = points;
}

} // namespace

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
template void seed_mesh_body<2>(const BodySection&, const ElementUnion<2>&,
                                const std::function<void(const Vec<2>&, double)>&);
template void seed_mesh_body<3>(const BodySection&, const ElementUnion<3>&,
                                const std::function<void(const Vec<3>&, double)>&);

} // namespace otmpm
