/// \file comm.cpp
/// The MPI layer (comm.hpp): ordered reductions along a binomial tree,
/// point-to-point and all-to-all byte exchanges, the MPI session. Without
/// MPI (no OTMPM_HAVE_MPI) every operation is that of a single rank.
#include "otmpm/distributed/comm.hpp"
#include "otmpm/distributed/comm_local.hpp"

#include "otmpm/core.hpp"
#include "otmpm/interrupt.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <initializer_list>
#include <new>
#include <thread>
#include <cstring>
#include <exception>
#include <limits>
#include <stdexcept>

#ifdef OTMPM_HAVE_MPI
#include <mpi.h>
#endif

namespace otmpm::distributed {

namespace {

#ifdef OTMPM_HAVE_MPI
/// Tags of the point-to-point messages (reductions, exchanges).
constexpr int kTreeTag = 7101;
constexpr int kExchangeTag = 7102;
/// Tag of a notice to the other ranks (interrupt_peers()).
constexpr int kNoticeTag = 7103;
/// Tag of a rank's failure (stop_every_rank()).
constexpr int kFailureTag = 7104;

/// The communicator of the ranks' operations: MPI_COMM_WORLD, until a rank
/// fails between two of them (stop_every_rank): then `spare`, a copy made
/// when MPI started, on which no operation of the abandoned step is pending.
MPI_Comm active = MPI_COMM_WORLD;
MPI_Comm spare = MPI_COMM_NULL;
/// This rank told the others of its failure (it waits for them at most Session::kExitWait).
bool failed = false;
std::string failure_message;

MPI_Comm world_comm() { return active; }

/// Takes the spare communicator: the operations of the step that failed are abandoned.
void abandon_step() {
  active = spare;
  spare = MPI_COMM_NULL;
}

/// When another rank told of its failure (stop_every_rank): every rank
/// throws its DeferredOutOfMemory from the operation it waits in. On the
/// rank that failed: when the others have not come within Session::kExitWait
/// (they wait inside a library's collective, out of this layer's sight), the
/// last resort ends every rank.
void look_for_failure(std::chrono::steady_clock::time_point start) {
  if (failed) {
    if (std::chrono::steady_clock::now() - start > std::chrono::duration<double>(Session::kExitWait)) {
      std::fprintf(stderr, "otmpm: out of memory: %s\n", failure_message.c_str());
      Session::abort(4);
    }
    return;
  }
  if (spare == MPI_COMM_NULL) return; // no step to abandon (MPI not started by a Session, or a failure before)
  int found = 0;
  MPI_Status status;
  MPI_Iprobe(MPI_ANY_SOURCE, kFailureTag, active, &found, &status);
  if (!found) return;
  int n = 0;
  MPI_Get_count(&status, MPI_CHAR, &n);
  std::string message(static_cast<std::size_t>(n), '\0');
  MPI_Recv(message.data(), n, MPI_CHAR, status.MPI_SOURCE, kFailureTag, active, MPI_STATUS_IGNORE);
  abandon_step();
  throw DeferredOutOfMemory(message);
}

/// A buffer that an operation of MPI writes into: freed when the operation
/// is done, kept (never freed) when the rank abandons the step inside the
/// operation (look_for_failure threw), since MPI may still write into it.
template <class T> class Landing {
public:
  explicit Landing(std::size_t n, T value = T()) : v_(new std::vector<T>(n, value)) {}
  ~Landing() {
    if (std::uncaught_exceptions() == exceptions_) delete v_;
  }
  Landing(const Landing&) = delete;
  Landing& operator=(const Landing&) = delete;
  std::vector<T>& operator*() { return *v_; }
  std::vector<T>* operator->() { return v_; }

private:
  std::vector<T>* v_;
  int exceptions_ = std::uncaught_exceptions();
};

/// MPI_Waitall that looks for another rank's failure while it waits.
void wait_all(int n, MPI_Request* requests) {
  const auto start = std::chrono::steady_clock::now();
  for (long spins = 0;; ++spins) {
    int done = 0;
    MPI_Testall(n, requests, &done, MPI_STATUSES_IGNORE);
    if (done) return;
    look_for_failure(start);
    if (spins > 1000) std::this_thread::yield();
  }
}
void wait_one(MPI_Request& request) { wait_all(1, &request); }

/// MPI_Probe of a message from `from` with `tag`, looking for failures while it waits.
void probe(int from, int tag, MPI_Status& status) {
  const auto start = std::chrono::steady_clock::now();
  for (long spins = 0;; ++spins) {
    int found = 0;
    MPI_Iprobe(from, tag, world_comm(), &found, &status);
    if (found) return;
    look_for_failure(start);
    if (spins > 1000) std::this_thread::yield();
  }
}

bool mpi_running() {
  int init = 0, fin = 0;
  MPI_Initialized(&init);
  MPI_Finalized(&fin);
  return init && !fin;
}

int checked_count(std::size_t n) {
  if (n > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    throw std::length_error("distributed: a message of " + std::to_string(n) + " bytes is too long for MPI");
  return static_cast<int>(n);
}

/// Combines `values` of every rank into rank 0 along a binomial tree
/// (children combined in increasing rank order): the first `sums` entries
/// added, the rest by maximum; then broadcasts the result.
void tree_reduce(double* values, int n, int sums, int rank, int size) {
  Landing<double> child(static_cast<std::size_t>(n));
  for (int mask = 1; mask < size; mask <<= 1) {
    MPI_Request r;
    if (rank & mask) {
      MPI_Isend(values, n, MPI_DOUBLE, rank - mask, kTreeTag, world_comm(), &r);
      wait_one(r);
      break;
    }
    if (rank + mask < size) {
      MPI_Irecv(child->data(), n, MPI_DOUBLE, rank + mask, kTreeTag, world_comm(), &r);
      wait_one(r);
      for (int i = 0; i < n; ++i) {
        const double c = (*child)[static_cast<std::size_t>(i)];
        values[i] = i < sums ? values[i] + c : std::max(values[i], c);
      }
    }
  }
  MPI_Request r;
  MPI_Ibcast(values, n, MPI_DOUBLE, 0, world_comm(), &r);
  wait_one(r);
}

/// MPI_Allreduce in place of `n` values of T, looking for failures while it waits.
template <class T> void allreduce(T* values, int n, MPI_Datatype type, MPI_Op op) {
  Landing<T> v(static_cast<std::size_t>(n));
  std::copy(values, values + n, v->begin());
  MPI_Request r;
  MPI_Iallreduce(MPI_IN_PLACE, v->data(), n, type, op, world_comm(), &r);
  wait_one(r);
  std::copy(v->begin(), v->end(), values);
}
#endif

/// Environment variables set by the launchers (OpenMPI's mpirun, PMI/PMIx, srun).
bool started_by_launcher() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_SIZE", "PMI_RANK"})
    if (std::getenv(v)) return true;
  return false;
}

} // namespace

namespace {

/// The first of the environment variables that holds an integer, else `fallback`.
int launcher_value(std::initializer_list<const char*> names, int fallback) {
  for (const char* v : names)
    if (const char* text = std::getenv(v)) {
      char* end = nullptr;
      const long n = std::strtol(text, &end, 10);
      if (end != text && *end == '\0' && n >= 0 && n < (1L << 30)) return static_cast<int>(n);
    }
  return fallback;
}

} // namespace

int launcher_size() { return std::max(1, launcher_value({"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"}, 1)); }
int launcher_rank() { return launcher_value({"OMPI_COMM_WORLD_RANK", "PMI_RANK"}, 0); }

const Comm& Comm::self() {
  static const Comm one;
  return one;
}

const Comm& Comm::world() {
#ifdef OTMPM_HAVE_MPI
  if (mpi_running()) {
    static const Comm w = [] {
      Comm c;
      c.mpi_ = true;
      MPI_Comm_rank(world_comm(), &c.rank_);
      MPI_Comm_size(world_comm(), &c.size_);
      return c;
    }();
    return w;
  }
#endif
  return self();
}

void Comm::sum(std::span<double> values) const { reduce(values, {}); }

void Comm::reduce(std::span<double> sums, std::span<double> maxima) const {
  if (local_) {
    std::vector<double> v(sums.begin(), sums.end());
    v.insert(v.end(), maxima.begin(), maxima.end());
    local_->reduce<double>(rank_, v, sums.size(), LocalRanks::Op::max);
    std::copy(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(sums.size()), sums.begin());
    std::copy(v.begin() + static_cast<std::ptrdiff_t>(sums.size()), v.end(), maxima.begin());
    return;
  }
#ifdef OTMPM_HAVE_MPI
  if (!mpi_ || size_ == 1) return;
  Landing<double> landing(sums.size() + maxima.size());
  std::vector<double>& v = *landing;
  std::copy(sums.begin(), sums.end(), v.begin());
  std::copy(maxima.begin(), maxima.end(), v.begin() + static_cast<std::ptrdiff_t>(sums.size()));
  tree_reduce(v.data(), checked_count(v.size()), static_cast<int>(sums.size()), rank_, size_);
  std::copy(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(sums.size()), sums.begin());
  std::copy(v.begin() + static_cast<std::ptrdiff_t>(sums.size()), v.end(), maxima.begin());
#else
  (void)sums, (void)maxima;
#endif
}

double Comm::sum(double value) const {
  sum(std::span<double>(&value, 1));
  return value;
}

void Comm::sum(std::span<std::int64_t> values) const {
  if (local_) return local_->reduce(rank_, values, values.size(), LocalRanks::Op::sum);
#ifdef OTMPM_HAVE_MPI
  if (mpi_ && size_ > 1)
    allreduce(values.data(), checked_count(values.size()), MPI_INT64_T, MPI_SUM);
#else
  (void)values;
#endif
}

std::int64_t Comm::sum(std::int64_t value) const {
  sum(std::span<std::int64_t>(&value, 1));
  return value;
}

void Comm::max(std::span<double> values) const {
  if (local_) return local_->reduce(rank_, values, 0, LocalRanks::Op::max);
#ifdef OTMPM_HAVE_MPI
  if (mpi_ && size_ > 1)
    allreduce(values.data(), checked_count(values.size()), MPI_DOUBLE, MPI_MAX);
#else
  (void)values;
#endif
}

void Comm::min(std::span<double> values) const {
  if (local_) return local_->reduce(rank_, values, 0, LocalRanks::Op::min);
#ifdef OTMPM_HAVE_MPI
  if (mpi_ && size_ > 1)
    allreduce(values.data(), checked_count(values.size()), MPI_DOUBLE, MPI_MIN);
#else
  (void)values;
#endif
}

double Comm::max(double value) const {
  max(std::span<double>(&value, 1));
  return value;
}

double Comm::min(double value) const {
  min(std::span<double>(&value, 1));
  return value;
}

std::int64_t Comm::min(std::int64_t value) const {
  if (local_) local_->reduce(rank_, std::span<std::int64_t>(&value, 1), 0, LocalRanks::Op::min);
#ifdef OTMPM_HAVE_MPI
  if (mpi_ && size_ > 1) allreduce(&value, 1, MPI_INT64_T, MPI_MIN);
#endif
  return value;
}

std::int64_t Comm::max(std::int64_t value) const {
  if (local_) local_->reduce(rank_, std::span<std::int64_t>(&value, 1), 0, LocalRanks::Op::max);
#ifdef OTMPM_HAVE_MPI
  if (mpi_ && size_ > 1) allreduce(&value, 1, MPI_INT64_T, MPI_MAX);
#endif
  return value;
}

std::vector<std::int64_t> Comm::allgather(std::int64_t value) const {
  std::vector<std::int64_t> all(static_cast<std::size_t>(size_), value);
  if (local_) {
    Bytes mine;
    put(mine, value);
    const Gathered in = local_->allgather(rank_, mine);
    for (std::size_t q = 0; q < in.size(); ++q) all[q] = Reader(in[q]).get<std::int64_t>();
  }
#ifdef OTMPM_HAVE_MPI
  if (mpi_ && size_ > 1) {
    Landing<std::int64_t> in(all.size());
    MPI_Request r;
    MPI_Iallgather(&value, 1, MPI_INT64_T, in->data(), 1, MPI_INT64_T, world_comm(), &r);
    wait_one(r);
    all = *in;
  }
#endif
  return all;
}

std::string Comm::broadcast(const std::string& text, int from) const {
  if (size_ == 1) return text;
  std::int64_t n = static_cast<std::int64_t>(text.size());
  broadcast(&n, sizeof n, from);
  std::string out = rank_ == from ? text : std::string(static_cast<std::size_t>(n), '\0');
  broadcast(out.data(), out.size(), from);
  return out;
}

void Comm::broadcast(void* data, std::size_t bytes, int from) const {
  if (local_) return local_->broadcast(rank_, data, bytes, from);
#ifdef OTMPM_HAVE_MPI
  if (mpi_ && size_ > 1 && bytes > 0) {
    Landing<char> v(bytes);
    if (rank_ == from) std::memcpy(v->data(), data, bytes);
    MPI_Request r;
    MPI_Ibcast(v->data(), checked_count(bytes), MPI_BYTE, from, world_comm(), &r);
    wait_one(r);
    std::memcpy(data, v->data(), bytes);
  }
#else
  (void)data, (void)bytes, (void)from;
#endif
}

std::vector<Bytes> Comm::exchange(const std::vector<int>& to, const std::vector<Bytes>& send,
                                  const std::vector<int>& from) const {
  std::vector<Bytes> received(from.size());
  if (local_) throw std::logic_error("Comm::exchange: not available between ranks played in one process");
#ifdef OTMPM_HAVE_MPI
  if (!mpi_) return received;
  std::vector<MPI_Request> requests(to.size());
  for (std::size_t i = 0; i < to.size(); ++i)
    MPI_Isend(send[i].data(), checked_count(send[i].size()), MPI_BYTE, to[i], kExchangeTag, world_comm(), &requests[i]);
  for (std::size_t i = 0; i < from.size(); ++i) {
    MPI_Status status;
    probe(from[i], kExchangeTag, status);
    int count = 0;
    MPI_Get_count(&status, MPI_BYTE, &count);
    received[i].resize(static_cast<std::size_t>(count));
    MPI_Recv(received[i].data(), count, MPI_BYTE, from[i], kExchangeTag, world_comm(), MPI_STATUS_IGNORE);
  }
  wait_all(static_cast<int>(requests.size()), requests.data());
#else
  (void)to, (void)send;
#endif
  return received;
}

std::vector<Bytes> Comm::alltoall(std::vector<Bytes> send) const {
  if (send.size() != static_cast<std::size_t>(size_))
    throw std::invalid_argument("Comm::alltoall: " + std::to_string(send.size()) + " buffers for " +
                                std::to_string(size_) + " ranks");
  if (size_ == 1) return send;
  if (local_) return local_->alltoall(rank_, std::move(send));
  std::vector<Bytes> received(static_cast<std::size_t>(size_));
#ifdef OTMPM_HAVE_MPI
  const std::size_t P = static_cast<std::size_t>(size_);
  // the counts and offsets too: MPI reads them until the operations end
  Landing<int> l1(P), l2(P), l3(P), l4(P);
  std::vector<int>& send_count = *l1;
  std::vector<int>& recv_count = *l2;
  std::vector<int>& send_at = *l3;
  std::vector<int>& recv_at = *l4;
  for (std::size_t q = 0; q < P; ++q) send_count[q] = checked_count(send[q].size());
  MPI_Request counted;
  MPI_Ialltoall(send_count.data(), 1, MPI_INT, recv_count.data(), 1, MPI_INT, world_comm(), &counted);
  wait_one(counted);
  std::size_t s = 0, r = 0;
  for (std::size_t q = 0; q < P; ++q) {
    send_at[q] = checked_count(s);
    recv_at[q] = checked_count(r);
    s += static_cast<std::size_t>(send_count[q]);
    r += static_cast<std::size_t>(recv_count[q]);
  }
  Landing<char> sent(s); // MPI may read it after the rank abandoned the step
  Bytes& out = *sent;
  for (std::size_t q = 0; q < P; ++q) {
    std::copy(send[q].begin(), send[q].end(), out.begin() + send_at[q]);
    Bytes().swap(send[q]);
  }
  Landing<char> landing(r);
  Bytes& in = *landing;
  MPI_Request req;
  MPI_Ialltoallv(out.data(), send_count.data(), send_at.data(), MPI_BYTE, in.data(), recv_count.data(),
                 recv_at.data(), MPI_BYTE, world_comm(), &req);
  wait_one(req);
  Bytes().swap(out);
  for (std::size_t q = 0; q < P; ++q)
    received[q].assign(in.begin() + recv_at[q], in.begin() + recv_at[q] + recv_count[q]);
#endif
  return received;
}

Messages Comm::sparse_alltoall(Messages send) const {
  std::stable_sort(send.begin(), send.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (std::size_t i = 0; i < send.size(); ++i) {
    const int to = send[i].first;
    if (to < 0 || to >= size_)
      throw std::invalid_argument("Comm::sparse_alltoall: a message to rank " + std::to_string(to) + " of " +
                                  std::to_string(size_));
    if (i > 0 && to == send[i - 1].first)
      throw std::invalid_argument("Comm::sparse_alltoall: two messages to rank " + std::to_string(to));
  }
  if (local_) return local_->sparse_alltoall(rank_, std::move(send));
  std::vector<Bytes> dense(static_cast<std::size_t>(size_));
  for (auto& [to, bytes] : send) dense[static_cast<std::size_t>(to)] = std::move(bytes);
  send.clear();
  Messages received;
  std::vector<Bytes> in = alltoall(std::move(dense));
  for (std::size_t q = 0; q < in.size(); ++q)
    if (!in[q].empty()) received.emplace_back(static_cast<int>(q), std::move(in[q]));
  return received;
}

Gathered Comm::allgather(const Bytes& mine) const {
  if (size_ == 1) return Gathered(std::make_shared<const std::vector<Bytes>>(1, mine));
  if (local_) return local_->allgather(rank_, mine);
  std::vector<Bytes> received(static_cast<std::size_t>(size_));
#ifdef OTMPM_HAVE_MPI
  const std::size_t P = static_cast<std::size_t>(size_);
  Landing<int> l1(P), l2(P); // MPI reads the counts and offsets until the operations end
  std::vector<int>& count = *l1;
  std::vector<int>& at = *l2;
  const int n = checked_count(mine.size());
  MPI_Request r;
  MPI_Iallgather(&n, 1, MPI_INT, count.data(), 1, MPI_INT, world_comm(), &r);
  wait_one(r);
  std::size_t total = 0;
  for (std::size_t q = 0; q < P; ++q) {
    at[q] = checked_count(total);
    total += static_cast<std::size_t>(count[q]);
  }
  Landing<char> landing(total);
  Bytes& in = *landing;
  MPI_Iallgatherv(mine.data(), n, MPI_BYTE, in.data(), count.data(), at.data(), MPI_BYTE, world_comm(), &r);
  wait_one(r);
  for (std::size_t q = 0; q < P; ++q) received[q].assign(in.begin() + at[q], in.begin() + at[q] + count[q]);
#endif
  return Gathered(std::make_shared<const std::vector<Bytes>>(std::move(received)));
}

void Comm::barrier() const {
  if (local_) return local_->wait(rank_);
#ifdef OTMPM_HAVE_MPI
  if (mpi_ && size_ > 1) {
    MPI_Request r;
    MPI_Ibarrier(world_comm(), &r);
    wait_one(r);
  }
#endif
}

const void* Comm::mpi_comm() const {
#ifdef OTMPM_HAVE_MPI
  if (mpi_) return &active; // MPI_COMM_WORLD; after a rank's failure the spare (stop_every_rank)
#endif
  return nullptr;
}

Session::Session(int& argc, char**& argv) {
#ifdef OTMPM_HAVE_MPI
  if (!started_by_launcher() || mpi_running()) return;
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  initialised_ = true;
  MPI_Comm_dup(MPI_COMM_WORLD, &spare); // for the end of a run whose step a rank abandoned (stop_every_rank)
#else
  (void)argc, (void)argv, (void)started_by_launcher;
#endif
}

Session::~Session() {
#ifdef OTMPM_HAVE_MPI
  if (initialised_ && mpi_running()) MPI_Finalize();
#endif
}

int Session::finish(int status, const std::string& message) {
  const Comm& comm = Comm::world();
  auto print = [&] {
    if (!message.empty()) std::fprintf(stderr, "%s\n", message.c_str());
    std::fflush(stderr);
  };
  if (comm.size() == 1) {
    print();
    return status;
  }
#ifdef OTMPM_HAVE_MPI
  MPI_Request barrier;
  MPI_Ibarrier(world_comm(), &barrier);
  const auto start = std::chrono::steady_clock::now();
  for (int done = 0;;) {
    MPI_Test(&barrier, &done, MPI_STATUS_IGNORE);
    if (done) break;
    const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (status != 0 && waited > kExitWait) {
      print();
      abort(status);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const std::int64_t worst = comm.max(static_cast<std::int64_t>(status));
  const std::int64_t speaker = comm.min(static_cast<std::int64_t>(status == worst ? comm.rank() : comm.size()));
  if (comm.rank() == speaker) print();
  return static_cast<int>(worst);
#else
  return status;
#endif
}

void Session::abort(int status) {
#ifdef OTMPM_HAVE_MPI
  if (mpi_running() && Comm::world().size() > 1) MPI_Abort(world_comm(), status);
#endif
  std::exit(status);
}

void agree_on(const Comm& comm, const std::function<void()>& step) {
  if (comm.size() == 1) return step();
  char kind = 0; // 0: no error; else which error to throw (below)
  std::string message;
  std::exception_ptr mine;
  try {
    step();
  } catch (const std::exception& e) {
    mine = std::current_exception();
    message = e.what();
    kind = dynamic_cast<const InputError*>(&e)         ? 'I'
           : dynamic_cast<const BasisError*>(&e)       ? 'B'
           : dynamic_cast<const InstabilityError*>(&e) ? 'U'
           : dynamic_cast<const OutputError*>(&e)      ? 'O'
           : dynamic_cast<const InterruptedError*>(&e) ? 'S'
                                                       : 'E';
  } catch (...) {
    mine = std::current_exception();
    message = "an exception of unknown type";
    kind = 'E';
  }
  const auto none = static_cast<std::int64_t>(comm.size());
  const std::int64_t first = comm.min(kind ? static_cast<std::int64_t>(comm.rank()) : none);
  if (first == none) return;
  const std::string agreed = comm.broadcast(comm.rank() == first ? std::string(1, kind) + message : "",
                                            static_cast<int>(first));
  if (comm.rank() == first) std::rethrow_exception(mine); // with all it carries (an InputError's source)
  const std::string what = agreed.substr(1);
  switch (agreed.front()) {
  case 'I': throw InputError(what);
  case 'B': throw BasisError(what);
  case 'U': throw InstabilityError(what);
  case 'O': throw OutputError(what);
  case 'S': throw InterruptedError(what);
  default: throw std::runtime_error(what);
  }
}

namespace {

/// At most this many bytes of a line are quoted in a message.
constexpr std::size_t kQuoted = 120;

std::string quoted(const std::string& line) {
  return "'" + (line.size() > kQuoted ? line.substr(0, kQuoted) + "..." : line) + "'";
}

/// The first difference of `mine` from `root`'s text, for a message.
std::string first_difference(const std::string& mine, const std::string& root) {
  std::size_t at = 0, line = 1;
  while (at < mine.size() && at < root.size() && mine[at] == root[at]) line += mine[at++] == '\n';
  const auto line_of = [&](const std::string& s) {
    const std::size_t from = at == 0 ? 0 : s.rfind('\n', at - 1) + 1; // npos + 1 == 0: the first line
    return s.substr(from, s.find('\n', from) - from);
  };
  const bool lines = mine.find('\n') != std::string::npos || root.find('\n') != std::string::npos;
  return (lines ? "line " + std::to_string(line) + " is " : std::string("it is ")) + quoted(line_of(mine)) +
         " where rank 0 has " + quoted(line_of(root));
}

} // namespace

void require_same(const Comm& comm, const std::string& what, const std::string& mine, const std::string& hint) {
  if (comm.size() == 1) return;
  const std::string root = comm.broadcast(mine, 0);
  agree_on(comm, [&] {
    if (mine != root)
      throw InputError("rank " + std::to_string(comm.rank()) + ": " + what + " differs from rank 0's: " +
                       first_difference(mine, root) + " (" + hint + ")");
  });
}

#ifdef OTMPM_HAVE_MPI
namespace {

/// The ranks of world() as InterruptPeers (one message of kNoticeTag per rank).
class WorldPeers final : public InterruptPeers {
public:
  void tell() override {
    if (told_them_) return;
    told_them_ = true;
    for (int q = 0; q < Comm::world().size(); ++q) {
      if (q == Comm::world().rank()) continue;
      MPI_Request r;
      MPI_Isend(&kStop, 1, MPI_INT, q, kNoticeTag, world_comm(), &r);
      MPI_Request_free(&r); // sent in the background; nothing waits for it
    }
  }
  bool told() override {
    if (heard_) return true;
    const auto now = std::chrono::steady_clock::now();
    if (now < next_) return false;
    next_ = now + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                      std::chrono::duration<double>(kNoticeInterval));
    int found = 0;
    MPI_Status status;
    MPI_Iprobe(MPI_ANY_SOURCE, kNoticeTag, world_comm(), &found, &status);
    if (!found) return false;
    int stop = 0;
    MPI_Recv(&stop, 1, MPI_INT, status.MPI_SOURCE, kNoticeTag, world_comm(), MPI_STATUS_IGNORE);
    heard_ = true;
    return true;
  }

private:
  static constexpr int kStop = 1;
  bool told_them_ = false, heard_ = false;
  std::chrono::steady_clock::time_point next_{};
};

} // namespace
#endif

InterruptPeers* interrupt_peers() {
#ifdef OTMPM_HAVE_MPI
  static WorldPeers peers;
  if (Comm::world().size() > 1) return &peers;
#endif
  return nullptr;
}

std::string stop_every_rank(const std::string& message) {
#ifdef OTMPM_HAVE_MPI
  const Comm& w = Comm::world();
  if (w.size() == 1 || spare == MPI_COMM_NULL || failed) throw std::bad_alloc();
  failed = true;
  failure_message = message;
  for (int q = 0; q < w.size(); ++q) {
    if (q == w.rank()) continue;
    MPI_Request r;
    MPI_Isend(failure_message.data(), checked_count(failure_message.size()), MPI_CHAR, q, kFailureTag, active, &r);
    MPI_Request_free(&r); // received by each rank in the operation it waits in
  }
  abandon_step();
  return message;
#else
  (void)message;
  throw std::bad_alloc();
#endif
}

bool built_with_mpi() {
#ifdef OTMPM_HAVE_MPI
  return true;
#else
  return false;
#endif
}

void put_bytes(Bytes& out, const void* data, std::size_t n) {
  const char* p = static_cast<const char*>(data);
  out.insert(out.end(), p, p + n);
}

void Reader::get_bytes(void* data, std::size_t n) {
  if (at_ + n > in_.size()) throw std::logic_error("distributed::Reader: message shorter than expected");
  std::memcpy(data, in_.data() + at_, n);
  at_ += n;
}

} // namespace otmpm::distributed
