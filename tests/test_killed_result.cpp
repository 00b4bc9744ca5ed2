// Result files and killed runs. A result file a SIGKILLed run left half-written: HDF5 itself crashed while
// iterating its /frames links (H5Literate sorting a half-written dense link
// table), which `otmpm run --force` did to inspect the file it replaces.
// tests/scenes/killed_run.h5 is such a file (left by a killed study in test_study_files.cpp).
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/core.hpp"
#include "h5_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

using namespace otmpm;
namespace fs = std::filesystem;

TEST_CASE("a killed run's half-written result file is inspected without iterating its links") {
  test::TempDir tmp("killed_result");
  const std::string path = tmp.file("a.h5");
  fs::copy_file(OTMPM_SOURCE_DIR "/tests/scenes/killed_run.h5", path);
  // Inspecting it (as claim_outputs does before a replacement) returns, with the run's id.
  CHECK(!result_run_id(path).empty());
}

TEST_CASE("link_count gives the number of links link_names lists") {
  test::TempDir tmp("link_count");
  const auto [path, file] = test::new_h5_file(tmp, "g.h5");
  const h5::Handle group(H5Gcreate2(file.get(), "frames", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  CHECK(h5::link_count(group.get(), path) == 0);
  for (int i = 0; i < 40; ++i) { // past the compact storage (8 links): the dense link table
    const std::string name = std::to_string(i);
    const h5::Handle g(H5Gcreate2(group.get(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  }
  CHECK(h5::link_count(group.get(), path) == 40);
  CHECK(h5::link_count(group.get(), path) == h5::link_names(group.get(), path).size());
}

namespace {

/// Whether `path` holds exactly `text`.
bool holds(const std::string& path, const std::string& text) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {}) == text;
}

} // namespace

TEST_CASE("a new result file takes its path only once its header is on disk, a killed run's temporary is replaced") {
  test::TempDir tmp("result_created");
  const std::string path = tmp.file("r.h5");
  std::ofstream(path + ".tmp") << "left by a run killed while creating its file";
  {
    ResultWriter w(path, "[simulation]\ndimension = 2\n", 2);
    CHECK(!fs::exists(path + ".tmp")); // renamed into place by the constructor
    CHECK(read_string_attribute(path, "status") == "running");
  }
  CHECK(read_string_attribute(path, "status") == "running");
}

TEST_CASE("a result file whose header cannot be written leaves the old file and no temporary") {
  test::TempDir tmp("result_refused");
  const std::string path = tmp.file("r.h5");
  const std::string old = "an older file of the same name";
  std::ofstream(path) << old;
  // A child process with a file size limit below the header (a 1 MB scene
  // text): the constructor refuses the write; the old file stays as it was.
  const pid_t child = ::fork();
  REQUIRE(child >= 0);
  if (child == 0) {
    ::signal(SIGXFSZ, SIG_IGN);
    const rlimit limit{64 * 1024, 64 * 1024};
    ::setrlimit(RLIMIT_FSIZE, &limit);
    int code = 0;
    try {
      ResultWriter w(path, std::string(1 << 20, '#'), 2);
      code = 10; // created against the limit
    } catch (const OutputError&) {
      code = 0;
    } catch (...) {
      code = 11;
    }
    ::_exit(code);
  }
  int status = 0;
  REQUIRE(::waitpid(child, &status, 0) == child);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);
  CHECK(holds(path, old));
  CHECK(!fs::exists(path + ".tmp"));
}

namespace {

constexpr const char* kKilledFields[] = {"x", "v", "a", "stress", "strain", "F", "density", "mass"};

/// Writes frames and history samples into `path` until killed: every
/// iteration a frame of 200 particles with eight fields and three samples,
/// each flushed, as a run does. After each frame it records the count in `count_file`.
[[noreturn]] void write_until_killed(const std::string& path, const std::string& count_file, int compression) {
  ResultOptions options;
  options.compression = compression;
  ResultWriter w(path, "[simulation]\ndimension = 2\n", 2, options);
  std::vector<double> x(400), s(600);
  for (int frame = 0;; ++frame) {
    for (std::size_t i = 0; i < x.size(); ++i) x[i] = 1e-3 * static_cast<double>(frame) + static_cast<double>(i);
    for (std::size_t i = 0; i < s.size(); ++i) s[i] = static_cast<double>(frame * 7 + static_cast<int>(i % 13));
    for (int k = 0; k < 3; ++k)
      w.append_series("energy", frame + 0.25 * k, {{"kinetic", 1.0 * frame}, {"strain", 2.0 * k}});
    std::vector<FieldView> fields;
    for (const char* name : kKilledFields) fields.push_back({name, 200, 3, s.data()});
    fields.front() = {"x", 200, 2, x.data()};
    w.write_frame(frame, fields);
    std::ofstream(count_file) << frame + 1;
  }
}

/// Reads every dataset of `path` with HDF5 alone: the number of frames, or -1 when the file does not read.
int frames_read_in_full(const std::string& path) {
  h5::silence();
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (id < 0) return -1;
  const h5::Handle file(id, H5Fclose);
  try {
    const h5::Handle frames = h5::open_group(id, "frames", path);
    const auto names = h5::link_names(frames.get(), path);
    for (const std::string& name : names)
      for (const char* field : kKilledFields) {
        const std::string set = "frames/" + name + "/" + field;
        const hid_t d = H5Dopen2(id, set.c_str(), H5P_DEFAULT);
        if (d < 0) return -1;
        const h5::Handle dataset(d, H5Dclose);
        std::vector<double> values(600);
        if (H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0) return -1;
      }
    return static_cast<int>(names.size());
  } catch (const std::exception&) {
    return -1;
  }
}

/// frames_read_in_full of the file as the kill left it, in a child process:
/// HDF5 1.10 leaks a little on a damaged file's failed open, which the leak
/// checker of a sanitizer build would count against this test.
int frames_read_in_child(const std::string& path) {
  const pid_t child = ::fork();
  if (child == 0) ::_exit(std::min(frames_read_in_full(path) + 1, 255)); // no exit handlers, no leak check
  int status = 0;
  if (child < 0 || ::waitpid(child, &status, 0) != child || !WIFEXITED(status)) return -1;
  return WEXITSTATUS(status) - 1;
}

} // namespace

TEST_CASE("a writer killed at 100 random moments leaves a file that otmpm restores to its last flush, read in full") {
  // A SIGKILL inside an HDF5 flush leaves groups that point at object headers
  // not yet written. The result file's driver journals what each write
  // replaces; otmpm's lock (taken by every run, restart and reader) writes the
  // journal back. Kills land at random moments of a writer that flushes
  // constantly: some inside a flush (a non-empty journal), and every file,
  // once restored, reads in full with at least the frames recorded as written.
  test::TempDir tmp("killed_writer");
  std::srand(20261130);
  int inside_flush = 0, unreadable_before = 0;
  for (int kill = 0; kill < 100; ++kill) {
    const std::string path = tmp.file("k" + std::to_string(kill) + ".h5"), count = path + ".count";
    const pid_t child = ::fork();
    REQUIRE(child >= 0);
    if (child == 0) write_until_killed(path, count, kill % 2 == 0 ? 0 : 6);
    for (int wait = 0; wait < 5000 && !fs::exists(count); ++wait) ::usleep(1000); // its first frame is written
    ::usleep(static_cast<useconds_t>(std::rand() % 40000));
    ::kill(child, SIGKILL);
    int status = 0;
    REQUIRE(::waitpid(child, &status, 0) == child);
    REQUIRE(WIFSIGNALED(status));
    int recorded = 0;
    std::ifstream(count) >> recorded;
    const std::string journal = undo_journal_path(path);
    if (fs::exists(journal) && fs::file_size(journal) > 0) ++inside_flush;
    if (frames_read_in_child(path) < recorded) ++unreadable_before;
    { const OutputLock restore({path}); } // as a run, a restart or a reader takes it
    CHECK(!fs::exists(journal));
    INFO("kill " << kill << " after " << recorded << " frames");
    CHECK(frames_read_in_full(path) >= recorded);
  }
  MESSAGE(inside_flush << " of 100 kills inside a flush, " << unreadable_before << " files unreadable before the restore");
  CHECK(inside_flush > 0); // the kills did hit the moments the journal is for
}
