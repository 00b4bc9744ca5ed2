/// \file comm_local.cpp
/// Ranks played by threads of one process (comm_local.hpp, Comm::run_local).
#include "otmpm/distributed/comm_local.hpp"

#include <algorithm>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <thread>
#include <type_traits>

namespace otmpm::distributed {

LocalRanks::LocalRanks(int size) : size_(size), calls_(static_cast<std::size_t>(size), 0) {
  const std::size_t P = static_cast<std::size_t>(size);
  for (Posts& p : posts_) p.slots.resize(P), p.posts.assign(P, std::vector<Bytes>(P)), p.data.resize(P);
}

void LocalRanks::wait() {
  if (stopped_) throw Stopped{};
  const long long generation = generation_.load();
  if (arrived_.fetch_add(1) + 1 == size_) {
    arrived_.store(0);
    ++generation_;
    generation_.notify_all();
  } else {
    while (generation_.load() == generation && !stopped_) generation_.wait(generation);
  }
  if (stopped_) throw Stopped{};
}

void LocalRanks::stop() {
  stopped_ = true;
  ++generation_; // wakes the waiting ranks, which then see stopped_
  generation_.notify_all();
}

std::vector<Bytes> LocalRanks::allgather(int rank, const Bytes& mine) {
  Posts& p = posts(rank);
  p.slots[static_cast<std::size_t>(rank)] = mine;
  wait();
  return p.slots;
}

std::vector<Bytes> LocalRanks::alltoall(int rank, std::vector<Bytes> send) {
  Posts& p = posts(rank);
  const std::size_t from = static_cast<std::size_t>(rank);
  for (std::size_t to = 0; to < send.size(); ++to) // only the messages there are: most are empty
    if (!send[to].empty()) p.posts[to][from] = std::move(send[to]);
  wait();
  std::vector<Bytes> received(static_cast<std::size_t>(size_));
  received.swap(p.posts[from]); // this rank's row, left empty for the next use
  return received;
}

void LocalRanks::broadcast(int rank, void* data, std::size_t bytes, int from) {
  Posts& p = posts(rank);
  if (rank == from) p.result.assign(static_cast<const char*>(data), static_cast<const char*>(data) + bytes);
  wait();
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
  wait();
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
  wait();
  if (n > 0) std::memcpy(static_cast<void*>(values.data()), p.result.data(), n * sizeof(T));
}

template void LocalRanks::reduce(int, std::span<double>, std::size_t, Op);
template void LocalRanks::reduce(int, std::span<std::int64_t>, std::size_t, Op);

void Comm::run_local(int ranks, const std::function<void(const Comm&)>& body) {
  if (ranks < 1) throw std::invalid_argument("Comm::run_local: " + std::to_string(ranks) + " ranks");
  auto group = std::make_shared<LocalRanks>(ranks);
  std::vector<std::exception_ptr> failed(static_cast<std::size_t>(ranks));
  std::vector<std::thread> threads;
  auto play = [&](int r) {
    Comm c;
    c.rank_ = r, c.size_ = ranks, c.local_ = group;
    try {
      body(c);
    } catch (const LocalRanks::Stopped&) {
    } catch (...) {
      failed[static_cast<std::size_t>(r)] = std::current_exception();
      group->stop();
    }
  };
  try {
    for (int r = 0; r < ranks; ++r) threads.emplace_back(play, r);
  } catch (const std::system_error& e) { // the process may not start that many threads
    group->stop();
    for (std::thread& t : threads) t.join();
    throw std::runtime_error("cannot start " + std::to_string(ranks) + " threads to play the ranks (" +
                             std::to_string(threads.size()) + " started): " + e.what());
  }
  for (std::thread& t : threads) t.join();
  for (const std::exception_ptr& e : failed)
    if (e) std::rethrow_exception(e);
}

} // namespace otmpm::distributed
