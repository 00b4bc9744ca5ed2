#pragma once
/// \file domain.hpp
/// One rank's share of a distributed run (docs/architecture.md,
/// "Distributed runs"): the engine's Distribution. It knows the
/// decomposition, this rank's window of the point lattice and its exchange
/// lists, the global ids of its particles, and does what the engine asks:
/// nodal sums with the neighbours, ordered reductions, agreeing on a
/// failure, the consistent mass solve (conjugate gradients), and the
/// migration of particles that left this rank's cells before each step.
#include "otmpm/distributed/halo.hpp"
#include "otmpm/distributed/particle_rows.hpp"
#include "otmpm/engine/engine.hpp"

#include <chrono>
#include <functional>
#include <memory>
#include <optional>

namespace otmpm::distributed {

/// Counters of a distributed run (per rank), for docs/performance.md.
struct DomainStats {
  long long steps = 0;
  long long migrated = 0;      ///< particles sent to another rank
  long long rebalances = 0;    ///< times the cells were bisected afresh
  long long halo_bytes = 0;    ///< bytes this rank sent in nodal exchanges
  long long halo_exchanges = 0; ///< nodal exchanges (two rounds of messages with the neighbours each)
  long long reductions = 0;     ///< global reductions and failure agreements
  double communication_seconds = 0.0; ///< wall time in the exchanges, reductions and migration
  long long cg_iterations = 0; ///< consistent mass: CG iterations, all solves
  long long cg_solves = 0;
  double cg_worst_residual = 0.0; ///< largest final relative residual
  /// Particles this rank held at once during set-up: its own share (it
  /// seeds only the particles of its cells, local_parts.hpp).
  long long setup_particles = 0;
  /// Lattice points (nodes or control points) this rank built node sets on
  /// during set-up: its window, and the few points of the basis probe
  /// (local_parts.hpp); never the whole lattice.
  long long setup_points = 0;
};

/// Relative residual |r - M y|_2 / |r|_2 (per component, the recursive CG
/// residual) at which the consistent-mass CG stops; results then agree with
/// the direct solve of a serial run to about 1e-13 relative
/// (tests/test_mpi.cpp; OTM runs: docs/user-guide.md, "Distributed runs").
inline constexpr double kMassTolerance = 1e-15;
/// CG iterations after which the consistent-mass solve gives up (InstabilityError).
inline constexpr int kMassMaxIterations = 1000;
/// A CG whose relative residual is below kMassStall and has not halved for
/// kMassStallIterations iterations has reached round-off: it stops there.
inline constexpr double kMassStall = 1e-13;
inline constexpr int kMassStallIterations = 20;
/// Rebalancing (`mpm` mode): every kRebalanceCheck steps the ranks compare
/// their loads (particles + kEmptyCellWeight per cell); when the largest is
/// more than kImbalanceThreshold times the mean, the cells are bisected
/// afresh from the particles' current cells. (`ul` mode never needs it: the
/// particles keep their cells while the lattice moves.)
inline constexpr int kRebalanceCheck = 10;
inline constexpr double kImbalanceThreshold = 1.2;

template <int D> class Domain final : public Distribution<D> {
public:
  /// What a rank's share is made of (local_parts.hpp builds it).
  struct Setup {
    PointLattice<D> lattice;
    Decomposition<D> decomposition;
    bool nodes_move = false;            ///< `ul`: particles keep the cell of X; no migration
    std::vector<long long> global_ids;  ///< of the local particles, ascending
    long long global_particles = 0;
    Index<D> hint_offset{};             ///< global cell index of the basis' local cell 0
    /// Per traction load, per local particle: its share of the loaded area, < 0: not loaded.
    std::vector<std::vector<double>> traction_area;
    /// The basis on a window (rebalancing), and the global offset of its cell hints.
    std::function<std::unique_ptr<Basis<D>>(const Window<D>&, Index<D>& hint_offset)> window_basis;
    /// The Dirichlet entries on a window with the basis built on it
    /// (rebalancing): found on the window's points from the scene's boxes.
    std::function<Dirichlet<D>(const Window<D>&, const Basis<D>&)> window_dirichlet;
    /// `ul` node reset (lay_out): the point lattice of a new node lattice,
    /// and the basis and Dirichlet entries on the window of the rank that
    /// owns `cells`, with the boundary boxes at time t (and the global cell
    /// of the basis' local cell 0). Collective.
    std::function<PointLattice<D>(const CartesianGrid<D>&)> reset_lattice;
    std::function<LatticePart<D>(const PointLattice<D>&, const IndexBox<D>& cells, const Window<D>&, double t,
                                 Index<D>& hint_offset)>
        reset_window;
    /// Particles this rank held at once during set-up (DomainStats::setup_particles).
    long long setup_particles = 0;
    /// Lattice points this rank built node sets on during set-up (DomainStats::setup_points).
    long long setup_points = 0;
    /// Steps the run has made (a restart: its checkpoint's; the rebalancing's cadence).
    long long steps = 0;
  };

  Domain(const Comm& comm, Setup setup);

  // ---- Distribution
  void before_step(Engine<D>& e) override;
  const PositionBox<D>* staying() const override { return nodes_move_ ? nullptr : &staying_; }
  void departures(bool any) override { departures_ = any; }
  void sum_nodal(std::span<const NodalArray> fields) override {
    const Clock clock(stats_);
    ++stats_.halo_exchanges;
    stats_.halo_bytes += exchange_.sum(comm_, fields);
  }
  void reduce(std::span<double> sums, std::span<double> maxima) override;
  void defer(const LocalFailure& failure) override;
  void agree(const LocalFailure* failure) override;
  void check_support(const BasisTable<D>& table) const override;
  LatticePart<D> lay_out(Engine<D>& e, const CartesianGrid<D>& grid, double t, bool restart) override;
  int rank() const override { return comm_.rank(); }
  long long global_id(int p) const override { return gid_[static_cast<std::size_t>(p)]; }
  const std::vector<char>& owned_nodes() const override { return exchange_.owned(); }
  void constrained_rows_product(const BasisTable<D>& table, const std::vector<double>& m_p,
                                const std::vector<char>& active, const std::vector<char>& constrained,
                                const AlignedVector<Vec<D>>& y, AlignedVector<Vec<D>>& rho) override;
  void solve_consistent_mass(const BasisTable<D>& table, const std::vector<double>& m_p,
                             const std::vector<double>& m_lumped, const std::vector<char>& active,
                             const std::vector<char>& constrained, const AlignedVector<Vec<D>>& r,
                             AlignedVector<Vec<D>>& y) override;

  const Comm& comm() const { return comm_; }
  const std::vector<long long>& global_ids() const { return gid_; }
  long long global_particles() const { return global_particles_; }
  const PointLattice<D>& lattice() const { return lattice_; }
  const Decomposition<D>& decomposition() const { return decomposition_; }
  const NodeExchange<D>& exchange() const { return exchange_; }
  const DomainStats& stats() const { return stats_; }
  /// Global cell index of the basis' local cell 0 (cell hints are local to it).
  const Index<D>& hint_offset() const { return hint_offset_; }
  /// The home cell of a particle at x with initial position X: the cell of
  /// x on the fixed grid (`mpm`), of X on the initial lattice (`ul`; after a
  /// node reset the cell of x at the reset, which lay_out gave it).
  Index<D> home_cell(const Vec<D>& x, const Vec<D>& X) const {
    return lattice_.grid.cell_of(nodes_move_ ? X : x);
  }

private:
  /// Adds the wall time of its lifetime to the communication time.
  struct Clock {
    explicit Clock(DomainStats& s) : stats(s), start(std::chrono::steady_clock::now()) {}
    ~Clock() { stats.communication_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); }
    DomainStats& stats;
    std::chrono::steady_clock::time_point start;
  };
  /// Sends the particles whose home cell another rank owns to that rank
  /// (`home`: the home cells of the particles, when not home_cell()'s).
  void migrate(Engine<D>& e, const std::vector<Index<D>>* home = nullptr);
  /// The columns that move with the particles (particle_rows.hpp plus the global ids and traction shares).
  std::vector<Column> columns(Engine<D>& e);
  /// Rebuilds the traction loads' particle lists from the shares.
  void rebuild_tractions(Engine<D>& e) const;
  /// Bisects the cells afresh when the loads drifted apart (kImbalanceThreshold).
  void rebalance(Engine<D>& e);
  /// The ranks whose cells touch this rank's cells.
  void find_neighbours();
  /// Adds `sign` times the hint offset to the basis' cell hints.
  void shift_hints(Engine<D>& e, int sign) const;

  const Comm& comm_;
  PointLattice<D> lattice_;
  Decomposition<D> decomposition_;
  NodeExchange<D> exchange_;
  bool nodes_move_ = false;
  std::vector<long long> gid_;
  long long global_particles_ = 0;
  Index<D> hint_offset_{};
  std::vector<std::vector<double>> traction_area_;
  std::vector<int> neighbours_; ///< ranks whose cells touch this rank's cells (migration)
  std::optional<LocalFailure> pending_; ///< deferred failure of this rank (the lowest key)
  std::vector<char> guard_;            ///< per local point: in the guard layer (PointLattice::guard)
  PositionBox<D> staying_{};           ///< interior_box() of this rank's cells (mpm mode)
  /// Whether migrate() must look at the particles: false only when the last
  /// after-step reduction found none outside staying_ on any rank.
  bool departures_ = true;
  /// Marks the guard layer of the current window.
  void find_guard();
  std::function<std::unique_ptr<Basis<D>>(const Window<D>&, Index<D>&)> window_basis_;
  std::function<Dirichlet<D>(const Window<D>&, const Basis<D>&)> window_dirichlet_;
  std::function<PointLattice<D>(const CartesianGrid<D>&)> reset_lattice_;
  std::function<LatticePart<D>(const PointLattice<D>&, const IndexBox<D>&, const Window<D>&, double,
                               Index<D>&)>
      reset_window_;
  DomainStats stats_;
};

extern template class Domain<1>;
extern template class Domain<2>;
extern template class Domain<3>;

} // namespace otmpm::distributed
