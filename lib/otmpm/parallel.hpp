#pragma once
/// \file parallel.hpp
/// The OpenMP building blocks of the engine's particle and node loops, all of
/// them giving the same bits for any thread count: contiguous
/// chunks of particles or nodes, a few per thread, each thread running its
/// own (the same particles in every pass, so their data stay in its caches)
/// and then taking those of a slowed thread (no result depends on which
/// thread ran a chunk), exceptions rethrown from
/// the lowest chunk (so the reported particle is the lowest failing index, as
/// in a serial loop), and sums over particles taken in fixed blocks whose
/// size does not depend on the thread count.
#include <algorithm>
#include <atomic>
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
/// waits for the thread whose core is busiest; with several, the other
/// threads take over a slowed thread's remaining share.
constexpr int chunks_per_thread = 8;

/// Items per alignment unit of the threads' home ranges: the particles of a
/// block of the particle-to-node sum (scatter_block), a whole number of the
/// blocks of blocked_reduce, so that a particle loop and a loop over either
/// kind of block give each thread the same particles.
constexpr long long home_granule = 8192;

/// Number of chunks parallel_chunks cuts [0, n) into for `team` threads.
inline long long chunk_count(long long n, int team) {
  return std::max(1LL, std::min<long long>(n, static_cast<long long>(team) * chunks_per_thread));
}

/// First item of thread t's home range when [0, n) is shared by `team`
/// threads: g floor(B t / team), at most n, with B = ceil(n / g) granules of
/// g = `granule` items while B >= team, else g = 1 (B = n). A loop over n
/// particles (granule home_granule) and one over their blocks of k particles
/// (granule home_granule / k) give thread t the same particles.
inline long long home_begin(long long n, int team, int t, long long granule) {
  long long g = granule, blocks = (n + g - 1) / g;
  if (blocks < team) g = 1, blocks = n;
  return std::min(n, g * (blocks * t / team));
}

/// Runs body(begin, end) on contiguous chunks of [0, n) with `team` threads.
/// Thread t owns the home range [home_begin(t), home_begin(t + 1)), cut into
/// up to chunks_per_thread chunks that it runs first, in order; a thread
/// done with its own chunks then takes the chunks other threads have not
/// started. So every loop over the same items gives each thread the same
/// items (their data stay in its caches from pass to pass), and a thread
/// slowed by other work on its core still leaves its remaining share to the
/// others. A body must not depend on which thread runs it, nor on the chunk
/// boundaries. An exception thrown by a body is rethrown after the loop; if
/// several chunks fail, the lowest chunk's exception wins (the lowest
/// failing index when each body stops at its first failure, as a serial loop
/// would). `granule`: see home_begin (1 for loops over blocks).
template <class Body> void parallel_chunks(long long n, int team, Body&& body, long long granule = home_granule) {
  if (team <= 1 || n <= 1) {
    body(0LL, n);
    return;
  }
  struct alignas(64) Home {
    long long begin = 0, size = 0;
    int chunks = 0, first = 0; // chunk count, global index of the first
    std::atomic<int> next{0};  // the next chunk to start
  };
  std::vector<Home> home(static_cast<std::size_t>(team));
  int total = 0;
  for (int t = 0; t < team; ++t) {
    Home& h = home[static_cast<std::size_t>(t)];
    h.begin = home_begin(n, team, t, granule);
    h.size = home_begin(n, team, t + 1, granule) - h.begin;
    h.chunks = static_cast<int>(std::min<long long>(h.size, chunks_per_thread));
    h.first = total;
    total += h.chunks;
  }
  std::vector<std::exception_ptr> errors(static_cast<std::size_t>(total));
  auto run = [&](Home& h) {
    for (int j = h.next.fetch_add(1, std::memory_order_relaxed); j < h.chunks;
         j = h.next.fetch_add(1, std::memory_order_relaxed)) {
      try {
        body(h.begin + h.size * j / h.chunks, h.begin + h.size * (j + 1) / h.chunks);
      } catch (...) {
        errors[static_cast<std::size_t>(h.first + j)] = std::current_exception();
      }
    }
  };
#ifdef OTMPM_HAVE_OPENMP
#pragma omp parallel num_threads(team)
  {
    // its own chunks, then the others' (also those of threads a smaller team lacks)
    const int t = omp_get_thread_num();
    for (int u = 0; u < team; ++u) run(home[static_cast<std::size_t>((t + u) % team)]);
  }
#else
  for (Home& h : home) run(h);
#endif
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
static_assert(home_granule % reduction_block == 0, "a particle loop and a blocked sum give each thread the same particles");

/// Blocks of reduction_block items of [0, n), the last one short.
inline long long reduction_blocks(long long n) { return (n + reduction_block - 1) / reduction_block; }

/// Runs body(b, begin, end) for every fixed block b = 0 .. reduction_blocks(n)
/// - 1 of [0, n), [begin, end) its items, on the threads of a loop over n
/// items (each thread its own home items, as parallel_chunks gives them).
template <class Body> void parallel_blocks(long long n, Body&& body) {
  parallel_chunks(
      reduction_blocks(n), team_size(n),
      [&](long long b0, long long b1) {
        for (long long b = b0; b < b1; ++b)
          body(b, b * reduction_block, std::min(n, (b + 1) * reduction_block));
      },
      home_granule / reduction_block);
}

/// The total of per-block sums in block order (Acc default-constructed =
/// zero, with `a += b`).
template <class Acc> Acc total_in_order(const std::vector<Acc>& partial) {
  Acc total{};
  for (const Acc& a : partial) total += a;
  return total;
}

/// Sums over [0, n) into an accumulator `Acc` (default-constructed = zero,
/// with `a += b`) block by block: term(begin, end, acc) adds items
/// [begin, end) to acc, in index order. The blocks are the fixed ranges of
/// reduction_block items, and their sums are added in block order - the
/// same bits for any thread count.
template <class Acc, class Term> Acc blocked_reduce_ranges(long long n, Term&& term) {
  std::vector<Acc> partial(static_cast<std::size_t>(reduction_blocks(n)));
  parallel_blocks(n, [&](long long b, long long begin, long long end) {
    Acc acc{};
    term(begin, end, acc);
    partial[static_cast<std::size_t>(b)] = acc;
  });
  return total_in_order(partial);
}

/// A list built over [0, n): emit(begin, end, list) appends what indices
/// [begin, end) give, in index order, so that [a, c) gives what [a, b) and
/// then [b, c) give. On several threads each fixed block of
/// reduction_block indices goes to a list of its own, and `out` is their
/// join in block order; on one, emit runs once over [0, n): the same list
/// for any thread count (out's memory is reused).
template <class Emit> void parallel_list(long long n, Emit&& emit, std::vector<int>& out) {
  const long long blocks = reduction_blocks(n);
  out.clear();
  if (blocks <= 1 || team_size(n) <= 1) return emit(0LL, n, out);
  std::vector<std::vector<int>> lists(static_cast<std::size_t>(blocks));
  parallel_chunks(
      blocks, team_size(n),
      [&](long long b0, long long b1) {
        for (long long b = b0; b < b1; ++b)
          emit(b * reduction_block, std::min(n, (b + 1) * reduction_block), lists[static_cast<std::size_t>(b)]);
      },
      home_granule / reduction_block);
  for (const std::vector<int>& l : lists) out.insert(out.end(), l.begin(), l.end());
}

/// The items of `items` for which keep(item) is true, in their order, into
/// `out` (parallel_list; not `items` itself). keep may write what belongs to
/// its item alone.
template <class Keep> void parallel_filter(const std::vector<int>& items, Keep&& keep, std::vector<int>& out) {
  parallel_list(
      static_cast<long long>(items.size()),
      [&](long long begin, long long end, std::vector<int>& list) {
        for (long long i = begin; i < end; ++i)
          if (keep(items[static_cast<std::size_t>(i)])) list.push_back(items[static_cast<std::size_t>(i)]);
      },
      out);
}

/// blocked_reduce_ranges with a term per item: term(i, acc) adds item i.
template <class Acc, class Term> Acc blocked_reduce(long long n, Term&& term) {
  return blocked_reduce_ranges<Acc>(n, [&](long long begin, long long end, Acc& acc) {
    for (long long i = begin; i < end; ++i) term(i, acc);
  });
}

} // namespace otmpm
