/// \file run_common.cpp
/// What the pieces of a run share: diagnoses, the output request, the
/// agreed interrupt.
#include "otmpm/run/run_common.hpp"

#include "otmpm/distributed/comm.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/run/restart.hpp"

#include <cstdint>
#include <tuple>

namespace otmpm {

std::string diagnosis(const std::string& what, long step, double t) {
  if (what.rfind("step ", 0) == 0) return what;
  return "step " + std::to_string(step) + ", t = " + format_number(t) + " s: " + what;
}

std::pair<std::string, std::string> result_file(const Scene& scene, const RunOptions& opt, const Checkpoint* resume) {
  if (!opt.out_file.empty()) return {opt.out_file, "RunOptions::out_file, otmpm run --out"};
  if (resume)
    return {resume->group("recorder").string("result_file"), "the interrupted run's result file, from " + resume->file};
  return {scene.output.file, scene.locate("output.file").describe()};
}

OutputRequest output_request(const Scene& scene, const std::string& text, const RunOptions& opt,
                             const Checkpoint* resume) {
  OutputRequest r;
  std::tie(r.result, r.result_origin) = result_file(scene, opt, resume);
  if (scene.output.checkpoint_every > 0) {
    r.checkpoint = checkpoint_path(scene, r.result);
    r.checkpoint_origin = scene.output.checkpoint_file.empty() ? "the default beside the result file"
                                                               : scene.locate("output.checkpoint_file").describe();
  }
  r.vtk_format = vtk_format(scene.output);
  r.scene_text = text;
  r.force = opt.force;
  if (resume) {
    r.continued_run = resume->run_id;
    r.previous_result = resume->group("recorder").string("result_file");
    r.previous_frames = static_cast<int>(resume->group("recorder").integer("frames"));
  }
  return r;
}

bool interrupt_requested(const RunOptions& options) {
  if (!options.interrupt) return false;
  const auto& comm = distributed::Comm::world();
  const std::int64_t flag = options.interrupt->load() ? 1 : 0;
  return (comm.size() > 1 ? comm.max(flag) : flag) != 0;
}

} // namespace otmpm
