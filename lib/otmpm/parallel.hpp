#pragma once
/// \file parallel.hpp
/// The OpenMP building blocks of the engine's particle and node loops, all of
/// them giving the same bits for any thread count (issue 7): static
/// contiguous chunks (each thread owns a range of particles or nodes),
/// exceptions rethrown from the lowest chunk (so the reported particle is the
/// lowest failing index, as in a serial loop), and sums over particles taken
/// in fixed blocks whose size does not depend on the thread count.
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

/// Runs body(begin, end) on contiguous chunks of [0, n), chunk t of `team`
/// covering [n t / team, n (t+1) / team). An exception thrown by a body is
/// rethrown after the loop; if several chunks fail, the lowest chunk's
/// exception wins (the lowest failing index when each body stops at its first
/// failure, as a serial loop would).
template <class Body> void parallel_chunks(long long n, int team, Body&& body) {
  if (team <= 1) {
    body(0LL, n);
    return;
  }
  std::vector<std::exception_ptr> errors(static_cast<std::size_t>(team));
#ifdef OTMPM_HAVE_OPENMP
#pragma omp parallel for schedule(static, 1) num_threads(team)
#endif
  for (int t = 0; t < team; ++t) {
    try {
      body(n * t / team, n * (t + 1) / team);
    } catch (...) {
      errors[static_cast<std::size_t>(t)] = std::current_exception();
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
