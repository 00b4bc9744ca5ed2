/// \file halo.cpp
/// The nodal exchange (halo.hpp).
#include "otmpm/distributed/halo.hpp"

#include <algorithm>

namespace otmpm::distributed {

namespace {

/// Local ids (in `window`) of the points of `box`, in lattice order.
template <int D> std::vector<int> local_ids(const Window<D>& window, const IndexBox<D>& box) {
  std::vector<int> ids;
  ids.reserve(static_cast<std::size_t>(std::max(0LL, box.count())));
  box.for_each([&](const Index<D>& i) { ids.push_back(window.local_id(i)); });
  return ids;
}

/// Doubles per point over all fields.
int point_width(std::span<const NodalArray> fields) {
  int w = 0;
  for (const NodalArray& f : fields) w += f.width;
  return w;
}

/// The values of the points `ids` (all fields, point by point) as bytes.
Bytes pack(std::span<const NodalArray> fields, const std::vector<int>& ids) {
  std::vector<double> v;
  v.reserve(ids.size() * static_cast<std::size_t>(point_width(fields)));
  for (int I : ids)
    for (const NodalArray& f : fields)
      for (int c = 0; c < f.width; ++c) v.push_back(f.data[static_cast<std::size_t>(I) * f.width + c]);
  Bytes out;
  put_bytes(out, v.data(), v.size() * sizeof(double));
  return out;
}

/// Adds (or, with `add` false, copies) received values into the points `ids`.
void unpack(std::span<const NodalArray> fields, const std::vector<int>& ids, const Bytes& in, bool add) {
  std::vector<double> v(ids.size() * static_cast<std::size_t>(point_width(fields)));
  Reader r(in);
  r.get_bytes(v.data(), v.size() * sizeof(double));
  std::size_t at = 0;
  for (int I : ids)
    for (const NodalArray& f : fields)
      for (int c = 0; c < f.width; ++c) {
        double& x = f.data[static_cast<std::size_t>(I) * f.width + c];
        x = add ? x + v[at] : v[at];
        ++at;
      }
}

} // namespace

template <int D>
NodeExchange<D>::NodeExchange(const PointLattice<D>& lattice, const Decomposition<D>& decomposition, int rank) {
  const IndexBox<D>& cells = decomposition.box(rank);
  window_.box = lattice.window(cells);
  const IndexBox<D> own = lattice.owned_points(cells);
  owned_.assign(static_cast<std::size_t>(window_.size()), 0);
  own.for_each([&](const Index<D>& i) { owned_[static_cast<std::size_t>(window_.local_id(i))] = 1; });
  for (int q = 0; q < decomposition.ranks(); ++q) {
    if (q == rank) continue;
    const IndexBox<D> theirs = lattice.owned_points(decomposition.box(q));
    const IndexBox<D> ghost = window_.box.intersect(theirs);
    const IndexBox<D> shared = own.intersect(lattice.window(decomposition.box(q)));
    if (ghost.empty() && shared.empty()) continue;
    ranks_.push_back(q);
    ghosts_.push_back(local_ids(window_, ghost));
    shared_.push_back(local_ids(window_, shared));
  }
}

template <int D> int NodeExchange<D>::ghost_count() const {
  int n = 0;
  for (const auto& g : ghosts_) n += static_cast<int>(g.size());
  return n;
}

template <int D> long long NodeExchange<D>::sum(const Comm& comm, std::span<const NodalArray> fields) {
  if (comm.size() == 1) return 0;
  const long long before = bytes_sent_;
  // 1. partial sums of the ghosts to their owners; owners add them in rank order
  std::vector<int> to, from;
  std::vector<Bytes> out;
  std::vector<std::size_t> to_index, from_index;
  for (std::size_t i = 0; i < ranks_.size(); ++i) {
    if (!ghosts_[i].empty()) {
      to.push_back(ranks_[i]);
      out.push_back(pack(fields, ghosts_[i]));
      bytes_sent_ += static_cast<long long>(out.back().size());
    }
    if (!shared_[i].empty()) from.push_back(ranks_[i]), from_index.push_back(i);
  }
  std::vector<Bytes> in = comm.exchange(to, out, from);
  for (std::size_t j = 0; j < from.size(); ++j) unpack(fields, shared_[from_index[j]], in[j], true);
  // 2. the totals back to the ranks holding them as ghosts
  to.clear(), from.clear(), out.clear(), from_index.clear();
  for (std::size_t i = 0; i < ranks_.size(); ++i) {
    if (!shared_[i].empty()) {
      to.push_back(ranks_[i]);
      out.push_back(pack(fields, shared_[i]));
      bytes_sent_ += static_cast<long long>(out.back().size());
    }
    if (!ghosts_[i].empty()) from.push_back(ranks_[i]), from_index.push_back(i);
  }
  in = comm.exchange(to, out, from);
  for (std::size_t j = 0; j < from.size(); ++j) unpack(fields, ghosts_[from_index[j]], in[j], false);
  return bytes_sent_ - before;
}

template class NodeExchange<1>;
template class NodeExchange<2>;
template class NodeExchange<3>;

} // namespace otmpm::distributed
