#pragma once
/// \file parallel.hpp
/// The OpenMP building blocks of the engine's particle and node loops, all of
/// them giving the same bits for any thread count: contiguous
/// chunks of particles or nodes, a few per thread, handed out dynamically (a
/// thread slowed by other work on its core leaves its share to the others;
/// no result depends on which thread ran a chunk), exceptions rethrown from
/// the lowest chunk (so the reported particle is the lowest failing index, as
/// in a serial loop), and sums over particles taken in fixed blocks whose
/// size does not depend on the thread count.
#include <algorithm>
#include <exception>
#include <vector>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

namespace otmpm {

/// Below this many items per thread, fork/join costs more than it saves (and
/// on a loaded machine spinning threads are slow).
constexpr int min_items_per_thread = 512;

/// Threads for a loop over n items: at most the OpenMP maximum, at least one,
/// and no more than n / min_items_per_thread.
inline int team_size(long long n) {
#ifdef OTMPM_HAVE_OPENMP
  const long long by_size = n / min_items_per_thread;
  return static_cast<int>(std::max(1LL, std::min<long long>(omp_get_max_threads(), by_size)));
#else
  (void)n;
  return 1;
#endif
}

/// Chunks per thread of a parallel loop: with one chunk per thread a step
/// waits for the thread whose core is busiest; with several, taken by
/// whichever thread is free, the other threads take over its share.
constexpr int chunks_per_thread = 8;

/// Number of chunks parallel_chunks cuts [0, n) into for `team` threads.
inline long long chunk_count(long long n, int team) {
  return std::max(1LL, std::min<long long>(n, static_cast<long long>(team) * chunks_per_thread));
}

/// Runs body(begin, end) on contiguous chunks of [0, n) with `team` threads:
/// chunk c of k = chunk_count(n, team) covers [n c / k, n (c+1) / k), and the
/// chunks are taken in turn by whichever thread is free (so a body must not
/// depend on which thread runs it, nor on the chunk boundaries). An exception
/// thrown by a body is rethrown after the loop; if several chunks fail, the
/// lowest chunk's exception wins (the lowest failing index when each body
/// stops at its first failure, as a serial loop would).
template <class Body> void parallel_chunks(long long n, int team, Body&& body) {
  if (team <= 1) {
    body(0LL, n);
    return;
  }
  const long long k = chunk_count(n, team);
  std::vector<std::exception_ptr> errors(static_cast<std::size_t>(k));
#ifdef OTMPM_HAVE_OPENMP
#pragma omp parallel for schedule(dynamic, 1) num_threads(team)
#endif
  for (long long c = 0; c < k; ++c) {
    try {
      body(n * c / k, n * (c + 1) / k);
    } catch (...) {
      errors[static_cast<std::size_t>(c)] = std::current_exception();
    }
  }
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
}

/// parallel_chunks with the team chosen by team_size(n).
template <class Body> void parallel_chunks(long long n, Body&& body) {
  parallel_chunks(n, team_size(n), static_cast<Body&&>(body));
}

/// Runs body(i) for every i in [0, n), parallel_chunks over team_size(n)
/// threads: for loops whose iteration i writes only item i (nodal and
/// particle updates), which are then the same bits for any thread count.
template <class Body> void parallel_for(long long n, Body&& body) {
  parallel_chunks(n, [&](long long begin, long long end) {
    for (long long i = begin; i < end; ++i) body(i);
  });
}

/// Items per block of a blocked_reduce: fixed, so that the grouping of the
/// partial sums (hence the bits of the result) does not depend on threads.
constexpr int reduction_block = 1024;

/// Sums over [0, n) into an accumulator `Acc` (default-constructed = zero,
/// with `a += b`) block by block: term(begin, end, acc) adds items
/// [begin, end) to acc, in index order. The blocks are the fixed ranges of
/// reduction_block items, and their sums are added in block order - the
/// same bits for any thread count.
template <class Acc, class Term> Acc blocked_reduce_ranges(long long n, Term&& term) {
  const long long blocks = (n + reduction_block - 1) / reduction_block;
  std::vector<Acc> partial(static_cast<std::size_t>(blocks));
  parallel_chunks(blocks, team_size(n), [&](long long b0, long long b1) {
    for (long long b = b0; b < b1; ++b) {
      Acc acc{};
      term(b * reduction_block, std::min(n, (b + 1) * reduction_block), acc);
      partial[static_cast<std::size_t>(b)] = acc;
    }
  });
  Acc total{};
  for (const Acc& a : partial) total += a;
  return total;
}

/// blocked_reduce_ranges with a term per item: term(i, acc) adds item i.
template <class Acc, class Term> Acc blocked_reduce(long long n, Term&& term) {
  return blocked_reduce_ranges<Acc>(n, [&](long long begin, long long end, Acc& acc) {
    for (long long i = begin; i < end; ++i) term(i, acc);
  });
}

} // namespace otmpm
