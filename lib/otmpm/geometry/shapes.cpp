/// \file shapes.cpp
/// The shapes of shapes.hpp. The polygon uses Boost.Geometry (validity,
/// area, perimeter, point in polygon).
#include "otmpm/geometry/shapes.hpp"

#include <boost/geometry.hpp>
#include <boost/geometry/geometries/point_xy.hpp>
#include <boost/geometry/geometries/polygon.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

namespace otmpm {

namespace {

namespace bg = boost::geometry;

/// Measure of the unit ball and of the unit sphere in D dimensions.
constexpr double unit_ball(int D) { return D == 1 ? 2.0 : D == 2 ? std::numbers::pi : 4.0 / 3.0 * std::numbers::pi; }
constexpr double unit_sphere(int D) { return D == 1 ? 2.0 : D == 2 ? 2.0 * std::numbers::pi : 4.0 * std::numbers::pi; }

/// Calls f(corner) for the 2^D corners of the box [lo, hi].
template <int D, class F> void for_each_corner(const Vec<D>& lo, const Vec<D>& hi, F&& f) {
  for (int m = 0; m < (1 << D); ++m) {
    Vec<D> x;
    for (int k = 0; k < D; ++k) x[k] = (m >> k) & 1 ? hi[k] : lo[k];
    f(static_cast<const Vec<D>&>(x));
  }
}

template <int D> class BoxShape final : public Shape<D> {
public:
  BoxShape(const Vec<D>& lower, const Vec<D>& upper) : lower_(lower), upper_(upper) {
    for (int k = 0; k < D; ++k)
      require(std::isfinite(lower[k]) && std::isfinite(upper[k]) && lower[k] < upper[k], "box: axis ", k,
              ": lower ", lower[k], " must be below upper ", upper[k], " (both finite)");
  }
  bool contains(const Vec<D>& x) const override {
    for (int k = 0; k < D; ++k)
      if (!(x[k] >= lower_[k] && x[k] <= upper_[k])) return false;
    return true;
  }
  void bounds(Vec<D>& lower, Vec<D>& upper) const override {
    lower = lower_;
    upper = upper_;
  }
  double measure() const override { return (upper_ - lower_).prod(); }
  /// Exact: contains() compares coordinates, without rounding.
  typename Shape<D>::Side side(const Vec<D>& lo, const Vec<D>& hi) const override {
    bool inside = true;
    for (int k = 0; k < D; ++k) {
      if (hi[k] < lower_[k] || lo[k] > upper_[k]) return Shape<D>::Side::outside;
      inside = inside && lo[k] >= lower_[k] && hi[k] <= upper_[k];
    }
    return inside ? Shape<D>::Side::inside : Shape<D>::Side::unknown;
  }
  double boundary_measure() const override {
    if constexpr (D == 1) return 2.0;
    const Vec<D> e = upper_ - lower_;
    if constexpr (D == 2) return 2.0 * (e[0] + e[1]);
    else return 2.0 * (e[0] * e[1] + e[1] * e[2] + e[0] * e[2]);
  }

private:
  Vec<D> lower_, upper_;
};

template <int D> class SphereShape final : public Shape<D> {
public:
  SphereShape(const Vec<D>& center, double radius) : c_(center), r_(radius) {
    require(center.allFinite(), "sphere: center ", center, " is not finite");
    require(finite_positive(radius), "sphere: radius must be finite and > 0, got ", radius);
  }
  bool contains(const Vec<D>& x) const override { return (x - c_).squaredNorm() <= r_ * r_; }
  void bounds(Vec<D>& lower, Vec<D>& upper) const override {
    lower = c_.array() - r_;
    upper = c_.array() + r_;
  }
  double measure() const override { return unit_ball(D) * std::pow(r_, D); }
  double boundary_measure() const override { return unit_sphere(D) * std::pow(r_, D - 1); }
  /// The box's nearest and farthest points from the centre against the radius.
  typename Shape<D>::Side side(const Vec<D>& lo, const Vec<D>& hi) const override {
    const double e = kSideSlack * (r_ + largest_coordinate<D>(lo, hi, c_, c_));
    double near = 0.0, far = 0.0;
    for (int k = 0; k < D; ++k) {
      const double a = std::abs(lo[k] - c_[k]), b = std::abs(hi[k] - c_[k]);
      const double in = c_[k] < lo[k] || c_[k] > hi[k] ? std::min(a, b) : 0.0;
      near += in * in, far += std::max(a, b) * std::max(a, b);
    }
    if (std::sqrt(far) < r_ - e) return Shape<D>::Side::inside;
    if (std::sqrt(near) > r_ + e) return Shape<D>::Side::outside;
    return Shape<D>::Side::unknown;
  }

private:
  Vec<D> c_;
  double r_;
};

class CylinderShape final : public Shape<3> {
public:
  CylinderShape(const Vec<3>& base, const Vec<3>& axis, double radius, double length)
      : base_(base), radius_(radius), length_(length) {
    require(base.allFinite(), "cylinder: center ", base, " is not finite");
    require(is_direction<3>(axis), "cylinder: axis ", axis, " must be a finite, non-zero vector");
    require(finite_positive(radius), "cylinder: radius must be finite and > 0, got ", radius);
    require(finite_positive(length), "cylinder: length must be finite and > 0, got ", length);
    axis_ = axis.stableNormalized();
  }
  bool contains(const Vec<3>& x) const override {
    const Vec<3> d = x - base_;
    const double s = d.dot(axis_);
    return s >= 0.0 && s <= length_ && (d - s * axis_).squaredNorm() <= radius_ * radius_;
  }
  void bounds(Vec<3>& lower, Vec<3>& upper) const override {
    // Each end disk extends radius * sqrt(1 - a_k^2) along axis k.
    const Vec<3> top = base_ + length_ * axis_;
    for (int k = 0; k < 3; ++k) {
      const double e = radius_ * std::sqrt(std::max(0.0, 1.0 - axis_[k] * axis_[k]));
      lower[k] = std::min(base_[k], top[k]) - e;
      upper[k] = std::max(base_[k], top[k]) + e;
    }
  }
  double measure() const override { return std::numbers::pi * radius_ * radius_ * length_; }
  double boundary_measure() const override {
    return 2.0 * std::numbers::pi * radius_ * (radius_ + length_);
  }
  /// Inside: every corner inside by the margin (the cylinder is convex).
  /// Outside: every corner beyond one end, or the box's bounding ball
  /// clear of the axis' line.
  Side side(const Vec<3>& lo, const Vec<3>& hi) const override {
    const double e = kSideSlack * (radius_ + length_ + largest_coordinate<3>(lo, hi, base_, base_));
    bool inside = true, below = true, beyond = true;
    for_each_corner<3>(lo, hi, [&](const Vec<3>& x) {
      const Vec<3> d = x - base_;
      const double s = d.dot(axis_);
      inside = inside && s > e && s < length_ - e && (d - s * axis_).norm() < radius_ - e;
      below = below && s < -e, beyond = beyond && s > length_ + e;
    });
    if (inside) return Side::inside;
    const Vec<3> d = 0.5 * (lo + hi) - base_;
    if (below || beyond || (d - d.dot(axis_) * axis_).norm() > radius_ + 0.5 * (hi - lo).norm() + e) return Side::outside;
    return Side::unknown;
  }

private:
  Vec<3> base_, axis_;
  double radius_, length_;
};

class PolygonShape final : public Shape<2> {
public:
  using Point = bg::model::d2::point_xy<double>;
  using Polygon = bg::model::polygon<Point>;

  explicit PolygonShape(const std::vector<Vec<2>>& vertices) {
    require(vertices.size() >= 3, "polygon: needs at least 3 vertices, got ", vertices.size());
    for (std::size_t i = 0; i < vertices.size(); ++i) {
      require(vertices[i].allFinite(), "polygon: vertex ", i, " ", vertices[i], " is not finite");
      bg::append(poly_.outer(), Point(vertices[i][0], vertices[i][1]));
    }
    bg::append(poly_.outer(), Point(vertices[0][0], vertices[0][1]));
    bg::correct(poly_); // orientation and closure as Boost.Geometry expects
    std::string why;
    require(bg::is_valid(poly_, why), "polygon: the vertices do not make a simple polygon (", why, ")");
    require(bg::area(poly_) > 0.0, "polygon: the area is zero");
    bg::envelope(poly_, box_);
  }
  bool contains(const Vec<2>& x) const override { return bg::covered_by(Point(x[0], x[1]), poly_); }
  void bounds(Vec<2>& lower, Vec<2>& upper) const override {
    lower = Vec<2>(box_.min_corner().x(), box_.min_corner().y());
    upper = Vec<2>(box_.max_corner().x(), box_.max_corner().y());
  }
  double measure() const override { return bg::area(poly_); }
  double boundary_measure() const override { return bg::perimeter(poly_); }
  /// The box widened by the margin, within the polygon or apart from it.
  Side side(const Vec<2>& lo, const Vec<2>& hi) const override {
    const Vec<2> a(box_.min_corner().x(), box_.min_corner().y()), b(box_.max_corner().x(), box_.max_corner().y());
    const double e = kSideSlack * largest_coordinate<2>(lo, hi, a, b);
    const bg::model::box<Point> wide(Point(lo[0] - e, lo[1] - e), Point(hi[0] + e, hi[1] + e));
    Polygon square;
    bg::convert(wide, square);
    if (bg::within(square, poly_)) return Side::inside;
    if (bg::disjoint(wide, poly_)) return Side::outside;
    return Side::unknown;
  }

private:
  Polygon poly_;
  bg::model::box<Point> box_;
};

} // namespace

template <int D> typename Shape<D>::Side Shape<D>::side(const Vec<D>& lo, const Vec<D>& hi) const {
  Vec<D> a, b;
  bounds(a, b);
  const double e = kSideSlack * largest_coordinate<D>(lo, hi, a, b);
  for (int k = 0; k < D; ++k)
    if (hi[k] < a[k] - e || lo[k] > b[k] + e) return Side::outside;
  return Side::unknown;
}

template class Shape<1>;
template class Shape<2>;
template class Shape<3>;

template <int D> std::unique_ptr<Shape<D>> make_box(const Vec<D>& lower, const Vec<D>& upper) {
  return std::make_unique<BoxShape<D>>(lower, upper);
}

template <int D> std::unique_ptr<Shape<D>> make_sphere(const Vec<D>& center, double radius) {
  return std::make_unique<SphereShape<D>>(center, radius);
}

std::unique_ptr<Shape<3>> make_cylinder(const Vec<3>& base, const Vec<3>& axis, double radius, double length) {
  return std::make_unique<CylinderShape>(base, axis, radius, length);
}

std::unique_ptr<Shape<2>> make_polygon(const std::vector<Vec<2>>& vertices) {
  return std::make_unique<PolygonShape>(vertices);
}

template <int D>
ParticleCells<D>::ParticleCells(const AlignedVector<Vec<D>>& x, const std::vector<double>& volume) {
  require(!x.empty(), "particle file: no particles");
  require<std::invalid_argument>(volume.size() == x.size(), "ParticleCells: ", x.size(), " positions, ",
                                 volume.size(), " volumes");
  cubes_.reserve(x.size());
  for (std::size_t p = 0; p < x.size(); ++p) add(x[p], volume[p], {});
  index();
}

template <int D> void ParticleCells<D>::add(const Vec<D>& x, double volume, const Filter& keep) {
  const std::size_t p = count_++;
  require(x.allFinite(), "particle file: particle ", p, ": position ", x, " is not finite");
  require(finite_positive(volume), "particle file: particle ", p, ": volume must be finite and > 0, got ", volume);
  const double half = 0.5 * std::pow(volume, 1.0 / D);
  if (p == 0) lower_ = upper_ = x;
  cell_ = p == 0 ? 2 * half : std::max(cell_, 2 * half);
  lower_ = lower_.cwiseMin(Vec<D>(x.array() - half));
  upper_ = upper_.cwiseMax(Vec<D>(x.array() + half));
  total_ += volume;
  if (keep && !keep(Vec<D>(x.array() - half), Vec<D>(x.array() + half))) return;
  cubes_.push_back({0, x, half});
}

template <int D> void ParticleCells<D>::index() {
  bucket_ = cell_;
  for (int d = 0; d < D; ++d) bucket_ = std::max(bucket_, (upper_[d] - lower_[d]) / kMaxBuckets);
  for (Cube& c : cubes_) c.key = key(c.x);
  std::sort(cubes_.begin(), cubes_.end(), [](const Cube& a, const Cube& b) { return a.key < b.key; });
}

template <int D>
ParticleCells<D>::Builder::Builder(Filter keep) : keep_(std::move(keep)), cells_(new ParticleCells<D>()) {}

template <int D> void ParticleCells<D>::Builder::add(const Vec<D>& x, double volume) {
  cells_->add(x, volume, keep_);
}

template <int D> std::unique_ptr<ParticleCells<D>> ParticleCells<D>::Builder::finish() {
  require(cells_->count_ > 0, "particle file: no particles");
  cells_->index();
  return std::move(cells_);
}

template <int D> long long ParticleCells<D>::key(const Vec<D>& x) const {
  long long k = 0;
  for (int d = 0; d < D; ++d) {
    const double c = std::floor((x[d] - lower_[d]) / bucket_);
    k = k * kKeyBase + (c >= -1.0 ? static_cast<long long>(std::min(c, kMaxBuckets + 1)) : -1LL); // NaN: -1
  }
  return k;
}

template <int D> bool ParticleCells<D>::contains(const Vec<D>& x) const {
  // Far from every cube (a cell beyond their bounds): no bucket to look in,
  // and no bucket index of a far point (an integer overflow) is formed.
  if (!((x.array() >= lower_.array() - bucket_).all() && (x.array() <= upper_.array() + bucket_).all())) return false;
  // A cube of half side <= cell / 2 <= bucket / 2 around a centre in bucket
  // c reaches at most the neighbouring buckets: look in the 3^D buckets around x.
  Vec<D> probe;
  for (int n = 0; n < (D == 1 ? 3 : D == 2 ? 9 : 27); ++n) {
    for (int d = 0, m = n; d < D; ++d, m /= 3) probe[d] = x[d] + ((m % 3) - 1) * bucket_;
    const long long k = key(probe);
    auto it = std::lower_bound(cubes_.begin(), cubes_.end(), k, [](const Cube& c, long long v) { return c.key < v; });
    for (; it != cubes_.end() && it->key == k; ++it)
      if (((x - it->x).cwiseAbs().array() <= it->half).all()) return true;
  }
  return false;
}

template <int D> void ParticleCells<D>::bounds(Vec<D>& lower, Vec<D>& upper) const {
  lower = lower_;
  upper = upper_;
}

template class ParticleCells<1>;
template class ParticleCells<2>;
template class ParticleCells<3>;
template std::unique_ptr<Shape<1>> make_box<1>(const Vec<1>&, const Vec<1>&);
template std::unique_ptr<Shape<2>> make_box<2>(const Vec<2>&, const Vec<2>&);
template std::unique_ptr<Shape<3>> make_box<3>(const Vec<3>&, const Vec<3>&);
template std::unique_ptr<Shape<1>> make_sphere<1>(const Vec<1>&, double);
template std::unique_ptr<Shape<2>> make_sphere<2>(const Vec<2>&, double);
template std::unique_ptr<Shape<3>> make_sphere<3>(const Vec<3>&, double);

} // namespace otmpm
