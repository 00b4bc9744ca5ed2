/// \file fuzz_run.cpp
/// libFuzzer target that runs short scenes end to end, the way a user (or a
/// script gone wrong) runs them: `otmpm run` as a child process in a fresh
/// temporary directory, with fuzzed output, checkpoint and probe settings -
/// result and checkpoint paths that collide, point at each other through
/// `.`, `..` and symbolic links, carry a sidecar's extension or name existing
/// files; checkpoint intervals, frame intervals, probe names, fields and
/// formats - sometimes twice in a row, sometimes followed by `--restart`.
///
/// Before each input the directory gets "victims": files otmpm must never
/// change without being told to (random bytes at likely output names, a
/// directory, a symbolic link to a file outside the directory). A finding is:
///  - an exit status outside {0, 1, 2}, or a signal (a crash, a sanitizer
///    report: the child is the instrumented build of `otmpm`);
///  - after exit status 0 or 1, a result file that HDF5 cannot read or whose
///    status is still "running";
///  - a victim changed, a lock file or undo journal left behind, or anything created or
///    changed outside the temporary directory (a sentinel directory beside it
///    is compared before and after).
/// Paths are built from a fixed pool of components with at most two `..`
/// from a working directory two levels deep, so every path the fuzzer writes
/// stays inside the temporary directory unless otmpm itself escapes it.
#include "otmpm/io/results.hpp"

#include "fuzz_common.hpp"

#include <fuzzer/FuzzedDataProvider.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

extern char** environ;

namespace {

namespace fs = std::filesystem;
using otmpm::fuzz::finding;

/// The temporary directory of this fuzzing session and the sentinel beside it.
fs::path root, sentinel;
/// Base scenes, relative to the source tree: a 1D bar and a 2D plate.
constexpr std::array<const char*, 2> kBaseScenes = {"tests/scenes/good_minimal.toml", "examples/mms_plate.toml"};
/// Overrides that make each base scene a run of a few tens of steps.
const std::array<std::vector<std::string>, 2> kShort = {
    std::vector<std::string>{"simulation.t_end=2e-6", "output.every=0"},
    std::vector<std::string>{"grid.cells=[4, 4]", "simulation.t_end=5e-4", "output.every=0"}};

/// Path components and extensions the fuzzer combines into file names.
constexpr std::array<const char*, 8> kNames = {"x", "res", "out", "link", "d", "a", "b", "nodir"};
constexpr std::array<const char*, 9> kExtensions = {".h5",  ".xdmf",  ".txt", "", ".checkpoint.h5",
                                                    ".pvd", ".h5.tmp", ".vtp", ".XDMF"};

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Everything under a directory: relative path -> content ("<dir>" for a
/// directory, "-> TARGET" for a symbolic link).
std::map<std::string, std::string> snapshot(const fs::path& dir) {
  std::map<std::string, std::string> s;
  for (auto it = fs::recursive_directory_iterator(dir); it != fs::recursive_directory_iterator(); ++it) {
    const std::string rel = fs::relative(it->path(), dir).string();
    if (it->is_symlink()) s[rel] = "-> " + fs::read_symlink(it->path()).string();
    else if (it->is_directory()) s[rel] = "<dir>";
    else s[rel] = read_file(it->path());
  }
  return s;
}

/// A relative or absolute path inside the case directory `base` (the working
/// directory is base/a/b): up to two "..", a directory or two, a name and an extension.
std::string fuzzed_path(FuzzedDataProvider& in, const fs::path& base) {
  std::string p;
  const int ups = in.ConsumeIntegralInRange(0, 2);
  for (int i = 0; i < ups; ++i) p += "../";
  if (in.ConsumeBool()) p += "./";
  if (in.ConsumeBool()) p += std::string(kNames[in.ConsumeIntegralInRange<std::size_t>(0, kNames.size() - 1)]) + "/";
  p += kNames[in.ConsumeIntegralInRange<std::size_t>(0, kNames.size() - 1)];
  p += kExtensions[in.ConsumeIntegralInRange<std::size_t>(0, kExtensions.size() - 1)];
  if (in.ConsumeIntegralInRange(0, 4) == 0) return (base / "a" / "b" / p).lexically_normal().string(); // absolute
  return p;
}

/// A TOML basic string holding `s` (control characters escaped).
std::string toml_string(const std::string& s) {
  std::string out = "\"";
  for (unsigned char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out + "\"";
}

/// The victims of one case: files at likely output names and a link out of the directory.
void plant_victims(const fs::path& base, FuzzedDataProvider& in) {
  fs::create_directories(base / "a" / "b");
  const std::array<const char*, 7> names = {"x.h5", "x.xdmf", "res.xdmf", "a/b/out.h5", "a/b/x.checkpoint.h5",
                                            "a/out.xdmf", "a/b/res.pvd"};
  for (const char* n : names)
    if (in.ConsumeBool()) std::ofstream(base / n, std::ios::binary) << "victim " << n << " " << in.ConsumeIntegral<int>();
  if (in.ConsumeBool()) fs::create_directories(base / "a" / "b" / "d.h5");
  if (in.ConsumeBool()) fs::create_symlink(sentinel / "victim.h5", base / "a" / "b" / "link.h5");
}

struct Exit {
  int status = -1;
  int signal = 0;
  std::string err;
};

/// Runs `otmpm ARGS` in `cwd` with ASan/UBSan aborting on a report.
Exit run_otmpm(const std::vector<std::string>& args, const fs::path& cwd) {
  std::vector<std::string> argv_s{OTMPM_BINARY};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  const std::string err_file = (root / "stderr.txt").string();
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  const fs::path here = fs::current_path();
  fs::current_path(cwd);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, argv_s[0].c_str(), &actions, nullptr, argv.data(), environ);
  fs::current_path(here);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) finding("cannot start " + argv_s[0]);
  int wstatus = 0;
  while (waitpid(pid, &wstatus, 0) < 0) // libFuzzer's timer (SIGALRM) interrupts the wait
    if (errno != EINTR) finding("waitpid failed: " + std::string(std::strerror(errno)));
  Exit e;
  e.status = WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -1;
  e.signal = WIFSIGNALED(wstatus) ? WTERMSIG(wstatus) : 0;
  e.err = read_file(err_file);
  return e;
}

/// The command line as a string, for findings.
std::string joined(const std::vector<std::string>& args) {
  std::string s = "otmpm";
  for (const std::string& a : args) s += " '" + a + "'";
  return s;
}

/// Checks one finished `otmpm` process; `result` is the result file it wrote ("" if unknown).
void check_exit(const Exit& e, const std::vector<std::string>& args, const fs::path& result) {
  const std::string what = joined(args) + "\nstderr: " + e.err;
  if (e.signal != 0) finding("killed by signal " + std::to_string(e.signal) + ": " + what);
  if (e.status < 0 || e.status > 2) finding("exit status " + std::to_string(e.status) + ": " + what);
  if (e.status == 2 || result.empty()) return;
  try {
    const std::string status = otmpm::read_string_attribute(result.string(), "status");
    if (status == "running") finding("status still 'running' after exit " + std::to_string(e.status) + ": " + what);
  } catch (const std::exception& x) {
    finding("result file " + result.string() + " unreadable after exit " + std::to_string(e.status) + ": " +
            x.what() + "\n" + what);
  }
}

/// A checkpoint file the run may have written (the first one found).
fs::path find_checkpoint(const fs::path& base) {
  for (auto& e : fs::recursive_directory_iterator(base))
    if (e.is_regular_file() && e.path().filename().string().ends_with(".h5") &&
        read_file(e.path()).rfind("otmpm checkpoint\n", 0) == 0)
      return e.path();
  return {};
}

/// The overrides of one fuzzed run.
std::vector<std::string> fuzzed_settings(FuzzedDataProvider& in, const fs::path& base, std::size_t scene) {
  std::vector<std::string> sets = kShort[scene];
  if (in.ConsumeBool()) sets.push_back("output.file=" + toml_string(fuzzed_path(in, base)));
  const std::array<long, 4> every = {0, 1, 7, 50};
  const long ck = every[in.ConsumeIntegralInRange<std::size_t>(0, 3)];
  if (ck > 0) sets.push_back("output.checkpoint_every=" + std::to_string(ck));
  if (in.ConsumeBool()) sets.push_back("output.checkpoint_file=" + toml_string(fuzzed_path(in, base)));
  const std::array<const char*, 3> frames = {"0", "1e-7", "2e-5"};
  sets.push_back(std::string("output.every=") + frames[in.ConsumeIntegralInRange<std::size_t>(0, 2)]);
  const std::array<const char*, 4> formats = {"[\"hdf5\"]", "[\"hdf5\", \"vtp\"]", "[\"hdf5\", \"vtu\"]", "[\"vtp\"]"};
  sets.push_back(std::string("output.format=") + formats[in.ConsumeIntegralInRange<std::size_t>(0, 3)]);
  if (in.ConsumeBool()) sets.push_back("output.precision=\"single\"");
  if (in.ConsumeBool()) sets.push_back("output.symmetric_tensors=true");
  if (in.ConsumeBool()) sets.push_back("output.compression=" + std::to_string(in.ConsumeIntegralInRange<int>(0, 9)));
  const std::array<const char*, 5> fields = {"[\"x\", \"v\"]", "[\"v\", \"stress\"]", "[\"x\", \"F\", \"mass\"]",
                                             "[\"x\", \"displacement\", \"density\", \"strain\"]",
                                             "[\"x\", \"stress\", \"stress_zz\"]"}; // stress_zz: 2D only (else refused)
  if (in.ConsumeBool()) sets.push_back(std::string("output.fields=") + fields[in.ConsumeIntegralInRange<std::size_t>(0, 4)]);
  if (in.ConsumeBool()) {
    std::string probes = "output.probes=[";
    const int n = in.ConsumeIntegralInRange(0, 3);
    const std::array<const char*, 3> kinds = {"leftmost", "rightmost", "middle"};
    for (int i = 0; i < n; ++i)
      probes += std::string(i ? ", " : "") + "{name = " + toml_string(in.ConsumeRandomLengthString(12)) +
                ", particle = \"" + kinds[in.ConsumeIntegralInRange<std::size_t>(0, 2)] + "\"}";
    sets.push_back(probes + "]");
  }
  return sets;
}

/// The result file a run with these arguments writes: --out, else output.file, else the scene's.
fs::path result_of(const std::vector<std::string>& args, const fs::path& cwd, const std::string& scene_default) {
  std::string out = scene_default;
  for (std::size_t i = 0; i + 1 < args.size(); ++i) {
    if (args[i] == "--set" && args[i + 1].rfind("output.file=", 0) == 0) {
      const std::string v = args[i + 1].substr(12);
      out = v.size() >= 2 ? v.substr(1, v.size() - 2) : v;
    }
  }
  for (std::size_t i = 0; i + 1 < args.size(); ++i)
    if (args[i] == "--out") out = args[i + 1];
  const fs::path p(out);
  return p.is_absolute() ? p : cwd / p;
}

} // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  std::string pattern = (fs::temp_directory_path() / "otmpm_fuzz_run_XXXXXX").string();
  if (!mkdtemp(pattern.data())) finding("cannot create a temporary directory");
  root = pattern;
  sentinel = root.string() + "_outside";
  fs::create_directories(sentinel);
  std::ofstream(sentinel / "victim.h5", std::ios::binary) << "outside the temporary directory";
  setenv("OMP_NUM_THREADS", "1", 1);
  setenv("ASAN_OPTIONS", "detect_leaks=1:abort_on_error=1", 1);
  setenv("UBSAN_OPTIONS", "print_stacktrace=1:halt_on_error=1:abort_on_error=1", 1);
  std::atexit([] {
    std::error_code ec;
    fs::remove_all(root, ec);
    fs::remove_all(sentinel, ec);
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  const fs::path base = root / "case";
  std::error_code ec;
  fs::remove_all(base, ec);
  plant_victims(base, in);
  const fs::path cwd = base / "a" / "b";
  const auto victims = snapshot(base), outside = snapshot(sentinel);
  const std::size_t scene = in.ConsumeIntegralInRange<std::size_t>(0, kBaseScenes.size() - 1);
  std::vector<std::string> args{"run", std::string(OTMPM_SOURCE_DIR) + "/" + kBaseScenes[scene], "--quiet"};
  if (in.ConsumeBool()) args.insert(args.end(), {"--out", fuzzed_path(in, base)});
  for (const std::string& s : fuzzed_settings(in, base, scene)) args.insert(args.end(), {"--set", s});
  const std::string scene_default = scene == 0 ? "dyka.h5" : "mms_plate.h5";
  const int repeats = in.ConsumeIntegralInRange(1, 2);
  for (int i = 0; i < repeats; ++i) check_exit(run_otmpm(args, cwd), args, result_of(args, cwd, scene_default));
  const fs::path checkpoint = find_checkpoint(base);
  if (!checkpoint.empty() && in.ConsumeBool()) {
    std::vector<std::string> restart{"run", "--restart", checkpoint.string(), "--quiet"};
    if (in.ConsumeBool()) restart.insert(restart.end(), {"--out", fuzzed_path(in, base)});
    const Exit e = run_otmpm(restart, cwd);
    check_exit(e, restart, {}); // its result path is the checkpoint's: checked by status alone
  }
  const auto after = snapshot(base);
  for (const auto& [path, content] : victims)
    if (content != "<dir>" && (!after.count(path) || after.at(path) != content))
      finding("victim " + path + " was changed or removed by " + joined(args));
  for (const auto& [path, content] : after)
    if (path.find("otmpm-lock") != std::string::npos || path.find("otmpm-undo") != std::string::npos)
      finding("lock file or undo journal left behind: " + path);
  if (snapshot(sentinel) != outside) finding("a file outside the temporary directory changed: " + joined(args));
  for (const auto& e : fs::directory_iterator(root))
    if (e.path().filename() != "case" && e.path().filename() != "stderr.txt")
      finding("a file appeared beside the case directory: " + e.path().string());
  if (otmpm::fuzz::verbose()) std::fprintf(stderr, "ran: %s\n", joined(args).c_str());
  return 0;
}
