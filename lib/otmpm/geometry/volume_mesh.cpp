/// \file volume_mesh.cpp
/// Element maps, exact volumes and seeding points, and the union of a
/// mesh's elements (volume_mesh.hpp).
#include "otmpm/geometry/volume_mesh.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <map>

namespace otmpm {

namespace {

/// A reference point xi with its quadrature weight.
struct RefPoint {
  std::array<double, 3> xi;
  double w;
};

/// The quadrature rule of a kind (exact for det J and x det J of its map).
std::vector<RefPoint> rule(ElementKind kind) {
  const double g = 1.0 / std::sqrt(3.0);
  switch (kind) {
  case ElementKind::triangle:
    return {{{1.0 / 6, 1.0 / 6, 0}, 1.0 / 6}, {{2.0 / 3, 1.0 / 6, 0}, 1.0 / 6}, {{1.0 / 6, 2.0 / 3, 0}, 1.0 / 6}};
  case ElementKind::quadrangle: return {{{-g, -g, 0}, 1}, {{g, -g, 0}, 1}, {{g, g, 0}, 1}, {{-g, g, 0}, 1}};
  case ElementKind::tetrahedron: {
    const double a = 0.5854101966249685, b = 0.1381966011250105;
    return {{{b, b, b}, 1.0 / 24}, {{a, b, b}, 1.0 / 24}, {{b, a, b}, 1.0 / 24}, {{b, b, a}, 1.0 / 24}};
  }
  case ElementKind::hexahedron: {
    std::vector<RefPoint> r;
    for (double z : {-g, g})
      for (double y : {-g, g})
        for (double x : {-g, g}) r.push_back({{x, y, z}, 1});
    return r;
  }
  }
  return {};
}

/// The corners of the reference element (tests of det J's sign).
std::vector<RefPoint> corners(ElementKind kind) {
  switch (kind) {
  case ElementKind::triangle: return {{{1.0 / 3, 1.0 / 3, 0}, 0}};
  case ElementKind::tetrahedron: return {{{0.25, 0.25, 0.25}, 0}};
  case ElementKind::quadrangle: return {{{-1, -1, 0}, 0}, {{1, -1, 0}, 0}, {{1, 1, 0}, 0}, {{-1, 1, 0}, 0}};
  case ElementKind::hexahedron: {
    std::vector<RefPoint> r;
    for (double z : {-1.0, 1.0})
      for (double y : {-1.0, 1.0})
        for (double x : {-1.0, 1.0}) r.push_back({{x, y, z}, 0});
    return r;
  }
  }
  return {};
}

/// The shape functions N_a(xi) and their derivatives dN_a/dxi_k.
void shape(ElementKind kind, const std::array<double, 3>& xi, std::array<double, 8>& N,
           std::array<std::array<double, 3>, 8>& dN) {
  const auto [r, s, t] = xi;
  switch (kind) {
  case ElementKind::triangle:
    N = {1 - r - s, r, s};
    dN = {{{-1, -1, 0}, {1, 0, 0}, {0, 1, 0}}};
    return;
  case ElementKind::tetrahedron:
    N = {1 - r - s - t, r, s, t};
    dN = {{{-1, -1, -1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
    return;
  case ElementKind::quadrangle: {
    const double sr[4] = {-1, 1, 1, -1}, ss[4] = {-1, -1, 1, 1};
    for (int a = 0; a < 4; ++a) {
      N[a] = 0.25 * (1 + sr[a] * r) * (1 + ss[a] * s);
      dN[a] = {0.25 * sr[a] * (1 + ss[a] * s), 0.25 * ss[a] * (1 + sr[a] * r), 0};
    }
    return;
  }
  case ElementKind::hexahedron: {
    const double sr[8] = {-1, 1, 1, -1, -1, 1, 1, -1}, ss[8] = {-1, -1, 1, 1, -1, -1, 1, 1},
                 st[8] = {-1, -1, -1, -1, 1, 1, 1, 1};
    for (int a = 0; a < 8; ++a) {
      const double fr = 1 + sr[a] * r, fs = 1 + ss[a] * s, ft = 1 + st[a] * t;
      N[a] = 0.125 * fr * fs * ft;
      dN[a] = {0.125 * sr[a] * fs * ft, 0.125 * ss[a] * fr * ft, 0.125 * st[a] * fr * fs};
    }
    return;
  }
  }
}

/// x(xi) and det J(xi) of an element.
template <int D> std::pair<Vec<D>, double> map_point(const MeshElement<D>& e, const std::array<double, 3>& xi) {
  std::array<double, 8> N{};
  std::array<std::array<double, 3>, 8> dN{};
  shape(e.kind, xi, N, dN);
  Vec<D> x = Vec<D>::Zero();
  Mat<D> J = Mat<D>::Zero();
  for (int a = 0; a < element_corners(e.kind); ++a) {
    x += N[static_cast<std::size_t>(a)] * e.x[static_cast<std::size_t>(a)];
    for (int i = 0; i < D; ++i)
      for (int k = 0; k < D; ++k) J(i, k) += e.x[static_cast<std::size_t>(a)][i] * dN[static_cast<std::size_t>(a)][static_cast<std::size_t>(k)];
  }
  return {x, J.determinant()};
}

/// The triangles (2D) or tetrahedra (3D) an element splits into, as corner indices.
std::vector<std::array<int, 4>> simplices(ElementKind kind) {
  switch (kind) {
  case ElementKind::triangle: return {{0, 1, 2, 0}};
  case ElementKind::quadrangle: return {{0, 1, 2, 0}, {0, 2, 3, 0}};
  case ElementKind::tetrahedron: return {{0, 1, 2, 3}};
  case ElementKind::hexahedron: return {{0, 1, 2, 6}, {0, 2, 3, 6}, {0, 3, 7, 6}, {0, 7, 4, 6}, {0, 4, 5, 6}, {0, 5, 1, 6}};
  }
  return {};
}

/// Whether x lies in the simplex (within a relative round-off margin).
template <int D> bool in_simplex(const MeshElement<D>& e, const std::array<int, 4>& s, const Vec<D>& x) {
  Mat<D> A;
  for (int k = 0; k < D; ++k) A.col(k) = e.x[static_cast<std::size_t>(s[static_cast<std::size_t>(k + 1)])] - e.x[static_cast<std::size_t>(s[0])];
  const double det = A.determinant();
  if (det == 0) return false;
  const Vec<D> l = A.inverse() * (x - e.x[static_cast<std::size_t>(s[0])]);
  constexpr double eps = 1e-12;
  return (l.array() >= -eps).all() && l.sum() <= 1 + eps;
}

/// The sides of an element (corner indices; 2 in 2D, 3 or 4 in 3D).
std::vector<std::vector<int>> sides(ElementKind kind) {
  switch (kind) {
  case ElementKind::triangle: return {{0, 1}, {1, 2}, {2, 0}};
  case ElementKind::quadrangle: return {{0, 1}, {1, 2}, {2, 3}, {3, 0}};
  case ElementKind::tetrahedron: return {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
  case ElementKind::hexahedron:
    return {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  }
  return {};
}

/// The length or area of a side (a quadrangle as two triangles).
template <int D> double side_measure(const std::vector<Vec<D>>& p) {
  if constexpr (D == 2) return (p[1] - p[0]).norm();
  else {
    double a = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).norm();
    if (p.size() == 4) a += 0.5 * (p[2] - p[0]).cross(p[3] - p[0]).norm();
    return a;
  }
}

/// The length or area of the sides that belong to one element only (sides
/// told apart by their corners' coordinates).
template <int D> double free_sides(const std::vector<MeshElement<D>>& elements) {
  std::map<std::vector<std::array<double, D>>, std::pair<int, double>> seen;
  for (const MeshElement<D>& e : elements)
    for (const std::vector<int>& side : sides(e.kind)) {
      std::vector<Vec<D>> p;
      std::vector<std::array<double, D>> key;
      for (int c : side) {
        p.push_back(e.x[static_cast<std::size_t>(c)]);
        std::array<double, D> k;
        for (int i = 0; i < D; ++i) k[static_cast<std::size_t>(i)] = p.back()[i];
        key.push_back(k);
      }
      std::sort(key.begin(), key.end());
      auto& [count, measure] = seen[key];
      ++count, measure = side_measure<D>(p);
    }
  double total = 0;
  for (const auto& [key, value] : seen)
    if (value.first == 1) total += value.second;
  return total;
}

} // namespace

int element_corners(ElementKind kind) {
  switch (kind) {
  case ElementKind::triangle: return 3;
  case ElementKind::quadrangle: return 4;
  case ElementKind::tetrahedron: return 4;
  case ElementKind::hexahedron: return 8;
  }
  return 0;
}

int element_dimension(ElementKind kind) {
  return kind == ElementKind::triangle || kind == ElementKind::quadrangle ? 2 : 3;
}

template <int D> std::vector<ElementPoint<D>> element_points(const MeshElement<D>& e, bool quadrature) {
  require(element_dimension(e.kind) == D, "element ", e.tag, ": a ", element_dimension(e.kind),
          "D element in a ", D, "D mesh body");
  // det J of one sign and not zero: at the corners (it is multilinear in between) and the rule's points
  Vec<D> lo = e.x[0], hi = e.x[0];
  for (int a = 0; a < element_corners(e.kind); ++a)
    lo = lo.cwiseMin(e.x[static_cast<std::size_t>(a)]), hi = hi.cwiseMax(e.x[static_cast<std::size_t>(a)]);
  const double tiny = 1e-12 * std::pow((hi - lo).norm(), D);
  int positive = 0, negative = 0;
  for (const std::vector<RefPoint>& points : {corners(e.kind), rule(e.kind)})
    for (const RefPoint& p : points) {
      const double det = map_point<D>(e, p.xi).second;
      positive += det > tiny, negative += det < -tiny;
    }
  const int tested = static_cast<int>(corners(e.kind).size() + rule(e.kind).size());
  require(positive == tested || negative == tested, "element ", e.tag, ": ",
          positive + negative < tested ? "degenerate (zero volume at a corner)" : "inverted (its Jacobian changes sign)");
  std::vector<ElementPoint<D>> out;
  Vec<D> moment = Vec<D>::Zero();
  double volume = 0;
  for (const RefPoint& p : rule(e.kind)) {
    const auto [x, det] = map_point<D>(e, p.xi);
    const double V = p.w * std::abs(det);
    if (quadrature) out.push_back({x, V});
    moment += V * x, volume += V;
  }
  if (!quadrature) out.push_back({moment / volume, volume});
  return out;
}

template <int D> ElementUnion<D>::ElementUnion(std::vector<MeshElement<D>> elements) : elements_(std::move(elements)) {
  require(!elements_.empty(), "the mesh body has no element");
  lower_ = upper_ = elements_[0].x[0];
  double size = 0;
  for (const MeshElement<D>& e : elements_) {
    volume_ += element_points<D>(e, false)[0].volume;
    for (int a = 0; a < element_corners(e.kind); ++a)
      lower_ = lower_.cwiseMin(e.x[static_cast<std::size_t>(a)]), upper_ = upper_.cwiseMax(e.x[static_cast<std::size_t>(a)]);
  }
  size = std::pow(volume_ / static_cast<double>(elements_.size()), 1.0 / D);
  boundary_ = free_sides<D>(elements_);
  // a bucket grid of about one element per cell, at most 2^20 cells
  const double cells = std::min(static_cast<double>(elements_.size()), 1048576.0);
  const Vec<D> extent = (upper_ - lower_).cwiseMax(size);
  const double h = std::pow(extent.prod() / cells, 1.0 / D);
  for (int k = 0; k < D; ++k) {
    cells_[static_cast<std::size_t>(k)] = std::clamp(static_cast<int>(std::ceil(extent[k] / h)), 1, 1024);
    cell_[k] = extent[k] / cells_[static_cast<std::size_t>(k)];
  }
  long long total = 1;
  for (int k = 0; k < D; ++k) total *= cells_[static_cast<std::size_t>(k)];
  buckets_.resize(static_cast<std::size_t>(total));
  for (std::size_t i = 0; i < elements_.size(); ++i) {
    const MeshElement<D>& e = elements_[i];
    Vec<D> lo = e.x[0], hi = e.x[0];
    for (int a = 0; a < element_corners(e.kind); ++a)
      lo = lo.cwiseMin(e.x[static_cast<std::size_t>(a)]), hi = hi.cwiseMax(e.x[static_cast<std::size_t>(a)]);
    Index<D> first, last;
    for (int k = 0; k < D; ++k) {
      const int c = cells_[static_cast<std::size_t>(k)] - 1;
      first[static_cast<std::size_t>(k)] = std::clamp(static_cast<int>(std::floor((lo[k] - lower_[k]) / cell_[k])), 0, c);
      last[static_cast<std::size_t>(k)] = std::clamp(static_cast<int>(std::floor((hi[k] - lower_[k]) / cell_[k])), 0, c);
    }
    Index<D> ijk = first;
    for (;;) {
      buckets_[static_cast<std::size_t>(bucket(ijk))].push_back(static_cast<int>(i));
      int k = 0;
      for (; k < D; ++k) {
        if (++ijk[static_cast<std::size_t>(k)] <= last[static_cast<std::size_t>(k)]) break;
        ijk[static_cast<std::size_t>(k)] = first[static_cast<std::size_t>(k)];
      }
      if (k == D) break;
    }
  }
}

template <int D> long long ElementUnion<D>::bucket(const Index<D>& cell) const {
  long long id = 0;
  for (int k = D - 1; k >= 0; --k) id = id * cells_[static_cast<std::size_t>(k)] + cell[static_cast<std::size_t>(k)];
  return id;
}

template <int D> bool ElementUnion<D>::contains(const Vec<D>& x) const {
  Index<D> cell;
  for (int k = 0; k < D; ++k) {
    const double tol = 1e-12 * (upper_[k] - lower_[k]);
    if (x[k] < lower_[k] - tol || x[k] > upper_[k] + tol) return false;
    cell[static_cast<std::size_t>(k)] =
        std::clamp(static_cast<int>(std::floor((x[k] - lower_[k]) / cell_[k])), 0, cells_[static_cast<std::size_t>(k)] - 1);
  }
  for (int i : buckets_[static_cast<std::size_t>(bucket(cell))]) {
    const MeshElement<D>& e = elements_[static_cast<std::size_t>(i)];
    for (const auto& s : simplices(e.kind))
      if (in_simplex<D>(e, s, x)) return true;
  }
  return false;
}

template <int D> void ElementUnion<D>::bounds(Vec<D>& lower, Vec<D>& upper) const {
  lower = lower_;
  upper = upper_;
}

template std::vector<ElementPoint<2>> element_points<2>(const MeshElement<2>&, bool);
template std::vector<ElementPoint<3>> element_points<3>(const MeshElement<3>&, bool);
template class ElementUnion<2>;
template class ElementUnion<3>;

} // namespace otmpm
