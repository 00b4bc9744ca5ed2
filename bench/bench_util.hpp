// Small helpers shared by the benchmark drivers.
#pragma once

#include <algorithm>
#include <ctime>
#include <vector>

namespace otmpm::bench {

/// Median of the values (the mean of the middle two for an even count).
inline double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// CPU time of the calling thread in nanoseconds (time spent descheduled on a
/// shared machine does not count).
inline double thread_ns() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e9 * double(t.tv_sec) + double(t.tv_nsec);
}

} // namespace otmpm::bench
