// otmpm - command line driver. `otmpm --help` and `otmpm COMMAND --help`
// print the usage, generated from the options (CLI11).
//
// Exit status: 0 success, 1 the simulation became unstable (diagnosis
// printed), 2 bad input (the message names file, line and key; a bad option
// gets CLI11's message), 3 internal error, 130/143 interrupted by
// SIGINT/SIGTERM (the result file stays valid, status "interrupted").
#include "cli.hpp"
#include "progress.hpp"

#include "otmpm/core.hpp"

#include <cstdio>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

namespace {

constexpr int kBadInput = 2;

const char* const kFooter =
    "Exit status: 0 ok, 1 the simulation became unstable, 2 bad input, 3 internal error,\n"
    "130/143 interrupted by SIGINT/SIGTERM. OMP_WAIT_POLICY defaults to passive (see the user guide).\n"
    "Each command has its own help: otmpm run --help, ...";

/// An unknown first word would otherwise get CLI11's "A subcommand is required".
bool unknown_command(int argc, char** argv, const CLI::App& app) {
  if (argc < 2 || argv[1][0] == '-') return false;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
    if (sub->get_name() == argv[1]) return false;
  std::fprintf(stderr, "otmpm: unknown command '%s' (commands: run, pair, study, basis, render)\n%s\n", argv[1],
               "Run with --help for more information.");
  return true;
}

int report(const char* kind, const char* what, int status) {
  otmpm::cli::end_progress_line();
  std::fprintf(stderr, "otmpm: %s: %s\n", kind, what);
  return status;
}

} // namespace

int main(int argc, char** argv) {
  otmpm::cli::default_passive_wait_policy(argv);
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
  if (unknown_command(argc, argv, app)) return kBadInput;
  try {
    app.parse(argc, argv);
    const std::vector<CLI::App*> chosen = app.get_subcommands();
    const std::vector<CLI::App*> all = app.get_subcommands([](const CLI::App*) { return true; });
    for (std::size_t i = 0; i < all.size(); ++i)
      if (!chosen.empty() && all[i] == chosen.front()) return commands[i]();
    return kBadInput;
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : kBadInput;
  } catch (const otmpm::InputError& e) {
    return report("error", e.what(), kBadInput);
  } catch (const otmpm::InstabilityError& e) {
    return report("unstable", e.what(), 1);
  } catch (const otmpm::BasisError& e) {
    return report("error", e.what(), kBadInput);
  } catch (const std::exception& e) {
    return report("internal error", e.what(), 3);
  }
}
