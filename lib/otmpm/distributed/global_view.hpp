#pragma once
/// \file global_view.hpp
/// What a run's recorder needs of the particles of all ranks: the probe
/// particles by global id, one particle's values on every rank, particle
/// fields in global order for the result file, global sums, and
/// checkpoints written by all ranks together (each rank its own rows, with
/// their global ids and the decomposition, so that a restart may use any
/// number of ranks). For a serial engine every operation is the plain
/// serial one.
#include "otmpm/distributed/local_parts.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/state.hpp"

#include <functional>

namespace otmpm::distributed {

template <int D> class GlobalView {
public:
  explicit GlobalView(const Engine<D>& e) : e_(e), d_(domain_of(e)) {}

  /// True on the rank that writes files (rank 0; the only rank of a serial run).
  bool writes() const { return !d_ || d_->comm().root(); }
  /// True for the engine of one rank of several.
  bool distributed() const { return d_ != nullptr; }
  /// Runs `write` on the writing rank; when it throws, every rank throws
  /// the same (InputError, InstabilityError, else std::runtime_error) with
  /// its message (collective in a distributed run).
  void on_writer(const std::function<void()>& write) const;
  /// Runs `write` on every rank (the calls of a parallel result file); when
  /// it throws on any rank, every rank throws what the lowest such rank threw
  /// (agree_on).
  void collectively(const std::function<void()>& write) const;
  /// How the ranks write one result file together (a serial file: none).
  ParallelIo parallel_io() const;
  /// Before the ranks write the file `path` together (collectively): that
  /// every rank resolves it to the same absolute path (require_same: a
  /// relative path in working directories that differ per node is refused)
  /// and reaches the same directory with write access - the writing rank
  /// creates a file of a random name and content beside it, every rank
  /// opens it for writing and reads its content back (a directory that is
  /// local to each node, or mounted read-only on one, is refused).
  /// InputError on every rank naming the lowest rank that fails. Where the
  /// writing rank itself cannot create a file, nothing more is checked here
  /// (the claim of the output files says why). Nothing to check in a serial run.
  void require_shared_file(const std::string& path) const;
  /// That every rank can read the file `path` (before the ranks read it and
  /// write what they read collectively): InputError on every rank naming
  /// the lowest rank that cannot.
  void require_readable(const std::string& path, const std::string& what) const;
  /// The writing rank's `text` on every rank.
  std::string share(const std::string& text) const { return d_ ? d_->comm().broadcast(text, 0) : text; }
  /// Facts of a distributed run for the result file's root attributes
  /// (collective; none for a serial run): ranks, particles sent to another
  /// rank, bytes of the nodal exchanges, consistent-mass CG iterations and
  /// solves, all summed over the ranks.
  std::vector<std::pair<std::string, double>> run_attributes() const;
  /// The largest `value` of all ranks.
  double max(double value) const { return d_ ? d_->comm().max(value) : value; }
  /// Particles of all ranks.
  long long particles() const { return d_ ? d_->global_particles() : e_.particles().size(); }
  /// Nodes (lattice points) of all ranks.
  long long nodes() const;
  /// The global id of the particle a probe follows: the smallest `score`
  /// (ties: the lowest id), as a serial loop keeping the first best would.
  long long best(const std::function<double(int)>& score) const;
  /// The values of global particle g, on every rank.
  struct Row {
    Vec<D> x, X, v;
    Mat<D> sigma;
  };
  Row row(long long g) const;
  /// This rank's block of a frame in global order: rows [first, first +
  /// count) of all particles' `cols` values (the ranks' blocks tile the
  /// frame; a serial run's block is the whole frame).
  struct Block {
    std::vector<double> values;
    long long first = 0, count = 0;
  };
  Block block(const double* local, int cols) const;
  /// sqrt(sum of all ranks' squared errors / particles) (rms_error in a serial run).
  double rms(const std::vector<double>& squared) const;
  /// Writes the checkpoint `local` of this rank (Engine::save_state and the
  /// recorder's groups) to `path` (io/checkpoint.hpp): in a distributed run
  /// all ranks write one file together, each its particles' rows (with
  /// their global ids, cell hints global) after the lower ranks' and its own
  /// lattice points' rows, the root its scalars and the decomposition
  /// (collective; an error on any rank is thrown on every rank).
  void write_checkpoint(const std::string& path, Checkpoint local) const;

private:
  const Engine<D>& e_;
  const Domain<D>* d_;
};

/// How the ranks of `comm` write and read one file together (a serial
/// file for one rank).
ParallelIo parallel_io(const Comm& comm);

/// What the engine of this rank restores from checkpoint `ck`: `rows`, its
/// particles' rows (restart_parts), with its window's lattice points' rows
/// and its cell hints made local (collective); a serial engine: every row
/// of `ck`, in the order of the global ids.
template <int D> Checkpoint local_checkpoint(const Engine<D>& e, const Checkpoint& ck, Checkpoint rows);

extern template class GlobalView<1>;
extern template class GlobalView<2>;
extern template class GlobalView<3>;

} // namespace otmpm::distributed
