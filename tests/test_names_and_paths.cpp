// Names and paths from hostile input, through the library API (the command
// line's cases are in test_cli_hostile.cpp): result names the XML sidecar and
// VTK files cannot quote are refused on every route and those they can are
// read back from them as written; a FIFO or a device where otmpm reads or
// writes a file is refused before it is opened; a --set value with a line
// break is refused; output.fields without x is refused; messages quote long
// names cut short; a CSV particle file may start with a byte-order mark.
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/io/particle_file.hpp"
#include "otmpm/io/text_files.hpp"
#include "otmpm/run/run.hpp"
#include "otmpm/scene/validate.hpp"

#include "run_support.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

using namespace otmpm;
namespace fs = std::filesystem;
using otmpm::test::input_error_of;
using otmpm::test::small_scene;
using otmpm::test::TempDir;

namespace {

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

} // namespace

TEST_CASE("shortened() cuts long text at a character boundary and says its length, InputError bounds "
          "its message") {
  CHECK(shortened("short") == "short");
  const std::string accents(200, 'e'); // then a two-byte character across the cut
  const std::string text = accents.substr(0, 59) + "\xc3\xa9" + accents;
  const std::string cut = shortened(text);
  CHECK(cut.size() < 100);
  CHECK(text::valid_utf8(cut));
  CHECK(contains(cut, "... (261 bytes)"));
  const std::string huge(10'000'000, 'n');
  const InputError e("start " + huge + " end");
  const std::string what = e.what();
  CHECK(what.size() <= kMaxMessageBytes + 64);
  CHECK(what.rfind("start ", 0) == 0);
  CHECK(what.ends_with(" end"));
  CHECK(contains(what, "10000010 bytes in all"));
  // A name of 10 MB in a scene: the message quotes it cut, once or twice, never whole.
  Scene s = small_scene();
  s.materials.front().name = huge;
  const std::string msg = input_error_of([&] { validate_scene(s, 1); });
  CHECK(contains(msg, "(10000000 bytes)"));
  CHECK(msg.size() < 1000);
}

TEST_CASE("result paths the XML outputs cannot quote are refused by output_files(), on every route") {
  for (const std::string& bad : {std::string("co:lon.h5"), std::string("dir/ctl\x01.h5"), std::string("nul\0.h5", 7),
                                 std::string("line\n.h5"), std::string("bad\xff.h5"), std::string("res.png"),
                                 std::string("anim.GIF")}) {
    CAPTURE(text::printable(bad));
    CHECK_THROWS_AS(output_files(bad, "", "vtp"), InputError);
  }
  CHECK(contains(input_error_of([] { output_files("a\x01.h5", "", ""); }),
                 "a\\x01.h5: the result path contains a control"));
  // A Scene built in code meets the reader's rule for output.file and output.checkpoint_file.
  Scene s = small_scene();
  s.output.checkpoint_file = std::string("ck\0.h5", 6);
  CHECK(contains(input_error_of([&] { validate_scene(s, 1); }), "output.checkpoint_file"));
  // Names with characters XML escapes are written and read back as they are.
  TempDir t("names");
  const std::string name = t.file("run--2 &<>\"q' \xc3\xa9.h5");
  Scene v = small_scene({"output.format=[\"hdf5\", \"vtp\"]"});
  RunOptions opt;
  opt.out_file = name;
  const RunSummary r = run_scene(v, opt);
  REQUIRE(r.exit_code == 0);
  const std::string id = result_run_id(name);
  for (const std::string& xml : {output_base(name) + ".pvd", output_base(name) + ".xdmf"}) {
    CAPTURE(xml);
    CHECK(xml_run_id(xml) == id);
    CHECK(xml_result(xml) == name);
  }
  CHECK(xml_run_id(output_base(name) + "_vtk/frame_000000.vtp") == id);
}

TEST_CASE("a FIFO where a run writes or reads a file is refused without opening it") {
  TempDir t("fifos");
  for (const std::string f : {"r.h5", "s.xdmf", "c.h5", "t.xdmf.tmp", "scene.toml", "ck.h5", "p.csv", "p.h5"})
    REQUIRE(::mkfifo(t.file(f).c_str(), 0644) == 0);
  CHECK(special_file(t.file("r.h5")) == "a FIFO (named pipe)");
  CHECK(special_file("/dev/null") == "a character device");
  CHECK(special_file(t.dir.string()).empty());
  CHECK(special_file(t.file("missing")).empty());
  // Every path the run writes (temporaries too), before anything is opened: with force as without.
  CHECK(contains(input_error_of([&] { output_files(t.file("r.h5"), "", ""); }), "the result file is a FIFO"));
  CHECK(contains(input_error_of([&] { output_files(t.file("s.h5"), "", ""); }), "the XDMF sidecar is a FIFO"));
  CHECK(contains(input_error_of([&] { output_files(t.file("x.h5"), t.file("c.h5"), ""); }),
                 "the checkpoint is a FIFO"));
  CHECK(contains(input_error_of([&] { output_files(t.file("t.h5"), "", ""); }), "temporary of the XDMF sidecar"));
  RunOptions force;
  force.out_file = t.file("r.h5");
  force.force = true;
  CHECK(contains(input_error_of([&] { run_scene(small_scene(), force); }), "FIFO"));
  // Reading: the scene, a checkpoint and particle files.
  CHECK(contains(input_error_of([&] { load_scene(t.file("scene.toml")); }),
                 "is a FIFO (named pipe), not a scene file"));
  CHECK(contains(input_error_of([&] { read_checkpoint(t.file("ck.h5")); }), "not a checkpoint file"));
  CHECK(checkpoint_run_id(t.file("ck.h5")).empty());
  for (const std::string f : {"p.csv", "p.h5"})
    CHECK(contains(input_error_of([&] { read_particle_file(t.file(f), 2); }), "not a particle file"));
  CHECK(xml_run_id(t.file("s.xdmf")).empty());
}

TEST_CASE("a --set value with a line break is refused, not cut at it") {
  for (const std::string& set : {std::string("simulation.t_end=1e-5\nsimulation.cfl=5"),
                                 std::string("output.file=a\nb.h5"), std::string("simulation.cfl=0.2\r")}) {
    CAPTURE(text::printable(set));
    const std::string msg = input_error_of([&] { small_scene({set}); });
    CHECK(contains(msg, "line break"));
    CHECK(msg.rfind("--set ", 0) == 0);
  }
  CHECK(contains(input_error_of([] { small_scene({"output.file=\"a\\nb.h5\""}); }), "control character (code 10)"));
}

TEST_CASE("output.fields without x is refused (with VTK output, also []), [] alone writes history-only frames") {
  CHECK(contains(input_error_of([] { small_scene({"output.fields=[\"v\"]"}); }), "must include \"x\""));
  CHECK(contains(input_error_of([] { small_scene({"output.fields=[]", "output.format=[\"hdf5\", \"vtu\"]"}); }),
                 "output.format"));
  CHECK(small_scene({"output.fields=[]"}).output.fields.empty());
  Scene s = small_scene();
  s.output.fields = {"v", "stress"}; // a Scene built in code: the same rule
  CHECK(contains(input_error_of([&] { validate_scene(s, 1); }), "output.fields"));
}

TEST_CASE("a CSV particle file starting with a UTF-8 byte-order mark reads as the same file without it") {
  TempDir t("bom");
  std::string rows = "# a comment\nx,y,volume\n";
  for (int i = 0; i < 12; ++i) rows += std::to_string(0.3 + 0.025 * i) + ",0.5,0.000625\n";
  std::ofstream(t.file("plain.csv")) << rows;
  std::ofstream(t.file("bom.csv")) << "\xEF\xBB\xBF" << rows;
  std::ofstream(t.file("utf16.csv")) << std::string("\xFF\xFEx\0,\0y\0", 8);
  const ParticleFile plain = read_particle_file(t.file("plain.csv"), 2);
  const ParticleFile bom = read_particle_file(t.file("bom.csv"), 2);
  CHECK(bom.x == plain.x);
  CHECK(bom.volume == plain.volume);
  CHECK(contains(input_error_of([&] { read_particle_file(t.file("utf16.csv"), 2); }), "UTF-16"));
}

TEST_CASE("a file name longer than the file system allows is refused for every file the run writes, before writing") {
  TempDir t("long_names");
  const std::string over(300, 'r'), near(250, 'r'); // the lock file .NAME.otmpm-lock of 250 bytes is too long
  CHECK(contains(input_error_of([&] { output_files(t.file(over + ".h5"), "", ""); }),
                 "the file name of the result file is 303 bytes long"));
  CHECK(contains(input_error_of([&] { output_files(t.file(near + ".h5"), "", ""); }), "lock file of the result file"));
  CHECK(contains(input_error_of([&] { output_files(t.file("r.h5"), t.file(over), ""); }),
                 "the file name of the checkpoint is 300 bytes long"));
  CHECK_NOTHROW(output_files(t.file(std::string(200, 'r') + ".h5"), "", ""));
  CHECK(fs::is_empty(t.dir));
}
