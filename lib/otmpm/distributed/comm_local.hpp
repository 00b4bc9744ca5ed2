#pragma once
/// \file comm_local.hpp
/// Ranks played by threads of one process (Comm::run_local): the shared
/// state of their collectives. Internal to comm.cpp and comm_local.cpp.
#include "otmpm/distributed/comm.hpp"

#include <array>
#include <atomic>

namespace otmpm::distributed {

/// The threads of Comm::run_local as the ranks of one group: a barrier,
/// and the buffers through which each collective passes its data.
class LocalRanks {
public:
  /// Thrown at a collective of a rank once another rank has failed (the
  /// group is stopped): it ends that rank's thread, not the program.
  struct Stopped {};
  enum class Op { sum, max, min };

  explicit LocalRanks(int size);
  int size() const { return size_; }
  /// Stops the group: every rank waiting in, or later entering, a
  /// collective throws Stopped.
  void stop();

  std::vector<Bytes> allgather(int rank, const Bytes& mine);
  std::vector<Bytes> alltoall(int rank, std::vector<Bytes> send);
  void broadcast(int rank, void* data, std::size_t bytes, int from);
  /// Combines the ranks' `values` entry by entry along MPI's binomial tree
  /// (children in increasing rank order: the bits an MPI run's ordered sums
  /// give): entries before `sums` added, the others by `rest`.
  template <class T> void reduce(int rank, std::span<T> values, std::size_t sums, Op rest);
  /// A barrier of the ranks.
  void wait();

private:
  int size_;
  // the barrier: the last rank to arrive starts the next generation
  // (std::atomic::wait: the ranks wake without taking a lock in turn)
  std::atomic<int> arrived_{0};
  std::atomic<long long> generation_{0};
  std::atomic<bool> stopped_{false};
  /// What the collectives pass through, twice: a collective uses the set
  /// of the parity of its number (each rank counts its calls, `calls_`), so
  /// it needs one barrier after the ranks post their data and none after
  /// they read it - a set is written again two collectives later, after
  /// every rank has passed the barrier of the one between.
  struct Posts {
    std::vector<Bytes> slots;              ///< allgather: each rank's message
    std::vector<std::vector<Bytes>> posts; ///< alltoall: posts[to][from]
    std::vector<const void*> data;         ///< reduce: each rank's values
    Bytes result;                          ///< reduce: the combined values; broadcast: the message
  };
  Posts& posts(int rank) { return posts_[calls_[static_cast<std::size_t>(rank)]++ & 1]; }
  std::array<Posts, 2> posts_;
  std::vector<long long> calls_; ///< per rank: the collectives it entered
};

} // namespace otmpm::distributed
