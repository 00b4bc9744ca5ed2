#pragma once
/// \file background_writer.hpp
/// The writer thread of RunOptions::background_output (internal to run/).
#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace otmpm {

/// One writer thread that runs one job at a time (RunOptions::background_output):
/// submit() waits for the job in flight, rethrows what it threw, and hands
/// the thread the next one, so at most one output time is in flight and its
/// writes happen in the order they were submitted. The first exception of a
/// job is kept and rethrown by the next submit() or wait() (once).
class BackgroundWriter {
public:
  BackgroundWriter();
  ~BackgroundWriter(); ///< the job in flight finishes first
  BackgroundWriter(const BackgroundWriter&) = delete;
  BackgroundWriter& operator=(const BackgroundWriter&) = delete;

  /// Waits for the job in flight, rethrows its exception, then starts `job`.
  void submit(std::function<void()> job);
  /// Waits until no job is in flight; rethrows the exception of the last one (once).
  void wait();
  /// Wall seconds the thread spent in jobs.
  double busy_seconds();

private:
  void loop();
  /// Runs job_ with the lock released; its exception, if any.
  std::exception_ptr run_job(std::unique_lock<std::mutex>& lock);

  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::function<void()> job_;
  std::exception_ptr error_;
  bool stop_ = false;
  double busy_ = 0.0;
  std::thread thread_; ///< last: started once the members above exist
};

} // namespace otmpm
