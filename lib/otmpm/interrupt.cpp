#include "otmpm/interrupt.hpp"

#ifdef OTMPM_HAVE_OPENMP
#include <omp.h>
#endif

namespace otmpm {

namespace {
std::atomic<const InterruptPolling*> polled{nullptr};
} // namespace

InterruptPolling::InterruptPolling(const std::atomic<bool>* flag, InterruptPeers* peers)
    : flag_(flag), peers_(peers), previous_(polled.exchange(this)) {}
InterruptPolling::~InterruptPolling() { polled.store(previous_); }

void interrupt_point(const char* what) {
  const InterruptPolling* p = polled.load(std::memory_order_relaxed);
  if (!p) return;
  const bool mine = p->flag() && p->flag()->load(std::memory_order_relaxed);
  if (!mine && !p->peers()) return;
#ifdef OTMPM_HAVE_OPENMP
  if (omp_in_parallel()) return; // an exception may not leave a parallel region (nor may a thread call MPI)
#endif
  if (mine) {
    if (p->peers()) p->peers()->tell();
  } else if (!p->peers()->told()) {
    return;
  }
  throw InterruptedError(std::string("interrupted while ") + what);
}

} // namespace otmpm
