// The multi-rank fuzzer (label mpi): distributed runs of a small scene under
// hostile use, drawn at random from a fixed seed until a time budget is
// spent, each checked against the documented outcome (docs/stability.md,
// "Distributed runs"):
//  - identical ranks: exit 0, status "ok", every frame readable;
//  - ranks whose scene (a --set), options (--force, --out) or working
//    directory differ, a rank that cannot read the scene, a rank that does
//    not share the result directory: exit 2 within kRefusal seconds, one
//    message naming the lowest rank that differs (or the missing file), no
//    result file left;
//  - SIGTERM or SIGINT to one rank at a random moment: exit 128 + signal
//    naming it (or 0 if the run had ended), the result file - when it was
//    created - readable with status "interrupted" (or "ok"), and, when a
//    checkpoint was written, a restart on 1 to 3 ranks that ends "ok";
//  - SIGKILL of one rank: every rank ends within kKilled seconds, the result
//    file - when it was created - still opens.
// Any run past kHang seconds is a hang. OTMPM_MPI_FUZZ_SECONDS sets the
// budget (default 120 s, CI's 2 cores included), OTMPM_MPI_FUZZ_SEED the
// seed (default 1); each case is printed so that a finding can be replayed.
#include "mpi_support.hpp"
#include "otmpm/io/hdf5.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace fs = std::filesystem;
using otmpm::test::MpiLaunch;
using otmpm::test::RankLine;
using otmpm::test::TempDir;

namespace {

const std::string kBinary = OTMPM_BINARY;
const std::string kMpiexec = OTMPM_MPIEXEC;
/// Seconds within which a refused run ends on every rank (mpirun's start included).
constexpr double kRefusal = 15.0;
/// Seconds within which every rank ends after one was killed.
constexpr double kKilled = 20.0;
/// Seconds after which a run counts as hung.
constexpr double kHang = 90.0;

const otmpm::test::RootMpi root_mpi;

/// A 2D elastic block falling onto a floor (20 x 20 cells, 576 particles) to t_end.
std::string block_scene(double t_end) {
  return "[simulation]\ndimension = 2\nintegrator = \"musl\"\nt_end = " + std::to_string(t_end) +
         "\ncfl = 0.1\n[basis]\nkind = \"linear\"\n[grid]\nlower = [0.0, 0.0]\nupper = [1.0, 1.0]\ncells = [20, 20]\n"
         "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1000.0\nyoung = 1.0e6\npoisson = 0.3\n"
         "[[body]]\nname = \"b\"\nmaterial = \"m\"\nlower = [0.2, 0.2]\nupper = [0.8, 0.6]\nvelocity = [0.0, -1.0]\n"
         "[[wall]]\nname = \"floor\"\npoint = [0.0, 0.1]\nnormal = [0.0, 1.0]\n[output]\nevery = 0.01\n";
}

/// Overrides that change the resolved scene (each differs from block_scene's value).
const std::vector<std::string> kOtherValues{
    "simulation.t_end=0.0123",   "simulation.cfl=0.09",           "material.m.young=1.1e6",
    "material.m.density=999.0",  "output.every=0.005",            "body.b.velocity=[0.0, -1.1]",
    "wall.floor.point=[0.0, 0.09]", "output.fields=[\"x\", \"v\"]", "simulation.integrator=\"fe\""};

/// The status attribute of a result file, or "" when the file does not open (or has none).
std::string status_of(const std::string& path) {
  otmpm::h5::silence();
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (id < 0) return "";
  const otmpm::h5::Handle file(id, H5Fclose);
  try {
    return otmpm::h5::read_string(file.get(), "status", path);
  } catch (const std::exception&) {
    return "";
  }
}

/// True when every frame of a result file reads back.
bool frames_read(const std::string& path) {
  otmpm::h5::silence();
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (id < 0) return false;
  const otmpm::h5::Handle file(id, H5Fclose);
  try {
    const otmpm::h5::Handle frames = otmpm::h5::open_group(file.get(), "frames", path);
    for (const std::string& name : otmpm::h5::link_names(frames.get(), path)) {
      const otmpm::h5::Handle g = otmpm::h5::open_group(frames.get(), name, path);
      for (const std::string& set : otmpm::h5::link_names(g.get(), path))
        if (otmpm::h5::read_double_matrix(g.get(), set, path).values.empty()) return false;
    }
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

std::string text_of(const std::string& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

double env_number(const char* name, double fallback) {
  const char* v = std::getenv(name);
  return v ? std::atof(v) : fallback;
}

/// One case of the fuzzer in its own directory.
class Case {
public:
  Case(std::mt19937& rng, int index) : rng_(rng), dir_("mpi_fuzz_" + std::to_string(index)) {
    ranks_ = pick(2, 3);
  }

  /// Draws a kind of case and runs it; its description goes to `what`.
  void run(std::string& what) {
    switch (pick(0, 5)) {
    case 0: return identical(what);
    case 1: return differing(what);
    case 2: return wrong_place(what);
    case 3: return missing_scene(what);
    case 4: return signal_one(what, pick(0, 1) ? SIGTERM : SIGINT);
    default: return kill_one(what);
    }
  }

private:
  int pick(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng_); }
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng_); }

  std::string scene(double t_end) {
    const std::string path = dir_.file("block.toml");
    std::ofstream(path) << block_scene(t_end);
    return path;
  }
  std::vector<std::string> run_args(const std::string& scene, const std::string& out) const {
    return {"run", scene, "--quiet", "--out", out};
  }
  std::string err() const { return text_of(dir_.file("stderr.txt")); }

  /// Every rank with the same line, ended within kHang: its exit status.
  int all_same(const std::vector<std::string>& args, double limit = kHang) {
    return MpiLaunch(kMpiexec, kBinary, dir_.dir, std::vector<RankLine>(static_cast<std::size_t>(ranks_), {args}),
                     dir_.file("stderr.txt"))
        .end_within(limit);
  }

  /// A refusal: exit 2 within kRefusal, one message line containing `part`, no result file.
  void refused(const std::vector<RankLine>& lines, const std::string& part) {
    const auto start = std::chrono::steady_clock::now();
    const int status = MpiLaunch(kMpiexec, kBinary, dir_.dir, lines, dir_.file("stderr.txt")).end_within(kHang);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const std::string e = err();
    CAPTURE(e);
    CHECK(status == 2);
    CHECK(seconds < kRefusal);
    CHECK(std::count(e.begin(), e.end(), '\n') == 1);
    CHECK(e.find(part) != std::string::npos);
    for (const auto& f : fs::recursive_directory_iterator(dir_.dir))
      CHECK(f.path().extension() != ".h5");
  }

  /// Which ranks differ (rank 0 never: it is the reference), at least one; the lowest.
  std::vector<bool> differing_ranks(int& lowest) {
    std::vector<bool> d(static_cast<std::size_t>(ranks_), false);
    lowest = pick(1, ranks_ - 1);
    d[static_cast<std::size_t>(lowest)] = true;
    for (int r = lowest + 1; r < ranks_; ++r) d[static_cast<std::size_t>(r)] = pick(0, 1) == 1;
    return d;
  }

  void identical(std::string& what) {
    what = "identical ranks";
    const int status = all_same(run_args(scene(0.02), "r.h5"));
    CAPTURE(err());
    CHECK(status == 0);
    CHECK(status_of(dir_.file("r.h5")) == "ok");
    CHECK(frames_read(dir_.file("r.h5")));
  }

  void differing(std::string& what) {
    int lowest = 0;
    const std::vector<bool> d = differing_ranks(lowest);
    const std::string path = scene(0.02);
    const bool option = pick(0, 2) == 0;
    const std::string change = option ? (pick(0, 1) ? "--force" : "--out other.h5")
                                       : kOtherValues[static_cast<std::size_t>(pick(0, static_cast<int>(kOtherValues.size()) - 1))];
    what = "rank " + std::to_string(lowest) + " (lowest of those that differ) with " + change;
    std::vector<RankLine> lines;
    for (int r = 0; r < ranks_; ++r) {
      std::vector<std::string> a = run_args(path, "r.h5");
      if (d[static_cast<std::size_t>(r)]) {
        if (change == "--force") a.push_back("--force");
        else if (option) a[4] = "other.h5";
        else a.insert(a.end(), {"--set", change});
      }
      lines.push_back({a});
    }
    refused(lines, "rank " + std::to_string(lowest) + ": the " +
                       (option ? std::string("set of run options") : std::string("resolved scene")));
  }

  void wrong_place(std::string& what) {
    int lowest = 0;
    const std::vector<bool> d = differing_ranks(lowest);
    const bool mounts = otmpm::test::private_mounts() && pick(0, 1) == 1;
    const std::string path = scene(0.02);
    fs::create_directories(dir_.dir / "A");
    fs::create_directories(dir_.dir / "B");
    const std::string a = (dir_.dir / "A").string(), b = (dir_.dir / "B").string();
    what = "rank " + std::to_string(lowest) + (mounts ? " without the shared result directory" : " in another working directory");
    std::vector<RankLine> lines;
    for (int r = 0; r < ranks_; ++r) {
      const bool other = d[static_cast<std::size_t>(r)];
      if (mounts) lines.push_back({run_args(path, a + "/r.h5"), "", other ? "mount -t tmpfs -o size=1M tmpfs " + a : ""});
      else lines.push_back({run_args(path, "r.h5"), other ? b : a});
    }
    refused(lines, "rank " + std::to_string(lowest) + (mounts ? " does not see the file rank 0 created"
                                                                : ": the absolute path of the result file"));
  }

  void missing_scene(std::string& what) {
    const int rank = pick(0, ranks_ - 1);
    what = "rank " + std::to_string(rank) + " given a scene that does not exist";
    const std::string path = scene(0.02);
    std::vector<RankLine> lines;
    for (int r = 0; r < ranks_; ++r) lines.push_back({run_args(r == rank ? dir_.file("missing.toml") : path, "r.h5")});
    refused(lines, "missing.toml");
  }

  void signal_one(std::string& what, int sig) {
    const int rank = pick(0, ranks_ - 1);
    const double delay = uniform(0.0, 4.0);
    const bool checkpoints = pick(0, 1) == 1;
    what = std::string(sig == SIGTERM ? "SIGTERM" : "SIGINT") + " to rank " + std::to_string(rank) + " after " +
           std::to_string(delay) + " s" + (checkpoints ? ", checkpoints on" : "");
    std::vector<std::string> args = run_args(scene(0.3), "r.h5");
    if (checkpoints) args.insert(args.end(), {"--set", "output.checkpoint_every=100"});
    MpiLaunch mpirun(kMpiexec, kBinary, dir_.dir, std::vector<RankLine>(static_cast<std::size_t>(ranks_), {args}),
                     dir_.file("stderr.txt"));
    const pid_t pid = mpirun.rank(rank);
    REQUIRE(pid > 0);
    REQUIRE(otmpm::test::catches(pid, sig, 30.0)); // from the moment otmpm's handlers are there
    std::this_thread::sleep_for(std::chrono::duration<double>(delay));
    ::kill(pid, sig);
    const int status = mpirun.end_within(kHang);
    const std::string e = err(), name = sig == SIGTERM ? "SIGTERM" : "SIGINT";
    CAPTURE(e);
    const std::string result = status_of(dir_.file("r.h5"));
    if (result == "ok") { // the run had ended (a signal after its end may still end the process)
      CHECK((status == 0 || status == 128 + sig));
      return;
    }
    CHECK(status == 128 + sig);
    CHECK(e.find("otmpm: interrupted by " + name) != std::string::npos);
    if (fs::exists(dir_.file("r.h5"))) {
      CHECK(result == "interrupted");
      CHECK(frames_read(dir_.file("r.h5")));
    }
    if (!fs::exists(dir_.file("r.checkpoint.h5"))) return;
    const int restart_ranks = pick(1, 3);
    what += ", restarted on " + std::to_string(restart_ranks) + " ranks";
    ranks_ = restart_ranks;
    const int restarted = all_same({"run", "--restart", "r.checkpoint.h5", "--quiet", "--out", "c.h5"});
    CAPTURE(err());
    CHECK(restarted == 0);
    CHECK(status_of(dir_.file("c.h5")) == "ok");
  }

  void kill_one(std::string& what) {
    const int rank = pick(0, ranks_ - 1);
    const double delay = uniform(0.3, 4.0);
    what = "SIGKILL to rank " + std::to_string(rank) + " after " + std::to_string(delay) + " s";
    MpiLaunch mpirun(kMpiexec, kBinary, dir_.dir,
                     std::vector<RankLine>(static_cast<std::size_t>(ranks_), {run_args(scene(0.3), "r.h5")}),
                     dir_.file("stderr.txt"));
    const pid_t pid = mpirun.rank(rank);
    REQUIRE(pid > 0);
    std::this_thread::sleep_for(std::chrono::duration<double>(delay));
    const auto start = std::chrono::steady_clock::now();
    ::kill(pid, SIGKILL);
    const int status = mpirun.end_within(kHang);
    CHECK(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() < kKilled);
    CHECK(status != -1);
    if (status != 0 && fs::exists(dir_.file("r.h5"))) CHECK(!status_of(dir_.file("r.h5")).empty()); // it opens
  }

  std::mt19937& rng_;
  TempDir dir_;
  int ranks_ = 2;
};

} // namespace

TEST_CASE("mpi fuzz: ranks with perturbed scenes, paths and signals end as documented, never hang") {
  const double budget = env_number("OTMPM_MPI_FUZZ_SECONDS", 120.0);
  const auto seed = static_cast<unsigned>(env_number("OTMPM_MPI_FUZZ_SEED", 1.0));
  std::mt19937 rng(seed);
  const auto start = std::chrono::steady_clock::now();
  int cases = 0;
  while (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() < budget) {
    std::string what;
    INFO("case " << cases << " (seed " << seed << "): " << what); // filled in by the case, shown with a failure
    Case c(rng, cases);
    const auto case_start = std::chrono::steady_clock::now();
    c.run(what);
    MESSAGE("case " << cases << " (seed " << seed << "): " << what << ", "
                    << std::chrono::duration<double>(std::chrono::steady_clock::now() - case_start).count() << " s");
    ++cases;
  }
  CHECK(cases >= std::min(5.0, budget / 20.0)); // the budget was spent on cases (about 2.5 s each here)
}
