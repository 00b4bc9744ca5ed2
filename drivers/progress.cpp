#include "progress.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <unistd.h>

namespace otmpm::cli {

namespace {

using Clock = std::chrono::steady_clock;

/// True while a bar is drawn and its line not ended.
bool bar_open = false;

constexpr int kBarWidth = 30;
constexpr auto kBarRedraw = std::chrono::milliseconds(100);

/// "12 s", "3 min 20 s", "2 h 05 min".
std::string duration(double seconds) {
  char b[48];
  if (!(seconds >= 0) || seconds > 1e7) return "?";
  const long s = std::lround(seconds);
  if (seconds < 60) std::snprintf(b, sizeof b, "%.1f s", seconds);
  else if (s < 3600) std::snprintf(b, sizeof b, "%ld min %02ld s", s / 60, s % 60);
  else std::snprintf(b, sizeof b, "%ld h %02ld min", s / 3600, (s % 3600) / 60);
  return b;
}

/// Elapsed wall time and ETA of one run, from the first call on.
struct Clocked {
  Clock::time_point start = Clock::now();
  double t0 = -1.0; ///< simulated time at the first call (a restart starts later)
  double elapsed() const { return std::chrono::duration<double>(Clock::now() - start).count(); }
  /// Seconds left at simulated time t of t_end; negative when unknown.
  double eta(double t, double t_end) {
    if (t0 < 0) t0 = t;
    const double done = t - t0;
    return done > 0 ? elapsed() * (t_end - t) / done : -1.0;
  }
};

} // namespace

void end_progress_line() {
  if (!bar_open) return;
  std::fputc('\n', stderr);
  std::fflush(stderr);
  bar_open = false;
}

std::function<void(double, double, long)> make_progress(bool quiet, double interval) {
  if (quiet) return {};
  auto clock = std::make_shared<Clocked>();
  if (isatty(STDERR_FILENO)) {
    auto last = std::make_shared<Clock::time_point>();
    return [clock, last](double t, double t_end, long steps) {
      const double eta = clock->eta(t, t_end);
      const bool done = t >= t_end;
      if (Clock::now() - *last < kBarRedraw && !done) return;
      *last = Clock::now();
      const double frac = t_end > 0 ? std::clamp(t / t_end, 0.0, 1.0) : 1.0;
      const int filled = static_cast<int>(frac * kBarWidth);
      std::fprintf(stderr, "\r[%s%s] %5.1f%%  step %ld  t = %.4g s  %s %s   ", std::string(filled, '#').c_str(),
                   std::string(kBarWidth - filled, ' ').c_str(), 100.0 * frac, steps, t, done ? "took" : "ETA",
                   duration(done ? clock->elapsed() : eta).c_str());
      bar_open = true;
      if (done) end_progress_line();
      std::fflush(stderr);
    };
  }
  auto next = std::make_shared<double>(interval);
  return [clock, next, interval](double t, double t_end, long steps) {
    const double eta = clock->eta(t, t_end);
    const double elapsed = clock->elapsed();
    if (elapsed < *next) return;
    while (*next <= elapsed) *next += interval;
    const double frac = t_end > 0 ? std::clamp(t / t_end, 0.0, 1.0) : 1.0;
    std::fprintf(stderr, "otmpm: step %ld, t = %.6g s of %.6g s (%.1f%%), elapsed %s, ETA %s\n", steps, t, t_end,
                 100.0 * frac, duration(elapsed).c_str(), duration(eta).c_str());
    std::fflush(stderr);
  };
}

} // namespace otmpm::cli
