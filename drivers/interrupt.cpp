#include "interrupt.hpp"

#include "otmpm/distributed/comm.hpp"

#include <csignal>
#include <cstdint>
#include <cstdio>

namespace otmpm::cli {

namespace {

std::atomic<bool> flag{false};
volatile std::sig_atomic_t signal_number = 0;
static_assert(std::atomic<bool>::is_always_lock_free, "the flag is set from a signal handler");

extern "C" void on_signal(int sig) {
  signal_number = sig;
  flag.store(true);
}

constexpr int kSignals[] = {SIGINT, SIGTERM};
struct sigaction previous[2];

} // namespace

InterruptHandlers::InterruptHandlers() : polling_(&flag) {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  // No SA_RESTART: a study's waitpid() returns (EINTR) so it can stop its
  // children. SA_RESETHAND: a second signal ends the process at once.
  sa.sa_flags = SA_RESETHAND;
  for (int i = 0; i < 2; ++i) sigaction(kSignals[i], &sa, &previous[i]);
}

InterruptHandlers::~InterruptHandlers() {
  for (int i = 0; i < 2; ++i) sigaction(kSignals[i], &previous[i], nullptr);
}

const std::atomic<bool>& interrupt_flag() { return flag; }
int interrupt_signal() { return signal_number; }
int interrupted_exit_status() { return 128 + (signal_number ? signal_number : SIGINT); }

const char* interrupt_signal_name() {
  static char buf[32];
  if (signal_number == SIGINT) return "SIGINT";
  if (signal_number == SIGTERM) return "SIGTERM";
  std::snprintf(buf, sizeof buf, "signal %d", static_cast<int>(signal_number));
  return buf;
}

void share_interrupt_signal() {
  const auto& world = distributed::Comm::world();
  if (world.size() > 1) signal_number = static_cast<int>(world.max(static_cast<std::int64_t>(signal_number)));
}

} // namespace otmpm::cli
