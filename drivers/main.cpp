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
#include "commands.hpp"

#include "otmpm/core.hpp"

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

} // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    usage(args.empty() ? stderr : stdout);
    return args.empty() ? 2 : 0;
  }
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  try {
    if (args[0] == "run") return otmpm::cli::run_command(rest);
    if (args[0] == "pair") return otmpm::cli::pair_command(rest);
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
    std::fprintf(stderr, "otmpm: error: %s\n", e.what());
    return 2;
  } catch (const otmpm::InstabilityError& e) {
    std::fprintf(stderr, "otmpm: unstable: %s\n", e.what());
    return 1;
  } catch (const otmpm::BasisError& e) {
    std::fprintf(stderr, "otmpm: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "otmpm: internal error: %s\n", e.what());
    return 3;
  }
}
