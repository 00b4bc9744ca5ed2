#pragma once
/// \file run_common.hpp
/// What the pieces of a run (run.cpp, simulation.cpp, the recorders) share
/// (internal to run/).
#include "otmpm/io/output_files.hpp"
#include "otmpm/run/run.hpp"

#include <string>
#include <utility>

namespace otmpm {

struct Checkpoint;

/// Relative slack when comparing the simulated time with output times.
inline constexpr double time_slack = 1e-9;

/// A diagnosis that names step and time: `what` as it is when it does (the
/// engine's start with "step N, t = T s"), else prefixed with them.
std::string diagnosis(const std::string& what, long step, double t);

/// The result file of a run and where its name came from: RunOptions::out_file,
/// else a restart's interrupted run's file, else output.file.
std::pair<std::string, std::string> result_file(const Scene& scene, const RunOptions& opt, const Checkpoint* resume);

/// What the run's output files are and where their names came from
/// (prepare_outputs); `text` is the scene as TOML (the identical-scene rule).
OutputRequest output_request(const Scene& scene, const std::string& text, const RunOptions& opt,
                             const Checkpoint* resume);

/// True when options.interrupt asks to stop; the ranks of a distributed run
/// agree (one of them got the signal: all stop at the same point).
bool interrupt_requested(const RunOptions& options);

} // namespace otmpm
