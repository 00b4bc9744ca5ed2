// otmpm - command line driver.
//
//   otmpm run   SCENE.toml [--set KEY=VALUE]... [--out FILE.h5] [--quiet]
//   otmpm run   --restart CHECKPOINT.h5 [--out FILE.h5] [--quiet]
//   otmpm pair  SCENE.toml [--set KEY=VALUE]... [--quiet]
//   otmpm study STUDY.toml
//   otmpm basis --kind K [options] --out FILE.csv
//
// Exit status: 0 success, 1 the simulation became unstable (diagnosis
// printed), 2 bad input (the message names file, line and key), 3 internal error.
//
// Under mpirun (or srun) `run` and `pair` run distributed over the ranks;
// every rank ends with the same status and one rank prints the diagnosis.
#include "commands.hpp"

#include "otmpm/core.hpp"
#include "otmpm/distributed/comm.hpp"

#include <cstdio>
#include <exception>
#include <string>
#include <vector>

namespace {

void usage(std::FILE* out) {
  std::fputs("usage:\n"
             "  otmpm run   SCENE.toml [--set KEY=VALUE]... [--out FILE.h5] [--quiet]\n"
             "  otmpm run   --restart CHECKPOINT.h5 [--out FILE.h5] [--quiet]\n"
             "  otmpm pair  SCENE.toml [--set KEY=VALUE]... [--quiet]\n"
             "  otmpm study STUDY.toml\n"
             "  otmpm basis --kind K [--dim D] [--lower X] [--upper X] [--cells N] [--perturb F]\n"
             "              [--gamma-lme G] [--tolerance T] [--d-max D] [--samples N] --out FILE.csv\n"
             "exit status: 0 ok, 1 unstable, 2 bad input, 3 internal error\n",
             out);
}

/// Runs the command; returns its exit status, and in `message` the diagnosis of an error.
int dispatch(const std::vector<std::string>& args, std::string& message) {
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  try {
    if (args[0] == "run") return otmpm::cli::run_command(rest);
    if (args[0] == "pair") return otmpm::cli::pair_command(rest);
    if (otmpm::distributed::Comm::world().size() > 1)
      throw otmpm::InputError("'" + args[0] + "' runs in one process: start it without mpirun");
    if (args[0] == "basis") return otmpm::cli::basis_command(rest);
    if (args[0] == "study") return otmpm::cli::study_command(rest);
    if (args[0] == "--version") {
      std::puts(otmpm::cli::version());
      return 0;
    }
    std::fprintf(stderr, "otmpm: unknown command '%s'\n", args[0].c_str());
    usage(stderr);
    return 2;
  } catch (const otmpm::InputError& e) {
    message = std::string("otmpm: error: ") + e.what();
    return 2;
  } catch (const otmpm::InstabilityError& e) {
    message = std::string("otmpm: unstable: ") + e.what();
    return 1;
  } catch (const otmpm::BasisError& e) {
    message = std::string("otmpm: error: ") + e.what();
    return 2;
  } catch (const std::exception& e) {
    message = std::string("otmpm: internal error: ") + e.what();
    return 3;
  }
}

} // namespace

int main(int argc, char** argv) {
  otmpm::distributed::Session mpi(argc, argv);
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    if (otmpm::distributed::Comm::world().root()) usage(args.empty() ? stderr : stdout);
    return mpi.finish(args.empty() ? 2 : 0, "");
  }
  std::string message;
  const int status = dispatch(args, message);
  return mpi.finish(status, message);
}
