#pragma once
/// \file comm.hpp
/// The ranks of a distributed run: a thin layer over MPI that the rest of
/// otmpm calls, the same code with or without MPI (docs/architecture.md,
/// "Distributed runs"). In a build without MPI, in a process that mpirun did
/// not start, or with one rank, Comm is that one rank and every operation is
/// trivial, so a serial run never depends on MPI.
///
/// Floating-point sums are ordered: the ranks' values are added along a fixed
/// binomial tree towards rank 0 (children in increasing rank order) and the
/// result is broadcast, so every rank holds the same bits and a run with the
/// same rank count gives the same bits again. Maxima, minima and integer
/// sums are exact in any order.
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace otmpm {
class InterruptPeers;
} // namespace otmpm

namespace otmpm::distributed {

/// Bytes of one message.
using Bytes = std::vector<char>;
/// Messages with their ranks: (destination or sender, bytes).
using Messages = std::vector<std::pair<int, Bytes>>;

class LocalRanks;

/// What allgather() returns: every rank's message in rank order, shared by
/// the ranks played in one process (Comm::run_local: one copy, not one per rank).
class Gathered {
public:
  explicit Gathered(std::shared_ptr<const std::vector<Bytes>> all) : all_(std::move(all)) {}
  auto begin() const { return all_->begin(); }
  auto end() const { return all_->end(); }
  std::size_t size() const { return all_->size(); }
  const Bytes& operator[](std::size_t q) const { return (*all_)[q]; }

private:
  std::shared_ptr<const std::vector<Bytes>> all_;
};

/// A group of ranks (all ranks of the program: world()).
class Comm {
public:
  /// All ranks of the program: MPI_COMM_WORLD when MPI was initialised by a
  /// Session, else one rank.
  static const Comm& world();
  /// One rank (a serial run inside a distributed program, tests).
  static const Comm& self();

  int rank() const { return rank_; }
  int size() const { return size_; }
  bool root() const { return rank_ == 0; }

  /// Ordered sum over the ranks of each entry (identical bits on every rank).
  void sum(std::span<double> values) const;
  /// Ordered sums of `sums` and maxima of `maxima` in one reduction.
  void reduce(std::span<double> sums, std::span<double> maxima) const;
  double sum(double value) const;
  /// Exact integer sums, maxima and minima of each entry over the ranks.
  void sum(std::span<std::int64_t> values) const;
  std::int64_t sum(std::int64_t value) const;
  void max(std::span<double> values) const;
  void min(std::span<double> values) const;
  double max(double value) const;
  double min(double value) const;
  std::int64_t min(std::int64_t value) const;
  std::int64_t max(std::int64_t value) const;
  /// Every rank's value, in rank order, on every rank.
  std::vector<std::int64_t> allgather(std::int64_t value) const;
  /// `text` of rank `from` on every rank.
  std::string broadcast(const std::string& text, int from) const;
  /// Broadcast of raw bytes from rank `from` (sizes must agree).
  void broadcast(void* data, std::size_t bytes, int from) const;
  /// Point-to-point exchange: send[i] goes to rank to[i]; one message is
  /// received from each rank of `from` (any size), returned in that order.
  std::vector<Bytes> exchange(const std::vector<int>& to, const std::vector<Bytes>& send,
                              const std::vector<int>& from) const;
  /// Every rank sends send[q] to rank q (send.size() == size()); returns what
  /// each rank q sent to this one. `send` is taken by value (move it in):
  /// each buffer is freed once packed, so the call holds about twice the
  /// larger of what this rank sends and receives, not four times.
  std::vector<Bytes> alltoall(std::vector<Bytes> send) const;
  /// alltoall where each rank writes to a few: `send` lists (destination,
  /// message), each destination at most once (std::invalid_argument for a
  /// destination out of range or repeated, empty messages included);
  /// returns (sender, message) for every non-empty message this rank
  /// received, in rank order. Its
  /// arguments and result do not grow with the rank count (played ranks:
  /// no vector of size() entries per rank and call).
  Messages sparse_alltoall(Messages send) const;
  /// Every rank's `mine`, in rank order, on every rank.
  Gathered allgather(const Bytes& mine) const;
  void barrier() const;
  /// The MPI communicator (an MPI_Comm*) for the parallel HDF5; null when
  /// this is not an MPI communicator.
  const void* mpi_comm() const;

  /// Runs body(comm) for `ranks` ranks of a Comm of that size in this
  /// process, each rank a fiber (its own stack, switched at its
  /// collectives) and the fibers shared out over the machine's cores: what
  /// a run on `ranks` processes computes in its collective set-up (`otmpm
  /// run --check --ranks N`: the decomposition, without starting N
  /// processes). Its collectives give the bits MPI's give (the same ordered
  /// sums); exchange() is not available (a std::logic_error). Returns once
  /// every rank has returned; when a rank throws, the others stop at their
  /// next collective and the lowest throwing rank's exception is rethrown
  /// here; a rank that returns while others wait in a collective is a
  /// std::logic_error (MPI would hang).
  static void run_local(int ranks, const std::function<void(const Comm&)>& body);

private:
  Comm() = default;
  int rank_ = 0, size_ = 1;
  bool mpi_ = false;
  std::shared_ptr<LocalRanks> local_; ///< the ranks of run_local, when this is one of them
};

/// How many processes a launcher (OpenMPI's mpirun, a PMI launcher such as
/// srun) says it started together with this one, from its environment
/// (OMPI_COMM_WORLD_SIZE, PMI_SIZE); 1 when none did. When it is more than
/// Comm::world().size(), this process cannot join the others as a rank (a
/// build without MPI, or another MPI than the launcher's): each would run
/// the whole program alone.
int launcher_size();
/// This process's rank among them (OMPI_COMM_WORLD_RANK, PMI_RANK), 0 when none.
int launcher_rank();

/// MPI for the lifetime of a program (its main): initialises MPI (threads
/// funnelled through the main thread, OpenMP inside each rank) when the
/// process was started by mpirun or srun, finalises it at the end. Without
/// MPI, or when the process was started directly, it does nothing: the
/// program then runs as one rank.
class Session {
public:
  Session(int& argc, char**& argv);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
  /// Ends every rank now with `status` (the last resort for an error that
  /// the ranks could not agree on: MPI_Abort).
  [[noreturn]] static void abort(int status);
  /// The end of the program on this rank, with its exit `status` and
  /// diagnosis (`message`, "" for none); returns the exit status. Serial:
  /// prints the message to stderr. Distributed: the ranks meet; the highest
  /// status wins, and the lowest rank with it prints its message - one
  /// message, not one per rank. A rank with an error that its peers did not
  /// share (they are not coming: an internal error on one rank) waits
  /// kExitWait seconds, prints its message and ends all ranks (MPI_Abort),
  /// so a run never hangs.
  int finish(int status, const std::string& message);
  /// Seconds a failed rank waits for the others at the end before it aborts them.
  static constexpr double kExitWait = 30.0;

private:
  bool initialised_ = false;
};

/// Runs `step` on every rank of `comm` and agrees on how it ended: when it
/// threw on any rank, every rank throws the error of the lowest rank it threw
/// on (that rank its own exception; the others an InputError, BasisError,
/// InstabilityError, OutputError or InterruptedError as such, anything else as a
/// std::runtime_error, with its message), so that no rank goes on into
/// the collectives after `step` while another one has failed, and the run
/// ends at once with one message and one exit status. For the set-up steps
/// that each rank does alone and that can fail on one rank only: reading a
/// file that one rank cannot read (not yet visible on its node, or
/// rewritten while the ranks read it so that it fails its checks); a file
/// that reads without an error but differently is for the caller to detect.
/// One reduction when no rank failed; nothing but `step` on one rank.
void agree_on(const Comm& comm, const std::function<void()>& step);

/// Requires that `mine` is the same text on every rank of `comm` - before a
/// collective operation that a difference would hang or corrupt (ranks that
/// read different scenes: a scene file rewritten while a job started, a
/// stale copy on one node, an MPMD command line; a relative path resolved in
/// working directories that differ per node). Otherwise every rank throws
/// the same InputError, naming the lowest rank R whose text differs and the
/// first difference: "rank R: WHAT differs from rank 0's: line N is 'A'
/// where rank 0 has 'B' (HINT)" ("line N" only for a text of several lines).
/// One broadcast and one reduction.
void require_same(const Comm& comm, const std::string& what, const std::string& mine, const std::string& hint);

/// For a rank that cannot go on with a step (memory ran out where no stage
/// defers the failure: a halo or migration buffer, a frame's rows, a sum):
/// tells every other rank, each of which throws DeferredOutOfMemory(message)
/// from the operation of Comm it waits in (Comm's operations wait while
/// looking for such a message), and every rank goes on with a communicator
/// on which no operation of the abandoned step is pending - so the ranks end
/// the run together: the result file's status set, one message, exit 4.
/// Returns `message`. Once per run; rethrows std::bad_alloc when it cannot
/// (one rank, MPI not started by a Session, a second failure). While the
/// others do not come (inside a library's collective call), this rank waits
/// at most Session::kExitWait, then ends every rank (MPI_Abort).
std::string stop_every_rank(const std::string& message);

/// The other ranks of Comm::world() as interrupt_point() sees them: a rank
/// that stops (its signal) sends each of them a notice, and a rank looks
/// for one (MPI_Iprobe) at most every kNoticeInterval seconds. Null when
/// there is one rank. Main thread only (MPI funnelled).
InterruptPeers* interrupt_peers();
/// Seconds between two looks for a notice (interrupt_peers()).
inline constexpr double kNoticeInterval = 0.005;

/// True when this otmpm was built with MPI (OTMPM_MPI).
bool built_with_mpi();

// ---- packing of trivially copyable values into byte buffers

/// Appends the bytes of `n` values at `data`.
void put_bytes(Bytes& out, const void* data, std::size_t n);
template <class T> void put(Bytes& out, const T& value) { put_bytes(out, &value, sizeof(T)); }

/// Reads values back from a buffer in the order they were put.
class Reader {
public:
  explicit Reader(const Bytes& in) : in_(in) {}
  void get_bytes(void* data, std::size_t n);
  template <class T> T get() {
    T v;
    get_bytes(&v, sizeof(T));
    return v;
  }
  bool done() const { return at_ == in_.size(); }

private:
  const Bytes& in_;
  std::size_t at_ = 0;
};

} // namespace otmpm::distributed
