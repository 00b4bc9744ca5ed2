// Simulation (run/simulation.hpp): a run stepped by hand is the run of
// run_scene(), bit for bit; frames can be written between steps; an
// instability finishes the run with its status in the result file; after
// finish() the run is closed (and its locks free); one dropped unfinished
// gets status "interrupted".
#include "otmpm/io/output_files.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/run/simulation.hpp"

#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>

using namespace otmpm;
using test::TempDir;

namespace {

const std::string kDyka = OTMPM_SOURCE_DIR "/examples/dyka.toml";

Scene short_dyka(const std::vector<std::string>& extra = {}) {
  std::vector<std::string> sets{"simulation.t_end=2e-5", "output.every=5e-6"};
  sets.insert(sets.end(), extra.begin(), extra.end());
  return load_scene(kDyka, sets);
}

/// The number of groups under /frames of a result file.
hsize_t frame_count(const std::string& path) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(file >= 0);
  const hid_t frames = H5Gopen2(file, "frames", H5P_DEFAULT);
  H5G_info_t info{};
  H5Gget_info(frames, &info);
  H5Gclose(frames);
  H5Fclose(file);
  return info.nlinks;
}

} // namespace

TEST_CASE("Simulation: stepping by hand to t_end gives run_scene's summary and state, bit for bit") {
  TempDir tmp("simulation");
  const Scene scene = short_dyka();
  RunOptions a, b;
  a.out_file = tmp.file("a.h5");
  b.out_file = tmp.file("b.h5");
  const RunSummary whole = run_scene(scene, a);
  Simulation sim(scene, b);
  while (!sim.finished()) sim.step();
  const auto x = sim.engine<1>().particles().x;
  const RunSummary by_hand = sim.finish();
  CHECK(by_hand.steps == whole.steps);
  CHECK(by_hand.time == whole.time);
  REQUIRE(by_hand.errors.size() == whole.errors.size());
  for (const auto& [name, value] : whole.errors) CHECK(by_hand.errors.at(name) == value);
  CHECK(by_hand.status == "ok");
  CHECK(read_string_attribute(b.out_file, "status") == "ok");
  // The same particle positions as a fresh run stepped the same number of times.
  Simulation again(scene, RunOptions{.out_file = "", .write_results = false, .progress = {}});
  for (long s = 0; s < whole.steps; ++s) again.step();
  CHECK(std::memcmp(again.engine<1>().particles().x.data(), x.data(), x.size() * sizeof(x[0])) == 0);
}

TEST_CASE("Simulation: advance_to stops at the first step at or past t, write_frame adds a frame") {
  TempDir tmp("advance");
  RunOptions opt;
  opt.out_file = tmp.file("r.h5");
  Simulation sim(short_dyka({"output.every=0"}), opt);
  sim.advance_to(1e-5);
  CHECK(sim.time() >= 1e-5 * (1 - 1e-9));
  const double dt = sim.engine<1>().last_dt();
  CHECK(sim.time() < 1e-5 + dt);
  sim.write_frame();
  sim.advance_to(1.0); // beyond t_end: stops at t_end
  CHECK(sim.finished());
  CHECK(sim.time() == doctest::Approx(2e-5).epsilon(1e-12));
  sim.finish();
  CHECK(read_double_attribute(opt.out_file, "steps") == static_cast<double>(sim.steps()));
  CHECK(frame_count(opt.out_file) == 3); // t = 0, the frame written by hand, t_end
}

TEST_CASE("Simulation: an instability finishes the run and sets the result file's status") {
  TempDir tmp("unstable");
  RunOptions opt;
  opt.out_file = tmp.file("r.h5");
  Simulation sim(short_dyka({"simulation.cfl=3.0"}), opt); // far beyond the stability limit
  CHECK_THROWS_AS(
      [&] {
        while (!sim.finished()) sim.step();
      }(),
      InstabilityError);
  CHECK(sim.finished());
  CHECK(sim.unstable());
  CHECK_THROWS_AS(sim.step(), std::logic_error);
  const RunSummary s = sim.finish();
  CHECK(s.exit_code == 1);
  CHECK(read_string_attribute(opt.out_file, "status").rfind("unstable: ", 0) == 0);
}

TEST_CASE("Simulation: engine<D> of another dimension is an interface error") {
  Simulation sim(short_dyka(), RunOptions{.out_file = "", .write_results = false, .progress = {}});
  CHECK(sim.dimension() == 1);
  CHECK_THROWS_AS(sim.engine<2>(), std::invalid_argument);
}

TEST_CASE("Simulation: interrupt() leaves a valid file with status interrupted and a last checkpoint") {
  TempDir tmp("interrupt");
  RunOptions opt;
  opt.out_file = tmp.file("r.h5");
  Simulation sim(short_dyka({"output.checkpoint_every=1000"}), opt);
  for (int s = 0; s < 7; ++s) sim.step();
  sim.interrupt();
  CHECK(sim.finished());
  const RunSummary s = sim.finish();
  CHECK(s.status == "interrupted");
  CHECK(s.exit_code == kInterruptedExit);
  CHECK(read_string_attribute(opt.out_file, "status") == "interrupted");
  CHECK(read_double_attribute(opt.out_file, "steps") == 7.0);
  CHECK(std::filesystem::exists(tmp.file("r.checkpoint.h5"))); // taken at the interruption, not at step 1000
}

TEST_CASE("after finish() write_frame, interrupt, step and finish throw std::logic_error and change nothing") {
  TempDir tmp("closed");
  RunOptions opt;
  opt.out_file = tmp.file("r.h5");
  Simulation sim(short_dyka(), opt);
  sim.step();
  sim.finish();
  const hsize_t frames = frame_count(opt.out_file);
  CHECK_THROWS_AS(sim.write_frame(), std::logic_error);
  CHECK_THROWS_AS(sim.interrupt(), std::logic_error);
  CHECK_THROWS_AS(sim.step(), std::logic_error);
  CHECK_THROWS_AS(sim.finish(), std::logic_error);
  CHECK(frame_count(opt.out_file) == frames);
  CHECK(read_string_attribute(opt.out_file, "status") == "ok");
  CHECK(sim.engine<1>().particles().size() == 80); // the state stays readable
}

TEST_CASE("write_frame after t_end, an instability or interrupt() still writes, interrupt() of a "
          "finished run throws") {
  TempDir tmp("after_end");
  RunOptions opt;
  opt.out_file = tmp.file("r.h5");
  Simulation sim(short_dyka({"output.every=0"}), opt);
  sim.advance_to(1.0);
  REQUIRE(sim.finished());
  sim.write_frame();
  CHECK_THROWS_AS(sim.interrupt(), std::logic_error); // it reached t_end: nothing to interrupt
  CHECK(sim.finish().status == "ok");
  CHECK(frame_count(opt.out_file) == 3); // t = 0, t_end, and the frame written by hand
}

TEST_CASE("finish() releases otmpm's locks, a Simulation destroyed before finish() leaves status interrupted") {
  TempDir tmp("locks");
  RunOptions opt;
  opt.out_file = tmp.file("r.h5");
  const Scene scene = short_dyka({"output.checkpoint_every=1000"});
  Simulation sim(scene, opt);
  sim.advance_to(1.0);
  CHECK(std::filesystem::exists(lock_path(opt.out_file)));
  sim.finish();
  CHECK_FALSE(std::filesystem::exists(lock_path(opt.out_file)));
  // The finished Simulation still exists: a new run of the same files is not refused.
  RunOptions again = opt;
  again.force = true;
  CHECK(run_scene(scene, again).status == "ok");
  {
    Simulation dropped(scene, again);
    for (int s = 0; s < 4; ++s) dropped.step();
  } // destroyed unfinished (an exception, a forgotten finish())
  CHECK(read_string_attribute(opt.out_file, "status") == "interrupted");
  CHECK(read_double_attribute(opt.out_file, "steps") == 4.0);
  CHECK(std::filesystem::exists(tmp.file("r.checkpoint.h5"))); // the restart point interrupt() writes
  for (const auto& e : std::filesystem::directory_iterator(tmp.dir))
    CHECK(e.path().filename().string().find("otmpm-lock") == std::string::npos);
}
