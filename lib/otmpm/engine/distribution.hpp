#pragma once
/// \file distribution.hpp
/// What the engine of one rank asks of a distributed run
/// (docs/architecture.md, "Distributed runs"). The engine of a serial run has
/// none; an MPI run gives each rank's engine the implementation in
/// distributed/domain.hpp. The engine then owns the particles of its cells
/// and computes on its window of the node lattice (owned nodes and a ghost
/// layer), and calls these hooks at the few places where ranks meet: nodal
/// sums, global reductions, agreeing on a failure, the consistent mass
/// solve, and particle migration before each step.
#include "otmpm/core.hpp"

#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace otmpm {

template <int D> class Engine;
template <int D> struct BasisTable;
template <int D> struct CartesianGrid;
template <int D> struct LatticePart;

/// A nodal array of the engine seen as `width` doubles per local node.
struct NodalArray {
  double* data = nullptr;
  int width = 1;
};

/// A failure on one rank that every rank must stop on: `key` orders
/// failures (the global particle id; kNoParticle + rank otherwise), the
/// lowest wins; `message` is the complete diagnosis; `instability` selects
/// InstabilityError (else InputError).
struct LocalFailure {
  static constexpr long long kNoParticle = 1LL << 62;
  long long key = kNoParticle;
  std::string message;
  bool instability = true;
  bool deferred = false; ///< a stage failure passed to defer(): thrown as DeferredInstability
  bool memory = false;   ///< an allocation that failed inside a stage: thrown as DeferredOutOfMemory
};

/// The InstabilityError of a stage failure that a rank deferred (defer()),
/// thrown on every rank by the reduction that found it - possibly the one
/// after the step, which the engine then takes back (as a serial run stops
/// inside the step).
class DeferredInstability : public InstabilityError {
public:
  using InstabilityError::InstabilityError;
};

/// Tests of a rank that runs out of memory (tests/test_mpi.cpp): true once,
/// at the first call for `site` at step `step` or later, when the variable
/// OTMPM_TEST_FAIL_ALLOCATION=SITE:STEP of this process names it ("STEP"
/// alone: the site "basis", a basis evaluation; "migration": particles
/// leaving for another rank; "output": a frame's rows). The caller then
/// throws std::bad_alloc, as a failed allocation there would. Unset (as
/// always outside those tests): never.
bool test_allocation_fails(std::string_view site, long step);

template <int D> class Distribution {
public:
  virtual ~Distribution() = default;
  /// Before every step: particles that left this rank's cells go to their
  /// owners (and the cells are rebalanced when needed).
  virtual void before_step(Engine<D>& e) = 0;
  /// Positions whose particles certainly stay on this rank at the next
  /// before_step(), or nullptr. The engine's after-step pass tests every
  /// particle against it and tells departures() whether any rank has one
  /// outside (in the after-step reduction): when none has, before_step()
  /// skips the migration pass and its reduction.
  virtual const PositionBox<D>* staying() const { return nullptr; }
  /// After the after-step reduction: whether any rank has a particle
  /// outside staying() (the same on every rank).
  virtual void departures(bool any) { (void)any; }
  /// Every rank has summed its particles into its local nodes: the owner of
  /// each node adds the partial sums of the other ranks, and every rank then
  /// holds the totals on all its local nodes (owned and ghost).
  virtual void sum_nodal(std::span<const NodalArray> fields) = 0;
  /// Global sums (ordered: the same bits on every rank) of `sums` and
  /// maxima of `maxima`, in one reduction. When a rank deferred a failure
  /// (defer), every rank throws it afterwards instead of returning.
  virtual void reduce(std::span<double> sums, std::span<double> maxima) = 0;
  void sum(std::span<double> values) { reduce(values, {}); }
  void max(std::span<double> values) { reduce({}, values); }
  void min(std::span<double> values) {
    for (double& v : values) v = -v;
    reduce({}, values);
    for (double& v : values) v = -v;
  }
  /// Notes a failure of this rank (the lowest key is kept) without meeting
  /// the other ranks: the rank goes on with the step, and every rank throws
  /// the failure with the lowest key at the next reduction - so none waits
  /// for a rank that stopped, and a step costs no extra reduction.
  virtual void defer(const LocalFailure& failure) = 0;
  /// Collective now: when any rank passes (or deferred) a failure, every
  /// rank throws the one with the lowest key (InstabilityError or InputError
  /// with its message).
  virtual void agree(const LocalFailure* failure) = 0;
  /// After each basis evaluation: throws ParticleFailure for a particle
  /// whose stencil reaches the outer edge of this rank's ghost layer (its
  /// support might go beyond the nodes this rank holds: `ul` mode, where
  /// particles keep their cell while the lattice moves).
  virtual void check_support(const BasisTable<D>& table) const = 0;
  /// `ul` node reset (NodeReset): the nodes are laid out anew on `grid` (the
  /// same on every rank), the boundary boxes where they are at time t. The
  /// ranks bisect the new lattice's cells afresh, weighted by the particles
  /// in each cell (of x), send every particle to the owner of its cell (its
  /// home cell until the next reset) and rebuild the nodal exchange; returns
  /// the basis and the Dirichlet entries on this rank's window of the new
  /// lattice. `restart`: the run restarts from a checkpoint written after
  /// the reset, whose lattice and division the ranks hold already: no
  /// particle moves. Collective.
  virtual LatticePart<D> lay_out(Engine<D>& e, const CartesianGrid<D>& grid, double t, bool restart) = 0;
  /// This process's rank.
  virtual int rank() const = 0;
  /// The global id of local particle p (its index in a serial run).
  virtual long long global_id(int p) const = 0;
  /// Per local node: 1 where this rank owns the node.
  virtual const std::vector<char>& owned_nodes() const = 0;
  /// y = M^{-1} r with the consistent mass M_IJ = sum_p N_Ip m_p N_Jp over
  /// all ranks, on the active nodes' free components (y = 0 on inactive
  /// nodes and constrained components, as MassMatrix::solve with y = 0);
  /// m_lumped: the nodal masses (the row sums of M) of every local node.
  virtual void solve_consistent_mass(const BasisTable<D>& table, const std::vector<double>& m_p,
                                     const std::vector<double>& m_lumped, const std::vector<char>& active,
                                     const std::vector<char>& constrained, const AlignedVector<Vec<D>>& r,
                                     AlignedVector<Vec<D>>& y) = 0;
  /// rho_Ik = sum_{J free} M_IJ y_Jk over all ranks on the constrained
  /// components (free: active and not constrained; rho = 0 elsewhere): the
  /// inertial reaction of the constrained rows of the consistent mass.
  virtual void constrained_rows_product(const BasisTable<D>& table, const std::vector<double>& m_p,
                                        const std::vector<char>& active, const std::vector<char>& constrained,
                                        const AlignedVector<Vec<D>>& y, AlignedVector<Vec<D>>& rho) = 0;
};

} // namespace otmpm
