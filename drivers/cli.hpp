#pragma once
/// \file cli.hpp
/// The pieces of the `otmpm` command. Each subcommand registers its options
/// on the CLI11 application (so `--help` and the usage text are generated
/// from the options themselves) and returns the function that runs it once
/// the command line is parsed; that function returns the exit status
/// (0 ok, 1 unstable, 2 bad input, 3 internal error, 128 + signal when
/// interrupted).
#include <CLI/CLI.hpp>

#include <functional>
#include <string>

namespace otmpm::cli {

using Command = std::function<int()>;

Command add_run_command(CLI::App& app);    ///< run_commands.cpp
Command add_pair_command(CLI::App& app);   ///< run_commands.cpp
Command add_basis_command(CLI::App& app);  ///< basis_command.cpp
Command add_render_command(CLI::App& app); ///< render_command.cpp
Command add_study_command(CLI::App& app);  ///< study/study_command.cpp

/// "otmpm 0.1.0".
const char* version();

/// Adds `--threads N` (OpenMP threads of this process; 0 or absent: the
/// OpenMP default, OMP_NUM_THREADS or one per core) to a subcommand.
CLI::Option* add_threads_option(CLI::App& sub, int& threads, const std::string& what = "");
/// Applies --threads (nothing for 0).
void set_threads(int threads);
/// True when the OpenMP threads leave at least one of the cores this process
/// may run on free (sched_getaffinity) for the result file's writer thread
/// (RunOptions::background_output): a writer sharing a core with the OpenMP
/// team slows each of its parallel loops (docs/performance.md).
bool core_free_for_writer();
/// The OpenMP threads and the CPUs this process may run on, for `run
/// --check`: "2 OpenMP threads on 2 CPUs", and when there are more threads
/// than CPUs what shares them and how to give each thread its core.
std::string threads_line();

} // namespace otmpm::cli
