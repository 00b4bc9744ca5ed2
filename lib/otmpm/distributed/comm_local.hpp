#pragma once
/// \file comm_local.hpp
/// Ranks played in one process (Comm::run_local): each rank a fiber (its
/// own stack, switched to and from at its collectives, never preempted),
/// the fibers shared out over a few threads, and the shared state of their
/// collectives. Internal to comm.cpp and comm_local.cpp.
#include "otmpm/distributed/comm.hpp"

#include <array>
#include <atomic>
#include <functional>
#include <memory>
#include <mutex>

namespace otmpm::distributed {

/// The ranks of Comm::run_local as one group: the collectives' barrier
/// and the buffers through which each collective passes its data.
///
/// The ranks are fibers, not threads: a thousand OS threads woken at every
/// collective spend their time in the scheduler. The fibers are shared out
/// over `threads` threads (rank r on thread r mod threads); a thread runs
/// each of its fibers until it reaches a collective (wait()) or returns,
/// then waits for the other threads: every rank has then posted its data,
/// and the next round (a generation) resumes them all.
class LocalRanks {
public:
  /// Thrown at a collective of a rank once another rank has failed (the
  /// group is stopped): it ends that rank's fiber, not the program.
  struct Stopped {};
  enum class Op { sum, max, min };

  /// A group of `size` ranks played on `threads` threads (at least 1).
  LocalRanks(int size, int threads);
  ~LocalRanks();
  LocalRanks(const LocalRanks&) = delete;
  LocalRanks& operator=(const LocalRanks&) = delete;
  int size() const { return size_; }
  /// Runs play(r) for every rank r, each on its fiber, until every one has
  /// returned (play must not throw). std::runtime_error when the fibers'
  /// stacks or the threads cannot be had.
  void run(const std::function<void(int)>& play);
  /// Stops the group: every rank waiting in, or later entering, a
  /// collective throws Stopped.
  void stop();

  Gathered allgather(int rank, const Bytes& mine);
  std::vector<Bytes> alltoall(int rank, std::vector<Bytes> send);
  Messages sparse_alltoall(int rank, Messages send);
  void broadcast(int rank, void* data, std::size_t bytes, int from);
  /// Combines the ranks' `values` entry by entry along MPI's binomial tree
  /// (children in increasing rank order: the bits an MPI run's ordered sums
  /// give): entries before `sums` added, the others by `rest`.
  template <class T> void reduce(int rank, std::span<T> values, std::size_t sums, Op rest);
  /// A barrier of the ranks: rank `rank` (the caller's fiber) waits until
  /// every rank has reached it or returned.
  void wait(int rank);

private:
  struct Fibers; ///< the stacks and contexts (comm_local.cpp)
  /// Where every fiber starts: runs its rank's play(), then switches to its thread for good.
  static void entry();
  /// Thread `t`'s share: its fibers, round after round, until all have returned.
  void work(int t);

  int size_, threads_;
  std::unique_ptr<Fibers> fibers_;
  std::atomic<bool> stopped_{false};
  /// What the collectives pass through, twice: a collective uses the set
  /// of the parity of its number (each rank counts its calls, `calls_`), so
  /// it needs one barrier after the ranks post their data and none after
  /// they read it - a set is written again two collectives later, after
  /// every rank has passed the barrier of the one between.
  struct Posts {
    std::shared_ptr<std::vector<Bytes>> slots; ///< allgather: each rank's message (shared by the ranks' results)
    long long slots_call = -1;                 ///< the collective (count of a rank's calls) `slots` belongs to
    std::vector<Messages> inbox;           ///< alltoall: per rank, (sender, message) in any order
    std::vector<const void*> data;         ///< reduce: each rank's values
    Bytes result;                          ///< reduce: the combined values; broadcast: the message
  };
  Posts& posts(int rank) { return posts_[calls_[static_cast<std::size_t>(rank)]++ & 1]; }
  std::array<Posts, 2> posts_;
  std::vector<long long> calls_; ///< per rank: the collectives it entered
  std::mutex mutex_;             ///< guards the making of Posts::slots and the inboxes (ranks on several threads)
  /// Posts this rank's (destination, message) pairs to the inboxes of `p`
  /// (destinations checked by Comm::sparse_alltoall: each in range, once).
  void post(Posts& p, int rank, Messages send);
  /// This rank's inbox of `p` (after the barrier), in rank order.
  Messages take(Posts& p, int rank);
};

} // namespace otmpm::distributed
