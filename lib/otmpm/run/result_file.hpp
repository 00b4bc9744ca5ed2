#pragma once
/// \file result_file.hpp
/// The result file of a run (internal to run/).
#include "otmpm/distributed/global_view.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/run/background_writer.hpp"
#include "otmpm/run/output_time.hpp"
#include "otmpm/run/run_common.hpp"

#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace otmpm {

/// The result file of a run and the files beside it: which files they are
/// (prepare_outputs on the writing rank, shared with every rank), the
/// ResultWriter, the frames a restart copies from the interrupted run's
/// file, the output times written (on the writer thread with
/// RunOptions::background_output), the status and the final summary
/// attributes (status, steps, errors, energies, phase times, body volumes).
template <int D> class ResultFile {
public:
  explicit ResultFile(const distributed::GlobalView<D>& view) : view_(view) {}

  /// Decides the output files and creates the result file (collective).
  void open(const Scene& scene, const std::string& text, const RunOptions& opt, const Checkpoint* resume) {
    // Before the writing rank claims, replaces or sets aside anything, and
    // before the collective create: every rank reaches the same result file.
    view_.require_shared_file(result_file(scene, opt, resume).first);
    prepare([&] { return output_request(scene, text, opt, resume); });
    view_.collectively([&] {
      const ResultOptions options{run_id_, vtk_extension_, scene.output.precision == "single",
                                  scene.output.compression};
      writer_ = std::make_unique<ResultWriter>(path_, text, D, options, view_.parallel_io());
    });
  }

  /// Starts the writer thread (serial runs only).
  void write_in_background() {
    if (!view_.distributed()) background_ = std::make_unique<BackgroundWriter>();
  }

  /// A restart: where the frames before the checkpoint come from (none for a new run).
  const std::optional<PreviousResults>& previous() const { return previous_; }

  /// Copies the first `frames` frames and history samples (`histories`) of
  /// the interrupted run's file.
  void copy_previous(int frames, const std::vector<HistoryLayout>& histories, const std::vector<std::string>& fields) {
    view_.collectively([&] { copy_results(previous_->path, *writer_, frames, histories, fields); });
    view_.on_writer([&] { release_previous_results(*previous_); });
  }

  /// The output time to fill next: background output reuses the buffers of
  /// the previous one once the thread is done with it.
  std::shared_ptr<OutputTime> next_output_time() {
    std::shared_ptr<OutputTime> o;
    if (background_) {
      background_->wait(); // the previous output time is written: its buffers (already allocated) can be reused
      o = std::exchange(spare_, nullptr);
    }
    return o ? o : std::make_shared<OutputTime>();
  }

  /// Writes an output time: now (collective), or checked now and written on the writer thread.
  void write(const std::shared_ptr<OutputTime>& o, const std::function<void(OutputTime&)>& own_fields) {
    if (!background_) {
      view_.collectively([&] { write_now(*o); });
      return;
    }
    own_fields(*o);
    writer_->check_frame(o->t, o->fields); // an instability stops the run here, as without the thread
    background_->submit([this, o] { write_now(*o); });
    spare_ = o; // its buffers are reused by the next output time, once the thread is done with it
  }

  /// Waits for the output time in flight on the writer thread (background
  /// output) and rethrows what its writing threw.
  void wait() {
    if (background_) background_->wait();
  }

  /// Marks the file with a diagnosis (the file stays valid). An output error
  /// here changes nothing more: the diagnosis is in the summary anyway.
  void set_status(const std::string& status) {
    try {
      wait();
    } catch (const std::exception&) { // the status says what went wrong already
    }
    view_.collectively([&] {
      if (!writer_ || !writer_->writable()) return;
      try {
        writer_->set_attribute("status", status);
        writer_->publish();
      } catch (const OutputError&) {
      }
    });
  }

  /// Writes the summary's attributes (and `distributed`'s, the bodies'
  /// volumes), closes the file and releases otmpm's locks on the run's files.
  void close(RunSummary& s, std::vector<std::pair<std::string, double>> distributed,
             const std::vector<BodyVolume>& volumes) {
    stop_background(distributed);
    view_.collectively([&] {
      if (writer_ && writer_->writable()) { // after a failed HDF5 write the file is left as it is
        try {
          write_summary(s, distributed, volumes);
        } catch (const OutputError& err) {
          s.status = std::string("output error: ") + err.what();
          s.exit_code = kOutputErrorExit;
        }
      }
      writer_.reset(); // closed now: the run is over, and readers may open the file at once
    });
    outputs_.lock = OutputLock(); // the files are free for the next run (otmpm's locks released)
  }

  const std::string& path() const { return path_; }
  const std::string& run_id() const { return run_id_; }
  const std::string& checkpoint_path() const { return checkpoint_path_; }

private:
  /// Decides the output files on the writing rank (request(): the paths and
  /// the checkpoint location tried, which the writing rank alone writes;
  /// prepare_outputs: collisions, otmpm's locks, what may be replaced, a
  /// restart's previous results; an InputError there is thrown on every
  /// rank) and shares the answer with every rank.
  void prepare(const std::function<OutputRequest()>& request) {
    view_.on_writer([&] { outputs_ = prepare_outputs(request()); });
    const PreviousResults p = outputs_.previous.value_or(PreviousResults{});
    const char sep = '\0'; // never part of a path
    const std::string mine = outputs_.files.result + sep + outputs_.files.checkpoint + sep +
                             outputs_.files.vtk_extension + sep + outputs_.run_id + sep +
                             (outputs_.previous ? "1" : "0") + (p.set_aside ? "1" : "0") + sep + p.path;
    std::vector<std::string> parts{""};
    for (char c : view_.share(mine))
      if (c == sep) parts.emplace_back();
      else parts.back() += c;
    require(parts.size() == 6, "Recorder: the output files shared by the writing rank are incomplete");
    path_ = parts[0];
    checkpoint_path_ = parts[1];
    vtk_extension_ = parts[2];
    run_id_ = parts[3];
    if (parts[4][0] == '1') previous_ = PreviousResults{parts[5], parts[4][1] == '1', ""};
  }

  /// Writes one output time: the probe, energy and wall samples, then the frame.
  void write_now(const OutputTime& o) {
    for (const auto& [name, values] : o.probes) writer_->append_probe(name, o.t, values);
    writer_->append_series("energy", o.t, o.energy);
    for (const auto& [name, values] : o.walls) writer_->append_group_sample("walls", name, o.t, values);
    if (!o.diagnostics.empty()) writer_->append_series("diagnostics", o.t, o.diagnostics);
    writer_->write_frame(o.t, o.fields);
  }

  /// Ends the writer thread (its error was reported before) and adds its busy time to `distributed`.
  void stop_background(std::vector<std::pair<std::string, double>>& distributed) {
    if (!background_) return;
    try {
      background_->wait();
    } catch (const std::exception&) { // reported by the runner's wait_for_output() before
    }
    distributed.emplace_back("seconds_output_thread", background_->busy_seconds());
    background_.reset();
  }

  /// The final status and summary attributes (and those of a distributed
  /// run; the bodies' volumes: volume_NAME as seeded, exact_volume_NAME of
  /// the shape).
  void write_summary(const RunSummary& s, const std::vector<std::pair<std::string, double>>& distributed,
                     const std::vector<BodyVolume>& volumes) {
    writer_->set_attribute("status", s.status);
    writer_->set_attribute("steps", static_cast<long long>(s.steps));
    writer_->set_attribute("t_end", s.time);
    writer_->set_attribute("wall_seconds", s.wall_seconds);
    writer_->set_attribute("particles", static_cast<long long>(s.particles));
    writer_->set_attribute("nodes", static_cast<long long>(s.nodes));
    if (!s.initial_equilibrium.empty()) writer_->set_attribute("initial_equilibrium", s.initial_equilibrium);
    for (const auto& [name, value] : s.errors) writer_->set_attribute(name, value);
    for (const auto& [name, value] : s.diagnostics) writer_->set_attribute(name, value);
    writer_->set_attribute("max_energy_ratio", s.energy.max_energy_ratio());
    writer_->set_attribute("energy_drift", s.energy.energy_drift());
    for (std::size_t i = 0; i < phase_names.size(); ++i)
      writer_->set_attribute("seconds_" + std::string(phase_names[i]), s.timers.seconds[i]);
    for (const auto& [name, value] : distributed) writer_->set_attribute(name, value);
    for (const BodyVolume& v : volumes) {
      writer_->set_attribute("volume_" + v.name, v.seeded);
      if (std::isfinite(v.exact)) writer_->set_attribute("exact_volume_" + v.name, v.exact);
    }
    writer_->publish();
  }

  const distributed::GlobalView<D>& view_;
  PreparedOutputs outputs_; ///< paths and otmpm's locks (on the writing rank), held for the whole run
  std::string path_;
  std::string checkpoint_path_;
  std::string vtk_extension_;               ///< "", "vtp" or "vtu"
  std::string run_id_;                      ///< this run's id (a restart: the continued run's)
  std::optional<PreviousResults> previous_; ///< a restart: where the frames before the checkpoint come from
  std::unique_ptr<ResultWriter> writer_;
  /// The writer thread (RunOptions::background_output, serial runs); declared
  /// after writer_, so it is joined before the writer is closed.
  std::unique_ptr<BackgroundWriter> background_;
  std::shared_ptr<OutputTime> spare_; ///< the output time last handed to the thread (its buffers are reused)
};

} // namespace otmpm
