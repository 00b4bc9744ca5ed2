/// \file node_set.cpp
/// Node sets (docs/theory.md sect. 3): Cartesian lattice arithmetic, the
/// perturbed lattice, clouds, and the neighbour search (index arithmetic on an
/// untouched lattice, a packed Boost.Geometry R-tree otherwise).
#include "otmpm/nodes/node_set.hpp"

#include <boost/geometry.hpp>
#include <boost/geometry/index/rtree.hpp>
#include <boost/iterator/function_output_iterator.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <utility>

namespace otmpm {

namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;

// ---------------------------------------------------------------------------
// CartesianGrid
// ---------------------------------------------------------------------------

namespace {
/// "[4, 5, 6]" for messages.
template <int D> std::string format_cells(const Index<D>& cells) {
  std::string s = "[";
  for (int k = 0; k < D; ++k) s += (k ? ", " : "") + std::to_string(cells[k]);
  return s + "]";
}
} // namespace

template <int D> Vec<D> CartesianGrid<D>::h() const {
  Vec<D> s;
  for (int k = 0; k < D; ++k) s[k] = (upper[k] - lower[k]) / cells[k];
  return s;
}

template <int D> Index<D> CartesianGrid<D>::nodes_per_axis() const {
  Index<D> n;
  for (int k = 0; k < D; ++k) n[k] = cells[k] + 1;
  return n;
}

template <int D> int CartesianGrid<D>::num_nodes() const {
  int n = 1;
  for (int k = 0; k < D; ++k) n *= cells[k] + 1;
  return n;
}

template <int D> int CartesianGrid<D>::num_cells() const {
  int n = 1;
  for (int k = 0; k < D; ++k) n *= cells[k];
  return n;
}

template <int D> Index<D> CartesianGrid<D>::node_index(int id) const {
  Index<D> ijk;
  for (int k = 0; k < D; ++k) {
    ijk[k] = id % (cells[k] + 1);
    id /= cells[k] + 1;
  }
  return ijk;
}

template <int D> Vec<D> CartesianGrid<D>::node_position(const Index<D>& ijk) const {
  Vec<D> x;
  for (int k = 0; k < D; ++k) {
    // The last node is exactly `upper`, so the lattice spans the box exactly.
    x[k] = ijk[k] == cells[k] ? upper[k]
                              : lower[k] + ijk[k] * ((upper[k] - lower[k]) / cells[k]);
  }
  return x;
}

template <int D> Index<D> CartesianGrid<D>::cell_of(const Vec<D>& x) const {
  Index<D> c;
  for (int k = 0; k < D; ++k) c[k] = cell_index(k, x[k]);
  return c;
}

template <int D> int CartesianGrid<D>::cell_index(int k, double xk) const {
  const double s = (xk - lower[k]) / (upper[k] - lower[k]) * cells[k];
  const double f = std::floor(s);
  // Clamp in floating point first: x may be far away (or NaN).
  const double clamped = std::isnan(f) ? 0.0 : std::clamp(f, 0.0, double(cells[k] - 1));
  return static_cast<int>(clamped);
}

template <int D> bool CartesianGrid<D>::contains(const Vec<D>& x) const {
  for (int k = 0; k < D; ++k)
    if (!(x[k] >= lower[k] && x[k] <= upper[k])) return false;
  return true;
}

template <int D> void CartesianGrid<D>::validate() const {
  long long nodes = 1;
  for (int k = 0; k < D; ++k) {
    require(std::isfinite(lower[k]) && std::isfinite(upper[k]) && lower[k] < upper[k], "grid: axis ", k,
            " needs finite lower < upper, got lower = ", lower, ", upper = ", upper);
    require(cells[k] >= 1, "grid: cells[", k, "] must be >= 1, got ", cells[k]);
    require(std::isfinite((upper[k] - lower[k]) / cells[k]), "grid: axis ", k, " spacing (upper - lower) / cells = ",
            (upper[k] - lower[k]) / cells[k], " is not finite");
    nodes *= cells[k] + 1LL;
    require(nodes <= std::numeric_limits<int>::max(), "grid: cells = ", format_cells<D>(cells),
            " gives more nodes than an int can count (", std::numeric_limits<int>::max(), ")");
  }
}

// ---------------------------------------------------------------------------
// Neighbour search index (R-tree over the current positions)
// ---------------------------------------------------------------------------

template <int D> struct NodeSet<D>::SearchIndex {
  using Point = bg::model::point<double, D, bg::cs::cartesian>;
  using Box = bg::model::box<Point>;
  using Value = std::pair<Point, int>;
  /// Node capacity of an R-tree leaf; packing (STR) fills the leaves, so the
  /// split algorithm only matters for later insertions, which we never do.
  static constexpr std::size_t kMaxElements = 16;
  using Tree = bgi::rtree<Value, bgi::quadratic<kMaxElements>>;

  Tree tree;

  static Point to_point(const Vec<D>& x) {
    Point p;
    set_coords(p, x, std::make_integer_sequence<int, D>{});
    return p;
  }
  template <int... K> static void set_coords(Point& p, const Vec<D>& x, std::integer_sequence<int, K...>) {
    (bg::set<K>(p, x[K]), ...);
  }

  /// The tree of the nodes x without those `absent` marks (empty: all).
  SearchIndex(const AlignedVector<Vec<D>>& x, const std::vector<char>& absent) : tree(make_values(x, absent)) {}

  static std::vector<Value> make_values(const AlignedVector<Vec<D>>& x, const std::vector<char>& absent) {
    std::vector<Value> v;
    v.reserve(x.size());
    for (std::size_t i = 0; i < x.size(); ++i)
      if (absent.empty() || !absent[i]) v.emplace_back(to_point(x[i]), static_cast<int>(i));
    return v;
  }
};

// ---------------------------------------------------------------------------
// NodeSet: factories and special members
// ---------------------------------------------------------------------------

namespace {

template <int D> AlignedVector<Vec<D>> lattice_positions(const CartesianGrid<D>& grid) {
  AlignedVector<Vec<D>> x(static_cast<std::size_t>(grid.num_nodes()));
  for (int id = 0; id < grid.num_nodes(); ++id) x[id] = grid.node_position(grid.node_index(id));
  return x;
}

template <int D> bool on_boundary(const CartesianGrid<D>& grid, const Index<D>& ijk) {
  for (int k = 0; k < D; ++k)
    if (ijk[k] == 0 || ijk[k] == grid.cells[k]) return true;
  return false;
}

/// Uniform in [-1, 1] from the raw 32-bit mt19937 stream (whose output the
/// standard fixes), so a seed gives the same layout with any standard library.
double symmetric_unit(std::mt19937& rng) {
  constexpr double kTwoPow32 = 4294967296.0;
  return 2.0 * (static_cast<double>(rng()) / kTwoPow32) - 1.0;
}

} // namespace

template <int D> NodeSet<D> NodeSet<D>::cartesian(const CartesianGrid<D>& grid) {
  grid.validate();
  NodeSet s;
  s.x_ = lattice_positions<D>(grid);
  s.x0_ = s.x_;
  s.grid_ = grid;
  s.layout_ = NodeLayout::cartesian;
  s.on_lattice_ = true;
  s.spacing_ = grid.h().minCoeff();
  return s;
}

template <int D>
NodeSet<D> NodeSet<D>::perturbed(const CartesianGrid<D>& grid, double fraction, unsigned seed) {
  // Beyond half a cell two neighbouring nodes could swap and invert an element.
  constexpr double kMaxFraction = 0.5;
  require(fraction >= 0.0 && fraction < kMaxFraction, "NodeSet::perturbed: fraction must be in [0, 0.5), got ",
          fraction);
  NodeSet s = cartesian(grid);
  std::mt19937 rng(seed);
  const Vec<D> h = grid.h();
  for (int id = 0; id < s.size(); ++id) {
    Vec<D> d;
    for (int k = 0; k < D; ++k) d[k] = fraction * h[k] * symmetric_unit(rng);
    if (!on_boundary<D>(grid, grid.node_index(id))) s.x_[id] += d;
  }
  s.x0_ = s.x_;
  s.layout_ = NodeLayout::perturbed;
  s.on_lattice_ = false;
  return s;
}

template <int D>
AlignedVector<Vec<D>> NodeSet<D>::perturbed_positions(const CartesianGrid<D>& grid, double fraction, unsigned seed,
                                                      const Index<D>& lo, const Index<D>& hi) {
  // The same stream and arithmetic as perturbed(): D draws per node id.
  constexpr double kMaxFraction = 0.5;
  require(fraction >= 0.0 && fraction < kMaxFraction, "NodeSet::perturbed: fraction must be in [0, 0.5), got ",
          fraction);
  grid.validate();
  Index<D> last;
  long long count = 1;
  for (int k = 0; k < D; ++k) {
    require<std::invalid_argument>(0 <= lo[k] && lo[k] < hi[k] && hi[k] <= grid.cells[k] + 1,
                                   "NodeSet::perturbed_positions: box [", lo[k], ", ", hi[k], ") of axis ", k,
                                   " outside [0, ", grid.cells[k] + 1, ")");
    last[k] = hi[k] - 1;
    count *= hi[k] - lo[k];
  }
  AlignedVector<Vec<D>> x(static_cast<std::size_t>(count));
  std::mt19937 rng(seed);
  const Vec<D> h = grid.h();
  const int end = grid.node_id(last) + 1;
  for (int id = 0; id < end; ++id) {
    Vec<D> d;
    for (int k = 0; k < D; ++k) d[k] = fraction * h[k] * symmetric_unit(rng);
    const Index<D> ijk = grid.node_index(id);
    long long local = 0;
    bool inside = true;
    for (int k = D - 1; k >= 0; --k) {
      inside = inside && ijk[k] >= lo[k] && ijk[k] < hi[k];
      local = local * (hi[k] - lo[k]) + (ijk[k] - lo[k]);
    }
    if (!inside) continue;
    Vec<D>& p = x[static_cast<std::size_t>(local)];
    p = grid.node_position(ijk);
    if (!on_boundary<D>(grid, ijk)) p += d;
  }
  return x;
}

template <int D> NodeSet<D> NodeSet<D>::cartesian(const CartesianGrid<D>& grid, double spacing) {
  require(finite_positive(spacing), "NodeSet::cartesian: spacing must be finite and > 0, got ", spacing);
  NodeSet s = cartesian(grid);
  s.spacing_ = spacing;
  return s;
}

template <int D> NodeSet<D> NodeSet<D>::cloud(AlignedVector<Vec<D>> positions, double spacing) {
  require(!positions.empty(), "NodeSet::cloud: positions is empty (no nodes)");
  require(positions.size() <= static_cast<std::size_t>(std::numeric_limits<int>::max()), "NodeSet::cloud: ",
          positions.size(), " positions, more than an int can count");
  require(finite_positive(spacing), "NodeSet::cloud: spacing must be finite and > 0, got ", spacing);
  for (std::size_t i = 0; i < positions.size(); ++i)
    require(positions[i].allFinite(), "NodeSet::cloud: positions[", i, "] = ", positions[i], " is not finite");
  NodeSet s;
  s.x_ = std::move(positions);
  s.x0_ = s.x_;
  s.layout_ = NodeLayout::cloud;
  s.on_lattice_ = false;
  s.spacing_ = spacing;
  return s;
}

template <int D> NodeSet<D>::NodeSet() = default;
template <int D> NodeSet<D>::~NodeSet() = default;
template <int D> NodeSet<D>::NodeSet(NodeSet&&) noexcept = default;
template <int D> NodeSet<D>& NodeSet<D>::operator=(NodeSet&&) noexcept = default;

// A copy rebuilds its own index lazily (the R-tree is a cache, not state).
template <int D>
NodeSet<D>::NodeSet(const NodeSet& o)
    : x_(o.x_), x0_(o.x0_), grid_(o.grid_), layout_(o.layout_), on_lattice_(o.on_lattice_),
      spacing_(o.spacing_), absent_(o.absent_), index_(nullptr), index_stale_(true) {}

template <int D> NodeSet<D>& NodeSet<D>::operator=(const NodeSet& o) {
  if (this != &o) {
    NodeSet tmp(o);
    *this = std::move(tmp);
  }
  return *this;
}

// ---------------------------------------------------------------------------
// Motion
// ---------------------------------------------------------------------------

template <int D> void NodeSet<D>::set_positions(AlignedVector<Vec<D>> x) {
  require<std::invalid_argument>(x.size() == x_.size(), "NodeSet::set_positions: x has ", x.size(),
                                 " positions for ", x_.size(), " nodes");
  for (std::size_t i = 0; i < x.size(); ++i)
    require<InstabilityError>(x[i].allFinite(), "NodeSet::set_positions: x[", i, "] = ", x[i], " is not finite");
  x_ = std::move(x);
  on_lattice_ = false;
  index_stale_ = true;
}

template <int D> void NodeSet<D>::remove(const std::vector<char>& absent) {
  require<std::invalid_argument>(absent.size() == x_.size(), "NodeSet::remove: ", absent.size(), " marks for ",
                                 x_.size(), " nodes");
  const auto gone = std::count(absent.begin(), absent.end(), char(1));
  require<std::invalid_argument>(gone < static_cast<long>(x_.size()), "NodeSet::remove: every node would be absent");
  if (gone == 0) return absent_.clear();
  absent_ = absent;
  index_stale_ = true;
}

template <int D> int NodeSet<D>::present_count() const {
  return size() - static_cast<int>(std::count(absent_.begin(), absent_.end(), char(1)));
}

template <int D> void NodeSet<D>::advect(const AlignedVector<Vec<D>>& dx) {
  require<std::invalid_argument>(dx.size() == x_.size(), "NodeSet::advect: dx has ", dx.size(),
                                 " increments for ", x_.size(), " nodes");
  for (std::size_t i = 0; i < dx.size(); ++i)
    require<InstabilityError>(dx[i].allFinite(), "NodeSet::advect: increment dx[", i, "] = ", dx[i],
                              " of the node at ", x_[i], " is not finite");
  for (std::size_t i = 0; i < x_.size(); ++i) x_[i] += dx[i];
  on_lattice_ = false;
  index_stale_ = true;
}

// ---------------------------------------------------------------------------
// Neighbour search
// ---------------------------------------------------------------------------

template <int D> void NodeSet<D>::prepare_search() const {
  if (lattice_search()) return; // index arithmetic, nothing to build
  if (index_ && !index_stale_) return;
  index_ = std::make_unique<SearchIndex>(x_, absent_);
  index_stale_ = false;
}

namespace {

/// Lattice index range [lo, hi] of the nodes that may lie within `reach` of
/// coordinate u along axis k, widened by one node on each side so that
/// rounding cannot lose one (the exact distance test decides). False when
/// the range misses the grid.
template <int D>
[[gnu::always_inline]] inline bool lattice_span(const CartesianGrid<D>& g, int k, double u, double reach,
                                                double inv_h, int& lo, int& hi) {
  const double a = (u - reach - g.lower[k]) * inv_h; // lattice coordinates of the span's ends
  const double b = (u + reach - g.lower[k]) * inv_h;
  if (!(a <= g.cells[k] + 1.0 && b >= -1.0)) return false; // misses the grid (or NaN)
  // Clamped to [-1, cells + 1] (any reach: no int overflow), a + 2 > 0 and
  // b + 2 > 0, so truncation of the shifted values is floor without a libm
  // call; -1 / +1 widen the span by up to one node on each side.
  const double ac = std::max(a, -1.0) + 2.0, bc = std::min(b, g.cells[k] + 1.0) + 2.0;
  lo = std::max(0, static_cast<int>(ac) - 2 - 1);
  hi = std::min(g.cells[k], static_cast<int>(bc) - 2 + 1);
  return lo <= hi;
}

/// The nodes of an untouched lattice within `radius` of x (exact test on the
/// stored positions), in ascending id. The outer axes run over their spans;
/// axis 0 (fastest) only over the span left by the distance already used on
/// the others, so the candidates are the rows of the ball, not its box.
template <int D>
void lattice_within(const CartesianGrid<D>& g, const AlignedVector<Vec<D>>& pos, const Vec<D>& x, double radius,
                    std::vector<int>& out) {
  constexpr double row_slack = 1e-9; // cells: covers rounding of the row coordinate
  const Vec<D> h = g.h();
  const Vec<D> inv_h = h.cwiseInverse();
  const double r2 = radius * radius;
  Index<D> lo{}, hi{};
  for (int k = 1; k < D; ++k)
    if (!lattice_span(g, k, x[k], radius, inv_h[k], lo[k], hi[k])) return;
  Index<D> ijk = lo;
  for (;;) {
    double rest = r2; // r^2 minus the squared offsets along axes 1..D-1
    int row = 0;
    for (int k = D - 1; k >= 1; --k) {
      const double d = std::max(0.0, std::abs(g.lower[k] + ijk[k] * h[k] - x[k]) - row_slack * h[k]);
      rest -= d * d;
      row = row * (g.cells[k] + 1) + ijk[k];
    }
    int a, b;
    if (rest >= 0.0 && lattice_span(g, 0, x[0], std::sqrt(rest), inv_h[0], a, b))
      for (int i = a, id = row * (g.cells[0] + 1) + a; i <= b; ++i, ++id)
        if ((pos[id] - x).squaredNorm() <= r2) out.push_back(id);
    int k = 1;
    for (; k < D; ++k) {
      if (++ijk[k] <= hi[k]) break;
      ijk[k] = lo[k];
    }
    if (k >= D) break;
  }
}

} // namespace

template <int D> void NodeSet<D>::within(const Vec<D>& x, double radius, std::vector<int>& out) const {
  require<std::invalid_argument>(radius >= 0.0 && std::isfinite(radius),
                                 "NodeSet::within: radius must be finite and >= 0, got ", radius);
  const std::size_t first = out.size();
  const double r2 = radius * radius;
  if (lattice_search()) {
    lattice_within(*grid_, x_, x, radius, out);
    return; // lattice order is already ascending in id
  }
  prepare_search();
  using SI = SearchIndex;
  typename SI::Box box(SI::to_point(x - Vec<D>::Constant(radius)), SI::to_point(x + Vec<D>::Constant(radius)));
  index_->tree.query(bgi::intersects(box), boost::make_function_output_iterator([&](const typename SI::Value& v) {
                       if ((x_[v.second] - x).squaredNorm() <= r2) out.push_back(v.second);
                     }));
  // Ascending ids: the same order as the lattice search and independent of
  // how the tree happened to be packed.
  std::sort(out.begin() + static_cast<std::ptrdiff_t>(first), out.end());
}

template <int D> double NodeSet<D>::min_spacing() const {
  double m = std::numeric_limits<double>::infinity();
  if (grid_) {
    const CartesianGrid<D>& g = *grid_;
    for (int id = 0; id < size(); ++id) {
      const Index<D> ijk = g.node_index(id);
      if (!present(id)) continue;
      for (int k = 0; k < D; ++k) {
        if (ijk[k] == g.cells[k]) continue;
        Index<D> nb = ijk;
        ++nb[k];
        if (present(g.node_id(nb))) m = std::min(m, (x_[g.node_id(nb)] - x_[id]).norm());
      }
    }
    return m;
  }
  prepare_search();
  using SI = SearchIndex;
  constexpr unsigned kSelfAndNearest = 2;
  for (int id = 0; id < size(); ++id) {
    if (!present(id)) continue;
    index_->tree.query(bgi::nearest(SI::to_point(x_[id]), kSelfAndNearest),
                       boost::make_function_output_iterator([&](const typename SI::Value& v) {
                         if (v.second != id) m = std::min(m, (x_[v.second] - x_[id]).norm());
                       }));
  }
  return m;
}

template struct CartesianGrid<1>;
template struct CartesianGrid<2>;
template struct CartesianGrid<3>;
template class NodeSet<1>;
template class NodeSet<2>;
template class NodeSet<3>;

} // namespace otmpm
