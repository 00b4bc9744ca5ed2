/// \file global_view.cpp
/// The particles of all ranks as the recorder sees them (global_view.hpp).
#include "otmpm/distributed/global_view.hpp"

#include "otmpm/io/checkpoint.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/reference/exact.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <new>
#include <set>
#include <sstream>

namespace otmpm::distributed {

namespace {

/// The cell hints, which are local to a rank's basis and travel as global cells.
constexpr const char* kCellHints = "cell_hint";

/// Every rank's `mine` on rank 0 (ranks 1, 2, ..., then rank 0's own);
/// nothing on the other ranks.
std::vector<Bytes> on_root(const Comm& comm, Bytes mine) {
  std::vector<int> to, from;
  std::vector<Bytes> out;
  if (!comm.root()) to.push_back(0), out.push_back(std::move(mine));
  else
    for (int q = 1; q < comm.size(); ++q) from.push_back(q);
  std::vector<Bytes> in = comm.exchange(to, out, from);
  if (comm.root()) in.push_back(std::move(mine));
  return in;
}

/// Adds `sign` times the hint offset to every cell hint of a basis group.
template <int D> void shift_hints(StateGroup& basis, const Index<D>& offset, int sign) {
  const auto it = basis.integer_arrays.find(kCellHints);
  if (it == basis.integer_arrays.end()) return;
  std::vector<std::int64_t>& v = it->second.values;
  for (std::size_t i = 0; i < v.size(); ++i) v[i] += sign * offset[i % D];
}

/// Lines "group kind cols name" (kind r: real, i: integer) of the per-particle
/// arrays of `ck` (checkpoint_row_kind).
std::set<std::string> particle_array_lines(const Checkpoint& ck) {
  std::set<std::string> lines;
  for (const auto& entry : ck.groups) {
    const std::string& gname = entry.first;
    auto add = [&](const auto& arrays, const char* kind) {
      for (const auto& a : arrays)
        if (checkpoint_row_kind(gname, a.first) == RowKind::particle)
          lines.insert(gname + " " + kind + " " + std::to_string(a.second.cols) + " " + a.first);
    };
    add(entry.second.real_arrays, "r");
    add(entry.second.integer_arrays, "i");
  }
  return lines;
}

/// Makes every rank's checkpoint hold the same per-particle arrays, adding
/// those it lacks, empty, with the width the others give them: a rank without
/// particles saves no particle field (every one is empty), and the file's
/// datasets are created by all ranks together, one per array in name order.
void same_particle_arrays(const Comm& comm, Checkpoint& ck) {
  std::string mine;
  for (const std::string& line : particle_array_lines(ck)) mine += line + "\n";
  std::string all;
  for (const Bytes& b : on_root(comm, Bytes(mine.begin(), mine.end()))) all.append(b.begin(), b.end());
  all = comm.broadcast(all, 0);
  std::istringstream lines(all);
  std::string group, kind, name;
  std::size_t cols = 0;
  while (lines >> group >> kind >> cols >> name) {
    StateGroup& g = ck.group(group);
    if (kind == "r" && !g.real_arrays.count(name)) g.real_arrays[name] = {cols, {}};
    if (kind == "i" && !g.integer_arrays.count(name)) g.integer_arrays[name] = {cols, {}};
  }
}

} // namespace

template <int D> void GlobalView<D>::on_writer(const std::function<void()>& write) const {
  if (!d_) return write();
  enum Kind : char { ok = 'o', input = 'i', unstable = 'u', other = 'x' };
  std::string outcome(1, ok);
  if (writes()) {
    try {
      write();
    } catch (const InputError& e) {
      outcome = std::string(1, input) + e.what();
    } catch (const InstabilityError& e) {
      outcome = std::string(1, unstable) + e.what();
    } catch (const std::exception& e) {
      outcome = std::string(1, other) + e.what();
    }
  }
  outcome = d_->comm().broadcast(outcome, 0);
  const std::string message = outcome.substr(1);
  switch (outcome.front()) {
  case input: throw InputError(message);
  case unstable: throw InstabilityError(message);
  case other: throw std::runtime_error(message);
  default: return;
  }
}

template <int D> void GlobalView<D>::collectively(const std::function<void()>& write) const {
  if (!d_) return write();
  // Every rank is here before any enters the parallel HDF5's calls, which
  // would wait without end for a rank that stopped before them
  // (stop_every_rank: the others learn of it in this barrier).
  d_->comm().barrier();
  agree_on(d_->comm(), write);
}

ParallelIo parallel_io(const Comm& comm) {
  ParallelIo io;
  if (comm.size() == 1) return io;
  io.mpi_comm = comm.mpi_comm();
  io.root = comm.root();
  io.rank = comm.rank();
  io.size = comm.size();
  io.all = [&comm](bool ok) { return comm.min(static_cast<std::int64_t>(ok)) != 0; };
  io.allgather = [&comm](std::int64_t value) { return comm.allgather(value); };
  io.broadcast = [&comm](const std::string& text) { return comm.broadcast(text, 0); };
  io.agree = [&comm](const std::function<void()>& step) { agree_on(comm, step); };
  return io;
}

template <int D> ParallelIo GlobalView<D>::parallel_io() const {
  return d_ ? distributed::parallel_io(d_->comm()) : ParallelIo{};
}

template <int D> void GlobalView<D>::require_shared_file(const std::string& path) const {
  if (!d_) return;
  const std::string token = share(new_run_id()); // the probe's name and content
  namespace fs = std::filesystem;
  const Comm& comm = d_->comm();
  std::error_code ec;
  const fs::path resolved = fs::weakly_canonical(fs::absolute(path, ec), ec);
  require_same(comm, "the absolute path of the result file '" + path + "'", resolved.string(),
               "the ranks write one result file together: give an absolute path, or start every rank in the same "
               "working directory");
  const std::string probe =
      (resolved.parent_path() / ("." + resolved.filename().string() + ".otmpm-ranks-" + token)).string();
  bool created = false;
  if (writes()) created = (std::ofstream(probe) << token).good();
  // Where the writing rank cannot create a file, the claim of the output
  // files that follows says why (prepare_outputs: a missing directory, ...).
  if (share(created ? "1" : "0") != "1") return;
  struct Remove { // by the writing rank, once every rank looked at it
    const std::string& path;
    bool writes;
    ~Remove() {
      if (writes) ::unlink(path.c_str());
    }
  } remove{probe, writes()};
  agree_on(comm, [&] {
    const std::string rank = "rank " + std::to_string(comm.rank()), file = "the result file '" + resolved.string() + "'";
    const int fd = ::open(probe.c_str(), O_RDWR | O_CLOEXEC);
    const int err = errno;
    char text[64] = {};
    const bool seen = fd >= 0 && ::read(fd, text, sizeof text - 1) >= 0 && token == text;
    if (fd >= 0) ::close(fd);
    require(fd >= 0 || err != ENOENT, rank, " does not see the file rank 0 created beside ", file,
            ": the ranks write one result file together, in a directory that every node shares (not one local to "
            "each node)");
    require(fd >= 0, rank, " cannot write beside ", file, " (", std::strerror(err),
            "): the ranks write one result file together, in a directory writable on every node");
    require(seen, rank, " does not see the content rank 0 wrote beside ", file,
            ": the ranks write one result file together, in a directory that every node shares");
  });
}

template <int D> void GlobalView<D>::require_readable(const std::string& path, const std::string& what) const {
  if (!d_) return;
  const Comm& comm = d_->comm();
  agree_on(comm, [&] {
    const std::ifstream in(path);
    require(in.good(), "rank ", comm.rank(), ": cannot read ", what, " '", path, "' (", std::strerror(errno), ")");
  });
}

template <int D> typename GlobalView<D>::Block GlobalView<D>::block(const double* local, int cols) const {
  const std::size_t n = static_cast<std::size_t>(e_.particles().size()), c = static_cast<std::size_t>(cols);
  Block b;
  if (!d_) {
    b.values.assign(local, local + n * c);
    b.count = static_cast<long long>(n);
    return b;
  }
  if (test_allocation_fails("output", e_.steps())) throw std::bad_alloc();
  const Comm& comm = d_->comm();
  const long long N = d_->global_particles(), P = comm.size();
  auto first_of = [&](long long r) { return N * r / P; };
  std::vector<Bytes> out(static_cast<std::size_t>(P));
  for (std::size_t p = 0; p < n; ++p) {
    const long long g = d_->global_id(static_cast<int>(p));
    long long r = std::min(P - 1, g * P / std::max(N, 1LL));
    while (first_of(r) > g) --r;
    while (first_of(r + 1) <= g) ++r;
    put(out[static_cast<std::size_t>(r)], static_cast<std::int64_t>(g));
    put_bytes(out[static_cast<std::size_t>(r)], local + p * c, c * sizeof(double));
  }
  const std::vector<Bytes> in = comm.alltoall(std::move(out));
  b.first = first_of(comm.rank());
  b.count = first_of(comm.rank() + 1) - b.first;
  b.values.assign(static_cast<std::size_t>(b.count) * c, 0.0);
  for (const Bytes& msg : in) {
    Reader r(msg);
    while (!r.done()) {
      const long long g = r.get<std::int64_t>();
      r.get_bytes(b.values.data() + static_cast<std::size_t>(g - b.first) * c, c * sizeof(double));
    }
  }
  return b;
}

template <int D> std::vector<std::pair<std::string, double>> GlobalView<D>::run_attributes() const {
  if (!d_) return {};
  const DomainStats& st = d_->stats();
  std::int64_t sums[] = {st.migrated, st.halo_bytes, st.cg_iterations, st.cg_solves, st.rebalances,
                         st.halo_exchanges, st.reductions};
  d_->comm().sum(sums);
  const Comm& comm = d_->comm();
  const double P = comm.size();
  return {{"ranks", P},
          {"migrated_particles", static_cast<double>(sums[0])},
          {"halo_bytes", static_cast<double>(sums[1])},
          {"cg_iterations", static_cast<double>(sums[2]) / P},
          {"cg_solves", static_cast<double>(sums[3]) / P},
          {"rebalances", static_cast<double>(sums[4]) / P},
          {"halo_exchanges", static_cast<double>(sums[5]) / P},
          {"reductions", static_cast<double>(sums[6]) / P},
          {"communication_seconds_mean", comm.sum(st.communication_seconds) / P},
          {"communication_seconds_max", comm.max(st.communication_seconds)},
          {"setup_particles_max", comm.max(static_cast<double>(st.setup_particles))},
          {"setup_particles_sum", comm.sum(static_cast<double>(st.setup_particles))},
          {"setup_points_max", comm.max(static_cast<double>(st.setup_points))},
          {"setup_points_sum", comm.sum(static_cast<double>(st.setup_points))}};
}

template <int D> long long GlobalView<D>::nodes() const {
  if (!d_) return e_.basis().nodes().size();
  long long n = 1;
  for (int k = 0; k < D; ++k) n *= d_->lattice().points[k];
  return n;
}

template <int D> long long GlobalView<D>::best(const std::function<double(int)>& score) const {
  const int n = e_.particles().size();
  int best = n > 0 ? 0 : -1;
  for (int p = 1; p < n; ++p)
    if (score(p) < score(best) || (d_ && score(p) == score(best) && d_->global_id(p) < d_->global_id(best))) best = p;
  if (!d_) return best;
  const double s = best >= 0 ? score(best) : std::numeric_limits<double>::infinity();
  const double smallest = d_->comm().min(s);
  const std::int64_t none = std::numeric_limits<std::int64_t>::max();
  return d_->comm().min(best >= 0 && s == smallest ? static_cast<std::int64_t>(d_->global_id(best)) : none);
}

template <int D> typename GlobalView<D>::Row GlobalView<D>::row(long long g) const {
  const Particles<D>& P = e_.particles();
  auto local_row = [&](int p) { return Row{P.x[p], P.X[p], P.v[p], P.sigma[p]}; };
  if (!d_) return local_row(static_cast<int>(g));
  const auto& ids = d_->global_ids();
  const auto it = std::find(ids.begin(), ids.end(), g);
  const Comm& comm = d_->comm();
  const int owner = static_cast<int>(comm.min(static_cast<std::int64_t>(it != ids.end() ? comm.rank() : comm.size())));
  Row r = it != ids.end() ? local_row(static_cast<int>(it - ids.begin())) : Row{};
  comm.broadcast(&r, sizeof r, owner);
  return r;
}

template <int D> double GlobalView<D>::rms(const std::vector<double>& squared) const {
  if (!d_) return rms_error(squared);
  double sum = 0.0;
  for (double e : squared) sum += e;
  return std::sqrt(d_->comm().sum(sum) / static_cast<double>(d_->global_particles()));
}

/// Keeps the rows of a per-point array of a window that `owned` marks.
template <class T> void keep_owned(StateArray<T>& a, const std::vector<char>& owned) {
  std::size_t w = 0;
  for (std::size_t i = 0; i < owned.size() && (i + 1) * a.cols <= a.values.size(); ++i)
    if (owned[i]) std::copy_n(a.values.begin() + static_cast<std::ptrdiff_t>(i * a.cols), a.cols,
                              a.values.begin() + static_cast<std::ptrdiff_t>(w++ * a.cols));
  a.values.resize(w * a.cols);
}

template <int D> void GlobalView<D>::write_checkpoint(const std::string& path, Checkpoint ck) const {
  if (!d_) return on_writer([&] { otmpm::write_checkpoint(path, ck); });
  const Comm& comm = d_->comm();
  same_particle_arrays(comm, ck);
  shift_hints<D>(ck.group("basis"), d_->hint_offset(), +1);
  const std::vector<long long>& ids = d_->global_ids();
  ck.group("particles").integer_arrays["global_id"] = {1, std::vector<std::int64_t>(ids.begin(), ids.end())};
  for (auto& [gname, g] : ck.groups) {
    for (auto& [name, a] : g.real_arrays)
      if (checkpoint_row_kind(gname, name) == RowKind::point) keep_owned(a, d_->owned_nodes());
    for (auto& [name, a] : g.integer_arrays)
      if (checkpoint_row_kind(gname, name) == RowKind::point) keep_owned(a, d_->owned_nodes());
  }
  const std::vector<std::int64_t> counts = comm.allgather(static_cast<std::int64_t>(ids.size()));
  long long first = 0;
  for (int r = 0; r < comm.rank(); ++r) first += counts[static_cast<std::size_t>(r)];
  StateGroup& g = ck.group("decomposition");
  g.integers["ranks"] = comm.size();
  g.integers["steps"] = d_->stats().steps;
  g.integer_arrays["rows_per_rank"] = {1, counts};
  g.integer_arrays["tree"] = {static_cast<std::size_t>(Decomposition<D>::kTreeColumns), d_->decomposition().tree_rows()};
  CheckpointShare share;
  share.io = parallel_io();
  share.particles = d_->global_particles();
  share.particle_rows = {{first, 1, 1, static_cast<long long>(ids.size())}};
  share.points = nodes();
  share.point_rows = point_blocks(d_->lattice(), d_->lattice().owned_points(d_->decomposition().box(comm.rank())));
  collectively([&] { otmpm::write_checkpoint(path, std::move(ck), share); });
}

template <int D> Checkpoint local_checkpoint(const Engine<D>& e, const Checkpoint& ck, Checkpoint rows) {
  const Domain<D>* d = domain_of(e);
  if (!d) { // every row, in the order of the global ids (a distributed run's file holds them by rank)
    Checkpoint all = ck.source ? checkpoint_head(ck) : ck;
    if (ck.source)
      for (const RowKind kind : {RowKind::particle, RowKind::point})
        read_checkpoint_rows(ck, kind, {{0, 1, 1, checkpoint_rows(ck, kind)}}, all);
    require_reset_homes<D>(ck, all, 1);
    order_by_global_id(all);
    return all;
  }
  read_checkpoint_rows(ck, RowKind::point, point_blocks(d->lattice(), d->exchange().window().box), rows);
  shift_hints<D>(rows.group("basis"), d->hint_offset(), -1);
  return rows;
}

template class GlobalView<1>;
template class GlobalView<2>;
template class GlobalView<3>;
#define OTMPM_INSTANTIATE(D)                                                  \
  template Checkpoint local_checkpoint<D>(const Engine<D>&, const Checkpoint&, Checkpoint);
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm::distributed
