#pragma once
/// \file triangle_surface.hpp
/// A closed triangulated surface as a body shape (`[[body]] shape = "stl"`):
/// inside is where the generalised winding number (Jacobson, Kavan and
/// Sorkine-Hornung 2013) w(x) = (1/4pi) sum_t Omega_t(x), the solid angles
/// of the triangles seen from x, rounds to an odd number. w is 1 inside and
/// 0 outside a closed, consistently oriented surface and stays within
/// round-off of that near the surface's small flaws (slivers, vertices that
/// nearly meet, points on an edge), where a ray-parity test breaks.
#include "otmpm/geometry/shapes.hpp"

#include <array>
#include <string>
#include <vector>

namespace otmpm {

/// A closed, orientable, not self-intersecting triangulated surface (the
/// union of its components: nested shells make hollow bodies by parity).
/// Vertices are welded where their coordinates are equal; triangles with
/// two equal vertices are dropped; the triangles are oriented consistently
/// across their edges and each component outwards (its enclosed signed
/// volume > 0), whatever the file's order was. w(x) is summed over a
/// bounding-volume tree: clusters seen from beyond 2 of their radii by the
/// second-order expansion of their solid angle (Barill et al. 2018), the
/// others triangle by triangle with the exact solid angle (van Oosterom and
/// Strackee 1983).
class TriangleSurface final : public Shape<3> {
public:
  /// InputError, naming `name` (the file) and the first bad triangle
  /// (counting from 1 in the given order), for a non-finite vertex, an edge
  /// that belongs to one triangle only (an open surface), an edge shared by
  /// more than two triangles, a non-orientable surface, or two triangles
  /// that share no vertex and cross each other (a self-intersection).
  TriangleSurface(const std::vector<std::array<Vec<3>, 3>>& triangles, const std::string& name);
  bool contains(const Vec<3>& x) const override;
  /// Shape::side: `unknown` where a triangle's bounding box comes within
  /// the margin of [lower, upper] (found through the tree); otherwise no
  /// triangle crosses the box, w(x) is the same integer all over it, and
  /// the box is on the side of its centre.
  Side side(const Vec<3>& lower, const Vec<3>& upper) const override;
  void bounds(Vec<3>& lower, Vec<3>& upper) const override;
  /// The enclosed volume, sum over triangles of x_c . a_t / 3 (divergence theorem: exact).
  double measure() const override { return volume_; }
  double boundary_measure() const override { return area_; }
  /// The generalised winding number at x (the tree's sum).
  double winding_number(const Vec<3>& x) const;
  /// The same sum triangle by triangle, every solid angle exact (tests).
  double exact_winding_number(const Vec<3>& x) const;
  /// The triangles kept (after welding and dropping degenerate ones).
  std::size_t triangles() const { return tri_.size(); }
  /// How many of them were flipped to orient the surface consistently.
  std::size_t flipped() const { return flipped_; }

private:
  struct Node {
    Vec<3> lower, upper;  ///< the box of its triangles' vertices
    Vec<3> centre;        ///< area-weighted centroid of its triangles
    double radius = 0;    ///< the largest distance from centre to a vertex
    Vec<3> area;          ///< sum of the area vectors a_t = (b - a) x (c - a) / 2
    Mat<3> moment;        ///< sum of a_t (c_t - centre)^T
    int first = 0, count = 0; ///< its triangles (a leaf) or 0 count and children left, right
    int left = -1, right = -1;
  };
  /// Checks the edges (closed, at most two triangles each) and orients
  /// the triangles consistently and outwards (component_, flipped_).
  void orient(const std::string& name);
  double signed_volume(int t) const; ///< the tetrahedron of triangle t and the box's centre
  Vec<3> area_vector(int t) const;
  Vec<3> centroid(int t) const;
  /// The tree over perm[first, first + count): splits at the median centroid of the longest axis.
  int build(std::vector<int>& perm, int first, int count);
  /// Fills a node's box, centre, radius and moments (and its children's).
  void summarise(int node);
  void collect(int node, std::vector<int>& out) const;
  /// Whether the bounding box of a triangle of node `node` meets the box [a, b].
  bool touches(int node, const Vec<3>& a, const Vec<3>& b) const;
  /// The sum of the solid angles of a node's triangles seen from x.
  double sum(int node, const Vec<3>& x) const;
  double solid_angle(int t, const Vec<3>& x) const;
  /// InputError when a triangle of node a crosses one of node b (sharing no vertex).
  void check_intersections(const std::string& name, int a, int b) const;
  bool cross(int s, int t) const;
  /// The area and the enclosed volume, nested shells alternating solid and hollow.
  void measure_components();

  std::vector<Vec<3>> vertex_;
  std::vector<std::array<int, 3>> tri_;
  std::vector<int> order_;  ///< the given index (from 0) of each kept triangle, for messages
  std::vector<int> component_; ///< the connected component of each triangle
  std::vector<Node> node_;
  Vec<3> lower_, upper_;
  double volume_ = 0, area_ = 0;
  std::size_t flipped_ = 0;
};

} // namespace otmpm
