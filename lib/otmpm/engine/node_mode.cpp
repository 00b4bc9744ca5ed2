/// \file node_mode.cpp
/// The node modes (node_mode.hpp).
#include "otmpm/engine/node_mode.hpp"

namespace otmpm {

template <int D> NodeMode<D> NodeMode<D>::fixed_grid(const Vec<D>& lower, const Vec<D>& upper) {
  NodeMode m;
  m.grid_ = {lower, upper};
  return m;
}

template <int D> NodeMode<D> NodeMode<D>::advected() {
  NodeMode m;
  m.advected_ = true;
  return m;
}

template <int D> void NodeMode<D>::advect(Basis<D>& basis, const AlignedVector<Vec<D>>& dx) const {
  if (!advected_) return;
  basis.nodes().advect(dx);
  basis.nodes_moved(dx);
}

template <int D>
double NodeMode<D>::cfl_spacing(const Basis<D>& basis, double h0, double spacing0, double gradient_ratio) const {
  if (!advected_) return h0;
  if (basis.search_radius() > 0.0) return h0 * gradient_ratio;
  return h0 * (basis.nodes().min_spacing() / spacing0);
}

template <int D> std::string NodeMode<D>::leaving(const Vec<D>& x, const Vec<D>& v) const {
  const std::string grid = "grid [" + format_point<D>(grid_.lo) + ", " + format_point<D>(grid_.hi) + "]";
  if (!grid_.contains(x)) return "left the " + grid + " (enlarge the grid or shorten t_end)";
  // Warned one step ahead: at the last step's size and the particle's
  // velocity, the next step would carry it out of the grid.
  return "moving at " + format_point<D>(v) + ", it would leave the grid in the next step (" + grid +
         "; enlarge the grid or shorten t_end)";
}

template class NodeMode<1>;
template class NodeMode<2>;
template class NodeMode<3>;

} // namespace otmpm
