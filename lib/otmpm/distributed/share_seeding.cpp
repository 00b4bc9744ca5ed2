/// \file share_seeding.cpp
/// A rank's particles, seeded once in its own cells (share_seeding.hpp).
#include "otmpm/distributed/share_seeding.hpp"

#include "otmpm/interrupt.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace otmpm::distributed {

namespace {

/// Particles of a body seeded as a whole that a rank counts in runs of this
/// many (rank r the runs r, r + N, ...): each rank's list of (cell, count)
/// stays short, as particles of one cell come together.
constexpr long long kCountRun = 4096;

constexpr long long kNone = std::numeric_limits<long long>::max();

/// The particles placed in each seeding cell of a body seeded cell by cell,
/// as runs of consecutive cells with one count, and the global id of each
/// run's first particle (after number()).
struct CellRuns {
  struct Run {
    long long first = 0, cells = 0, per_cell = 0, id = 0;
  };
  std::vector<Run> runs;

  /// Appends `cells` cells from `first` of `per_cell` particles each.
  void add(long long first, long long cells, long long per_cell) {
    if (cells <= 0) return;
    if (!runs.empty() && runs.back().per_cell == per_cell && runs.back().first + runs.back().cells == first)
      runs.back().cells += cells;
    else runs.push_back({first, cells, per_cell, 0});
  }
  /// Numbers the runs from global id `id`; returns the id after the last particle.
  long long number(long long id) {
    for (Run& r : runs) r.id = id, id += r.cells * r.per_cell;
    return id;
  }
  /// The global id of the first particle of seeding cell `cell`.
  long long id(long long cell) const {
    const auto it = std::upper_bound(runs.begin(), runs.end(), cell, [](long long c, const Run& r) { return c < r.first; });
    const Run& r = *(it - 1);
    return r.id + (cell - r.first) * r.per_cell;
  }
};

/// Counts the particles per seeding cell of a rank's range [from, to) of a
/// body's cells, which a pass visits in order (cells without a particle
/// are never visited: the gaps count 0).
class RangeCounter {
public:
  RangeCounter(CellRuns& runs, long long from) : runs_(runs), cell_(from) {}
  void placed(long long cell) {
    if (cell != cell_) {
      runs_.add(cell_, 1, count_);
      runs_.add(cell_ + 1, cell - cell_ - 1, 0);
      cell_ = cell, count_ = 0;
    }
    ++count_;
  }
  /// Cells [first, first + cells) of per_cell particles each, counted at
  /// once (a CellRun), after the cells before them.
  void placed_run(long long first, long long cells, long long per_cell) {
    if (first != cell_) runs_.add(cell_, 1, count_), runs_.add(cell_ + 1, first - cell_ - 1, 0);
    runs_.add(first, cells, per_cell);
    cell_ = first + cells, count_ = 0;
  }
  void finish(long long to) {
    if (cell_ >= to) return;
    runs_.add(cell_, 1, count_);
    runs_.add(cell_ + 1, to - cell_ - 1, 0);
  }

private:
  CellRuns& runs_;
  long long cell_, count_ = 0;
};

/// The particles of a rank's counting pass per home cell (the lattice cell
/// of their position), as runs along axis 0 of cells with one count each:
/// the weights of the bisection (Decomposition::rcb with lengths).
template <int D> class HomeRuns {
public:
  std::vector<Index<D>> home;
  std::vector<std::int64_t> weight;
  std::vector<int> length;

  /// A particle whose home cell is c.
  void add(const Index<D>& c) {
    if (!home.empty() && home.back() == c && length.back() == 1) ++weight.back();
    else home.push_back(c), weight.push_back(1), length.push_back(1);
  }
  /// The particles of a CellRun: their home cells counted per axis (the
  /// index of a home cell along axis k depends on coordinate k only,
  /// CartesianGrid::cell_index), multiplied over the axes.
  void add(const CellRun<D>& run, const CartesianGrid<D>& lattice) {
    std::array<std::vector<std::pair<int, long long>>, D> per_axis; // per axis: (cell index, particles), increasing
    for (int k = 1; k < D; ++k) per_axis[k] = axis_counts(*run.box, lattice, k, run.c[k], run.c[k] + 1);
    const auto& along = line_runs(run, lattice);
    Index<D> c{}, at{};
    while (true) {
      long long factor = 1;
      for (int k = 1; k < D; ++k) {
        const auto& [index, count] = per_axis[k][static_cast<std::size_t>(at[k])];
        c[k] = index, factor *= count;
      }
      for (const auto& [first, cells, count] : along) {
        c[0] = static_cast<int>(first);
        home.push_back(c), weight.push_back(count * factor), length.push_back(static_cast<int>(cells));
      }
      int k = 1;
      while (k < D && ++at[k] == static_cast<int>(per_axis[k].size())) at[k++] = 0;
      if (k >= D) return;
    }
  }

private:
  /// The particles of cells [c0, c1) along axis k per home cell index along
  /// k: (index, particles), indices increasing (BoxCells::coordinate grows).
  static std::vector<std::pair<int, long long>> axis_counts(const BoxCells<D>& box, const CartesianGrid<D>& lattice,
                                                            int k, int c0, int c1) {
    std::vector<std::pair<int, long long>> out;
    for (int c = c0; c < c1; ++c)
      for (int q = 0; q < box.per_axis(); ++q) {
        const int i = lattice.cell_index(k, box.coordinate(k, c, q));
        if (!out.empty() && out.back().first == i) ++out.back().second;
        else out.emplace_back(i, 1);
      }
    return out;
  }
  /// axis_counts along axis 0 of the run as runs of consecutive cells of
  /// one count: (first cell, cells, count); the last run's are kept, as
  /// runs of whole lines repeat.
  const std::vector<std::array<long long, 3>>& line_runs(const CellRun<D>& run, const CartesianGrid<D>& lattice) {
    if (run.body == last_body_ && run.c[0] == last_from_ && run.cells == last_cells_) return last_;
    last_body_ = run.body, last_from_ = run.c[0], last_cells_ = run.cells;
    last_.clear();
    for (const auto& [i, n] : axis_counts(*run.box, lattice, 0, run.c[0], run.c[0] + static_cast<int>(run.cells))) {
      auto& r = last_;
      if (!r.empty() && r.back()[0] + r.back()[1] == i && r.back()[2] == n) ++r.back()[1];
      else r.push_back({i, 1, n});
    }
    return last_;
  }
  int last_body_ = -1;
  long long last_from_ = -1, last_cells_ = 0;
  std::vector<std::array<long long, 3>> last_;
};

/// Where the first error of a pass happened, in the serial seeding order:
/// (unit, index), a unit being a seeding cell of a body seeded by cells or
/// a whole body otherwise.
struct ErrorAt {
  long long unit = kNone, index = kNone;
  std::exception_ptr error;
  bool operator<(const ErrorAt& o) const { return unit < o.unit || (unit == o.unit && index < o.index); }
};

/// Every rank throws the first of the ranks' errors (InputError), if any:
/// the rank that met it its own exception, the others its message.
void agree_on_first(const Comm& comm, const ErrorAt& mine) {
  const long long unit = comm.min(static_cast<std::int64_t>(mine.unit));
  if (unit == kNone) return;
  const long long index = comm.min(static_cast<std::int64_t>(mine.unit == unit ? mine.index : kNone));
  const bool first = mine.unit == unit && mine.index == index && mine.error;
  const int winner = static_cast<int>(comm.min(static_cast<std::int64_t>(first ? comm.rank() : comm.size())));
  std::string message;
  if (comm.rank() == winner) try {
      std::rethrow_exception(mine.error);
    } catch (const std::exception& e) {
      message = e.what();
    }
  message = comm.broadcast(message, winner);
  if (comm.rank() == winner) std::rethrow_exception(mine.error);
  throw InputError(message);
}

/// The bodies' seeding cells, their ranks' ranges and the particles' ids.
template <int D> struct Plan {
  std::vector<BodyCells<D>> cells;
  std::vector<long long> unit;          ///< per body: its first unit (ErrorAt)
  std::vector<long long> first, last;   ///< per body seeded by cells: this rank's range of its cells
  std::vector<CellRuns> runs;           ///< per body seeded by cells: the particles per cell
  std::vector<long long> offset, whole; ///< per body: the id of its first particle; seeded whole: its particles
  std::vector<double> volume_factor;    ///< per body: body_volume_factor of all ranks' particles
  long long particles = 0;

  Plan(const Scene& scene, const Comm& comm, const Vec<D>& h, const CartesianGrid<D>& lattice) {
    agree_on(comm, [&] { cells = body_cells<D>(scene, h, lattice); }); // an STL file one rank cannot read
    const std::size_t B = cells.size();
    unit.resize(B), first.resize(B), last.resize(B), runs.resize(B), offset.resize(B), whole.resize(B);
    long long all = 0, units = 0; // the cells of the bodies seeded by cells, one sequence
    for (std::size_t b = 0; b < B; ++b) {
      unit[b] = units;
      units += cells[b].count();
      all += cells[b].by_cells ? cells[b].count() : 0;
    }
    const long long P = comm.size(), r = comm.rank(), from = all * r / P, to = all * (r + 1) / P;
    for (std::size_t b = 0, at = 0; b < B; ++b) {
      if (!cells[b].by_cells) continue;
      const long long n = cells[b].count();
      first[b] = std::clamp(from - static_cast<long long>(at), 0LL, n);
      last[b] = std::clamp(to - static_cast<long long>(at), 0LL, n);
      at += static_cast<std::size_t>(n);
    }
  }

  /// This rank's range of body b's cells (counting, surfaces).
  CellRange<D> range(int b) const {
    CellRange<D> r;
    r.hi = cells[static_cast<std::size_t>(b)].cells;
    r.from = first[static_cast<std::size_t>(b)], r.to = last[static_cast<std::size_t>(b)];
    return r;
  }
  /// The global id of a placed particle (after number()).
  long long id(const SeedSpot& s) const {
    const std::size_t b = static_cast<std::size_t>(s.body);
    return cells[b].by_cells ? runs[b].id(s.cell) + s.index : offset[b] + s.index;
  }
  /// The error of a spot: its unit and index (ErrorAt).
  ErrorAt at(const SeedSpot& s, std::exception_ptr e) const {
    return {unit[static_cast<std::size_t>(s.body)] + s.cell, s.index, std::move(e)};
  }

  /// Shares the ranks' runs, then numbers every body's particles in seeding order.
  void number(const Comm& comm) {
    Bytes mine;
    for (std::size_t b = 0; b < runs.size(); ++b)
      for (const CellRuns::Run& r : runs[b].runs) {
        const std::int64_t v[4] = {static_cast<std::int64_t>(b), r.first, r.cells, r.per_cell};
        put_bytes(mine, v, sizeof v);
      }
    for (CellRuns& r : runs) r.runs.clear();
    for (const Bytes& in : comm.allgather(mine)) // rank order: each body's ranges in turn
      for (Reader rd(in); !rd.done();) {
        std::int64_t v[4];
        rd.get_bytes(v, sizeof v);
        runs[static_cast<std::size_t>(v[0])].add(v[1], v[2], v[3]);
      }
    long long id = 0;
    for (std::size_t b = 0; b < runs.size(); ++b) {
      offset[b] = id;
      id = cells[b].by_cells ? runs[b].number(id) : id + whole[b];
    }
    particles = id;
  }
};

/// The counting pass (share_seeding.hpp, 1.): this rank's range of the
/// seeding cells, counted per cell (plan.runs) and per home cell (`homes`);
/// 1/N of the rows of each body seeded whole. With `by_runs`, the runs of
/// cells whose particles are all placed, none behind a wall, are counted
/// without generating them (TakeRun: the same counts). The first error
/// of the ranks, and a body without particles, is thrown on every rank.
template <int D>
void count(const Scene& scene, const Comm& comm, const Vec<D>& h, const CartesianGrid<D>& lattice, Plan<D>& plan,
           HomeRuns<D>& homes, bool by_runs) {
  std::vector<std::unique_ptr<RangeCounter>> counters(plan.cells.size());
  for (std::size_t b = 0; b < counters.size(); ++b)
    if (plan.cells[b].by_cells) counters[b] = std::make_unique<RangeCounter>(plan.runs[b], plan.first[b]);
  WallSides<D> sides(scene, h);
  auto place = [&](const SeedSpot& s, const Vec<D>& x) {
    const std::size_t b = static_cast<std::size_t>(s.body);
    if (counters[b]) counters[b]->placed(s.cell);
    else if ((s.index / kCountRun) % comm.size() != comm.rank()) return -1LL;
    sides.visit(x, s.body, seeding_order(s));
    homes.add(lattice.cell_of(x));
    return -1LL;
  };
  TakeRun<D> take;
  if (by_runs)
    take = [&](const CellRun<D>& run) {
      if (!sides.clear(run.lower, run.upper)) return false;
      counters[static_cast<std::size_t>(run.body)]->placed_run(run.first, run.cells, run.per_cell);
      homes.add(run, lattice);
      return true;
    };
  SeedSpot at;
  ErrorAt error;
  std::vector<BodyTally> tally;
  std::exception_ptr interrupted;
  try {
    tally = seed_cells_where<D>(scene, h, lattice, [&plan](int b) { return plan.range(b); }, place, nullptr, &at,
                                nullptr, take);
  } catch (const InputError&) {
    error = plan.at(at, std::current_exception());
  } catch (const InterruptedError&) { // a signal here or a peer's notice (interrupt_peers): every rank stops
    interrupted = std::current_exception();
  }
  agree_on(comm, [&] {
    if (interrupted) std::rethrow_exception(interrupted);
  });
  tally.resize(plan.cells.size());
  std::vector<std::int64_t> generated(tally.size());
  for (std::size_t b = 0; b < tally.size(); ++b) {
    generated[b] = plan.cells[b].by_cells ? tally[b].generated : 0;
    plan.whole[b] = tally[b].placed;
    if (counters[b]) counters[b]->finish(plan.last[b]);
  }
  comm.sum(generated);
  for (std::size_t b = 0; b < tally.size(); ++b) // a body of cells split over the ranks that holds no particle
    if (plan.cells[b].by_cells && generated[b] == 0) try {
        no_particle(scene.bodies[b]);
      } catch (const InputError&) {
        error = std::min(error, ErrorAt{plan.unit[b] + plan.cells[b].count() - 1, kNone, std::current_exception()});
      }
  agree_on_first(comm, error);
  std::vector<double> seeded(tally.size()); // of a body seeded by cells: each rank's share; else every rank's whole
  for (std::size_t b = 0; b < tally.size(); ++b) seeded[b] = plan.cells[b].by_cells ? tally[b].seeded : 0.0;
  comm.sum(seeded);
  plan.volume_factor.resize(tally.size());
  for (std::size_t b = 0; b < tally.size(); ++b)
    plan.volume_factor[b] =
        body_volume_factor<D>(scene.bodies[b], plan.cells[b].by_cells ? seeded[b] : tally[b].seeded);
  const std::string packed = sides.pack(); // the particles behind walls, of all ranks
  WallSides<D> all(scene, h);
  for (const Bytes& in : comm.allgather(Bytes(packed.begin(), packed.end()))) all.merge(std::string(in.begin(), in.end()));
  all.refuse();
  for (std::size_t b = 0; b < tally.size(); ++b)
    if (!plan.cells[b].by_cells &&
        comm.min(static_cast<std::int64_t>(plan.whole[b])) != comm.max(static_cast<std::int64_t>(plan.whole[b])))
      throw InputError("the ranks counted different numbers of particles in body '" + scene.bodies[b].name +
                       "': a particle file read differently by the ranks (rewritten while they read it, or not the "
                       "same on every node)");
}

/// The traction loads' surface particles (share_seeding.hpp, 2.): each rank
/// visits its range, then the ranks merge their columns.
template <int D>
std::shared_ptr<TractionSurfaces<D>> surfaces(const Scene& scene, const Comm& comm, const Vec<D>& h,
                                              const CartesianGrid<D>& lattice, const Plan<D>& plan) {
  const double tol = kBoxTolerance * lattice.h().minCoeff();
  TractionSurfaces<D> mine(scene, tol);
  agree_on(comm, [&] {
    seed_cells_where<D>(
        scene, h, lattice, [&plan](int b) { return plan.range(b); },
        [&](const SeedSpot& s, const Vec<D>& x) {
          if (plan.cells[static_cast<std::size_t>(s.body)].by_cells || (s.index / kCountRun) % comm.size() == comm.rank())
            mine.visit(plan.id(s), x);
          return -1LL;
        },
        nullptr);
  });
  const std::string packed = mine.pack();
  auto all = std::make_shared<TractionSurfaces<D>>(scene, tol);
  for (const Bytes& in : comm.allgather(Bytes(packed.begin(), packed.end()))) all->merge(std::string(in.begin(), in.end()));
  all->finish();
  return all;
}

/// The seeding cells of body b that may hold particles whose home cell
/// lies in `cells` (the cells' box in positions; unbounded at the lattice's
/// edges, where cell_of() clamps).
template <int D>
CellRange<D> near(const BodyCells<D>& body, const CartesianGrid<D>& lattice, const IndexBox<D>& cells) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  Vec<D> lo, hi;
  const Vec<D> h = lattice.h();
  for (int k = 0; k < D; ++k) {
    lo[k] = cells.lo[k] <= 0 ? -inf : lattice.lower[k] + cells.lo[k] * h[k];
    hi[k] = cells.hi[k] >= lattice.cells[k] ? inf : lattice.lower[k] + cells.hi[k] * h[k];
  }
  CellRange<D> r;
  std::tie(r.lo, r.hi) = body.near(lo, hi);
  return r;
}

} // namespace

template <int D>
SeededBodies<D> share_seeding(const Scene& scene, const Comm& comm, const Vec<D>& h, const CartesianGrid<D>& lattice,
                              ShareSeeding<D>& out, const BeforeKeeping<D>& before_keeping, CountBy count_by) {
  Plan<D> plan(scene, comm, h, lattice);
  HomeRuns<D> homes;
  count<D>(scene, comm, h, lattice, plan, homes, count_by == CountBy::runs);
  plan.number(comm);
  out.particles = plan.particles;
  SeededBodies<D> mine;
  try {
    out.decomposition =
        Decomposition<D>::rcb(lattice.cells, comm.size(), homes.home, homes.weight, homes.length, comm, &out.per_rank);
  } catch (...) {
    out.deferred = std::current_exception();
    if (!scene.tractions.empty()) mine.surfaces = surfaces<D>(scene, comm, h, lattice, plan);
    return mine;
  }
  comm.sum(out.per_rank); // each rank's particles
  homes = {};
  const auto most = std::max_element(out.per_rank.begin(), out.per_rank.end());
  if (static_cast<double>(*most) > kMaxRankParticles)
    throw InputError("rank " + std::to_string(most - out.per_rank.begin()) + " of " + std::to_string(comm.size()) +
                     " would hold " + std::to_string(*most) + " particles; at most " +
                     format_number(kMaxRankParticles) + " per rank are allowed (run on more ranks)");
  if (before_keeping && !before_keeping(out)) return mine;
  if (!scene.tractions.empty()) mine.surfaces = surfaces<D>(scene, comm, h, lattice, plan);
  const IndexBox<D>& own = out.decomposition.box(comm.rank());
  agree_on(comm, [&] {
    seed_cells_where<D>(
        scene, h, lattice,
        [&](int b) { return near<D>(plan.cells[static_cast<std::size_t>(b)], lattice, own); },
        [&](const SeedSpot& s, const Vec<D>& x) {
          return out.decomposition.owner(lattice.cell_of(x)) == comm.rank() ? plan.id(s) : -1LL;
        },
        &mine, nullptr, &plan.volume_factor);
  });
  return mine;
}

#define OTMPM_INSTANTIATE(D)                                                                                   \
  template SeededBodies<D> share_seeding<D>(const Scene&, const Comm&, const Vec<D>&, const CartesianGrid<D>&, \
                                            ShareSeeding<D>&, const BeforeKeeping<D>&, CountBy);
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm::distributed
