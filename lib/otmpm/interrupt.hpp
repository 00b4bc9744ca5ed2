#pragma once
/// \file interrupt.hpp
/// A request from outside to stop (otmpm run on SIGINT/SIGTERM) seen inside
/// the long loops of a set-up - a particle file's rows, a body's seeding
/// cells, a mesh body's elements - and not only between steps: while an
/// InterruptPolling is alive, interrupt_point() throws InterruptedError as
/// soon as its flag is set, so a set-up of 1e8 rows stops within one block
/// of rows. Nothing has been created then (the result file is created after
/// the set-up), so nothing is left half-written.
#include <atomic>
#include <stdexcept>
#include <string>

namespace otmpm {

/// The set-up stopped at the user's request (a polled flag was set).
class InterruptedError : public std::runtime_error {
public:
  explicit InterruptedError(const std::string& what) : std::runtime_error(what) {}
};

/// Makes interrupt_point() poll `flag` (nullptr: poll nothing) for the
/// lifetime of the object; the previous flag is polled again afterwards.
/// One process-wide flag (a signal handler's), set up from one thread.
class InterruptPolling {
public:
  explicit InterruptPolling(const std::atomic<bool>* flag);
  ~InterruptPolling();
  InterruptPolling(const InterruptPolling&) = delete;
  InterruptPolling& operator=(const InterruptPolling&) = delete;

private:
  const std::atomic<bool>* previous_;
};

/// Throws InterruptedError ("interrupted while WHAT") when the polled flag is
/// set. Cheap (one load); does nothing inside an OpenMP parallel region.
void interrupt_point(const char* what);

} // namespace otmpm
