#pragma once
// The otmpm subcommands; each returns the process exit status.
#include <string>
#include <vector>

namespace otmpm::cli {
int run_command(const std::vector<std::string>& args);
int pair_command(const std::vector<std::string>& args);
int basis_command(const std::vector<std::string>& args);
const char* version();
} // namespace otmpm::cli
namespace otmpm::cli {
int study_command(const std::vector<std::string>& args);
}
