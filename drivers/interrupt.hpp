#pragma once
/// \file interrupt.hpp
/// SIGINT and SIGTERM while otmpm works: the first one sets a flag that the
/// run loop reads once per step (RunOptions::interrupt) and the study loop
/// reads while it waits for its children; the run then stops cleanly (status
/// "interrupted", a last checkpoint if checkpointing is on). A second signal
/// of the same kind takes its default action (the process ends at once).
/// While the handlers are installed, the loops of reading a scene and seeding
/// its bodies poll the flag too (otmpm::InterruptPolling): a large particle
/// file stops within a block of rows, with InterruptedError.
#include "otmpm/interrupt.hpp"

#include <atomic>

namespace otmpm::cli {

/// Installs the handlers for the lifetime of the object (not nested).
class InterruptHandlers {
public:
  InterruptHandlers();
  ~InterruptHandlers();
  InterruptHandlers(const InterruptHandlers&) = delete;
  InterruptHandlers& operator=(const InterruptHandlers&) = delete;

private:
  InterruptPolling polling_;
};

/// The flag the handlers set (false until a signal arrives).
const std::atomic<bool>& interrupt_flag();
/// The signal that set the flag (0 if none).
int interrupt_signal();
/// 128 + the signal (130 for SIGINT, 143 for SIGTERM): the exit status of an
/// interrupted command, as a shell reports a process killed by that signal.
int interrupted_exit_status();
/// "SIGINT", "SIGTERM" or "signal N".
const char* interrupt_signal_name();
/// After a distributed run that was interrupted (every rank stops when one
/// got a signal): every rank takes the largest signal any rank got, so the
/// rank that reports it names the signal that stopped the run, not its own
/// (none). Collective; nothing to do in one process.
void share_interrupt_signal();

} // namespace otmpm::cli
