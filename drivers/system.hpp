#pragma once
/// \file system.hpp
/// What the otmpm command needs from the operating system: its own path, the
/// data directory with the Python scripts, a Python interpreter, child
/// processes, and checks of input paths.
#include <filesystem>
#include <string>
#include <vector>

namespace otmpm::cli {

/// The running executable (/proc/self/exe), or "otmpm" if unknown.
std::filesystem::path self_path();

/// Where the Python scripts (render.py, plot_study.py, plot_stability.py)
/// are: `given` if not empty, else BINDIR/../share/otmpm next to the running
/// executable - PREFIX/share/otmpm after `cmake --install`, BUILD/share/otmpm
/// in a build tree (the build copies them there). Never the source tree.
std::filesystem::path scripts_dir(const std::string& given = "");

/// The Python that runs the scripts: `given` if not empty, else
/// /usr/bin/python3 (Debian's, with matplotlib) if it exists, else python3
/// on PATH; "" if there is none.
std::string find_python(const std::string& given = "");

/// Runs argv[0] (looked up on PATH if it has no '/') with the given
/// arguments, waits, and returns its exit status (128 + signal if killed;
/// 127 if it could not be started).
int run_and_wait(const std::vector<std::string>& argv);

/// InputError unless `path` is an existing regular file: "PATH: no such
/// WHAT", "PATH: is a directory, not a WHAT" or "PATH: is a FIFO (named
/// pipe), not a WHAT" (a device, a socket).
void require_file(const std::string& path, const std::string& what);

} // namespace otmpm::cli
