/// \file triangle_surface.cpp
/// The closed triangulated surface (triangle_surface.hpp): welding, the
/// checks, orientation, the tree and the winding number.
#include "otmpm/geometry/triangle_surface.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <numeric>

namespace otmpm {

namespace {

/// Beyond this many of its radii a cluster's solid angle is taken from its expansion.
constexpr double kFarField = 2.0;
constexpr int kLeafSize = 8;

/// One directed edge of a triangle, keyed by its undirected vertex pair.
struct Edge {
  std::uint64_t key;
  int triangle;
  bool forward; ///< traversed from the smaller vertex id to the larger
};

double orient3d(const Vec<3>& a, const Vec<3>& b, const Vec<3>& c, const Vec<3>& d) {
  return (b - a).cross(c - a).dot(d - a);
}

int sign(double x) { return (x > 0) - (x < 0); }

/// The directed edges of the triangles, sorted by their vertex pairs.
std::vector<Edge> edges_of(const std::vector<std::array<int, 3>>& tri) {
  std::vector<Edge> edges;
  edges.reserve(3 * tri.size());
  for (std::size_t t = 0; t < tri.size(); ++t)
    for (int e = 0; e < 3; ++e) {
      const auto i = static_cast<std::uint64_t>(tri[t][static_cast<std::size_t>(e)]);
      const auto j = static_cast<std::uint64_t>(tri[t][static_cast<std::size_t>((e + 1) % 3)]);
      edges.push_back({std::min(i, j) << 32 | std::max(i, j), static_cast<int>(t), i < j});
    }
  std::sort(edges.begin(), edges.end(), [](const Edge& a, const Edge& b) {
    return a.key != b.key ? a.key < b.key : a.triangle < b.triangle;
  });
  return edges;
}

} // namespace

TriangleSurface::TriangleSurface(const std::vector<std::array<Vec<3>, 3>>& triangles, const std::string& name) {
  std::map<std::array<double, 3>, int> index; // welds equal coordinates
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    std::array<int, 3> ids{};
    for (std::size_t v = 0; v < 3; ++v) {
      const Vec<3>& x = triangles[t][v];
      require(x.allFinite(), name, ": triangle ", t + 1, ": a vertex is not finite");
      auto [it, fresh] = index.try_emplace({x[0], x[1], x[2]}, static_cast<int>(vertex_.size()));
      if (fresh) vertex_.push_back(x);
      ids[v] = it->second;
    }
    if (ids[0] == ids[1] || ids[1] == ids[2] || ids[0] == ids[2]) continue; // no area, no edge of the surface
    tri_.push_back(ids);
    order_.push_back(static_cast<int>(t));
  }
  require(!tri_.empty(), name, ": every triangle has two equal vertices");
  lower_ = upper_ = vertex_[0];
  for (const Vec<3>& x : vertex_) lower_ = lower_.cwiseMin(x), upper_ = upper_.cwiseMax(x);
  orient(name);
  std::vector<int> perm(tri_.size());
  std::iota(perm.begin(), perm.end(), 0);
  node_.reserve(2 * tri_.size() / kLeafSize + 2);
  build(perm, 0, static_cast<int>(perm.size()));
  auto permuted = [&perm](const auto& v) {
    std::remove_cvref_t<decltype(v)> out(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) out[i] = v[static_cast<std::size_t>(perm[i])];
    return out;
  };
  tri_ = permuted(tri_), order_ = permuted(order_), component_ = permuted(component_);
  summarise(0);
  check_intersections(name, 0, 0);
  measure_components();
}

void TriangleSurface::orient(const std::string& name) {
  const std::vector<Edge> edges = edges_of(tri_);
  std::vector<std::vector<std::pair<int, bool>>> next(tri_.size()); // neighbour, whether it runs the edge alike
  int bad = -1;                                                     // the first bad triangle (given order)
  std::string why;
  auto refuse = [&](int t, const std::string& what) {
    if (bad < 0 || order_[static_cast<std::size_t>(t)] < bad) bad = order_[static_cast<std::size_t>(t)], why = what;
  };
  for (std::size_t i = 0, j; i < edges.size(); i = j) {
    for (j = i + 1; j < edges.size() && edges[j].key == edges[i].key;) ++j;
    const Vec<3>& a = vertex_[edges[i].key >> 32];
    const Vec<3>& b = vertex_[edges[i].key & 0xffffffffu];
    const std::string edge = "its edge " + format_point<3>(a) + " - " + format_point<3>(b);
    if (j - i == 1) refuse(edges[i].triangle, edge + " belongs to no other triangle: the surface is open");
    if (j - i > 2)
      refuse(edges[i].triangle, edge + " is shared by " + std::to_string(j - i) + " triangles (at most 2)");
    if (j - i != 2) continue;
    const bool alike = edges[i].forward == edges[i + 1].forward;
    next[static_cast<std::size_t>(edges[i].triangle)].push_back({edges[i + 1].triangle, alike});
    next[static_cast<std::size_t>(edges[i + 1].triangle)].push_back({edges[i].triangle, alike});
  }
  require(bad < 0, name, ": triangle ", bad + 1, ": ", why);
  // walk each component from its first triangle, flipping a neighbour that runs a shared edge alike
  component_.assign(tri_.size(), -1);
  std::vector<char> flip(tri_.size(), 0);
  int components = 0;
  for (std::size_t seed = 0; seed < tri_.size(); ++seed) {
    if (component_[seed] >= 0) continue;
    std::vector<int> stack{static_cast<int>(seed)};
    component_[seed] = components++;
    while (!stack.empty()) {
      const auto t = static_cast<std::size_t>(stack.back());
      stack.pop_back();
      for (const auto& [n, alike] : next[t]) {
        const auto u = static_cast<std::size_t>(n);
        const char wanted = static_cast<char>(flip[t] ^ static_cast<char>(alike));
        if (component_[u] < 0) {
          component_[u] = component_[t], flip[u] = wanted;
          stack.push_back(n);
        } else if (flip[u] != wanted) {
          refuse(n, "the surface is not orientable (a Moebius-like band)");
        }
      }
    }
  }
  require(bad < 0, name, ": triangle ", bad + 1, ": ", why);
  // outwards: each component's enclosed signed volume > 0
  std::vector<double> volume(static_cast<std::size_t>(components), 0.0);
  for (std::size_t t = 0; t < tri_.size(); ++t) {
    if (flip[t]) std::swap(tri_[t][1], tri_[t][2]);
    volume[static_cast<std::size_t>(component_[t])] += signed_volume(static_cast<int>(t));
  }
  for (std::size_t t = 0; t < tri_.size(); ++t) {
    const bool inward = volume[static_cast<std::size_t>(component_[t])] < 0;
    if (inward) std::swap(tri_[t][1], tri_[t][2]);
    flipped_ += static_cast<std::size_t>(flip[t] != static_cast<char>(inward));
  }
}

double TriangleSurface::signed_volume(int t) const {
  const auto& [a, b, c] = tri_[static_cast<std::size_t>(t)];
  // about the box's centre: the terms stay small for a body far from the origin
  const Vec<3> o = 0.5 * (lower_ + upper_);
  return (vertex_[a] - o).dot((vertex_[b] - o).cross(vertex_[c] - o)) / 6.0;
}

Vec<3> TriangleSurface::area_vector(int t) const {
  const auto& [a, b, c] = tri_[static_cast<std::size_t>(t)];
  return 0.5 * (vertex_[b] - vertex_[a]).cross(vertex_[c] - vertex_[a]);
}

Vec<3> TriangleSurface::centroid(int t) const {
  const auto& [a, b, c] = tri_[static_cast<std::size_t>(t)];
  return (vertex_[a] + vertex_[b] + vertex_[c]) / 3.0;
}

int TriangleSurface::build(std::vector<int>& perm, int first, int count) {
  const int id = static_cast<int>(node_.size());
  node_.emplace_back();
  Vec<3> lo = Vec<3>::Constant(INFINITY), hi = Vec<3>::Constant(-INFINITY);
  for (int i = first; i < first + count; ++i) {
    const Vec<3> c = centroid(perm[static_cast<std::size_t>(i)]);
    lo = lo.cwiseMin(c), hi = hi.cwiseMax(c);
  }
  if (count <= kLeafSize) {
    node_[static_cast<std::size_t>(id)].first = first, node_[static_cast<std::size_t>(id)].count = count;
    return id;
  }
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  const int half = count / 2;
  std::nth_element(perm.begin() + first, perm.begin() + first + half, perm.begin() + first + count,
                   [&](int a, int b) { return centroid(a)[axis] < centroid(b)[axis]; });
  const int left = build(perm, first, half);
  const int right = build(perm, first + half, count - half);
  node_[static_cast<std::size_t>(id)].left = left, node_[static_cast<std::size_t>(id)].right = right;
  return id;
}

void TriangleSurface::summarise(int id) {
  Node& n = node_[static_cast<std::size_t>(id)];
  std::vector<int> tris; // the node's triangles
  collect(id, tris);
  n.lower = Vec<3>::Constant(INFINITY), n.upper = Vec<3>::Constant(-INFINITY);
  n.area.setZero();
  double total = 0;
  Vec<3> centre = Vec<3>::Zero();
  for (int t : tris) {
    for (int v : tri_[static_cast<std::size_t>(t)]) {
      n.lower = n.lower.cwiseMin(vertex_[static_cast<std::size_t>(v)]);
      n.upper = n.upper.cwiseMax(vertex_[static_cast<std::size_t>(v)]);
    }
    const double a = area_vector(t).norm();
    centre += a * centroid(t), total += a;
    n.area += area_vector(t);
  }
  n.centre = total > 0 ? Vec<3>(centre / total) : Vec<3>(0.5 * (n.lower + n.upper));
  n.radius = 0;
  n.moment.setZero();
  for (int t : tris) {
    for (int v : tri_[static_cast<std::size_t>(t)])
      n.radius = std::max(n.radius, (vertex_[static_cast<std::size_t>(v)] - n.centre).norm());
    n.moment += area_vector(t) * (centroid(t) - n.centre).transpose();
  }
  if (n.count == 0) summarise(n.left), summarise(n.right);
}

void TriangleSurface::collect(int id, std::vector<int>& out) const {
  const Node& n = node_[static_cast<std::size_t>(id)];
  if (n.count > 0) {
    for (int t = n.first; t < n.first + n.count; ++t) out.push_back(t);
    return;
  }
  collect(n.left, out), collect(n.right, out);
}

double TriangleSurface::solid_angle(int t, const Vec<3>& x) const {
  const auto& [i, j, k] = tri_[static_cast<std::size_t>(t)];
  const Vec<3> a = vertex_[static_cast<std::size_t>(i)] - x, b = vertex_[static_cast<std::size_t>(j)] - x,
               c = vertex_[static_cast<std::size_t>(k)] - x;
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double det = a.dot(b.cross(c));
  const double den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
  return 2.0 * std::atan2(det, den);
}

double TriangleSurface::sum(int id, const Vec<3>& x) const {
  const Node& n = node_[static_cast<std::size_t>(id)];
  const Vec<3> r = n.centre - x;
  const double d = r.norm();
  if (d > kFarField * n.radius) { // the area vectors' expansion about the centre, to second order
    const double d3 = d * d * d;
    const Mat<3> J = Mat<3>::Identity() / d3 - 3.0 * r * r.transpose() / (d3 * d * d);
    return n.area.dot(r) / d3 + (J.cwiseProduct(n.moment)).sum();
  }
  if (n.count == 0) return sum(n.left, x) + sum(n.right, x);
  double omega = 0;
  for (int t = n.first; t < n.first + n.count; ++t) omega += solid_angle(t, x);
  return omega;
}

double TriangleSurface::winding_number(const Vec<3>& x) const { return sum(0, x) / (4.0 * std::numbers::pi); }

double TriangleSurface::exact_winding_number(const Vec<3>& x) const {
  double omega = 0;
  for (std::size_t t = 0; t < tri_.size(); ++t) omega += solid_angle(static_cast<int>(t), x);
  return omega / (4.0 * std::numbers::pi);
}

bool TriangleSurface::contains(const Vec<3>& x) const {
  for (int k = 0; k < 3; ++k)
    if (x[k] < lower_[k] || x[k] > upper_[k]) return false;
  return std::llround(std::abs(winding_number(x))) % 2 == 1;
}

Shape<3>::Side TriangleSurface::side(const Vec<3>& lo, const Vec<3>& hi) const {
  const Side around = Shape<3>::side(lo, hi);
  if (around == Side::outside || node_.empty()) return around;
  const double e = kSideSlack * largest_coordinate<3>(lo, hi, lower_, upper_);
  if (touches(0, lo.array() - e, hi.array() + e)) return Side::unknown;
  return contains(0.5 * (lo + hi)) ? Side::inside : Side::outside;
}

bool TriangleSurface::touches(int id, const Vec<3>& a, const Vec<3>& b) const {
  const auto apart = [&](const Vec<3>& lo, const Vec<3>& hi) {
    return (hi.array() < a.array()).any() || (lo.array() > b.array()).any();
  };
  const Node& n = node_[static_cast<std::size_t>(id)];
  if (apart(n.lower, n.upper)) return false;
  if (n.count == 0) return touches(n.left, a, b) || touches(n.right, a, b);
  for (int t = n.first; t < n.first + n.count; ++t) {
    const auto& v = tri_[static_cast<std::size_t>(t)];
    const Vec<3>& p = vertex_[static_cast<std::size_t>(v[0])];
    const Vec<3>& q = vertex_[static_cast<std::size_t>(v[1])];
    const Vec<3>& r = vertex_[static_cast<std::size_t>(v[2])];
    if (!apart(p.cwiseMin(q).cwiseMin(r), p.cwiseMax(q).cwiseMax(r))) return true;
  }
  return false;
}

void TriangleSurface::bounds(Vec<3>& lower, Vec<3>& upper) const {
  lower = lower_;
  upper = upper_;
}

bool TriangleSurface::cross(int s, int t) const {
  const auto& S = tri_[static_cast<std::size_t>(s)];
  const auto& T = tri_[static_cast<std::size_t>(t)];
  auto x = [this](int v) -> const Vec<3>& { return vertex_[static_cast<std::size_t>(v)]; };
  // an edge pq of one triangle passes through the inside of the other, abc
  auto pierces = [&](const std::array<int, 3>& edge_of, const std::array<int, 3>& tri) {
    const Vec<3>&a = x(tri[0]), &b = x(tri[1]), &c = x(tri[2]);
    for (std::size_t e = 0; e < 3; ++e) {
      const Vec<3>&p = x(edge_of[e]), &q = x(edge_of[(e + 1) % 3]);
      if (sign(orient3d(a, b, c, p)) * sign(orient3d(a, b, c, q)) >= 0) continue;
      const int s1 = sign(orient3d(p, q, a, b)), s2 = sign(orient3d(p, q, b, c)), s3 = sign(orient3d(p, q, c, a));
      if (s1 != 0 && s1 == s2 && s2 == s3) return true;
    }
    return false;
  };
  return pierces(S, T) || pierces(T, S);
}

void TriangleSurface::check_intersections(const std::string& name, int a, int b) const {
  const Node& A = node_[static_cast<std::size_t>(a)];
  const Node& B = node_[static_cast<std::size_t>(b)];
  if ((A.lower.array() > B.upper.array()).any() || (B.lower.array() > A.upper.array()).any()) return;
  if (A.count == 0 || B.count == 0) {
    if (a == b) { // the pairs within the node: each child with itself and with the other
      check_intersections(name, A.left, A.left);
      check_intersections(name, A.left, A.right);
      check_intersections(name, A.right, A.right);
    } else if (A.count == 0 && (B.count > 0 || A.radius >= B.radius)) {
      check_intersections(name, A.left, b), check_intersections(name, A.right, b);
    } else {
      check_intersections(name, a, B.left), check_intersections(name, a, B.right);
    }
    return;
  }
  for (int s = A.first; s < A.first + A.count; ++s)
    for (int t = (a == b ? s + 1 : B.first); t < B.first + B.count; ++t) {
      const auto& S = tri_[static_cast<std::size_t>(s)];
      const auto& T = tri_[static_cast<std::size_t>(t)];
      const bool share = std::any_of(S.begin(), S.end(), [&T](int v) { return std::find(T.begin(), T.end(), v) != T.end(); });
      if (share || !cross(s, t)) continue;
      const int first = std::min(order_[static_cast<std::size_t>(s)], order_[static_cast<std::size_t>(t)]);
      const int other = std::max(order_[static_cast<std::size_t>(s)], order_[static_cast<std::size_t>(t)]);
      require(false, name, ": triangle ", first + 1, ": it crosses triangle ", other + 1,
              ": the surface intersects itself");
    }
}

void TriangleSurface::measure_components() {
  const int components = *std::max_element(component_.begin(), component_.end()) + 1;
  std::vector<double> volume(static_cast<std::size_t>(components), 0.0);
  std::vector<int> vertex(static_cast<std::size_t>(components), -1);
  for (std::size_t t = 0; t < tri_.size(); ++t) {
    const auto c = static_cast<std::size_t>(component_[t]);
    volume[c] += signed_volume(static_cast<int>(t));
    area_ += area_vector(static_cast<int>(t)).norm();
    if (vertex[c] < 0) vertex[c] = tri_[t][0];
  }
  volume_ = 0;
  for (std::size_t c = 0; c < volume.size(); ++c) {
    // the depth of a shell: how many other shells enclose it (its winding number without its own triangles)
    double omega = 0;
    const Vec<3>& x = vertex_[static_cast<std::size_t>(vertex[c])];
    if (components > 1)
      for (std::size_t t = 0; t < tri_.size(); ++t)
        if (static_cast<std::size_t>(component_[t]) != c) omega += solid_angle(static_cast<int>(t), x);
    const long long depth = std::llround(omega / (4.0 * std::numbers::pi));
    volume_ += depth % 2 == 0 ? volume[c] : -volume[c];
  }
}

} // namespace otmpm
