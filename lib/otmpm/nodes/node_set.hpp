#pragma once
/// \file node_set.hpp
/// Node sets: the points x_I that carry the nodal unknowns (docs/theory.md
/// sect. 3). A Cartesian grid, a perturbed grid of the same topology, or an
/// arbitrary cloud. In `ul` mode the nodes are advected every step.
#include "otmpm/core.hpp"

#include <memory>
#include <optional>

namespace otmpm {

/// An axis-aligned Cartesian lattice: `cells[k]` cells of width `h[k]` from
/// `lower` to `upper` on each axis, `cells[k] + 1` nodes per axis. Node ids are
/// lexicographic with axis 0 fastest: id = i0 + n0 * (i1 + n1 * i2).
template <int D> struct CartesianGrid {
  Vec<D> lower = Vec<D>::Zero();
  Vec<D> upper = Vec<D>::Ones();
  Index<D> cells{};

  /// Grid spacing per axis, (upper - lower) / cells.
  Vec<D> h() const;
  /// Nodes per axis (cells + 1).
  Index<D> nodes_per_axis() const;
  int num_nodes() const;
  int num_cells() const;
  /// Flat id of the node with lattice index ijk (inline: called per entry).
  int node_id(const Index<D>& ijk) const {
    int id = 0;
    for (int k = D - 1; k >= 0; --k) id = id * (cells[k] + 1) + ijk[k];
    return id;
  }
  /// Lattice index of node id.
  Index<D> node_index(int id) const;
  /// Position of the lattice node ijk.
  Vec<D> node_position(const Index<D>& ijk) const;
  /// The cell that contains x (clamped to the grid), lattice index of its lower corner.
  Index<D> cell_of(const Vec<D>& x) const;
  /// Index k of cell_of(x) from x[k] alone (it does not depend on the
  /// other coordinates, and it never decreases as x[k] grows).
  int cell_index(int k, double xk) const;
  /// True when x lies in the closed box [lower, upper].
  bool contains(const Vec<D>& x) const;
  /// Throws InputError (naming the axis and the values) unless lower < upper
  /// are finite, cells >= 1 on every axis, the spacing is finite and the node
  /// count fits an int.
  void validate() const;
};

/// How a node set was laid out; decides which neighbour search applies and
/// which bases are allowed (uGIMP needs an untouched Cartesian layout).
enum class NodeLayout { cartesian, perturbed, cloud };

/// The nodes of a discretisation: current positions x_I, initial positions,
/// an optional structured topology (the lattice they came from), and a
/// neighbour search that is index arithmetic while the nodes sit on an
/// untouched Cartesian lattice and a Boost.Geometry R-tree otherwise (built
/// lazily; rebuilt after the nodes move).
template <int D> class NodeSet {
public:
  /// Nodes on the vertices of a Cartesian grid (grid.validate() first).
  static NodeSet cartesian(const CartesianGrid<D>& grid);
  /// The same topology with every interior node moved by a random vector whose
  /// components are uniform in [-fraction*h, fraction*h] (fixed seed). Boundary
  /// nodes keep their position, so the domain stays the same box. Throws
  /// InputError unless 0 <= fraction < 0.5 (and the grid is valid).
  static NodeSet perturbed(const CartesianGrid<D>& grid, double fraction, unsigned seed);
  /// The positions perturbed(grid, fraction, seed) gives the nodes with
  /// lattice index in [lo, hi) (axis 0 fastest), bit for bit, without
  /// storing the others: the random stream is drawn up to the box's last
  /// node (a rank's window of a distributed run). Same errors as perturbed().
  static AlignedVector<Vec<D>> perturbed_positions(const CartesianGrid<D>& grid, double fraction, unsigned seed,
                                                   const Index<D>& lo, const Index<D>& hi);
  /// cartesian(grid) with `spacing` as its characteristic spacing: a few
  /// cells of a larger lattice that stand for it (the basis probe of a
  /// distributed run's set-up, distributed/local_parts.cpp).
  static NodeSet cartesian(const CartesianGrid<D>& grid, double spacing);
  /// An arbitrary cloud; `spacing` is the characteristic nodal spacing h used
  /// by LME (beta = gamma_lme / h^2) and for the time step. Throws InputError
  /// for no positions, a non-finite position (naming its index) or a spacing
  /// that is not finite and > 0.
  static NodeSet cloud(AlignedVector<Vec<D>> positions, double spacing);

  NodeSet();
  NodeSet(const NodeSet&);
  NodeSet& operator=(const NodeSet&);
  NodeSet(NodeSet&&) noexcept;
  NodeSet& operator=(NodeSet&&) noexcept;
  ~NodeSet();

  int size() const { return static_cast<int>(x_.size()); }
  NodeLayout layout() const { return layout_; }
  /// The lattice the nodes came from (cartesian and perturbed layouts).
  const std::optional<CartesianGrid<D>>& grid() const { return grid_; }
  /// True while the nodes are exactly on their Cartesian lattice (never moved).
  bool on_lattice() const { return on_lattice_; }
  /// Characteristic initial spacing h (the smallest grid spacing, or the cloud's).
  double spacing() const { return spacing_; }
  /// Takes the nodes marked in `absent` (one mark per node) out of the set:
  /// they keep their ids and positions, but no neighbour search finds them
  /// and min_spacing() leaves them out (`ul` mode: a lattice whose cells the
  /// body does not fill, docs/theory.md sect. 3). All marks 0: every node is
  /// present. std::invalid_argument for another size or no node left.
  void remove(const std::vector<char>& absent);
  /// True unless node I was taken out by remove().
  bool present(int I) const { return absent_.empty() || !absent_[static_cast<std::size_t>(I)]; }
  /// True when remove() took nodes out.
  bool has_absent() const { return !absent_.empty(); }
  /// The nodes present.
  int present_count() const;

  const AlignedVector<Vec<D>>& positions() const { return x_; }
  const Vec<D>& position(int I) const { return x_[I]; }
  const AlignedVector<Vec<D>>& initial_positions() const { return x0_; }

  /// Replaces node positions (advection in `ul` mode). Marks the set as moved:
  /// the next neighbour query rebuilds the R-tree. Throws std::invalid_argument
  /// when x.size() != size(), InstabilityError for a non-finite position.
  void set_positions(AlignedVector<Vec<D>> x);
  /// Adds dx_I to every node (x_I += dx_I) and marks the set as moved. Throws
  /// std::invalid_argument when dx.size() != size(), InstabilityError (naming
  /// the node) for a non-finite increment; the set is unchanged then.
  void advect(const AlignedVector<Vec<D>>& dx);

  /// Appends to `out` the ids of all nodes with |x_I - x| <= radius (order
  /// unspecified but deterministic). Thread-safe once the index is built;
  /// call prepare_search() before querying from several threads. A
  /// non-finite x has no node within any radius; a radius that is negative or
  /// not finite throws std::invalid_argument.
  void within(const Vec<D>& x, double radius, std::vector<int>& out) const;
  /// Builds the R-tree now if the layout needs one and it is stale.
  void prepare_search() const;
  /// Smallest distance between two neighbouring nodes along a lattice edge
  /// (structured sets) or to the nearest neighbour (clouds); h_min of the CFL.
  double min_spacing() const;

private:
  struct SearchIndex;
  /// The search is index arithmetic on the lattice (untouched, every node present).
  bool lattice_search() const { return on_lattice_ && grid_ && absent_.empty(); }
  AlignedVector<Vec<D>> x_, x0_;
  std::optional<CartesianGrid<D>> grid_;
  NodeLayout layout_ = NodeLayout::cartesian;
  bool on_lattice_ = true;
  double spacing_ = 1.0;
  std::vector<char> absent_; ///< remove(): 1 for a node taken out (empty: none)
  mutable std::unique_ptr<SearchIndex> index_;
  mutable bool index_stale_ = true;
};

extern template struct CartesianGrid<1>;
extern template struct CartesianGrid<2>;
extern template struct CartesianGrid<3>;
extern template class NodeSet<1>;
extern template class NodeSet<2>;
extern template class NodeSet<3>;

} // namespace otmpm
