#pragma once
/// \file parallel_io.hpp
/// How the ranks of a distributed run write (and read) one file together
/// with the parallel HDF5 (MPI-IO): the communicator for HDF5 and the few
/// collective operations the files need besides it, given by the caller
/// (distributed/global_view.hpp), so that io/ knows no rank layer. A
/// default ParallelIo is a serial file of one process.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace otmpm {

/// Rows of a rows x cols array in a regular pattern: rows first + i stride +
/// j for i < count and j < block. A rank's particles in a file of all
/// ranks' particles are one block; a box of a lattice numbered axis 0
/// fastest is one block per layer of its last axis.
struct RowBlock {
  long long first = 0, stride = 1, count = 1, block = 0;
};

/// The rows of `blocks`.
inline long long block_rows(const std::vector<RowBlock>& blocks) {
  long long n = 0;
  for (const RowBlock& b : blocks) n += b.count * b.block;
  return n;
}

struct ParallelIo {
  const void* mpi_comm = nullptr; ///< the MPI_Comm* of the ranks (null: a serial file)
  bool root = true;
  int rank = 0, size = 1;
  /// Whether every rank's `ok` holds (collective): a frame is written only
  /// when all ranks' rows are finite.
  std::function<bool(bool)> all;
  /// Every rank's value, in rank order (collective).
  std::function<std::vector<std::int64_t>(std::int64_t)> allgather;
  /// The root's `text` on every rank (collective).
  std::function<std::string(const std::string&)> broadcast;
  /// Runs `step` on every rank; when it threw on any, every rank throws the
  /// error of the lowest rank it threw on (collective).
  std::function<void(const std::function<void()>&)> agree;
};

} // namespace otmpm
