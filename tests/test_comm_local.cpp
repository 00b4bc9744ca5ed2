// Ranks played in one process (Comm::run_local, which `otmpm run
// --check --ranks N` plans a distributed run with): each collective gives
// what MPI's ranks give - the ordered sums with the binomial tree's bits,
// gathers in rank order - and a rank that fails stops the others instead of
// leaving them waiting.
#include "otmpm/core.hpp"
#include "otmpm/distributed/comm.hpp"
#include "otmpm/distributed/decomposition.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <stdexcept>
#include <thread>

using namespace otmpm;
using namespace otmpm::distributed;

namespace {

/// A value per rank whose sum depends on the order of the additions.
double ragged(int r) { return std::ldexp(1.0, (r * 37) % 60 - 30) * (1.0 + 1e-3 * r); }

/// The sum of ragged(0 .. P-1) along MPI's binomial tree (children added
/// in increasing rank order), as comm.cpp's tree_reduce adds them.
double tree_sum(int P) {
  std::vector<double> v(static_cast<std::size_t>(P));
  for (int r = 0; r < P; ++r) v[static_cast<std::size_t>(r)] = ragged(r);
  for (int mask = 1; mask < P; mask <<= 1)
    for (int r = 0; r + mask < P; r += 2 * mask) v[static_cast<std::size_t>(r)] += v[static_cast<std::size_t>(r + mask)];
  return v[0];
}

} // namespace

TEST_CASE("local ranks: the ordered sum has the binomial tree's bits on every rank, integers and extrema exact") {
  for (int P : {1, 2, 3, 7, 13, 64}) {
    CAPTURE(P);
    std::mutex m;
    std::vector<double> sums;
    std::vector<std::int64_t> isums, mins, maxs;
    Comm::run_local(P, [&](const Comm& c) {
      double s[2] = {ragged(c.rank()), -ragged(c.rank())}, mx[1] = {static_cast<double>(c.rank())};
      c.reduce(s, mx);
      const std::int64_t i = c.sum(static_cast<std::int64_t>(c.rank() + 1));
      const std::int64_t lo = c.min(static_cast<std::int64_t>(100 - c.rank())), hi = c.max(static_cast<std::int64_t>(c.rank()));
      std::lock_guard<std::mutex> g(m);
      sums.push_back(s[0]), sums.push_back(-s[1]), sums.push_back(mx[0]);
      isums.push_back(i), mins.push_back(lo), maxs.push_back(hi);
    });
    REQUIRE(sums.size() == 3u * static_cast<std::size_t>(P));
    for (std::size_t k = 0; k < sums.size(); k += 3) {
      CHECK(sums[k] == tree_sum(P)); // bitwise
      CHECK(sums[k + 1] == tree_sum(P));
      CHECK(sums[k + 2] == P - 1);
    }
    for (std::size_t k = 0; k < isums.size(); ++k) {
      CHECK(isums[k] == static_cast<std::int64_t>(P) * (P + 1) / 2);
      CHECK(mins[k] == 100 - (P - 1));
      CHECK(maxs[k] == P - 1);
    }
  }
}

TEST_CASE("local ranks: gathers in rank order, all-to-all, broadcast from any rank") {
  constexpr int P = 5;
  std::atomic<int> checked{0};
  Comm::run_local(P, [&](const Comm& c) {
    const std::vector<std::int64_t> all = c.allgather(static_cast<std::int64_t>(10 * c.rank()));
    std::vector<Bytes> to(P);
    for (int q = 0; q < P; ++q) to[static_cast<std::size_t>(q)] = Bytes(static_cast<std::size_t>(c.rank() + 1), static_cast<char>(q));
    const std::vector<Bytes> from = c.alltoall(std::move(to));
    const std::string text = c.broadcast(c.rank() == 3 ? std::string("from rank 3") : std::string(), 3);
    bool ok = all.size() == P && text == "from rank 3";
    for (int q = 0; q < P; ++q) {
      ok = ok && all[static_cast<std::size_t>(q)] == 10 * q;
      ok = ok && from[static_cast<std::size_t>(q)] == Bytes(static_cast<std::size_t>(q + 1), static_cast<char>(c.rank()));
    }
    c.barrier();
    if (ok) ++checked;
  });
  CHECK(checked.load() == P);
}

TEST_CASE("local ranks: a sparse all-to-all lists each sender's message in rank order, a repeated destination is an error") {
  constexpr int P = 6;
  std::atomic<int> checked{0};
  Comm::run_local(P, [&](const Comm& c) {
    const int r = c.rank();
    Messages send; // to r + 3 and r + 1 (this order), and an empty one to itself
    send.emplace_back((r + 3) % P, Bytes(2, static_cast<char>(r)));
    send.emplace_back((r + 1) % P, Bytes(1, static_cast<char>(r)));
    send.emplace_back(r, Bytes{});
    const Messages got = c.sparse_alltoall(std::move(send));
    Messages want; // from r - 3 (two bytes) and r - 1 (one byte), in rank order
    for (int q = 0; q < P; ++q)
      if (q == (r + P - 3) % P || q == (r + P - 1) % P)
        want.emplace_back(q, Bytes(q == (r + P - 3) % P ? 2 : 1, static_cast<char>(q)));
    if (got == want) ++checked;
  });
  CHECK(checked.load() == P);
  Messages self;
  self.emplace_back(0, Bytes(3, 'x'));
  CHECK(Comm::self().sparse_alltoall(self) == self);
  // A repeated destination, also when the first message to it is empty or
  // the two are apart, and a destination out of range: errors on local
  // ranks and on a communicator of its own alike.
  for (const Messages& bad : {Messages{{0, Bytes(1, 'a')}, {0, Bytes(1, 'b')}}, Messages{{0, Bytes{}}, {0, Bytes(1, 'b')}},
                              Messages{{0, Bytes(1, 'a')}, {1, Bytes{}}, {0, Bytes{}}}, Messages{{3, Bytes(1, 'a')}},
                              Messages{{-1, Bytes{}}}}) {
    const auto send_bad = [&](const Comm& c) { c.sparse_alltoall(bad); };
    CHECK_THROWS_AS(Comm::run_local(3, send_bad), std::invalid_argument);
    CHECK_THROWS_AS(send_bad(Comm::self()), std::invalid_argument);
  }
}

TEST_CASE("local ranks: a gather's result stays as it was through the collectives after it (one copy for all ranks)") {
  constexpr int P = 7;
  std::atomic<int> checked{0};
  Comm::run_local(P, [&](const Comm& c) {
    const Gathered first = c.allgather(Bytes(static_cast<std::size_t>(c.rank() + 1), 'a'));
    bool ok = true;
    for (int round = 0; round < 4; ++round) { // reuses the buffers of the first one twice
      const Gathered later = c.allgather(Bytes(1, static_cast<char>('b' + round)));
      for (const Bytes& b : later) ok = ok && b == Bytes(1, static_cast<char>('b' + round));
      c.barrier();
    }
    ok = ok && first.size() == P;
    for (int q = 0; q < P; ++q) ok = ok && first[static_cast<std::size_t>(q)] == Bytes(static_cast<std::size_t>(q + 1), 'a');
    if (ok) ++checked;
  });
  CHECK(checked.load() == P);
}

TEST_CASE("local ranks: a rank that throws stops the others at their next collective, its exception is rethrown") {
  for (int thrower : {0, 3}) {
    CAPTURE(thrower);
    std::atomic<int> returned{0};
    auto body = [&](const Comm& c) {
      if (c.rank() == thrower) throw InputError("rank " + std::to_string(c.rank()) + " failed");
      for (int i = 0; i < 3; ++i) c.barrier(); // the others would wait for it forever
      ++returned;
    };
    CHECK_THROWS_WITH_AS(Comm::run_local(4, body), ("rank " + std::to_string(thrower) + " failed").c_str(), InputError);
    CHECK(returned.load() == 0);
  }
  CHECK_THROWS_AS(Comm::run_local(4, [](const Comm& c) { c.exchange({}, {}, {}); }), std::logic_error);
}

TEST_CASE("local ranks: the bisection over ranks that each hold a slice of the particles equals it in one process") {
  const Index<2> cells{40, 30};
  std::vector<Index<2>> home;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 30; ++j)
      for (int n = 0; n < 1 + (i * j) % 5; ++n) home.push_back({i, j}); // uneven weights
  constexpr int P = 6;
  const Decomposition<2> one = Decomposition<2>::rcb(cells, P, home, Comm::self());
  std::vector<Decomposition<2>> found(P, one);
  Comm::run_local(P, [&](const Comm& c) {
    const std::size_t n = home.size(), r = static_cast<std::size_t>(c.rank());
    const std::span<const Index<2>> mine(home.data() + n * r / P, n * (r + 1) / P - n * r / P);
    found[r] = Decomposition<2>::rcb(cells, P, mine, c);
  });
  for (int r = 0; r < P; ++r)
    for (int q = 0; q < P; ++q) {
      CHECK(found[static_cast<std::size_t>(r)].box(q).lo == one.box(q).lo);
      CHECK(found[static_cast<std::size_t>(r)].box(q).hi == one.box(q).hi);
    }
}

TEST_CASE("local ranks: a thousand ranks play their collectives as fibers on a few threads, not the caller's") {
  constexpr int P = 1000;
  std::vector<std::int64_t> sums(P), gathered(P);
  std::vector<std::thread::id> threads(P);
  Comm::run_local(P, [&](const Comm& c) {
    const std::size_t r = static_cast<std::size_t>(c.rank());
    std::int64_t total = 0;
    for (int round = 0; round < 5; ++round) total += c.sum(static_cast<std::int64_t>(c.rank()) + round);
    sums[r] = total;
    const std::vector<std::int64_t> all = c.allgather(static_cast<std::int64_t>(c.rank()));
    for (std::size_t q = 0; q < all.size(); ++q) gathered[r] += all[q] == static_cast<std::int64_t>(q);
    threads[r] = std::this_thread::get_id();
  });
  const std::int64_t expect = 5 * static_cast<std::int64_t>(P) * (P - 1) / 2 + static_cast<std::int64_t>(P) * (0 + 1 + 2 + 3 + 4);
  for (int r = 0; r < P; ++r) {
    CHECK(sums[static_cast<std::size_t>(r)] == expect);
    CHECK(gathered[static_cast<std::size_t>(r)] == P);
  }
  // never on the caller's thread: what a rank sets on its thread (omp_set_num_threads) stays with the ranks
  CHECK(std::count(threads.begin(), threads.end(), std::this_thread::get_id()) == 0);
  std::sort(threads.begin(), threads.end());
  const auto distinct = std::unique(threads.begin(), threads.end()) - threads.begin();
  CHECK(distinct >= 1);
  CHECK(distinct <= static_cast<long>(std::max(1u, std::thread::hardware_concurrency()))); // not a thread per rank
}

TEST_CASE("local ranks: a rank that returns while the others wait in a collective is a logic error, not a wrong answer") {
  std::atomic<int> past{0};
  auto body = [&](const Comm& c) {
    if (c.rank() == 2) return; // skips the barrier the others wait in
    c.barrier();
    ++past;
  };
  CHECK_THROWS_AS(Comm::run_local(5, body), std::logic_error);
  CHECK(past.load() == 0);
}
