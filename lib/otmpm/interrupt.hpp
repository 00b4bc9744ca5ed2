#pragma once
/// \file interrupt.hpp
/// A request from outside to stop (otmpm run on SIGINT/SIGTERM) seen inside
/// the long loops of a set-up - a particle file's rows, a body's seeding
/// cells, a mesh body's elements, a checkpoint's arrays - and not only
/// between steps: while an InterruptPolling is alive, interrupt_point()
/// throws InterruptedError as soon as its flag is set, so a set-up of 1e8
/// rows stops within one block of rows. Nothing has been created then (the
/// result file is created after the set-up), so nothing is left half-written.
///
/// The processes of a distributed run each get their own signal (a batch
/// system may signal one rank only): with InterruptPeers, the process that
/// sees its flag tells the others, and each of them stops at its own next
/// interrupt_point() - inside its loop, not after it. The ranks then meet
/// at the agreement after the loop (distributed::agree_on), which every
/// rank reaches with the same InterruptedError.
#include <atomic>
#include <stdexcept>
#include <string>

namespace otmpm {

/// The set-up stopped at the user's request (a polled flag was set).
class InterruptedError : public std::runtime_error {
public:
  explicit InterruptedError(const std::string& what) : std::runtime_error(what) {}
};

/// The other processes of a distributed run, as interrupt_point() sees them.
class InterruptPeers {
public:
  virtual ~InterruptPeers() = default;
  /// Tells every other process that this one stops (once; does not wait).
  virtual void tell() = 0;
  /// True when another process told this one that it stops (cheap: it
  /// looks at most every few milliseconds).
  virtual bool told() = 0;
};

/// Makes interrupt_point() poll `flag` (nullptr: poll nothing) - and, with
/// `peers`, the other processes' stops - for the lifetime of the object;
/// the previous polling holds again afterwards. One process-wide polling,
/// set up from one thread.
class InterruptPolling {
public:
  explicit InterruptPolling(const std::atomic<bool>* flag, InterruptPeers* peers = nullptr);
  ~InterruptPolling();
  InterruptPolling(const InterruptPolling&) = delete;
  InterruptPolling& operator=(const InterruptPolling&) = delete;

  /// The polled flag (nullptr: none) and the peers (nullptr: none).
  const std::atomic<bool>* flag() const { return flag_; }
  InterruptPeers* peers() const { return peers_; }

private:
  const std::atomic<bool>* flag_;
  InterruptPeers* peers_;
  const InterruptPolling* previous_;
};

/// Throws InterruptedError ("interrupted while WHAT") when the polled flag is
/// set or a peer stopped. Cheap (one load, and a clock read with peers);
/// does nothing inside an OpenMP parallel region.
void interrupt_point(const char* what);

} // namespace otmpm
