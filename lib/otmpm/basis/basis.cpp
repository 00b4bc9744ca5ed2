/// \file basis.cpp
/// The basis factory (make_basis: scene name -> family) and the per-step
/// basis table (docs/architecture.md): every particle's stencil evaluated once,
/// stored in compressed rows, independent of the OpenMP thread count.
#include "otmpm/basis/basis.hpp"

#include "otmpm/text.hpp"
#include "otmpm/parallel.hpp"
#include "otmpm/state.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <limits>
#include <stdexcept>
#include <utility>

namespace otmpm {

double BasisOptions::value(const ParameterSpec& p) const {
  const auto it = values.find(p.key);
  return it != values.end() ? it->second : p.fallback.value_or(0.0);
}

void require_options(const BasisOptions& o, std::span<const ParameterSpec> parameters) {
  for (const ParameterSpec& p : parameters) {
    const std::string problem = p.check(o.value(p));
    if (!problem.empty()) throw InputError(o.kind + " basis: " + std::string(p.key) + " " + problem);
  }
}

template <int D> void Basis<D>::bind_points(int n, bool nodes_move) {
  require<std::invalid_argument>(n >= 0, "Basis::bind_points: n must be >= 0, got ", n);
  const PointStateUse use = point_state_use(nodes_move);
  points_.lambda.assign(use.lambda ? static_cast<std::size_t>(n) : 0, Vec<D>::Zero());
  points_.slope.assign(use.slope ? static_cast<std::size_t>(n) : 0, MultiplierSlope<D>{});
  points_.history.assign(use.history ? static_cast<std::size_t>(n) : 0, MultiplierHistory<D>{});
  points_.cell_hint.assign(use.cell_hint ? static_cast<std::size_t>(n) : 0, Index<D>{});
  points_.neighbours = NeighbourLists<D>();
  use_ = use;
}

template <int D>
void Basis<D>::evaluate_points(const AlignedVector<Vec<D>>& x, BasisTable<D>& table,
                               const AlignedVector<Mat<D>>* deformation, AlignedVector<Vec<D>>* moved) {
  require<std::invalid_argument>(!use_.deformation || (deformation && deformation->size() == x.size()),
                                 "Basis::evaluate_points: the ", kind(),
                                 " basis with metric 'deformation' needs the deformation gradient of each of the ",
                                 x.size(), " points, got ", deformation ? deformation->size() : 0);
  PointArrays<D> a;
  a.lambda = &points_.lambda;
  a.slope = &points_.slope;
  a.history = &points_.history;
  a.cell_hint = &points_.cell_hint;
  a.neighbours = &points_.neighbours;
  a.deformation = use_.deformation ? deformation : nullptr;
  a.moved = moved;
  fill_basis_table(*this, x, a, table);
}

namespace {
/// Stores an array of fixed-size items (Vec<D> or Index<D>) as rows of D values.
template <class Array, class Out> void put_rows(Out& out, const Array& a, std::size_t cols) {
  out.cols = cols;
  out.values.clear();
  for (const auto& item : a)
    for (std::size_t k = 0; k < cols; ++k) out.values.push_back(item[static_cast<int>(k)]);
}
/// Restores what put_rows stored into `a`, which has its size already
/// (an empty `a`: the family keeps no such state, nor may the checkpoint).
template <class Array, class In> void get_rows(const In& in, Array& a, std::size_t cols) {
  for (std::size_t i = 0; i < a.size(); ++i)
    for (std::size_t k = 0; k < cols; ++k)
      a[i][static_cast<int>(k)] = static_cast<std::remove_reference_t<decltype(a[i][0])>>(in.values[i * cols + k]);
}
/// A vector and a matrix member of MultiplierSlope (x0 and G, or e and G_prev).
template <int D> struct SlopeColumns {
  Vec<D> MultiplierSlope<D>::*v;
  Mat<D> MultiplierSlope<D>::*m;
};
/// Stores the members `c` of the slopes as rows of D + D * D values: the
/// vector, then the matrix by rows.
template <int D, class Out>
void put_slopes(Out& out, const AlignedVector<MultiplierSlope<D>>& a, SlopeColumns<D> c) {
  out.cols = D + D * D;
  out.values.clear();
  for (const MultiplierSlope<D>& s : a) {
    for (int k = 0; k < D; ++k) out.values.push_back((s.*c.v)[k]);
    for (int k = 0; k < D; ++k)
      for (int l = 0; l < D; ++l) out.values.push_back((s.*c.m)(k, l));
  }
}
/// Restores what put_slopes stored into `a`, which has its size already.
template <int D, class In> void get_slopes(const In& in, AlignedVector<MultiplierSlope<D>>& a, SlopeColumns<D> c) {
  std::size_t i = 0;
  for (MultiplierSlope<D>& s : a) {
    for (int k = 0; k < D; ++k) (s.*c.v)[k] = in.values[i++];
    for (int k = 0; k < D; ++k)
      for (int l = 0; l < D; ++l) (s.*c.m)(k, l) = in.values[i++];
  }
}
/// x0 and G ("lambda_slope"); e and G_prev ("lambda_curvature").
template <int D> constexpr SlopeColumns<D> kSlope{&MultiplierSlope<D>::x0, &MultiplierSlope<D>::G};
template <int D> constexpr SlopeColumns<D> kCurvature{&MultiplierSlope<D>::e, &MultiplierSlope<D>::G_prev};

/// Stores the histories as rows of 2 D + 1 values: previous, before, solves.
template <int D, class Out> void put_histories(Out& out, const AlignedVector<MultiplierHistory<D>>& a) {
  out.cols = 2 * D + 1;
  out.values.clear();
  for (const MultiplierHistory<D>& h : a) {
    for (int k = 0; k < D; ++k) out.values.push_back(h.previous[k]);
    for (int k = 0; k < D; ++k) out.values.push_back(h.before[k]);
    out.values.push_back(h.solves);
  }
}
/// Restores what put_histories stored in the array "lambda_history" of `in`
/// into `a`, which has its size already; a count of solves other than 0 to
/// 3 is an error of the checkpoint (InputError naming it).
template <int D> void get_histories(const StateGroup& in, AlignedVector<MultiplierHistory<D>>& a) {
  constexpr std::size_t cols = 2 * D + 1;
  const auto& values = in.real_array("lambda_history", a.size(), cols).values;
  for (std::size_t p = 0; p < a.size(); ++p) {
    const double* row = values.data() + p * cols;
    MultiplierHistory<D>& h = a[p];
    for (int k = 0; k < D; ++k) h.previous[k] = row[k], h.before[k] = row[D + k];
    const double solves = row[2 * D];
    if (!(solves == 0.0 || solves == 1.0 || solves == 2.0 || solves == 3.0))
      in.error("per-point state 'lambda_history': a count of solves of " + text::exact(solves) +
               " (0 to 3 expected) in row " + std::to_string(p) + " of the particles restored here");
    h.solves = static_cast<int>(solves);
  }
}
} // namespace

template <int D> void Basis<D>::save_state(StateGroup& out) const {
  // the arrays the basis keeps, also when empty (a rank without particles)
  if (use_.lambda) put_rows(out.real_arrays["lambda"], points_.lambda, D);
  if (use_.slope) {
    put_slopes(out.real_arrays["lambda_slope"], points_.slope, kSlope<D>);
    put_slopes(out.real_arrays["lambda_curvature"], points_.slope, kCurvature<D>);
  }
  if (use_.history) put_histories(out.real_arrays["lambda_history"], points_.history);
  if (use_.cell_hint) put_rows(out.integer_arrays["cell_hint"], points_.cell_hint, D);
  save_family_state(out);
}

template <int D> void Basis<D>::restore_state(const StateGroup& in) {
  auto expect = [&](const char* name, bool kept) {
    if (in.has_array(name) != kept) in.error(std::string("per-point state '") + name + "' does not fit this basis");
  };
  // by what the basis keeps, not by the arrays' sizes: a rank without
  // particles restores empty arrays
  expect("lambda", use_.lambda);
  expect("cell_hint", use_.cell_hint);
  if (use_.lambda) get_rows(in.real_array("lambda", points_.lambda.size(), D), points_.lambda, D);
  // A checkpoint without slopes (an older otmpm, or one written in `ul`
  // mode) restarts from the plain warm start: G = 0; one without the
  // second-order part from the first-order prediction: e = 0.
  if (use_.slope && in.has_array("lambda_slope")) {
    get_slopes(in.real_array("lambda_slope", points_.slope.size(), D + D * D), points_.slope, kSlope<D>);
    if (in.has_array("lambda_curvature"))
      get_slopes(in.real_array("lambda_curvature", points_.slope.size(), D + D * D), points_.slope, kCurvature<D>);
    else
      for (MultiplierSlope<D>& m : points_.slope) m.e.setZero();
  }
  // One without histories (an older otmpm): the plain warm start until
  // the run has made its own solves.
  if (use_.history && in.has_array("lambda_history"))
    get_histories<D>(in, points_.history);
  else if (use_.history)
    std::fill(points_.history.begin(), points_.history.end(), MultiplierHistory<D>{});
  if (use_.cell_hint) get_rows(in.integer_array("cell_hint", points_.cell_hint.size(), D), points_.cell_hint, D);
  restore_family_state(in);
}

namespace {

/// The argument checks of fill_basis_table (sizes only: the points themselves
/// are checked by each family's evaluate()).
template <int D> void check_table_arguments(const AlignedVector<Vec<D>>& x, const PointArrays<D>& a) {
  require<std::invalid_argument>(x.size() <= static_cast<std::size_t>(std::numeric_limits<int>::max()),
                                 "fill_basis_table: x has ", x.size(), " points, more than an int can count");
  auto check = [&](const char* name, const auto* array) {
    require<std::invalid_argument>(!array || array->empty() || array->size() == x.size(), "fill_basis_table: ", name,
                                   " has ", array ? array->size() : 0, " entries for ", x.size(), " points x");
  };
  check("lambda", a.lambda);
  check("slope", a.slope);
  check("history", a.history);
  check("cell_hint", a.cell_hint);
  check("deformation", a.deformation);
  check("moved", a.moved);
}

/// `a` with the empty arrays replaced by null.
template <int D> PointArrays<D> used_arrays(PointArrays<D> a) {
  auto drop_empty = [](auto*& array) {
    if (array && array->empty()) array = nullptr;
  };
  drop_empty(a.lambda);
  drop_empty(a.slope);
  drop_empty(a.history);
  drop_empty(a.cell_hint);
  drop_empty(a.deformation);
  drop_empty(a.moved);
  return a;
}

/// Copies entries [e0, e1) of the entry arrays of `from` (a Stencil, a
/// TableChunk's buffer or a BasisTable: node, N, dN) to node/N/dN.
template <class From, int D>
void copy_entries(const From& from, std::size_t e0, std::size_t e1, int* node, double* N, Vec<D>* dN) {
  const auto b = static_cast<std::ptrdiff_t>(e0), e = static_cast<std::ptrdiff_t>(e1);
  std::copy(from.node.begin() + b, from.node.begin() + e, node);
  std::copy(from.N.begin() + b, from.N.begin() + e, N);
  std::copy(from.dN.begin() + b, from.dN.begin() + e, dN);
}

/// The rows of a contiguous range of particles, evaluated by one thread.
template <int D> struct TableChunk {
  std::vector<int> count; // stencil size per particle of the chunk
  std::vector<int> node;
  std::vector<double> N;
  AlignedVector<Vec<D>> dN;
  Stencil<D> stencil;
  /// First failure in the chunk (lowest particle index, since rows go in order).
  std::exception_ptr error;
  /// fill_placed: the chunk's place in the table, entries [start, limit);
  /// its first `placed` rows were written there, up to entry `end`, the
  /// rest (count, node, N, dN) did not fit.
  int start = 0, limit = 0, placed = 0, end = 0;
};

/// The query for point p of a table fill.
template <int D> PointQuery<D> point_query(const AlignedVector<Vec<D>>& x, const PointArrays<D>& a, int p) {
  PointQuery<D> q;
  q.x = x[p];
  q.id = p;
  q.lambda = a.lambda ? &(*a.lambda)[p] : nullptr;
  q.slope = a.slope ? &(*a.slope)[p] : nullptr;
  q.history = a.history ? &(*a.history)[p] : nullptr;
  q.cell_hint = a.cell_hint ? &(*a.cell_hint)[p] : nullptr;
  q.neighbours = a.neighbours;
  q.deformation = a.deformation ? &(*a.deformation)[p] : nullptr;
  q.moved = a.moved ? &(*a.moved)[p] : nullptr;
  return q;
}

/// The BasisError of point p, with the particle index and position prepended.
template <int D> BasisError point_error(const AlignedVector<Vec<D>>& x, int p, const BasisError& e) {
  return BasisError("particle " + std::to_string(p) + " at " + format_point<D>(x[p]) + ": " + e.what());
}

/// The calling thread's scratch stencil, kept from call to call (no
/// allocation once it has grown). Out of line on purpose: its address is then
/// taken once per loop, where a thread_local used in the loop itself is looked
/// up again (__tls_get_addr) after every call the loop makes.
template <int D> [[gnu::noinline]] Stencil<D>& thread_stencil() {
  thread_local Stencil<D> st;
  return st;
}

/// Fills the table of a family whose stencils all have S entries: row p is
/// entries p S .. (p+1) S - 1, written in place by the thread evaluating p (no
/// per-thread buffer, no copy). Returns false when some point gave another
/// stencil size; the caller then takes the general path.
template <int D>
bool fill_fixed(const Basis<D>& basis, int S, const AlignedVector<Vec<D>>& x, const PointArrays<D>& a,
                BasisTable<D>& table) {
  const int n = static_cast<int>(x.size());
  const std::size_t entries = static_cast<std::size_t>(n) * static_cast<std::size_t>(S);
  table.offset.resize(static_cast<std::size_t>(n) + 1);
  table.node.resize(entries);
  table.N.resize(entries);
  table.dN.resize(entries);
  std::atomic<bool> irregular{false};
  parallel_chunks(n, [&](long long begin, long long end) {
    Stencil<D>& st = thread_stencil<D>();
    for (long long p = begin; p < end; ++p) table.offset[static_cast<std::size_t>(p)] = static_cast<int>(p * S);
    // The batched path (evaluate_fixed_points); a point it stops at goes
    // through evaluate_fixed()/evaluate(), then the batch resumes after it.
    // A family without a batch in its present state (-1) is not asked again
    // in the chunk.
    bool batch = true;
    for (int p = static_cast<int>(begin); p < end; ++p) {
      if (batch) {
        const std::size_t b0 = static_cast<std::size_t>(p) * static_cast<std::size_t>(S);
        const int done = basis.evaluate_fixed_points(&x[static_cast<std::size_t>(p)], static_cast<int>(end - p),
                                                     a.cell_hint ? &(*a.cell_hint)[static_cast<std::size_t>(p)] : nullptr,
                                                     &table.node[b0], &table.N[b0], &table.dN[b0]);
        batch = done >= 0;
        p += std::max(done, 0);
        if (p == end) break;
      }
      const std::size_t e0 = static_cast<std::size_t>(p) * static_cast<std::size_t>(S);
      const PointQuery<D> q = point_query<D>(x, a, p);
      try {
        if (basis.evaluate_fixed(q, &table.node[e0], &table.N[e0], &table.dN[e0])) continue;
        basis.evaluate(q, st);
      } catch (const BasisError& e) {
        throw point_error<D>(x, p, e);
      }
      if (st.size() != S) {
        irregular.store(true, std::memory_order_relaxed);
        return;
      }
      copy_entries(st, 0, st.node.size(), table.node.data() + e0, table.N.data() + e0, table.dN.data() + e0);
    }
  });
  table.offset[static_cast<std::size_t>(n)] = static_cast<int>(entries);
  return !irregular.load();
}

/// Appends rows to the entry arrays of a table (or chunk) through a write
/// cursor: the arrays keep their size from the last fill (about the entries
/// of this one), are grown ahead of the cursor when a row does not fit and
/// are cut to the entries written by finish(). A row costs three copies, not
/// three vector::insert calls, and nothing is value-initialised or allocated
/// once the arrays have reached their size.
template <int D> class RowWriter {
public:
  /// The three arrays are brought to one size (they have it, unless a
  /// caller's table did not or an allocation of grow() failed half-way).
  RowWriter(std::vector<int>& node, std::vector<double>& N, AlignedVector<Vec<D>>& dN)
      : node_(node), N_(N), dN_(dN) {
    N_.resize(node_.size());
    dN_.resize(node_.size());
  }
  /// Appends the stencil `s`; returns the entries written so far.
  std::size_t append(const Stencil<D>& s) {
    const std::size_t m = s.node.size();
    if (used_ + m > node_.size()) grow(used_ + m);
    copy_entries(s, 0, m, node_.data() + used_, N_.data() + used_, dN_.data() + used_);
    return used_ += m;
  }
  /// Appends the stencil of q: written in place by basis.evaluate_into()
  /// into the room left before the arrays' end (nothing is grown or
  /// value-initialised for it) when `in_place` (Basis::writes_in_place),
  /// or evaluated into `st` and copied. Returns the entries written so far.
  std::size_t append_point(const Basis<D>& basis, const PointQuery<D>& q, bool in_place, Stencil<D>& st) {
    if (!in_place) {
      basis.evaluate(q, st);
      return append(st);
    }
    const std::size_t left = node_.size() - used_;
    const int room = static_cast<int>(std::min<std::size_t>(left, std::numeric_limits<int>::max()));
    const int m = basis.evaluate_into(q, room, node_.data() + used_, N_.data() + used_, dN_.data() + used_, st);
    if (m >= 0) return used_ += static_cast<std::size_t>(m);
    return append(st);
  }
  /// Entries written so far.
  std::size_t used() const { return used_; }
  /// Cuts the arrays to the entries written.
  void finish() {
    node_.resize(used_);
    N_.resize(used_);
    dN_.resize(used_);
  }

private:
  [[gnu::noinline]] void grow(std::size_t need) {
    const std::size_t size = std::max(need, node_.size() + node_.size() / 4 + 64);
    node_.resize(size);
    N_.resize(size);
    dN_.resize(size);
  }
  std::vector<int>& node_;
  std::vector<double>& N_;
  AlignedVector<Vec<D>>& dN_;
  std::size_t used_ = 0;
};

/// One thread: every row appended straight to the table (no chunk copy).
template <int D>
void fill_serial(const Basis<D>& basis, const AlignedVector<Vec<D>>& x, const PointArrays<D>& a,
                 BasisTable<D>& table) {
  Stencil<D>& st = thread_stencil<D>();
  const int n = static_cast<int>(x.size());
  table.offset.resize(static_cast<std::size_t>(n) + 1);
  table.offset[0] = 0;
  RowWriter<D> rows(table.node, table.N, table.dN);
  const bool in_place = basis.writes_in_place();
  for (int p = 0; p < n; ++p) {
    std::size_t used = 0;
    try {
      used = rows.append_point(basis, point_query<D>(x, a, p), in_place, st);
    } catch (const BasisError& e) {
      rows.finish();
      throw point_error<D>(x, p, e);
    }
    table.offset[static_cast<std::size_t>(p) + 1] = static_cast<int>(used);
  }
  rows.finish();
}

/// Runs row(), the evaluation of particle p for chunk `c`; an exception it
/// throws is kept in c.error (a BasisError with the particle's index and
/// position prepended). False when it threw.
template <int D, class Row> bool keeps_error(Row&& row, const AlignedVector<Vec<D>>& x, int p, TableChunk<D>& c) {
  try {
    row();
    return true;
  } catch (const BasisError& e) {
    c.error = std::make_exception_ptr(point_error<D>(x, p, e));
  } catch (...) {
    c.error = std::current_exception();
  }
  return false;
}

/// Appends the rows of particles [begin, end) to `rows`, their sizes to
/// c.count; stops at the first error (kept in c.error).
template <int D>
void append_rows(const Basis<D>& basis, const AlignedVector<Vec<D>>& x, const PointArrays<D>& a, int begin, int end,
                 RowWriter<D>& rows, TableChunk<D>& c) {
  const bool in_place = basis.writes_in_place();
  std::size_t used = rows.used();
  for (int p = begin; p < end; ++p) {
    std::size_t now = used;
    if (!keeps_error<D>([&] { now = rows.append_point(basis, point_query<D>(x, a, p), in_place, c.stencil); }, x, p, c))
      return;
    c.count.push_back(static_cast<int>(now - used));
    used = now;
  }
}

/// Evaluates particles [begin, end) into `c`'s buffer, after the row left
/// in c.stencil when `carried` (then that of particle begin - 1); stops at
/// the first error.
template <int D>
void fill_chunk(const Basis<D>& basis, const AlignedVector<Vec<D>>& x, const PointArrays<D>& a, int begin, int end,
                TableChunk<D>& c, bool carried = false) {
  c.count.clear();
  c.error = nullptr;
  c.count.reserve(static_cast<std::size_t>(end - begin + (carried ? 1 : 0)));
  RowWriter<D> rows(c.node, c.N, c.dN); // the chunk's arrays keep their size from the last fill
  if (carried) c.count.push_back(static_cast<int>(rows.append(c.stencil)));
  append_rows<D>(basis, x, a, begin, end, rows, c);
  rows.finish();
}

/// Copies the rows of chunk `c`'s buffer into node/N/dN from entry
/// `entry0`, their offsets into `offset` from row `row0` (all sized).
template <int D>
void copy_rows(const TableChunk<D>& c, int row0, int entry0, std::vector<int>& offset, std::vector<int>& node,
               std::vector<double>& N, AlignedVector<Vec<D>>& dN) {
  int end = entry0;
  for (std::size_t i = 0; i < c.count.size(); ++i) {
    end += c.count[i];
    offset[static_cast<std::size_t>(row0) + i + 1] = end;
  }
  copy_entries(c, 0, c.node.size(), node.data() + entry0, N.data() + entry0, dN.data() + entry0);
}

/// Turns per-chunk counts (in slots 1..team) into starting positions and
/// sizes the table for all of them.
template <int D>
void size_table(std::vector<int>& rows, std::vector<int>& entries, int team, BasisTable<D>& table) {
  for (int t = 0; t < team; ++t) {
    rows[t + 1] += rows[t];
    entries[t + 1] += entries[t];
  }
  table.offset.resize(static_cast<std::size_t>(rows[team]) + 1);
  table.offset[0] = 0;
  table.node.resize(static_cast<std::size_t>(entries[team]));
  table.N.resize(static_cast<std::size_t>(entries[team]));
  table.dN.resize(static_cast<std::size_t>(entries[team]));
}

/// The first particle of each of the chunk_count(n, threads) chunks a
/// threaded fill cuts [0, n) into, and n after the last.
inline std::vector<int> chunk_firsts(int n, int threads) {
  const long long k = chunk_count(n, threads);
  std::vector<int> first(static_cast<std::size_t>(k) + 1);
  for (long long c = 0; c <= k; ++c) first[static_cast<std::size_t>(c)] = static_cast<int>(n * c / k);
  return first;
}

/// What a threaded fill keeps on the calling thread from call to call (a
/// worker thread's own would be empty), so that after the first steps a
/// fill allocates nothing: the chunks' buffers, and spare entry arrays
/// that gather_placed copies into and swaps with the table's.
template <int D> struct FillScratch {
  std::vector<TableChunk<D>> chunks;
  std::vector<int> node;
  std::vector<double> N;
  AlignedVector<Vec<D>> dN;
};

/// The calling thread's FillScratch, with at least k chunk buffers.
template <int D> FillScratch<D>& fill_scratch(std::size_t k) {
  thread_local FillScratch<D> scratch;
  if (scratch.chunks.size() < k) scratch.chunks.resize(k);
  return scratch;
}

/// fill_placed's plan: chunk c goes where its rows were in the table's
/// last fill, [start, limit) (the particles move little in a step, and the
/// sizes of their rows with them). False when `table` does not hold a fill
/// of as many rows (the first fill, another point count, or a table not
/// filled here).
template <int D>
bool place_chunks(const std::vector<int>& first, std::vector<TableChunk<D>>& pool, const BasisTable<D>& table) {
  const std::size_t k = first.size() - 1;
  const std::vector<int>& offset = table.offset;
  if (offset.size() != static_cast<std::size_t>(first[k]) + 1 || offset[0] != 0) return false;
  const auto entries = static_cast<std::size_t>(offset.back());
  if (offset.back() < 0 || table.node.size() != entries || table.N.size() != entries || table.dN.size() != entries)
    return false;
  for (std::size_t c = 0; c < k; ++c) {
    pool[c].start = offset[static_cast<std::size_t>(first[c])];
    pool[c].limit = offset[static_cast<std::size_t>(first[c + 1])];
    if (pool[c].start < 0 || pool[c].limit < pool[c].start || pool[c].limit > offset.back()) return false;
  }
  return true;
}

/// Writes the row of q at node/N/dN when it fits in `room` entries and
/// returns its size; else returns -1 with the row in `st`.
template <int D>
int place_row(const Basis<D>& basis, const PointQuery<D>& q, int room, int* node, double* N, Vec<D>* dN,
              Stencil<D>& st) {
  const int m = basis.evaluate_into(q, room, node, N, dN, st);
  if (m >= 0) return m;
  const int size = st.size();
  if (size > room) return -1;
  copy_entries(st, 0, st.node.size(), node, N, dN);
  return size;
}

/// fill_placed's second pass over the particles [begin, end) of chunk `c`:
/// their rows (and offsets) written straight into the table from c.start
/// while they fit before c.limit; from the first that does not, the rest
/// into the chunk's buffer. Stops at the first error.
template <int D>
void fill_chunk_placed(const Basis<D>& basis, const AlignedVector<Vec<D>>& x, const PointArrays<D>& a, int begin,
                       int end, TableChunk<D>& c, BasisTable<D>& table) {
  c.count.clear();
  c.error = nullptr;
  // the cursor in locals: the next chunk's fields may share a cache line
  // with this one's and be another thread's
  const int limit = c.limit;
  int at = c.start, p = begin;
  for (; p < end; ++p) {
    int m = 0;
    const auto row = [&] {
      m = place_row<D>(basis, point_query<D>(x, a, p), limit - at, table.node.data() + at, table.N.data() + at,
                       table.dN.data() + at, c.stencil);
    };
    if (!keeps_error<D>(row, x, p, c) || m < 0) break; // m < 0: the row, in c.stencil, does not fit
    table.offset[static_cast<std::size_t>(p) + 1] = at += m;
  }
  c.placed = p - begin;
  c.end = at;
  if (p < end && !c.error) return fill_chunk<D>(basis, x, a, p + 1, end, c, true);
  // nothing beyond the place: the buffer's memory (a whole chunk's rows
  // after a fill_chunked) goes back
  std::vector<int>().swap(c.node);
  std::vector<double>().swap(c.N);
  AlignedVector<Vec<D>>().swap(c.dN);
}

/// Closes the gaps fill_placed left: chunk c's placed rows move to the end
/// of the rows before it, its buffered rows after them - a copy of every
/// entry into the spare arrays, which are then swapped with the table's;
/// only when some chunk's entries were not where its rows were last time.
template <int D>
void gather_placed(const std::vector<int>& first, int threads, FillScratch<D>& s, BasisTable<D>& table) {
  const std::size_t k = first.size() - 1;
  std::vector<TableChunk<D>>& pool = s.chunks;
  std::vector<int> at(k + 1, 0); // each chunk's first entry in the new arrays
  for (std::size_t c = 0; c < k; ++c)
    at[c + 1] = at[c] + (pool[c].end - pool[c].start) + static_cast<int>(pool[c].node.size());
  const auto entries = static_cast<std::size_t>(at[k]);
  s.node.resize(entries);
  s.N.resize(entries);
  s.dN.resize(entries);
  parallel_chunks(static_cast<long long>(k), threads, [&](long long c0, long long c1) {
    for (auto c = static_cast<std::size_t>(c0); c < static_cast<std::size_t>(c1); ++c) {
      const TableChunk<D>& ch = pool[c];
      const int shift = at[c] - ch.start;
      for (int p = first[c]; p < first[c] + ch.placed; ++p) table.offset[static_cast<std::size_t>(p) + 1] += shift;
      copy_entries(table, ch.start, ch.end, s.node.data() + at[c], s.N.data() + at[c], s.dN.data() + at[c]);
      copy_rows<D>(ch, first[c] + ch.placed, at[c] + ch.end - ch.start, table.offset, s.node, s.N, s.dN);
    }
  });
  table.node.swap(s.node);
  table.N.swap(s.N);
  table.dN.swap(s.dN);
}

/// Several threads, the table holding the last fill of as many points
/// (every step after the first): each chunk of particles is placed where
/// its rows were and written there in place by whichever thread evaluates
/// it - no buffer and no copy while the chunks' entries stay the same.
/// Rows beyond a chunk's place go to its buffer, and when any chunk's
/// entries changed gather_placed closes the gaps: the same table as
/// fill_chunked's either way. False (nothing evaluated) when the table
/// holds no such fill.
template <int D>
bool fill_placed(const Basis<D>& basis, const AlignedVector<Vec<D>>& x, const PointArrays<D>& a, int threads,
                 BasisTable<D>& table) {
  const std::vector<int> first = chunk_firsts(static_cast<int>(x.size()), threads);
  const std::size_t k = first.size() - 1;
  FillScratch<D>& scratch = fill_scratch<D>(k);
  std::vector<TableChunk<D>>& pool = scratch.chunks;
  if (!place_chunks<D>(first, pool, table)) return false;
  parallel_chunks(static_cast<long long>(k), threads, [&](long long c0, long long c1) {
    for (auto c = static_cast<std::size_t>(c0); c < static_cast<std::size_t>(c1); ++c)
      fill_chunk_placed<D>(basis, x, a, first[c], first[c + 1], pool[c], table);
  });
  bool exact = true;
  for (std::size_t c = 0; c < k; ++c) {
    if (pool[c].error) std::rethrow_exception(pool[c].error); // the failing particle with the lowest index
    exact = exact && pool[c].end == pool[c].limit && pool[c].node.empty();
  }
  if (!exact) gather_placed<D>(first, threads, scratch, table);
  return true;
}

/// Several threads, when fill_placed has no last fill to place rows by (the
/// first step, or another point count): the particles cut into
/// parallel_chunks' chunks, each evaluated into a buffer of its own by
/// whichever thread is free, then the buffers copied into the table in
/// particle order (the same table for any thread count). The buffers are
/// the calling thread's (fill_scratch); fill_placed gives their memory
/// back once the chunks fit their places.
template <int D>
void fill_chunked(const Basis<D>& basis, const AlignedVector<Vec<D>>& x, const PointArrays<D>& a, int threads,
                  BasisTable<D>& table) {
  const std::vector<int> first = chunk_firsts(static_cast<int>(x.size()), threads);
  const std::size_t k = first.size() - 1;
  std::vector<TableChunk<D>>& pool = fill_scratch<D>(k).chunks;
  parallel_chunks(static_cast<long long>(k), threads, [&](long long c0, long long c1) {
    for (auto c = static_cast<std::size_t>(c0); c < static_cast<std::size_t>(c1); ++c)
      fill_chunk<D>(basis, x, a, first[c], first[c + 1], pool[c]);
  });
  std::vector<int> rows(k + 1, 0), entries(k + 1, 0);
  for (std::size_t c = 0; c < k; ++c) {
    if (pool[c].error) std::rethrow_exception(pool[c].error); // the failing particle with the lowest index
    rows[c + 1] = static_cast<int>(pool[c].count.size());
    entries[c + 1] = static_cast<int>(pool[c].node.size());
  }
  size_table<D>(rows, entries, static_cast<int>(k), table);
  // Rows land in particle order whatever the team size.
  parallel_chunks(static_cast<long long>(k), threads, [&](long long c0, long long c1) {
    for (auto c = static_cast<std::size_t>(c0); c < static_cast<std::size_t>(c1); ++c)
      copy_rows<D>(pool[c], rows[c], entries[c], table.offset, table.node, table.N, table.dN);
  });
}

} // namespace

template <int D>
void fill_basis_table(const Basis<D>& basis, const AlignedVector<Vec<D>>& x, const PointArrays<D>& arrays,
                      BasisTable<D>& table) {
  check_table_arguments<D>(x, arrays);
  const int n = static_cast<int>(x.size());
  PointArrays<D> a = used_arrays<D>(arrays);

  if (basis.search_radius() > 0.0) {
    basis.nodes().prepare_search(); // build the R-tree before threads query it
    if (a.neighbours) a.neighbours->prepare(basis.nodes(), n, basis.search_radius());
  } else {
    a.neighbours = nullptr; // a family that does not search (NodeSet::within) needs no index
  }
  if (const int S = basis.fixed_stencil(); S > 0 && fill_fixed<D>(basis, S, x, a, table)) return;

  const int threads = team_size(n);
  if (threads == 1) return fill_serial<D>(basis, x, a, table);
  if (!fill_placed<D>(basis, x, a, threads, table)) fill_chunked<D>(basis, x, a, threads, table);
}

template <int D>
void fill_basis_table(const Basis<D>& basis, const AlignedVector<Vec<D>>& x,
                      std::type_identity_t<AlignedVector<Vec<D>>>* lambda,
                      std::type_identity_t<std::vector<Index<D>>>* cell_hint, BasisTable<D>& table,
                      std::type_identity_t<NeighbourLists<D>>* neighbours) {
  PointArrays<D> a;
  a.lambda = lambda;
  a.cell_hint = cell_hint;
  a.neighbours = neighbours;
  fill_basis_table<D>(basis, x, a, table);
}

namespace {

/// transpose_basis_table over `rows` rows of `entries` entries: row p holds
/// entries [first(p), first(p + 1)), entry e at node node_of(e).
template <class First, class NodeOf>
void transpose_rows(int rows, std::size_t entries, int nodes, First&& first, NodeOf&& node_of,
                    NodeColumns& columns) {
  const int team = team_size(static_cast<long long>(entries));
  // counts[t * nodes + I]: entries of node I in thread t's particle chunk;
  // turned into that chunk's first slot in column I.
  std::vector<int>& counts = columns.scratch;
  counts.assign(static_cast<std::size_t>(team) * static_cast<std::size_t>(nodes), 0);
  auto chunk_of = [&](int t, int& begin, int& end) {
    begin = static_cast<int>(static_cast<long long>(rows) * t / team);
    end = static_cast<int>(static_cast<long long>(rows) * (t + 1) / team);
  };
  parallel_chunks(team, team, [&](long long t0, long long t1) {
    for (int t = static_cast<int>(t0); t < t1; ++t) {
      int b, e;
      chunk_of(t, b, e);
      int* c = &counts[static_cast<std::size_t>(t) * static_cast<std::size_t>(nodes)];
      for (int a = first(b); a < first(e); ++a) ++c[node_of(a)];
    }
  });
  columns.offset.assign(static_cast<std::size_t>(nodes) + 1, 0);
  int slot = 0;
  for (int I = 0; I < nodes; ++I) {
    columns.offset[static_cast<std::size_t>(I)] = slot;
    for (int t = 0; t < team; ++t) {
      int& c = counts[static_cast<std::size_t>(t) * static_cast<std::size_t>(nodes) + static_cast<std::size_t>(I)];
      const int k = c;
      c = slot;
      slot += k;
    }
  }
  columns.offset[static_cast<std::size_t>(nodes)] = slot;
  columns.entry.resize(entries);
  columns.particle.resize(entries);
  parallel_chunks(team, team, [&](long long t0, long long t1) {
    for (int t = static_cast<int>(t0); t < t1; ++t) {
      int b, e;
      chunk_of(t, b, e);
      int* c = &counts[static_cast<std::size_t>(t) * static_cast<std::size_t>(nodes)];
      for (int p = b; p < e; ++p)
        for (int a = first(p); a < first(p + 1); ++a) {
          const int s = c[node_of(a)]++;
          columns.entry[static_cast<std::size_t>(s)] = a;
          columns.particle[static_cast<std::size_t>(s)] = p;
        }
    }
  });
}

} // namespace

template <int D> void transpose_basis_table(const BasisTable<D>& table, int nodes, NodeColumns& columns) {
  const int* node = table.node.data();
  transpose_rows(
      table.rows(), table.entries(), nodes, [&](int p) { return table.offset[static_cast<std::size_t>(p)]; },
      [node](int e) { return node[e]; }, columns);
}

template <int D> void transpose_basis_table(const LatticeRows<D>& rows, int nodes, NodeColumns& columns) {
  constexpr int S = LatticeRows<D>::kCorners;
  transpose_rows(
      rows.rows(), static_cast<std::size_t>(rows.rows()) * S, nodes, [](int p) { return p * S; },
      [&rows](int e) { return rows.node(e); }, columns);
}

template <int D> void expand_lattice_rows(const LatticeRows<D>& rows, BasisTable<D>& table) {
  constexpr int S = LatticeRows<D>::kCorners;
  const int n = rows.rows();
  table.offset.resize(static_cast<std::size_t>(n) + 1);
  table.node.resize(static_cast<std::size_t>(n) * S);
  table.N.resize(static_cast<std::size_t>(n) * S);
  table.dN.resize(static_cast<std::size_t>(n) * S);
  parallel_for(n, [&](long long p) {
    auto e = static_cast<std::size_t>(p) * S;
    table.offset[static_cast<std::size_t>(p)] = static_cast<int>(e);
    rows.visit_row(static_cast<int>(p), [&](int I, double N, const Vec<D>& dN) {
      table.node[e] = I, table.N[e] = N, table.dN[e] = dN;
      ++e;
    });
  });
  table.offset.back() = n * S;
}

template <int D> void transpose_basis_table(const ProductRows<D>& rows, int nodes, NodeColumns& columns) {
  // every entry's node once, read twice by the transposition
  std::vector<int> node(static_cast<std::size_t>(rows.offset.back()));
  parallel_for(rows.rows(), [&](long long p) {
    auto e = static_cast<std::size_t>(rows.offset[static_cast<std::size_t>(p)]);
    rows.visit_nodes(static_cast<int>(p), [&](int I) { node[e++] = I; });
  });
  transpose_rows(
      rows.rows(), node.size(), nodes, [&rows](int p) { return rows.offset[static_cast<std::size_t>(p)]; },
      [&node](int e) { return node[static_cast<std::size_t>(e)]; }, columns);
}

template <int D> bool ProductRows<D>::count_entries() {
  const long long n = rows();
  std::vector<long long> start(static_cast<std::size_t>(reduction_blocks(n)) + 1, 0);
  parallel_blocks(n, [&](long long b, long long p0, long long p1) { // the block's own prefix sums
    long long sum = 0;
    for (long long p = p0; p < p1; ++p) {
      int entries = 1;
      for (const int mk : m[static_cast<std::size_t>(p)]) entries *= mk;
      sum += entries;
      offset[static_cast<std::size_t>(p) + 1] = static_cast<int>(sum);
    }
    start[static_cast<std::size_t>(b) + 1] = sum;
  });
  for (std::size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
  if (start.back() > std::numeric_limits<int>::max()) return false;
  parallel_blocks(n, [&](long long b, long long p0, long long p1) {
    const auto s = static_cast<int>(start[static_cast<std::size_t>(b)]);
    for (long long p = p0; p < p1; ++p) offset[static_cast<std::size_t>(p) + 1] += s;
  });
  offset[0] = 0;
  return true;
}

template <int D> void expand_product_rows(const ProductRows<D>& rows, BasisTable<D>& table) {
  const int n = rows.rows();
  const auto entries = static_cast<std::size_t>(rows.offset.back());
  table.offset.assign(rows.offset.begin(), rows.offset.end());
  table.node.resize(entries);
  table.N.resize(entries);
  table.dN.resize(entries);
  parallel_for(n, [&](long long p) {
    auto e = static_cast<std::size_t>(rows.offset[static_cast<std::size_t>(p)]);
    rows.visit_row(static_cast<int>(p), [&](int I, double N, const Vec<D>& dN) {
      table.node[e] = I, table.N[e] = N, table.dN[e] = dN;
      ++e;
    });
  });
}

#define OTMPM_INSTANTIATE_BASIS(D)                                                                           \
  template class Basis<D>;                                                                                   \
  template void fill_basis_table<D>(const Basis<D>&, const AlignedVector<Vec<D>>&, AlignedVector<Vec<D>>*,   \
                                    std::vector<Index<D>>*, BasisTable<D>&, NeighbourLists<D>*);             \
  template void fill_basis_table<D>(const Basis<D>&, const AlignedVector<Vec<D>>&, const PointArrays<D>&,    \
                                    BasisTable<D>&);                                                         \
  template void transpose_basis_table<D>(const BasisTable<D>&, int, NodeColumns&);                           \
  template void transpose_basis_table<D>(const LatticeRows<D>&, int, NodeColumns&);                          \
  template void expand_lattice_rows<D>(const LatticeRows<D>&, BasisTable<D>&);                               \
  template void transpose_basis_table<D>(const ProductRows<D>&, int, NodeColumns&);                          \
  template void expand_product_rows<D>(const ProductRows<D>&, BasisTable<D>&);                               \
  template struct ProductRows<D>;
OTMPM_INSTANTIATE_BASIS(1)
OTMPM_INSTANTIATE_BASIS(2)
OTMPM_INSTANTIATE_BASIS(3)
#undef OTMPM_INSTANTIATE_BASIS

} // namespace otmpm
