#pragma once
/// \file progress.hpp
/// Progress of a run on stderr. On a terminal: a bar redrawn at most ten
/// times a second with step, t and the estimated time left (ETA). Otherwise
/// (a log file, a batch system): one line every `interval` seconds,
///   otmpm: step 1200, t = 4.1e-05 s of 0.0001 s (41.0%), elapsed 5.0 s, ETA 7.2 s
/// The ETA assumes the remaining simulated time costs as much wall time per
/// second as the part done so far (since this process started stepping).
#include <functional>

namespace otmpm::cli {

/// The RunOptions::progress callback for one run (empty when `quiet`).
std::function<void(double t, double t_end, long steps)> make_progress(bool quiet, double interval);

/// Ends the bar's line if one is drawn, so that what is printed next (a
/// diagnosis, an error, the summary) starts on its own line.
void end_progress_line();

} // namespace otmpm::cli
