/// \file background_writer.cpp
/// BackgroundWriter: one job at a time on a thread of its own.
#include "otmpm/run/background_writer.hpp"

#include "otmpm/openmp_wait.hpp"

#include <chrono>
#include <utility>

namespace otmpm {

// Bound OpenMP threads: the writer would otherwise inherit the first
// thread's place and share its core (allow_every_place).
BackgroundWriter::BackgroundWriter()
    : thread_([this] {
        allow_every_place();
        loop();
      }) {}

BackgroundWriter::~BackgroundWriter() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join(); // the job in flight finishes first
}

void BackgroundWriter::submit(std::function<void()> job) {
  wait();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    job_ = std::move(job);
  }
  wake_.notify_all();
}

void BackgroundWriter::wait() {
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [this] { return !job_; });
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

double BackgroundWriter::busy_seconds() {
  std::lock_guard<std::mutex> lock(mutex_);
  return busy_;
}

std::exception_ptr BackgroundWriter::run_job(std::unique_lock<std::mutex>& lock) {
  lock.unlock();
  const auto start = std::chrono::steady_clock::now();
  std::exception_ptr error;
  try {
    job_(); // only this thread touches job_ while it is set
  } catch (...) {
    error = std::current_exception();
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  lock.lock();
  busy_ += seconds;
  return error;
}

void BackgroundWriter::loop() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return stop_ || job_; });
    if (!job_) return; // stopped with nothing left to do
    const std::exception_ptr error = run_job(lock);
    if (error && !error_) error_ = error;
    job_ = nullptr;
    done_.notify_all();
  }
}

} // namespace otmpm
