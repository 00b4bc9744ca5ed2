#pragma once
/// \file shapes.hpp
/// The regions bodies fill (docs/theory.md sect. 7, "Bodies"): a box, a
/// sphere (a disk in 2D, an interval in 1D), a cylinder (3D), a polygon
/// (2D), or the union of the cells of particles read from a file. Particles
/// are seeded on the background lattice and kept where their point lies in
/// the shape; overlapping bodies are found with contains().
#include "otmpm/core.hpp"

#include <algorithm>
#include <functional>
#include <memory>
#include <vector>

namespace otmpm {

/// A region of space in D dimensions.
template <int D> class Shape {
public:
  virtual ~Shape() = default;
  /// True when x lies in the closed region.
  virtual bool contains(const Vec<D>& x) const = 0;
  /// The smallest axis-aligned box [lower, upper] holding the region.
  virtual void bounds(Vec<D>& lower, Vec<D>& upper) const = 0;
  /// The exact measure of the region (volume; area in 2D; length in 1D).
  virtual double measure() const = 0;
  /// The measure of its boundary (surface; perimeter in 2D; 2 in 1D).
  virtual double boundary_measure() const = 0;
  /// Where the closed box [lower, upper] lies: `inside` only when
  /// contains(x) is true at every point x of the box, `outside` only when
  /// it is false at every one (rounding included: a box within a relative
  /// kSideSlack of the boundary is `unknown`), `unknown` otherwise. It lets
  /// the seeding count the particles of whole blocks of cells without
  /// generating them. This one knows only the bounds (outside them, or
  /// unknown); the shapes with a closed form say more.
  enum class Side { inside, outside, unknown };
  virtual Side side(const Vec<D>& lower, const Vec<D>& upper) const;
};

/// The margin of Shape::side relative to the size of the coordinates: far
/// above the rounding of contains(), far below a seeding cell.
inline constexpr double kSideSlack = 1e-9;

/// The largest coordinate of the boxes [a, b] and [c, d] (the scale of Shape::side's margin).
template <int D> double largest_coordinate(const Vec<D>& a, const Vec<D>& b, const Vec<D>& c, const Vec<D>& d) {
  return std::max({a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff(), c.cwiseAbs().maxCoeff(), d.cwiseAbs().maxCoeff()});
}

extern template class Shape<1>;
extern template class Shape<2>;
extern template class Shape<3>;

/// The box [lower, upper]. InputError unless lower < upper, finite.
template <int D> std::unique_ptr<Shape<D>> make_box(const Vec<D>& lower, const Vec<D>& upper);
/// The ball |x - center| <= radius. InputError unless radius > 0, finite.
template <int D> std::unique_ptr<Shape<D>> make_sphere(const Vec<D>& center, double radius);
/// The cylinder with one end centred at `base`, unit-free `axis` (normalised
/// here), `radius` and `length` (3D). InputError for a zero axis or a
/// radius or length that is not finite and > 0.
std::unique_ptr<Shape<3>> make_cylinder(const Vec<3>& base, const Vec<3>& axis, double radius, double length);
/// The simple polygon with these vertices (2D, either orientation, not
/// closed: the last vertex joins the first). InputError for fewer than 3
/// vertices, a non-finite vertex, self-intersecting edges or zero area.
std::unique_ptr<Shape<2>> make_polygon(const std::vector<Vec<2>>& vertices);

/// The union of the cubes of side V_p^(1/D) centred at a set of particles
/// (a body read from a file).
template <int D> class ParticleCells final : public Shape<D> {
public:
  /// InputError for no particles, a position that is not finite or a
  /// volume that is not finite and > 0 (naming the particle).
  ParticleCells(const AlignedVector<Vec<D>>& x, const std::vector<double>& volume);
  bool contains(const Vec<D>& x) const override;
  void bounds(Vec<D>& lower, Vec<D>& upper) const override;
  double measure() const override { return total_; }
  double boundary_measure() const override { return 0.0; }

  /// Which particles' cubes [lower, upper] a shape holds (empty: all).
  using Filter = std::function<bool(const Vec<D>& lower, const Vec<D>& upper)>;

  /// Builds the shape one particle at a time (a particle file read in
  /// blocks), holding only the particles whose cube [lower, upper] `keep`
  /// accepts (all without it). Its bounds and measure are those of all the
  /// particles, and contains(x) answers as the shape of all of them
  /// wherever only accepted cubes can hold x (where the caller asks).
  class Builder {
  public:
    explicit Builder(Filter keep = {});
    /// Adds the next particle; InputError as the constructor's.
    void add(const Vec<D>& x, double volume);
    /// The shape of the particles added (once); InputError when there are none.
    std::unique_ptr<ParticleCells<D>> finish();

  private:
    Filter keep_;
    std::unique_ptr<ParticleCells<D>> cells_;
  };

  /// The particles held (all but those a Builder's filter left out).
  std::size_t held() const { return cubes_.size(); }

private:
  ParticleCells() = default;
  /// Checks the next particle and adds it to the bounds and measure, and
  /// to the held particles unless `keep` refuses its cube.
  void add(const Vec<D>& x, double volume, const Filter& keep);
  /// Sorts the held particles into their buckets (after the last add):
  /// cubes of side bucket_ - the largest particle's cube, or more where the
  /// particles' extent would need more than kMaxBuckets of them per axis
  /// (tiny volumes far apart), so that a bucket's key never overflows.
  void index();
  /// The key of the bucket of x: its coordinates floor((x - lower) / bucket_)
  /// clamped to [-1, kMaxBuckets + 1] (outside: no cube), base kKeyBase digits.
  long long key(const Vec<D>& x) const;
  static constexpr double kMaxBuckets = 1 << 20;
  static constexpr long long kKeyBase = 2000003; ///< > kMaxBuckets + 3: keys of distinct buckets differ
  /// A held particle's cube: its bucket's key, centre and half side.
  struct Cube {
    long long key;
    Vec<D> x;
    double half;
  };
  AlignedVector<Cube> cubes_; ///< sorted by key after index() (32 bytes each in 2D, 40 in 3D)
  Vec<D> lower_, upper_;
  double cell_ = 1.0, total_ = 0.0;
  double bucket_ = 1.0; ///< side of a bucket (index())
  std::size_t count_ = 0; ///< the particles added
};

extern template class ParticleCells<1>;
extern template class ParticleCells<2>;
extern template class ParticleCells<3>;

} // namespace otmpm
