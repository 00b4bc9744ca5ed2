#include "otmpm/interrupt.hpp"

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

namespace otmpm {

namespace {
std::atomic<const std::atomic<bool>*> polled{nullptr};
} // namespace

InterruptPolling::InterruptPolling(const std::atomic<bool>* flag) : previous_(polled.exchange(flag)) {}
InterruptPolling::~InterruptPolling() { polled.store(previous_); }

void interrupt_point(const char* what) {
  const std::atomic<bool>* flag = polled.load(std::memory_order_relaxed);
  if (!flag || !flag->load(std::memory_order_relaxed)) return;
#ifdef OTMPM_HAVE_OPENMP
  if (omp_in_parallel()) return; // an exception may not leave a parallel region
#endif
  throw InterruptedError(std::string("interrupted while ") + what);
}

} // namespace otmpm
