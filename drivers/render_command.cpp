// `otmpm render RESULT.h5 --field NAME [--frame K | --all] --out FILE.png|.gif`:
// draws the particles of a result file coloured by a field with matplotlib,
// through render.py in the scripts folder (system.hpp: share/otmpm beside the
// executable's bin folder, or --scripts). The script checks the field and
// the frame and exits 2 with a message for bad input.
#include "cli.hpp"
#include "system.hpp"

#include "otmpm/core.hpp"

#include <cstdio>
#include <memory>

namespace fs = std::filesystem;

namespace otmpm::cli {

namespace {

struct RenderArgs {
  std::string result, field, out, component = "norm", view = "xy";
  int frame = -1;
  bool all = false;
  int stride = 1;
  double fps = 10;
  std::string scripts, python;
};

/// The exit status of the script: 0 and 2 (bad input, message printed by the
/// script) pass through; anything else is an internal error.
int render(const RenderArgs& a) {
  require_file(a.result, "result file");
  const std::string python = find_python(a.python);
  if (python.empty())
    throw InputError("otmpm render needs python3 with matplotlib, numpy and h5py (Debian: apt-get install "
                     "python3-matplotlib python3-h5py); none found (/usr/bin/python3, python3 on PATH, --python)");
  const fs::path script = scripts_dir(a.scripts) / "render.py";
  if (!fs::exists(script))
    throw std::runtime_error(script.string() + " not found: otmpm is not installed completely (give --scripts DIR)");
  std::vector<std::string> argv{python,      script.string(), a.result, "--field", a.field, "--out", a.out,
                                "--component", a.component, "--view", a.view};
  if (a.all) argv.insert(argv.end(), {"--all", "--stride", std::to_string(a.stride)});
  else argv.insert(argv.end(), {"--frame", std::to_string(a.frame)});
  char fps[32];
  std::snprintf(fps, sizeof fps, "%g", a.fps);
  argv.insert(argv.end(), {"--fps", fps});
  std::fflush(stdout);
  const int rc = run_and_wait(argv);
  if (rc == 0 || rc == 2) return rc;
  if (rc == 127) throw InputError("cannot start " + python + " (--python)");
  throw std::runtime_error("render.py failed with exit status " + std::to_string(rc));
}

} // namespace

Command add_render_command(CLI::App& app) {
  auto a = std::make_shared<RenderArgs>();
  CLI::App* sub = app.add_subcommand(
      "render", "Draw the particles of a result file coloured by a field, as a PNG or an animated GIF (matplotlib)");
  sub->add_option("result", a->result, "Result file of otmpm run")->required()->type_name("RESULT.h5");
  sub->add_option("--field", a->field, "Particle field of the frames (x, v, stress, ...; see output.fields)")
      ->required()
      ->type_name("NAME");
  sub->add_option("--out", a->out, "Picture to write: .png (one frame) or .gif (an animation with --all)")
      ->required()
      ->type_name("FILE")
      ->check([](const std::string& s) {
        const std::string ext = fs::path(s).extension().string();
        return ext == ".png" || ext == ".gif" ? std::string() : std::string("--out must end in .png or .gif");
      });
  CLI::Option* frame = sub->add_option("--frame", a->frame, "Frame to draw, from 0; negative counts from the end")
                           ->type_name("K")
                           ->capture_default_str();
  CLI::Option* all = sub->add_flag("--all", a->all, "Every frame, as an animated GIF")->excludes(frame);
  sub->add_option("--stride", a->stride, "With --all: every K-th frame (and the last)")
      ->type_name("K")
      ->check(CLI::PositiveNumber)
      ->needs(all)
      ->capture_default_str();
  sub->add_option("--component", a->component,
                  "For a vector or tensor field: norm (Euclidean / Frobenius), a component (x, y, z; xx, xy, ...) "
                  "or its index")
      ->type_name("C")
      ->capture_default_str();
  sub->add_option("--view", a->view,
                  "3D: the plane the particles are projected on (xy: seen from +z, the particles with the "
                  "largest z on top; xz, yz likewise)")
      ->check(CLI::IsMember({"xy", "xz", "yz"}))
      ->capture_default_str();
  sub->add_option("--fps", a->fps, "Frames per second of a GIF")->check(CLI::Range(0.1, 100.0))->capture_default_str();
  sub->add_option("--scripts", a->scripts, "Folder with render.py (default: share/otmpm beside the bin folder)")
      ->type_name("DIR");
  sub->add_option("--python", a->python, "Python with matplotlib, numpy and h5py (default: /usr/bin/python3)")
      ->type_name("PATH");
  sub->footer("1D: the field against x. 2D: the particles in the x-y plane. 3D: projected on --view. Colour limits "
              "are shared by all frames of a GIF; a field that changes sign gets a diverging colour map centred "
              "on 0.");
  return [a] { return render(*a); };
}

} // namespace otmpm::cli
