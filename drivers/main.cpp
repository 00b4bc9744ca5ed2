// otmpm - command line driver. `otmpm --help` and `otmpm COMMAND --help`
// print the usage, generated from the options (CLI11).
//
// Exit status: 0 success, 1 the simulation became unstable (diagnosis
// printed), 2 bad input (the message names file, line and key; a bad option
// gets CLI11's message; memory running out before the first step), 3
// internal error, 4 a resource ran out during the run (the results could not
// be written, or memory), 130/143 interrupted by SIGINT/SIGTERM (the result
// file stays valid, status "interrupted").
//
// Under mpirun (or srun) `run` and `pair` run distributed over the ranks;
// every rank ends with the same status and one rank prints the diagnosis.
#include "cli.hpp"
#include "interrupt.hpp"
#include "progress.hpp"

#include "otmpm/core.hpp"
#include "otmpm/distributed/comm.hpp"
#include "otmpm/openmp_wait.hpp"

#include <cstdio>
#include <cstring>
#include <exception>
#include <new>
#include <string>
#include <vector>

namespace {

constexpr int kBadInput = 2;

const char* const kFooter =
    "Exit status: 0 ok, 1 the simulation became unstable, 2 bad input (also memory running out\n"
    "before the first step), 3 internal error, 4 the results could not be written or memory ran\n"
    "out while stepping, 130/143 interrupted by SIGINT/SIGTERM. Units: SI (m, s, kg, Pa) or any\n"
    "consistent set. OpenMP threads spin about 0.2 ms, then sleep (OMP_WAIT_POLICY=passive,\n"
    "GOMP_SPINCOUNT for this processor; see the user guide).\n"
    "Each command has its own help: otmpm run --help, ...";

/// An unknown first word would otherwise get CLI11's "A subcommand is required".
bool unknown_command(int argc, char** argv, const CLI::App& app) {
  if (argc < 2 || argv[1][0] == '-') return false;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
    if (sub->get_name() == argv[1]) return false;
  if (!otmpm::distributed::Comm::world().root()) return true;
  std::fprintf(stderr, "otmpm: unknown command '%s' (commands: run, pair, study, basis, render)\n%s\n", argv[1],
               "Run with --help for more information.");
  return true;
}

/// The diagnosis line of an error, ended progress line first.
std::string diagnosis(const char* kind, const char* what) {
  otmpm::cli::end_progress_line();
  return std::string("otmpm: ") + kind + ": " + what;
}

/// Only `run` and `pair` run distributed; the other commands in one process.
void refuse_under_mpirun(const CLI::App& command) {
  const std::string& name = command.get_name();
  if (otmpm::distributed::Comm::world().size() > 1 && name != "run" && name != "pair")
    throw otmpm::InputError("'" + name + "' runs in one process: start it without mpirun");
}

/// Parses the command line and runs the chosen command; returns the exit
/// status, and in `message` the diagnosis of an error (printed by one rank).
int dispatch(CLI::App& app, const std::vector<otmpm::cli::Command>& commands, int argc, char** argv,
             std::string& message) {
  try {
    app.parse(argc, argv);
    const std::vector<CLI::App*> chosen = app.get_subcommands();
    const std::vector<CLI::App*> all = app.get_subcommands([](const CLI::App*) { return true; });
    for (std::size_t i = 0; i < all.size(); ++i)
      if (!chosen.empty() && all[i] == chosen.front()) {
        refuse_under_mpirun(*all[i]);
        return commands[i]();
      }
    return kBadInput;
  } catch (const CLI::ParseError& e) {
    // Help, --version and CLI11's messages from one rank only.
    const int code = otmpm::distributed::Comm::world().root() ? app.exit(e) : e.get_exit_code();
    return code == 0 ? 0 : kBadInput;
  } catch (const otmpm::InputError& e) {
    message = diagnosis("error", e.what());
    return kBadInput;
  } catch (const otmpm::InstabilityError& e) {
    message = diagnosis("unstable", e.what());
    return 1;
  } catch (const otmpm::BasisError& e) {
    message = diagnosis("error", e.what());
    return kBadInput;
  } catch (const otmpm::InterruptedError& e) { // a signal inside the scene's reading: nothing was written
    otmpm::cli::end_progress_line();
    message = std::string("otmpm: ") + e.what() + " (" + otmpm::cli::interrupt_signal_name() +
              "); no result file was written";
    return otmpm::cli::interrupted_exit_status();
  } catch (const std::bad_alloc&) { // not a bug: the input asked for more than this machine gives
    message = diagnosis("error", "out of memory: this process could not get the memory the input asks for "
                                 "(a run that starts stepping stops with status \"out of memory\" and exit status 4)");
    return kBadInput;
  } catch (const std::exception& e) {
    message = diagnosis("internal error", e.what());
    return 3;
  }
}

/// True (and, from the launcher's first process, a message) when mpirun or
/// srun started this process among others that it cannot join as a rank.
bool refuse_lone_ranks() {
  const int n = otmpm::distributed::launcher_size();
  if (n <= otmpm::distributed::Comm::world().size()) return false;
  if (otmpm::distributed::launcher_rank() == 0)
    std::fprintf(stderr,
                 "otmpm: error: started by mpirun or srun as one of %d processes, but this otmpm cannot join them "
                 "as ranks: it was built without MPI (-DOTMPM_MPI=OFF, or OpenMPI and the parallel HDF5 were not "
                 "installed when it was built), or with another MPI than this launcher's. Each process would run "
                 "the whole scene alone: run it without mpirun, or with the mpirun of the MPI it was built with "
                 "(scripts/install-deps.sh installs OpenMPI; then rebuild)\n",
                 n);
  return true;
}

} // namespace

int main(int argc, char** argv) {
  // Before MPI starts: it may execute the process again.
  otmpm::default_openmp_wait(argv);
  otmpm::distributed::Session mpi(argc, argv);
  if (refuse_lone_ranks()) return kBadInput;
  CLI::App app{"otmpm: explicit solid dynamics with the Material Point Method and an OTM-style "
               "updated-Lagrangian scheme",
               "otmpm"};
  app.set_version_flag("--version", otmpm::cli::version(), "Print the version and exit");
  app.require_subcommand(1);
  app.footer(kFooter);
  app.get_formatter()->column_width(34);
  // One entry per subcommand, in the order they are added (get_subcommands' order).
  std::vector<otmpm::cli::Command> commands;
  for (auto add : {otmpm::cli::add_run_command, otmpm::cli::add_pair_command, otmpm::cli::add_study_command,
                   otmpm::cli::add_basis_command, otmpm::cli::add_render_command})
    commands.push_back(add(app));
  if (unknown_command(argc, argv, app)) return mpi.finish(kBadInput, "");
  std::string message;
  const int status = dispatch(app, commands, argc, argv, message);
  return mpi.finish(status, message);
}
