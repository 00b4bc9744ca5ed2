#pragma once
/// \file recorder.hpp
/// What a run records, composed of one recorder per concern (internal to run/).
#include "otmpm/engine/timers.hpp"
#include "otmpm/run/energy_series.hpp"
#include "otmpm/run/exact_errors.hpp"
#include "otmpm/run/frame_recorder.hpp"
#include "otmpm/run/probe_series.hpp"
#include "otmpm/run/restart.hpp"
#include "otmpm/run/result_file.hpp"
#include "otmpm/run/support_series.hpp"
#include "otmpm/run/wall_series.hpp"

#include <filesystem>
#include <optional>
#include <string>

namespace otmpm {

/// Records a run: at every output time one sample of each history (probes,
/// energy, walls, support diagnostics) and a frame into the result file, a
/// checkpoint every output.checkpoint_every steps (the engine's state and
/// each recorder's accumulators), and at the end the summary (energies,
/// errors against the exact solution, diagnostics) with the file's final
/// attributes. Each concern is its own recorder; this class calls them in
/// the order the result file holds them.
template <int D> class Recorder {
public:
  /// `resume`: the checkpoint a restarted run continues (null for a new run).
  Recorder(const Scene& scene, const RunOptions& opt, Engine<D>& e, const ExactSolution<D>* exact,
           const Checkpoint* resume)
      : scene_(scene), text_(scene.text.empty() ? to_toml(scene) : scene.text), e_(e), view_(e),
        results_(opt.write_results), probes_(scene, view_, e.particles(), exact), energy_(e), walls_(e),
        supports_(e), frames_(scene.output, e, view_), file_(view_) {
    if (exact) exact_.emplace(e, view_, *exact);
    if (resume) restore(resume->group("recorder"));
    if (!opt.write_results) return;
    if (resume) frame_count_ = static_cast<int>(resume->group("recorder").integer("frames"));
    file_.open(scene, text_, opt, resume);
    if (file_.previous()) continue_results(resume->group("recorder"));
    if (opt.background_output) file_.write_in_background();
  }

  /// Waits for the output time in flight on the writer thread (background
  /// output) and rethrows what its writing threw.
  void wait_for_output() { file_.wait(); }

  /// Writes a checkpoint after every output.checkpoint_every steps (not after
  /// the last step) when checkpoints are on; `wall_seconds` is the wall time
  /// of this process so far.
  void maybe_checkpoint(double wall_seconds, bool last) {
    const long every = scene_.output.checkpoint_every;
    if (!results_ || every <= 0 || last || e_.steps() % every != 0) return;
    checkpoint(wall_seconds);
  }

  /// Writes a checkpoint of the current state now (when checkpoints are on).
  void checkpoint(double wall_seconds) {
    if (!results_ || scene_.output.checkpoint_every <= 0) return;
    ScopedPhase timer(e_.timers(), Phase::output);
    wait_for_output(); // a restart copies the frames before the checkpoint from the result file
    Checkpoint ck;
    ck.scene = text_;
    ck.run_id = file_.run_id();
    e_.save_state(ck);
    save(ck.group("recorder"), wall_seconds);
    view_.write_checkpoint(file_.checkpoint_path(), std::move(ck)); // any rank count can restart from it
  }

  /// Wall time of the interrupted run up to its checkpoint (0 for a new run).
  double wall_before() const { return wall_before_; }

  /// How the gravity-loading phase before t = 0 ended (RunSummary::
  /// initial_equilibrium; empty: the scene has none): a new run's, stored in
  /// its checkpoints, or the one a restart's checkpoint stored.
  const std::string& initial_equilibrium() const { return initial_equilibrium_; }
  void set_initial_equilibrium(const std::string& how) { initial_equilibrium_ = how; }

  /// Adds the engine's current energy balance to the run's EnergySummary (every step).
  void sample_energy() { energy_.sample_summary(); }

  /// Writes a frame and probe samples when t reached the next output time.
  void maybe_record(bool force) {
    const double every = scene_.output.every;
    const double t = e_.time();
    if (!force && !(every > 0.0 && t >= next_ * (1.0 - time_slack))) return;
    ScopedPhase timer(e_.timers(), Phase::output);
    record(t);
    if (every > 0.0)
      while (next_ <= t * (1.0 + time_slack)) next_ += every;
  }

  /// The summary of each recorder, then the result file's final attributes.
  void finish(RunSummary& s) {
    energy_.summarize(s);
    supports_.summarize(s);
    const std::vector<BodyVolume> volumes = body_volumes<D>(scene_, e_); // every rank
    probes_.summarize(s);
    if (exact_ && s.exit_code == 0 && !s.interrupted) exact_->summarize(s);
    if (results_) s.out_file = file_.path();
    file_.close(s, view_.run_attributes(), volumes);
  }

  /// Marks the file with a diagnosis (the file stays valid).
  void set_status(const std::string& status) { file_.set_status(status); }

private:
  /// The histories record() appends a sample to, in its order.
  std::vector<HistoryLayout> histories() const {
    std::vector<HistoryLayout> h;
    probes_.layout(h);
    energy_.layout(h);
    walls_.layout(h);
    supports_.layout(h);
    return h;
  }

  /// One output time: the probes (every rank, also without a result file),
  /// then the other series and the frame.
  void record(double t) {
    Samples probes = probes_.sample(t);
    if (!results_) return;
    const std::shared_ptr<OutputTime> o = file_.next_output_time();
    o->t = t;
    o->probes = std::move(probes);
    o->energy = energy_.sample();
    o->diagnostics = supports_.sample();
    o->walls = walls_.sample(t);
    frames_.fill(*o);
    ++frame_count_;
    file_.write(o, &FrameRecorder<D>::own_fields);
  }

  /// Copies the frames and history samples written before the checkpoint.
  /// A damaged file: the new one says why it holds only part of the frames.
  void continue_results(const StateGroup& g) {
    try {
      const std::string& path = file_.previous()->path;
      view_.require_readable(path, "the result file of the interrupted run"); // every rank copies from it
      frames_.continue_file(path, g.integer("frames"));
      file_.copy_previous(static_cast<int>(g.integer("frames")), histories(), scene_.output.fields);
    } catch (const InputError& e) {
      set_status(std::string("input error: ") + e.what());
      throw;
    }
  }

  void save(StateGroup& g, double wall_seconds) const {
    g.reals["next_output_time"] = next_;
    g.reals["wall_seconds"] = wall_before_ + wall_seconds;
    g.integers["frames"] = frame_count_;
    g.strings["result_file"] = std::filesystem::absolute(file_.path()).string();
    g.strings["particle_files"] = particle_file_record(scene_);
    if (!initial_equilibrium_.empty()) g.strings["initial_equilibrium"] = initial_equilibrium_;
    energy_.save(g);
    supports_.save(g);
    walls_.save(g);
    probes_.save(g);
  }

  void restore(const StateGroup& g) {
    next_ = g.real("next_output_time");
    wall_before_ = g.real("wall_seconds");
    if (auto it = g.strings.find("initial_equilibrium"); it != g.strings.end()) initial_equilibrium_ = it->second;
    energy_.restore(g);
    walls_.restore(g);
    supports_.restore(g);
    probes_.restore(g);
  }

  const Scene& scene_;
  std::string text_; ///< the scene as TOML: Scene::text, or to_toml() for a scene built in code
  Engine<D>& e_;
  distributed::GlobalView<D> view_;
  bool results_ = true; ///< the run writes a result file (its writer lives on the writing rank only)
  int frame_count_ = 0; ///< frames written so far (every rank counts them)
  double next_ = 0.0;   ///< the next output time
  double wall_before_ = 0.0;
  std::string initial_equilibrium_; ///< initial_equilibrium()
  ProbeSeries<D> probes_;
  EnergySeries<D> energy_;
  WallSeries<D> walls_;
  SupportSeries<D> supports_;
  FrameRecorder<D> frames_;
  std::optional<ExactErrors<D>> exact_;
  ResultFile<D> file_; ///< last: the writer thread ends before the recorders it reads go
};

} // namespace otmpm
