// `otmpm render RESULT.h5 --field NAME [--frame K | --all] --out FILE.png|.gif`:
// draws the particles of a result file coloured by a field with matplotlib,
// through render.py in the scripts folder (system.hpp: share/otmpm beside the
// executable's bin folder, or --scripts). The script checks the field and
// the frame and exits 2 with a message for bad input.
#include "cli.hpp"
#include "system.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/output_files.hpp"

#include <cstdio>
#include <cstdlib>
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

/// InputError when the picture `out` cannot be written without harm: it is
/// the result file itself (or a link to it), a directory, a FIFO or a device.
void check_picture(const std::string& out, const std::string& result) {
  std::error_code ec;
  if (fs::exists(out, ec) && same_file(out, result))
    throw InputError("--out " + out + " is the result file " + result +
                     " (or a link to it): the picture would replace the results; choose another name");
  if (fs::is_directory(out, ec)) throw InputError("--out " + out + " is a directory; name the picture file");
  if (const std::string kind = special_file(out); !kind.empty())
    throw InputError("--out " + out + " is " + kind + ", not a picture file");
}

/// The exit status of the script: 0 and 2 (bad input, message printed by the
/// script) pass through; 1 - what the script never returns itself - is an
/// interpreter that cannot run it (--python), anything else an internal error.
int render(const RenderArgs& a) {
  require_file(a.result, "result file");
  check_picture(a.out, a.result);
  roll_back_interrupted_flush(a.result); // a run killed inside a flush: the script reads the last flushed state
  const std::string python = find_python(a.python);
  if (python.empty())
    throw InputError("otmpm render needs python3 with matplotlib, numpy and h5py (Debian: apt-get install "
                     "python3-matplotlib python3-h5py); none found (/usr/bin/python3, python3 on PATH, --python)");
  const fs::path script = scripts_dir(a.scripts) / "render.py";
  if (!fs::is_regular_file(script) && !a.scripts.empty())
    throw InputError("--scripts " + a.scripts + ": no render.py in that folder");
  if (!fs::is_regular_file(script))
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
  if (rc == 1)
    throw InputError(python + " could not run render.py (exit status 1): give --python a Python 3 with matplotlib, "
                              "numpy and h5py");
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
  sub->add_option("--fps", a->fps, "Frames per second of a GIF, 0.1 to 100")
      ->check([](const std::string& s) { // CLI::Range lets NaN through (every comparison with it is false)
        char* end = nullptr;
        const double v = std::strtod(s.c_str(), &end);
        const bool ok = end != s.c_str() && *end == '\0' && v >= 0.1 && v <= 100.0;
        return ok ? std::string() : std::string("--fps must be a number from 0.1 to 100");
      })
      ->capture_default_str();
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
