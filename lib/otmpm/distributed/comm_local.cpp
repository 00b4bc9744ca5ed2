/// \file comm_local.cpp
/// Ranks played in one process (comm_local.hpp, Comm::run_local): fibers
/// (ucontext) on a few threads.
#include "otmpm/distributed/comm_local.hpp"

#include <algorithm>
#include <barrier>
#include <cstring>
#include <exception>
#include <latch>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <type_traits>

#include <sys/mman.h>
#include <ucontext.h>
#include <unistd.h>

#if defined(__SANITIZE_ADDRESS__)
#define OTMPM_FIBERS_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define OTMPM_FIBERS_ASAN 1
#endif
#endif
#ifdef OTMPM_FIBERS_ASAN
#include <sanitizer/common_interface_defs.h>
#endif

namespace otmpm::distributed {

namespace {

/// Each fiber's stack: the size of a thread's default stack, reserved
/// (MAP_NORESERVE: only the pages a rank touches take memory), below it a
/// guard page.
constexpr std::size_t kStackBytes = std::size_t{8} << 20;

/// AddressSanitizer's notices of a switch of stacks (no-ops without it):
/// before switching to the stack [bottom, bottom + size) and after arriving.
/// `save` null: the stack left is never switched to again.
void switching_to([[maybe_unused]] void** save, [[maybe_unused]] const void* bottom, [[maybe_unused]] std::size_t size) {
#ifdef OTMPM_FIBERS_ASAN
  __sanitizer_start_switch_fiber(save, bottom, size);
#endif
}
void arrived([[maybe_unused]] void* save, [[maybe_unused]] const void** bottom, [[maybe_unused]] std::size_t* size) {
#ifdef OTMPM_FIBERS_ASAN
  __sanitizer_finish_switch_fiber(save, bottom, size);
#endif
}

} // namespace

/// The ranks' fibers: a stack and a context each, and each thread's own
/// context (`home`) they switch back to at a collective or on returning.
struct LocalRanks::Fibers {
  struct Fiber {
    ucontext_t context{};
    char* mapping = nullptr; ///< guard page, then the stack
    bool done = false;
  };
  /// Each thread's context and stack (the stack for AddressSanitizer's notices).
  struct Home {
    ucontext_t context{};
    const void* bottom = nullptr;
    std::size_t size = 0;
  };
  /// At the end of a round (every thread arrived): whether every fiber has
  /// returned, and whether one returned while another still waits in a
  /// collective of a group not stopped (the ranks' collectives do not
  /// match: the group is stopped, the waiting ranks are not let through).
  struct RoundEnd {
    Fibers* f;
    void operator()() noexcept {
      f->finished = f->live.load() == 0;
      if (f->returned.exchange(0) > 0 && !f->finished && !f->stopped->load()) f->mismatch = true, f->stopped->store(true);
    }
  };

  std::size_t page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  std::vector<Fiber> fiber;
  std::vector<Home> home;
  std::function<void(int)> play;
  std::atomic<int> live{0}, returned{0};
  bool finished = false, mismatch = false;
  std::atomic<bool>* stopped = nullptr; ///< the group's flag (LocalRanks::stop)
  std::optional<std::barrier<RoundEnd>> round;

  Fibers(int ranks, int threads) : fiber(static_cast<std::size_t>(ranks)), home(static_cast<std::size_t>(threads)) {}
  ~Fibers() {
    for (Fiber& f : fiber)
      if (f.mapping) munmap(f.mapping, kStackBytes + page);
  }
  char* stack(int r) { return fiber[static_cast<std::size_t>(r)].mapping + page; }

  /// Maps rank r's stack and makes its context, to start in entry().
  void make(int r);
  /// Runs rank r's fiber on thread t until it waits in a collective or returns.
  void resume(int t, int r);
  /// Rank r's fiber (on thread t) gives the thread back until the next round.
  void park(int t, int r);
};

namespace {

/// The group and rank a fiber starts with (read by entry(), on the thread
/// that first switches to it, before the thread switches to another).
thread_local LocalRanks* starting_group = nullptr;
thread_local int starting_rank = 0, starting_thread = 0;

} // namespace

void LocalRanks::Fibers::make(int r) {
  void* m = mmap(nullptr, kStackBytes + page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE | MAP_STACK,
                 -1, 0);
  if (m == MAP_FAILED)
    throw std::runtime_error("cannot map the stacks of " + std::to_string(fiber.size()) + " played ranks (" +
                             std::to_string(r) + " mapped): " + std::strerror(errno));
  Fiber& f = fiber[static_cast<std::size_t>(r)];
  f.mapping = static_cast<char*>(m);
  mprotect(f.mapping, page, PROT_NONE);
  getcontext(&f.context);
  f.context.uc_stack.ss_sp = stack(r);
  f.context.uc_stack.ss_size = kStackBytes;
  f.context.uc_link = nullptr; // entry() never returns: it switches home
  makecontext(&f.context, &LocalRanks::entry, 0);
}

void LocalRanks::Fibers::resume(int t, int r) {
  Home& h = home[static_cast<std::size_t>(t)];
  starting_rank = r, starting_thread = t;
  void* save = nullptr;
  switching_to(&save, stack(r), kStackBytes);
  swapcontext(&h.context, &fiber[static_cast<std::size_t>(r)].context);
  arrived(save, nullptr, nullptr);
}

void LocalRanks::Fibers::park(int t, int r) {
  Home& h = home[static_cast<std::size_t>(t)];
  void* save = nullptr;
  switching_to(&save, h.bottom, h.size);
  swapcontext(&fiber[static_cast<std::size_t>(r)].context, &h.context);
  arrived(save, &h.bottom, &h.size);
}

void LocalRanks::entry() {
  LocalRanks* group = starting_group;
  const int r = starting_rank, t = starting_thread;
  Fibers& F = *group->fibers_;
  Fibers::Home& h = F.home[static_cast<std::size_t>(t)];
  arrived(nullptr, &h.bottom, &h.size);
  F.play(r);
  F.fiber[static_cast<std::size_t>(r)].done = true;
  --F.live, ++F.returned;
  switching_to(nullptr, h.bottom, h.size);
  setcontext(&h.context);
}

LocalRanks::LocalRanks(int size, int threads)
    : size_(size), threads_(std::clamp(threads, 1, size)), fibers_(std::make_unique<Fibers>(size, threads_)),
      calls_(static_cast<std::size_t>(size), 0) {
  const std::size_t P = static_cast<std::size_t>(size);
  for (Posts& p : posts_) p.inbox.resize(P), p.data.resize(P);
}

LocalRanks::~LocalRanks() = default;

void LocalRanks::work(int t) {
  Fibers& F = *fibers_;
  starting_group = this;
  for (;;) {
    for (int r = t; r < size_; r += threads_)
      if (!F.fiber[static_cast<std::size_t>(r)].done) F.resume(t, r);
    F.round->arrive_and_wait();
    if (F.finished) return;
  }
}

void LocalRanks::run(const std::function<void(int)>& play) {
  Fibers& F = *fibers_;
  F.play = play;
  F.stopped = &stopped_;
  for (int r = 0; r < size_; ++r) F.make(r);
  F.live = size_;
  // threads of their own, not the caller's: a rank's settings of its thread
  // (omp_set_num_threads) stay with the played ranks; a thread that cannot
  // start leaves its share to fewer threads
  std::latch go(1);
  std::vector<std::jthread> threads;
  std::string why;
  try {
    for (int t = 0; t < threads_; ++t)
      threads.emplace_back([this, &go, t] {
        go.wait();
        work(t);
      });
  } catch (const std::system_error& e) {
    why = e.what();
  }
  threads_ = static_cast<int>(threads.size()); // read by the threads only after go
  if (threads_ > 0) F.round.emplace(threads_, Fibers::RoundEnd{&F});
  go.count_down();
  threads.clear(); // joins
  if (threads_ == 0) throw std::runtime_error("cannot start a thread to play the ranks: " + why);
  if (F.mismatch)
    throw std::logic_error("Comm::run_local: a rank returned while another waited in a collective (the ranks' "
                           "collectives do not match)");
}

void LocalRanks::wait(int rank) {
  if (stopped_) throw Stopped{};
  fibers_->park(rank % threads_, rank);
  if (stopped_) throw Stopped{};
}

void LocalRanks::stop() { stopped_ = true; } // the waiting ranks see it when the next round resumes them

Gathered LocalRanks::allgather(int rank, const Bytes& mine) {
  const long long call = calls_[static_cast<std::size_t>(rank)];
  Posts& p = posts(rank);
  std::shared_ptr<std::vector<Bytes>> slots;
  {
    // The first rank of this collective makes the vector every rank writes
    // to and shares; those of two collectives before still hold theirs.
    const std::lock_guard<std::mutex> lock(mutex_);
    if (p.slots_call != call) p.slots = std::make_shared<std::vector<Bytes>>(static_cast<std::size_t>(size_)), p.slots_call = call;
    slots = p.slots;
  }
  (*slots)[static_cast<std::size_t>(rank)] = mine;
  wait(rank);
  return Gathered(std::move(slots));
}

void LocalRanks::post(Posts& p, int rank, Messages send) {
  const std::lock_guard<std::mutex> lock(mutex_);
  for (auto& [to, bytes] : send) p.inbox[static_cast<std::size_t>(to)].emplace_back(rank, std::move(bytes));
}

Messages LocalRanks::take(Posts& p, int rank) {
  Messages received;
  received.swap(p.inbox[static_cast<std::size_t>(rank)]); // left empty for the next use
  std::sort(received.begin(), received.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return received;
}

std::vector<Bytes> LocalRanks::alltoall(int rank, std::vector<Bytes> send) {
  Messages some; // only the messages there are: most are empty
  for (std::size_t to = 0; to < send.size(); ++to)
    if (!send[to].empty()) some.emplace_back(static_cast<int>(to), std::move(send[to]));
  send = {};
  std::vector<Bytes> received(static_cast<std::size_t>(size_));
  for (auto& [from, bytes] : sparse_alltoall(rank, std::move(some))) received[static_cast<std::size_t>(from)] = std::move(bytes);
  return received;
}

Messages LocalRanks::sparse_alltoall(int rank, Messages send) {
  Posts& p = posts(rank);
  post(p, rank, std::move(send));
  wait(rank);
  Messages received = take(p, rank);
  std::erase_if(received, [](const auto& m) { return m.second.empty(); });
  return received;
}

void LocalRanks::broadcast(int rank, void* data, std::size_t bytes, int from) {
  Posts& p = posts(rank);
  if (rank == from) p.result.assign(static_cast<const char*>(data), static_cast<const char*>(data) + bytes);
  wait(rank);
  if (rank != from && bytes > 0) std::memcpy(data, p.result.data(), bytes);
}

namespace {

template <class T> T combine(T a, T b, LocalRanks::Op op) {
  switch (op) {
  case LocalRanks::Op::sum: return a + b;
  case LocalRanks::Op::max: return std::max(a, b);
  default: return std::min(a, b);
  }
}

} // namespace

template <class T> void LocalRanks::reduce(int rank, std::span<T> values, std::size_t sums, Op rest) {
  const std::size_t n = values.size(), P = static_cast<std::size_t>(size_), r = static_cast<std::size_t>(rank);
  Posts& p = posts(rank);
  if (rank == 0) p.result.assign(n * sizeof(T), 0);
  p.data[r] = values.data();
  wait(rank);
  // each rank combines its slice of the entries, as the tree would
  const std::size_t from = n * r / P, to = n * (r + 1) / P;
  if constexpr (std::is_integral_v<T>) { // exact in any order: rank after rank, along the memory
    std::vector<T> slice(static_cast<const T*>(p.data[0]) + from, static_cast<const T*>(p.data[0]) + to);
    for (std::size_t q = 1; q < P; ++q)
      for (std::size_t i = from; i < to; ++i)
        slice[i - from] = combine(slice[i - from], static_cast<const T*>(p.data[q])[i], i < sums ? Op::sum : rest);
    if (to > from) std::memcpy(p.result.data() + from * sizeof(T), slice.data(), (to - from) * sizeof(T));
  } else {
    std::vector<T> tree(P);
    for (std::size_t i = from; i < to; ++i) {
      for (std::size_t q = 0; q < P; ++q) tree[q] = static_cast<const T*>(p.data[q])[i];
      const Op op = i < sums ? Op::sum : rest;
      for (std::size_t mask = 1; mask < P; mask <<= 1)
        for (std::size_t q = 0; q + mask < P; q += 2 * mask) tree[q] = combine(tree[q], tree[q + mask], op);
      std::memcpy(p.result.data() + i * sizeof(T), &tree[0], sizeof(T));
    }
  }
  wait(rank);
  if (n > 0) std::memcpy(static_cast<void*>(values.data()), p.result.data(), n * sizeof(T));
}

template void LocalRanks::reduce(int, std::span<double>, std::size_t, Op);
template void LocalRanks::reduce(int, std::span<std::int64_t>, std::size_t, Op);

void Comm::run_local(int ranks, const std::function<void(const Comm&)>& body) {
  if (ranks < 1) throw std::invalid_argument("Comm::run_local: " + std::to_string(ranks) + " ranks");
  const int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  auto group = std::make_shared<LocalRanks>(ranks, threads);
  std::vector<std::exception_ptr> failed(static_cast<std::size_t>(ranks));
  group->run([&](int r) {
    Comm c;
    c.rank_ = r, c.size_ = ranks, c.local_ = group;
    try {
      body(c);
    } catch (const LocalRanks::Stopped&) {
    } catch (...) {
      failed[static_cast<std::size_t>(r)] = std::current_exception();
      group->stop();
    }
  });
  for (const std::exception_ptr& e : failed)
    if (e) std::rethrow_exception(e);
}

} // namespace otmpm::distributed
