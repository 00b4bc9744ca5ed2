// The OpenMP building blocks (parallel.hpp): parallel_chunks cuts [0, n)
// into contiguous chunks, several per thread, each thread's own (its home
// range, the same particles in a particle loop and in a loop over their
// blocks) run first and the rest taken by whichever thread is free; the lowest failing chunk's exception is the one rethrown;
// parallel_list and parallel_filter give a serial loop's list; the basis
// table's general fill (stencils of varying size) buffers those chunks and
// gives the table of one thread.
#include "otmpm/basis/basis.hpp"
#include "otmpm/openmp_wait.hpp"
#include "otmpm/parallel.hpp"
#include "support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cstdlib>
#include <chrono>
#include <mutex>
#include <random>
#include <string>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

using namespace otmpm;
using otmpm::test::ScopedThreads;

namespace {

/// The ranges parallel_chunks hands out for n items and `team` threads, in
/// chunk order.
std::vector<std::pair<long long, long long>> chunks_of(long long n, int team) {
  std::mutex m;
  std::vector<std::pair<long long, long long>> ranges;
  parallel_chunks(n, team, [&](long long begin, long long end) {
    const std::lock_guard lock(m);
    ranges.emplace_back(begin, end);
  });
  std::sort(ranges.begin(), ranges.end());
  return ranges;
}

CartesianGrid<2> grid() {
  CartesianGrid<2> g;
  g.lower = Vec<2>(0.0, 0.0);
  g.upper = Vec<2>(1.0, 1.0);
  g.cells = {10, 10};
  return g;
}

AlignedVector<Vec<2>> points_inside(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.15, 0.85);
  AlignedVector<Vec<2>> x;
  for (int i = 0; i < n; ++i) x.emplace_back(u(rng), u(rng));
  return x;
}

std::unique_ptr<Basis<2>> lme_basis() {
  BasisOptions opt;
  opt.kind = "lme";
  opt.values["gamma_lme"] = 3.0;
  return make_basis<2>(opt, NodeSet<2>::cartesian(grid()));
}

void fill(int threads, const Basis<2>& b, const AlignedVector<Vec<2>>& x, BasisTable<2>& t) {
  const ScopedThreads scope(threads);
  fill_basis_table(b, x, nullptr, nullptr, t);
}

} // namespace

TEST_CASE("parallel_chunks covers every item once, in contiguous chunks, several per thread") {
  for (const long long n : {1LL, 2LL, 7LL, 16LL, 1000LL, 100003LL})
    for (const int team : {2, 3}) {
      CAPTURE(n);
      CAPTURE(team);
      const auto ranges = chunks_of(n, team);
      REQUIRE(static_cast<long long>(ranges.size()) == chunk_count(n, team));
      CHECK(chunk_count(n, team) == std::min<long long>(n, team * chunks_per_thread));
      long long next = 0;
      for (const auto& [begin, end] : ranges) {
        CHECK(begin == next);
        CHECK(end > begin);
        next = end;
      }
      CHECK(next == n);
    }
  // One thread: one call over everything.
  const auto one = chunks_of(12345, 1);
  REQUIRE(one.size() == 1);
  CHECK(one.front() == std::pair<long long, long long>(0, 12345));
}

TEST_CASE("parallel_filter keeps the items of a serial filter, in their order, on any thread count") {
  // Items in no order, more blocks of reduction_block than threads; keep()
  // writes its own item's flag (what the wall and mass passes do).
  std::vector<int> items(25000);
  std::mt19937 rng(7);
  for (int& i : items) i = static_cast<int>(rng() % 100000);
  auto keep = [](int i) { return i % 7 == 3 || i % 11 == 0; };
  std::vector<int> serial;
  for (const int i : items)
    if (keep(i)) serial.push_back(i);
  REQUIRE(serial.size() > 3000);
  for (const int threads : {1, 2, 3})
    for (const std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{1024}, std::size_t{1025}, items.size()}) {
      CAPTURE(threads);
      CAPTURE(n);
      const ScopedThreads scope(threads);
      const std::vector<int> part(items.begin(), items.begin() + static_cast<std::ptrdiff_t>(n));
      std::vector<char> seen(100000, 0);
      std::vector<int> out{-1, -2}; // what was in it before goes
      parallel_filter(
          part,
          [&](int i) {
            seen[static_cast<std::size_t>(i)] = 1;
            return keep(i);
          },
          out);
      std::vector<int> expected;
      for (const int i : part)
        if (keep(i)) expected.push_back(i);
      CHECK(out == expected);
      CHECK(std::all_of(part.begin(), part.end(), [&](int i) { return seen[static_cast<std::size_t>(i)] == 1; }));
    }
}

TEST_CASE("parallel_list joins the blocks' lists in block order: the same list for 1, 2 and 3 threads") {
  // Each range appends the multiples of 5 it holds, ascending: a join out of
  // block order, a block lost or a block twice would show.
  const long long n = 10 * reduction_block + 17;
  auto emit = [](long long begin, long long end, std::vector<int>& list) {
    for (long long i = begin; i < end; ++i)
      if (i % 5 == 0) list.push_back(static_cast<int>(i));
  };
  std::vector<int> serial;
  emit(0, n, serial);
  REQUIRE(serial.size() == static_cast<std::size_t>((n + 4) / 5));
  for (const int threads : {1, 2, 3}) {
    CAPTURE(threads);
    const ScopedThreads scope(threads);
    std::vector<int> out;
    parallel_list(n, emit, out);
    CHECK(out == serial);
  }
}

TEST_CASE("home ranges: a particle loop and a loop over its blocks give each thread the same particles") {
  // n particles: thread t's first particle in a particle loop is that of its
  // first block in a loop over the scatter blocks (scatter_block particles,
  // granule 1) and over the blocks of blocked_reduce (reduction_block
  // particles, granule home_granule / reduction_block), for every team; the
  // ranges tile [0, n) in thread order, cut at whole scatter blocks.
  for (const long long n : {16384LL, 16848LL, 25600LL, 160000LL, 2097152LL, 10000019LL})
    for (const int team : {2, 3, 4, 7}) {
      const long long blocks = (n + home_granule - 1) / home_granule;
      if (blocks < team) continue;
      CAPTURE(n);
      CAPTURE(team);
      const long long sums = (n + reduction_block - 1) / reduction_block;
      long long last = 0;
      for (int t = 0; t <= team; ++t) {
        const long long first = home_begin(n, team, t, home_granule);
        CHECK(first == std::min(n, home_granule * home_begin(blocks, team, t, 1)));
        CHECK(first == std::min(n, reduction_block * home_begin(sums, team, t, home_granule / reduction_block)));
        CHECK(first >= last);
        CHECK((t == team || first % home_granule == 0));
        last = first;
      }
      CHECK(home_begin(n, team, 0, home_granule) == 0);
      CHECK(last == n);
    }
  // Fewer granules than threads: even ranges of single items.
  CHECK(home_begin(1000, 2, 1, home_granule) == 500);
  CHECK(home_begin(8000, 2, 1, home_granule) == 4000);
  CHECK(home_begin(12000, 2, 1, home_granule) == 8192); // two scatter blocks: one each
  CHECK(home_begin(7, 2, 1, home_granule) == 3);
}

TEST_CASE("parallel_chunks rethrows the exception of the lowest failing chunk") {
  // Items 60000 and 90000 fail (each body stops at its first failure); so does
  // 3000, in an earlier chunk that may well finish after the others.
  for (const int team : {1, 2, 3}) {
    CAPTURE(team);
    try {
      parallel_chunks(100000, team, [](long long begin, long long end) {
        for (long long i = begin; i < end; ++i)
          if (i == 3000 || i == 60000 || i == 90000) throw std::runtime_error("item " + std::to_string(i));
      });
      FAIL("no exception");
    } catch (const std::runtime_error& e) {
      CHECK(std::string(e.what()) == "item 3000");
    }
  }
}

#ifdef OTMPM_HAVE_OPENMP
TEST_CASE("parallel_chunks: a slow chunk does not hold the other chunks back") {
  // The chunk of item 0 takes 300 ms (a thread whose core is taken by another
  // process); every other chunk is instant. A thread done with its own
  // chunks takes those the others have not started, so the thread held up
  // in the slow chunk starts no chunk after it: the other thread runs every
  // chunk left (with one chunk per thread, or a static share, the slow
  // thread would still own half of them).
  std::mutex m;
  struct Start {
    long long begin;
    int thread, order;
  };
  std::vector<Start> starts;
  parallel_chunks(64000, 2, [&](long long begin, long long) {
    {
      const std::lock_guard lock(m);
      starts.push_back({begin, omp_get_thread_num(), static_cast<int>(starts.size())});
    }
    if (begin == 0) std::this_thread::sleep_for(std::chrono::milliseconds(300));
  });
  const long long k = chunk_count(64000, 2);
  REQUIRE(k == 2 * chunks_per_thread);
  REQUIRE(static_cast<long long>(starts.size()) == k);
  const auto slow = *std::find_if(starts.begin(), starts.end(), [](const Start& c) { return c.begin == 0; });
  // Without a second thread (OMP_THREAD_LIMIT=1, OMP_DYNAMIC) there is nothing to hand over.
  if (std::all_of(starts.begin(), starts.end(), [&](const Start& c) { return c.thread == slow.thread; })) return;
  for (const Start& c : starts) {
    CAPTURE(c.begin);
    CHECK((c.thread != slow.thread || c.order <= slow.order));
  }
}
#endif

TEST_CASE("general basis table fill (LME): chunked with 2 and 3 threads = one thread, buffers reused") {
  const auto b = lme_basis();
  // Sizes that leave chunks of unequal length; the second call shrinks the
  // point set and the third grows it again (the chunk buffers are reused).
  for (const int n : {3001, 1499, 4096}) {
    CAPTURE(n);
    const AlignedVector<Vec<2>> x = points_inside(n, static_cast<unsigned>(n));
    BasisTable<2> one, two, three;
    fill(1, *b, x, one);
    fill(2, *b, x, two);
    fill(3, *b, x, three);
    REQUIRE(one.rows() == n);
    CHECK(one.entries() > static_cast<std::size_t>(n) * 9); // LME stencils: many nodes each
    for (const BasisTable<2>* t : {&two, &three}) {
      CHECK(t->offset == one.offset);
      CHECK(t->node == one.node);
      CHECK(t->N == one.N);
      CHECK(t->dN == one.dN);
    }
  }
}

TEST_CASE("general basis table fill (LME): the error names the lowest failing particle, whatever the chunks") {
  const auto b = lme_basis();
  AlignedVector<Vec<2>> x = points_inside(4000, 9u);
  x[1234] = Vec<2>(3.0, 0.5); // far outside the nodes
  x[3900] = Vec<2>(-2.0, 0.5);
  for (const int threads : {1, 2, 3}) {
    CAPTURE(threads);
    BasisTable<2> t;
    try {
      fill(threads, *b, x, t);
      FAIL("no BasisError");
    } catch (const BasisError& e) {
      CHECK(std::string(e.what()).find("particle 1234 at ") == 0);
    }
  }
}

TEST_CASE("openmp wait: the spin count is clamped to [100, 10^7], the default in between") {
  // timings of a few microseconds vary with the load, so only what does not:
  // no time gives the least count, 100 s the most (a spin takes ~1-50 ns,
  // far below the 10 us that would spin 10^7 times in 100 s, also under a
  // sanitizer or valgrind), and the default (0.2 ms) lies between
  CHECK(otmpm::spin_count_for(0.0) == 100);
  CHECK(otmpm::spin_count_for(100.0) == 10000000);
  const long long spins = otmpm::spin_count_for(otmpm::kDefaultSpinSeconds);
  CHECK(spins >= 100);
  CHECK(spins < 10000000);
}

TEST_CASE("openmp wait: valgrind is recognised by its preloaded core, and nothing else is") {
  // the program is not executed again under valgrind, whose /proc/self/exe is its tool
  const char* saved = std::getenv("LD_PRELOAD");
  const std::string before = saved ? saved : "";
  setenv("LD_PRELOAD",
         "/usr/libexec/valgrind/vgpreload_core-amd64-linux.so:/usr/libexec/valgrind/vgpreload_memcheck-amd64-linux.so", 1);
  CHECK(otmpm::under_valgrind());
  setenv("LD_PRELOAD", "/usr/lib/x86_64-linux-gnu/libasan.so.8", 1);
  CHECK_FALSE(otmpm::under_valgrind());
  unsetenv("LD_PRELOAD");
  CHECK_FALSE(otmpm::under_valgrind());
  if (saved) setenv("LD_PRELOAD", before.c_str(), 1);
}
