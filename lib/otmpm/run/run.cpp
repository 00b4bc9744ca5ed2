/// \file run.cpp
/// A run of a scene (run.hpp, simulation.hpp): the engine built by the
/// assembler, stepped to t_end, with the Recorder that writes the result
/// file (frames, probes, energy series, final errors and status) and the
/// checkpoints.
#include "otmpm/run/run.hpp"

#include "otmpm/run/simulation.hpp"

#include "otmpm/assembly/assembler.hpp"
#include "otmpm/distributed/global_view.hpp"
#include "otmpm/interrupt.hpp"
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/parallel.hpp"
#include "otmpm/particles/output_fields.hpp"
#include "otmpm/run/restart.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/reference/exact.hpp"
#include "otmpm/scene/resources.hpp"
#include "otmpm/scene/validate.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <array>
#include <condition_variable>
#include <exception>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <new>
#include <optional>
#include <thread>
#include <tuple>
#include <utility>

namespace otmpm {

namespace {

/// Relative slack when comparing the simulated time with output times.
constexpr double time_slack = 1e-9;
/// Floor of EnergySummary::reference(), so a body at rest with no load has ratio 0, not 0/0.
constexpr double energy_reference_floor = 1e-300;

/// The result file of a run and where its name came from: RunOptions::out_file,
/// else a restart's interrupted run's file, else output.file.
std::pair<std::string, std::string> result_file(const Scene& scene, const RunOptions& opt, const Checkpoint* resume) {
  if (!opt.out_file.empty()) return {opt.out_file, "RunOptions::out_file, otmpm run --out"};
  if (resume)
    return {resume->group("recorder").string("result_file"), "the interrupted run's result file, from " + resume->file};
  return {scene.output.file, scene.locate("output.file").describe()};
}
std::string diagnosis(const std::string& what, long step, double t);

/// What the run's output files are and where their names came from
/// (prepare_outputs); `text` is the scene as TOML (the identical-scene rule).
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

/// The (global) particle a probe follows: the leftmost/rightmost by initial
/// position (ties: lowest index) or the one nearest to a point.
template <int D>
long long probe_particle(const distributed::GlobalView<D>& view, const Particles<D>& P, const ProbeSection& probe) {
  Vec<D> at;
  for (int k = 0; k < D; ++k) at[k] = probe.at[k];
  return view.best([&](int p) {
    return probe.particle == "leftmost" ? P.X[p][0] : probe.particle == "rightmost" ? -P.X[p][0] : (P.X[p] - at).norm();
  });
}

// A member added to EnergySummary must be saved and restored here.
static_assert(sizeof(EnergySummary) == 4 * sizeof(double), "EnergySummary changed: update the checkpoint");

/// The members of an EnergySummary (const or not) by checkpoint name.
template <class S> auto summary_fields(S& s) {
  return std::array{std::pair{"energy_initial", &s.initial}, std::pair{"max_energy", &s.max_energy},
                    std::pair{"max_work", &s.max_work}, std::pair{"max_balance_error", &s.max_balance_error}};
}

/// One writer thread that runs one job at a time (RunOptions::background_output):
/// submit() waits for the job in flight, rethrows what it threw, and hands
/// the thread the next one, so at most one output time is in flight and its
/// writes happen in the order they were submitted. The first exception of a
/// job is kept and rethrown by the next submit() or wait() (once).
class BackgroundWriter {
public:
  BackgroundWriter() : thread_([this] { loop(); }) {}
  ~BackgroundWriter() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    thread_.join(); // the job in flight finishes first
  }
  BackgroundWriter(const BackgroundWriter&) = delete;
  BackgroundWriter& operator=(const BackgroundWriter&) = delete;

  /// Waits for the job in flight, rethrows its exception, then starts `job`.
  void submit(std::function<void()> job) {
    wait();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      job_ = std::move(job);
    }
    wake_.notify_all();
  }

  /// Waits until no job is in flight; rethrows the exception of the last one (once).
  void wait() {
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return !job_; });
    if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  }

  /// Wall seconds the thread spent in jobs.
  double busy_seconds() {
    std::lock_guard<std::mutex> lock(mutex_);
    return busy_;
  }

private:
  void loop() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      wake_.wait(lock, [this] { return stop_ || job_; });
      if (!job_) return; // stopped with nothing left to do
      lock.unlock();
      const auto start = std::chrono::steady_clock::now();
      std::exception_ptr error;
      try {
        job_(); // only this thread touches job_ while it is set
      } catch (...) {
        error = std::current_exception();
      }
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      lock.lock();
      busy_ += seconds;
      if (error && !error_) error_ = error;
      job_ = nullptr;
      done_.notify_all();
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::function<void()> job_;
  std::exception_ptr error_;
  bool stop_ = false;
  double busy_ = 0.0;
  std::thread thread_; ///< last: started once the members above exist
};

template <int D> class Recorder {
public:
  /// `resume`: the checkpoint a restarted run continues (null for a new run).
  Recorder(const Scene& scene, const RunOptions& opt, Engine<D>& e, const ExactSolution<D>* exact,
           const Checkpoint* resume)
      : scene_(scene), text_(scene.text.empty() ? to_toml(scene) : scene.text), e_(e), exact_(exact), view_(e),
        results_(opt.write_results) {
    for (const ProbeSection& pr : scene.output.probes)
      probes_.push_back({pr.name, probe_particle(view_, e.particles(), pr), 0.0, 0});
    if (resume) restore_accumulators(resume->group("recorder"));
    if (!opt.write_results) return;
    if (resume) frames_ = static_cast<int>(resume->group("recorder").integer("frames"));
    // Before the writing rank claims, replaces or sets aside anything, and
    // before the collective create: every rank reaches the same result file.
    view_.require_shared_file(result_file(scene, opt, resume).first);
    prepare([&] { return output_request(scene, text_, opt, resume); });
    view_.collectively([&] {
      const ResultOptions options{run_id_, vtk_extension_, scene.output.precision == "single",
                                  scene.output.compression};
      writer_ = std::make_unique<ResultWriter>(path_, text_, D, options, view_.parallel_io());
    });
    if (previous_) {
      try {
        continue_results(*previous_, resume->group("recorder"));
      } catch (const InputError& e) { // a damaged file: the new one says why it holds only part of the frames
        set_status(std::string("input error: ") + e.what());
        throw;
      }
    }
    if (opt.background_output && !view_.distributed()) background_ = std::make_unique<BackgroundWriter>();
  }

  /// Waits for the output time in flight on the writer thread (background
  /// output) and rethrows what its writing threw.
  void wait_for_output() {
    if (background_) background_->wait();
  }

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
    ck.run_id = run_id_;
    e_.save_state(ck);
    StateGroup& g = ck.group("recorder");
    g.reals["next_output_time"] = next_;
    g.reals["wall_seconds"] = wall_before_ + wall_seconds;
    g.integers["frames"] = frames_;
    g.strings["result_file"] = std::filesystem::absolute(path_).string();
    g.strings["particle_files"] = particle_file_record(scene_);
    g.put_reals(summary_fields(energy_));
    g.reals["wall_time"] = wall_time_;
    if (support_diagnostics()) {
      const auto counts = support_counts();
      g.reals["widened_supports"] = counts[0];
      g.reals["moved_points"] = counts[1];
    }
    StateArray<double>& walls = g.real_arrays["wall_last_impulse"];
    walls.cols = D;
    for (const Vec<D>& J : wall_last_) walls.values.insert(walls.values.end(), J.data(), J.data() + D);
    StateArray<double>& sum_sq = g.real_arrays["probe_sum_sq"];
    StateArray<std::int64_t>& samples = g.integer_arrays["probe_samples"];
    for (const Probe& pr : probes_) {
      sum_sq.values.push_back(pr.sum_sq);
      samples.values.push_back(pr.samples);
    }
    view_.write_checkpoint(checkpoint_path_, std::move(ck)); // any rank count can restart from it
  }

  /// Wall time of the interrupted run up to its checkpoint (0 for a new run).
  double wall_before() const { return wall_before_; }

  /// Adds the engine's current energy balance to the run's EnergySummary (every step).
  void sample_energy() {
    const EnergyBalance& E = e_.energy();
    energy_.initial = E.initial;
    energy_.sample(E.total() + E.spent(), E.work(), E.balance_error()); // W_p, W_f, W_i and W_d count as spent energy
  }

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

  void finish(RunSummary& s) {
    s.energy = energy_;
    s.impact = e_.energy().impact;
    if (support_diagnostics()) {
      const auto counts = support_counts();
      s.diagnostics = {{"widened_supports", counts[0]}, {"moved_points", counts[1]}};
    }
    const std::vector<BodyVolume> volumes = body_volumes<D>(scene_, e_); // every rank
    for (const Probe& pr : probes_)
      if (exact_ && pr.samples > 0) s.errors["history_error_" + pr.name] = std::sqrt(pr.sum_sq / pr.samples);
    if (exact_ && s.exit_code == 0 && !s.interrupted) final_errors(s);
    if (results_) s.out_file = path_;
    auto distributed = view_.run_attributes();
    if (background_) {
      try {
        background_->wait();
      } catch (const std::exception&) { // reported by the runner's wait_for_output() before
      }
      distributed.emplace_back("seconds_output_thread", background_->busy_seconds());
      background_.reset();
    }
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

  /// Marks the file with a diagnosis (the file stays valid). An output error
  /// here changes nothing more: the diagnosis is in the summary anyway.
  void set_status(const std::string& status) {
    try {
      wait_for_output();
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

private:
  struct Probe {
    std::string name;
    long long particle; ///< global id
    double sum_sq;
    int samples;
  };

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

  void restore_accumulators(const StateGroup& g) {
    next_ = g.real("next_output_time");
    wall_before_ = g.real("wall_seconds");
    g.get_reals(summary_fields(energy_));
    wall_time_ = g.real("wall_time");
    // The counts before the checkpoint (this process' basis counts from 0).
    if (g.reals.count("widened_supports")) support_before_ = {g.real("widened_supports"), g.real("moved_points")};
    const auto& walls = g.real_array("wall_last_impulse", e_.walls().size(), D).values;
    wall_last_.assign(e_.walls().size(), Vec<D>::Zero());
    for (std::size_t w = 0; w < wall_last_.size(); ++w)
      for (int k = 0; k < D; ++k) wall_last_[w][k] = walls[w * D + static_cast<std::size_t>(k)];
    const auto& sum_sq = g.real_array("probe_sum_sq", probes_.size(), 1).values;
    const auto& samples = g.integer_array("probe_samples", probes_.size(), 1).values;
    for (std::size_t i = 0; i < probes_.size(); ++i) {
      probes_[i].sum_sq = sum_sq[i];
      probes_[i].samples = static_cast<int>(samples[i]);
    }
  }

  /// The histories record() appends a sample to, in its order.
  std::vector<HistoryLayout> histories() const {
    std::vector<HistoryLayout> h;
    for (const Probe& pr : probes_) h.push_back({pr.name, true, {"x", "v", "stress"}});
    std::vector<std::string> energy{"kinetic", "strain", "external_work", "reaction_work"};
    if (dissipative()) energy.push_back("dissipated");
    if (e_.has_friction()) energy.push_back("friction"), energy.push_back("impact");
    if (e_.settings().two_phase) energy.push_back("darcy");
    h.push_back({"energy", false, energy});
    for (const Wall<D>& w : e_.walls()) h.push_back({w.name, true, {"force", "impulse"}, "walls"});
    if (support_diagnostics()) h.push_back({"diagnostics", false, {"widened_supports", "moved_points"}});
    return h;
  }

  /// True when the run counts the supports that degenerated (`ul` mode with
  /// a family that searches its support: docs/theory.md sect. 4.8).
  bool support_diagnostics() const { return e_.mode().nodes_move() && e_.basis().search_radius() > 0.0; }

  /// The evaluations since t = 0 that needed a wider support, and the points
  /// moved into their support's hull (over every rank).
  std::array<double, 2> support_counts() const {
    std::array<double, 2> c{static_cast<double>(e_.basis().widened_supports()),
                            static_cast<double>(e_.basis().moved_points())};
    if (Distribution<D>* d = e_.distribution()) d->sum(c);
    return {support_before_[0] + c[0], support_before_[1] + c[1]};
  }

  /// True when a material of the run has internal variables (and so may
  /// dissipate energy): the energy series then has a "dissipated" column.
  bool dissipative() const {
    for (int i = 0; i < e_.material_count(); ++i)
      if (!e_.material(i).state().empty()) return true;
    return false;
  }

  /// True when the first frame of the result file `path` stores the 2D
  /// stress as "xx xy yy", as otmpm did before it stored plane strain's
  /// sigma_zz (false when there is no such frame or attribute).
  static bool legacy_plane_stress(const std::string& path) {
    h5::silence();
    const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    if (id < 0) return false; // copy_results says why
    const h5::Handle file(id, H5Fclose);
    if (!h5::has_link(file.get(), "frames") || !h5::has_link(file.get(), "frames/000000") ||
        !h5::has_link(file.get(), "frames/000000/stress"))
      return false;
    try {
      const h5::Handle set(
          h5::checked(H5Dopen2(file.get(), "frames/000000/stress", H5P_DEFAULT), path, "open stress"), H5Dclose);
      return h5::has_attribute(set.get(), "components") && h5::read_string(set.get(), "components", path) == "xx xy yy";
    } catch (const h5::Failure&) {
      return false; // a damaged file: copy_results says why
    }
  }

  /// Copies the frames and history samples written before the checkpoint.
  /// A 2D file whose symmetric stress has 3 columns (an otmpm before
  /// sigma_zz) goes on with 3: the file stays what the interrupted run wrote.
  void continue_results(const PreviousResults& previous, const StateGroup& g) {
    view_.require_readable(previous.path, "the result file of the interrupted run"); // every rank copies from it
    if (D == 2 && scene_.output.symmetric_tensors && g.integer("frames") > 0)
      plane_zz_ = !legacy_plane_stress(previous.path);
    view_.collectively([&] {
      copy_results(previous.path, *writer_, static_cast<int>(g.integer("frames")), histories(), scene_.output.fields);
    });
    view_.on_writer([&] { release_previous_results(previous); });
  }

  using Samples = std::vector<std::pair<std::string, std::vector<std::pair<std::string, std::vector<double>>>>>;

  /// What one output time writes, owned (the writer thread may write it
  /// while the engine steps on).
  struct Output {
    double t = 0.0;
    Samples probes; ///< per probe: x, v, stress
    std::vector<std::pair<std::string, double>> energy;
    std::vector<std::pair<std::string, double>> diagnostics; ///< support_counts (when support_diagnostics)
    Samples walls; ///< per wall: force, impulse
    std::vector<std::vector<double>> buffers, packed;
    std::vector<FieldView> fields;
  };

  /// /walls/NAME: the impulse the wall gave the body since t = 0 and the
  /// mean force over the time since the previous sample (zero at the first).
  Samples wall_samples(double t) {
    const auto& walls = e_.walls();
    Samples out;
    wall_last_.resize(walls.size(), Vec<D>::Zero());
    for (std::size_t w = 0; w < walls.size(); ++w) {
      const Vec<D>& J = e_.wall_impulse()[w];
      const Vec<D> F = t > wall_time_ ? Vec<D>((J - wall_last_[w]) / (t - wall_time_)) : Vec<D>::Zero();
      out.push_back({walls[w].name,
                     {{"force", std::vector<double>(F.data(), F.data() + D)},
                      {"impulse", std::vector<double>(J.data(), J.data() + D)}}});
      wall_last_[w] = J;
    }
    wall_time_ = t;
    return out;
  }

  /// Writes one output time: the probe, energy and wall samples, then the frame.
  void write_output(const Output& o) {
    for (const auto& [name, values] : o.probes) writer_->append_probe(name, o.t, values);
    writer_->append_series("energy", o.t, o.energy);
    for (const auto& [name, values] : o.walls) writer_->append_group_sample("walls", name, o.t, values);
    if (!o.diagnostics.empty()) writer_->append_series("diagnostics", o.t, o.diagnostics);
    writer_->write_frame(o.t, o.fields);
  }

  /// Makes the frame's fields own their values (background output): the
  /// fields that point into the particle arrays are copied into their buffers.
  static void own_fields(Output& o) {
    for (std::size_t i = 0; i < o.fields.size(); ++i) {
      FieldView& f = o.fields[i];
      if (!f.data || f.data == o.buffers[i].data() || f.data == o.packed[i].data()) continue;
      std::vector<double>& b = o.buffers[i];
      const double* from = f.data;
      b.resize(static_cast<std::size_t>(f.rows) * static_cast<std::size_t>(f.cols));
      parallel_chunks(static_cast<long long>(b.size()), [&](long long begin, long long end) {
        std::copy(from + begin, from + end, b.begin() + begin);
      });
      f.data = b.data();
    }
  }

  void record(double t) {
    Samples samples;
    for (Probe& pr : probes_) {
      const auto r = view_.row(pr.particle); // its values on every rank
      if (exact_) {
        pr.sum_sq += (r.v - exact_->velocity(r.X, t)).squaredNorm();
        ++pr.samples;
      }
      std::vector<double> x(r.x.data(), r.x.data() + D), v(r.v.data(), r.v.data() + D);
      std::vector<double> sig(r.sigma.data(), r.sigma.data() + D * D);
      samples.push_back({pr.name, {{"x", x}, {"v", v}, {"stress", sig}}});
    }
    if (!results_) return;
    std::shared_ptr<Output> o;
    if (background_) {
      background_->wait(); // the previous output time is written: its buffers (already allocated) can be reused
      o = std::exchange(spare_, nullptr);
    }
    if (!o) o = std::make_shared<Output>();
    o->t = t;
    o->probes = std::move(samples);
    const EnergyBalance& E = e_.energy();
    o->energy = {{"kinetic", E.kinetic}, {"strain", E.strain}, {"external_work", E.external_work},
                 {"reaction_work", E.reaction_work}};
    if (dissipative()) o->energy.emplace_back("dissipated", E.dissipated);
    if (e_.has_friction()) o->energy.emplace_back("friction", E.friction), o->energy.emplace_back("impact", E.impact);
    if (e_.settings().two_phase) o->energy.emplace_back("darcy", E.darcy);
    o->diagnostics.clear();
    if (support_diagnostics()) {
      const auto counts = support_counts();
      o->diagnostics = {{"widened_supports", counts[0]}, {"moved_points", counts[1]}};
    }
    o->walls = wall_samples(t);
    o->buffers.resize(scene_.output.fields.size());
    o->packed.resize(o->buffers.size());
    o->fields = frame_fields(o->buffers, o->packed);
    ++frames_;
    if (background_) {
      own_fields(*o);
      writer_->check_frame(t, o->fields); // an instability stops the run here, as without the thread
      background_->submit([this, o] { write_output(*o); });
      spare_ = o; // its buffers are reused by the next output time, once the thread is done with it
      return;
    }
    view_.collectively([&] { write_output(*o); });
  }

  /// The output fields of all particles in global order (buffers hold the
  /// values that are not stored as they are written); a distributed run:
  /// this rank's block of rows of the frame (collective).
  std::vector<FieldView> frame_fields(std::vector<std::vector<double>>& buffers,
                                      std::vector<std::vector<double>>& packed) const {
    const Particles<D>& P = e_.particles();
    const auto n = static_cast<std::size_t>(P.size());
    std::vector<double> zz; // plane strain's sigma_zz, when a field of the frame holds it
    std::vector<FieldView> fields;
    for (std::size_t i = 0; i < scene_.output.fields.size(); ++i) {
      const std::string& name = scene_.output.fields[i];
      const bool symmetric = scene_.output.symmetric_tensors && is_symmetric_tensor_field(name);
      const bool packed_zz = D == 2 && symmetric && name == "stress" && plane_zz_;
      if (D == 2 && zz.empty() && (name == kStressZzField || packed_zz)) zz = out_of_plane_stress();
      FieldData d;
      if (name == kStressZzField) {
        buffers[i] = zz;
        d = {buffers[i].data(), 1};
      } else {
        d = output_field_data<D>(name, P, buffers[i]);
      }
      std::string components;
      if (packed_zz) { // output.symmetric_tensors: and sigma_zz
        pack_plane_stress(d.data, zz.data(), n, packed[i]);
        d = {packed[i].data(), 4};
        components = plane_stress_components();
      } else if (symmetric) { // output.symmetric_tensors
        pack_symmetric(d.data, n, D, packed[i]);
        d = {packed[i].data(), D * (D + 1) / 2};
        components = symmetric_components(D);
      }
      if (!view_.distributed()) {
        fields.push_back({name, P.size(), d.cols, d.data, -1, 0, components});
        continue;
      }
      auto block = view_.block(d.data, d.cols); // this rank's rows of the frame, in global order
      buffers[i] = std::move(block.values);
      fields.push_back({name, static_cast<int>(block.count), d.cols, buffers[i].data(), view_.particles(), block.first,
                        components});
    }
    return fields;
  }

  /// Plane strain's sigma_zz of every particle (2D), from each run of
  /// particles of one material (Material::out_of_plane_stress).
  std::vector<double> out_of_plane_stress() const {
    const Particles<D>& P = e_.particles();
    std::vector<double> zz(static_cast<std::size_t>(P.size()));
    for (int p0 = 0; p0 < P.size();) {
      const int id = P.material[p0];
      int p1 = p0 + 1;
      while (p1 < P.size() && P.material[p1] == id) ++p1;
      e_.material(id).out_of_plane_stress(P, p0, p1, zz.data() + p0);
      p0 = p1;
    }
    return zz;
  }

  void final_errors(RunSummary& s) const {
    const Particles<D>& P = e_.particles();
    const double t = e_.time();
    std::vector<double> ev, eu, es;
    for (int p = 0; p < P.size(); ++p) {
      ev.push_back((P.v[p] - exact_->velocity(P.X[p], t)).squaredNorm());
      eu.push_back((P.x[p] - P.X[p] - exact_->displacement(P.X[p], t)).squaredNorm());
      es.push_back((P.sigma[p] - exact_->stress(P.X[p], t)).squaredNorm());
    }
    // A finite state that overflows against the exact solution (a value near 1e300 written by hand through
    // a view after the last step, which checked the state) has no error: it ends the run as unstable.
    bool overflow = false;
    for (const std::vector<double>* e : {&ev, &eu, &es})
      overflow = overflow || !std::all_of(e->begin(), e->end(), [](double x) { return std::isfinite(x); });
    if (view_.max(overflow ? 1.0 : 0.0) > 0.0) {
      s.status = "unstable: " + diagnosis("the state is too far from the exact solution for its error to be a "
                                          "finite number",
                                          e_.steps(), t);
      s.exit_code = 1;
      return;
    }
    s.errors["rms_velocity_error"] = view_.rms(ev);
    s.errors["rms_displacement_error"] = view_.rms(eu);
    s.errors["rms_stress_error"] = view_.rms(es);
    pore_pressure_errors(s);
  }

  /// A saturated body against an exact pore pressure: rms_pore_pressure_error
  /// (eq. 12.1 over the saturated particles) and max_pore_pressure_error, the
  /// largest |p_p - p(X_p, t)|.
  void pore_pressure_errors(RunSummary& s) const {
    const TwoPhase<D>* liquid = e_.settings().two_phase.get();
    if (!liquid || !exact_->has_pore_pressure()) return;
    const Particles<D>& P = e_.particles();
    const StateField& pressure = *P.find_state(kPorePressureField);
    std::vector<double> ep;
    double largest = 0.0;
    for (int p = 0; p < P.size(); ++p) {
      if (!liquid->fluid(P.material[p])) continue;
      const double d = pressure.values[static_cast<std::size_t>(p)] - exact_->pore_pressure(P.X[p], e_.time());
      ep.push_back(d * d);
      largest = std::max(largest, std::abs(d));
    }
    if (ep.empty()) return;
    s.errors["rms_pore_pressure_error"] = view_.rms(ep);
    s.errors["max_pore_pressure_error"] = view_.max(largest);
  }

  const Scene& scene_;
  std::string text_; ///< the scene as TOML: Scene::text, or to_toml() for a scene built in code
  Engine<D>& e_;
  const ExactSolution<D>* exact_;
  distributed::GlobalView<D> view_;
  bool results_ = true; ///< the run writes a result file (writer_ lives on the writing rank only)
  int frames_ = 0;      ///< frames written so far (every rank counts them)
  std::vector<Probe> probes_;
  PreparedOutputs outputs_; ///< paths and otmpm's locks (on the writing rank), held for the whole run
  std::string path_;
  std::string vtk_extension_;               ///< "", "vtp" or "vtu"
  std::string run_id_;                      ///< this run's id (a restart: the continued run's)
  std::optional<PreviousResults> previous_; ///< a restart: where the frames before the checkpoint come from
  bool plane_zz_ = true; ///< 2D symmetric stress with sigma_zz (false: a restart of a file without it)
  std::unique_ptr<ResultWriter> writer_;
  /// The writer thread (RunOptions::background_output, serial runs); declared
  /// after writer_, so it is joined before the writer is closed.
  std::unique_ptr<BackgroundWriter> background_;
  std::shared_ptr<Output> spare_; ///< the output time last handed to the thread (its buffers are reused)
  std::array<double, 2> support_before_{}; ///< support_counts of the run before its checkpoint (a restart)
  double next_ = 0.0;
  EnergySummary energy_;
  std::string checkpoint_path_;
  double wall_before_ = 0.0;
  AlignedVector<Vec<D>> wall_last_; ///< wall impulses at the previous sample
  double wall_time_ = 0.0;          ///< time of the previous sample
};

/// A diagnosis that names step and time: `what` as it is when it does (the
/// engine's start with "step N, t = T s"), else prefixed with them.
std::string diagnosis(const std::string& what, long step, double t) {
  if (what.rfind("step ", 0) == 0) return what;
  return "step " + std::to_string(step) + ", t = " + format_number(t) + " s: " + what;
}

/// What a run that ran out of memory had been told it could use: otmpm's
/// estimate (scene/resources.hpp) and the limit the estimate passed.
std::string memory_note(const Scene& scene) {
  const bool set = scene.simulation.memory_limit > 0;
  const int ranks = distributed::Comm::world().size();
  return "otmpm's estimate was about " + format_bytes(estimate_even_share(scene, ranks).bytes) +
         (ranks > 1 ? " per rank (an even share of " + std::to_string(ranks) + ")" : "") + " against a limit of " +
         format_bytes(memory_limit(scene)) +
         (set ? " set by simulation.memory_limit: more than this process could get" : " this process may use");
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// What every rank of a distributed run must share besides its scene: the
/// otmpm version, the options that change the run or its files, and the
/// checkpoint a restart continues.
std::string run_inputs(const RunOptions& opt, const Checkpoint* resume) {
  std::string s = "otmpm " OTMPM_VERSION "\nout_file = " + opt.out_file + "\nforce = " + (opt.force ? "1" : "0") +
                  "\nwrite_results = " + (opt.write_results ? "1" : "0") + "\n";
  if (resume) {
    const StateGroup& g = resume->group("engine");
    s += "checkpoint of run " + resume->run_id + " at step " + std::to_string(g.integer("step")) + "\n";
  }
  return s;
}

/// Every rank of a distributed run reads the scene (or checkpoint) itself:
/// they must have read the same one, with the same options, before they
/// set anything up together (distributed::require_same).
void require_same_inputs(const Scene& scene, const RunOptions& opt, const Checkpoint* resume) {
  const auto& comm = distributed::Comm::world();
  if (comm.size() == 1) return;
  const char* why = "every rank must run the same scene with the same options: does the scene file differ between "
                    "nodes, was it rewritten while the job started, or do the ranks' command lines differ?";
  distributed::require_same(comm, "the resolved scene (after --set)", scene.text.empty() ? to_toml(scene) : scene.text,
                            why);
  distributed::require_same(comm, "the set of run options", run_inputs(opt, resume), why);
}

/// True when options.interrupt asks to stop; the ranks of a distributed run
/// agree (one of them got the signal: all stop at the same point).
bool interrupt_requested(const RunOptions& options) {
  if (!options.interrupt) return false;
  const auto& comm = distributed::Comm::world();
  const std::int64_t flag = options.interrupt->load() ? 1 : 0;
  return (comm.size() > 1 ? comm.max(flag) : flag) != 0;
}

} // namespace

/// The dimension-independent face of a simulation.
struct Simulation::Runner {
  virtual ~Runner() = default;
  Scene scene;
  RunSummary summary;
  bool finished = false;
  bool closed = false; ///< finish() has run: the result file is complete and closed
  virtual int dimension() const = 0;
  virtual double time() const = 0;
  virtual long steps() const = 0;
  virtual void step() = 0;
  virtual void write_frame() = 0;
  virtual void interrupt() = 0;
  virtual void finish() = 0;
};

/// A simulation in D dimensions: the engine, its exact solution (if any)
/// and the recorder of its result file.
template <int D> struct Simulation::DimRunner final : Simulation::Runner {
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  RunOptions options;
  /// A distributed restart: this rank's rows of the checkpoint, from build() to init().
  Checkpoint restart_rows;
  Engine<D> e;
  std::unique_ptr<ExactSolution<D>> exact;
  Recorder<D> rec;

  DimRunner(const Scene& s, const RunOptions& opt, const Checkpoint* resume)
      : options(opt), e(build(s, opt, resume, restart_rows)), exact(make_exact_solution<D>(s)),
        rec(init(s, resume), opt, e, exact.get(), resume) {
    const distributed::GlobalView<D> view(e);
    summary.mode = scene.simulation.mode;
    summary.integrator = scene.simulation.integrator;
    summary.basis = scene.basis.kind;
    summary.particles = view.particles();
    summary.nodes = view.nodes();
    summary.status = "running";
    if (resume) return;
    if (interrupt_requested(opt)) { // during the set-up: no initial frame, no checkpoint (nothing was run)
      stop_interrupted();
      return;
    }
    try { // an initial state that is not finite or cannot be written is a diagnosis too
      rec.sample_energy();
      rec.maybe_record(true);
    } catch (const InstabilityError& err) {
      stop_unstable(err);
    } catch (const OutputError& err) {
      stop_output_error(err);
    }
  }

  /// This rank's engine of the scene (the whole scene in a serial run); a
  /// distributed restart builds it from its rows of the checkpoint (`rows`).
  /// The run stops inside the seeding's loops when opt.interrupt is set
  /// (InterruptedError, before any file is created); in a distributed run
  /// the rank that got the signal tells the others (interrupt_peers), each
  /// leaves its loop, and the agreement after the loop stops them all.
  static Engine<D> build(const Scene& s, const RunOptions& opt, const Checkpoint* resume, Checkpoint& rows) {
    const auto& comm = distributed::Comm::world();
    std::optional<InterruptPolling> polling; // else the caller's (Python's signal handlers), if any
    if (opt.interrupt) polling.emplace(opt.interrupt, distributed::interrupt_peers());
    if (!resume || comm.size() == 1) return Engine<D>(distributed::rank_parts<D>(s, comm));
    return Engine<D>(distributed::restart_parts<D>(s, comm, *resume, rows));
  }

  /// Stores the scene and restores the checkpoint - or, for a new run,
  /// checks the step count on the seeded particles' first step - before
  /// the recorder is built.
  const Scene& init(const Scene& s, const Checkpoint* resume) {
    scene = s;
    if (resume) e.restore_state(distributed::local_checkpoint(e, *resume, std::exchange(restart_rows, {})));
    else check_first_step(scene, e.stable_dt(), e.wave_speed());
    return scene;
  }

  int dimension() const override { return D; }
  double time() const override { return e.time(); }
  long steps() const override { return e.steps(); }

  void step() override {
    const double t_end = scene.simulation.t_end;
    stopping_on_failure([&] {
      e.step();
      rec.sample_energy();
      const bool last = e.time() >= t_end * (1.0 - time_slack);
      rec.maybe_record(last);
      rec.maybe_checkpoint(seconds_since(start), last);
      finished = last;
    });
    if (options.progress) options.progress(e.time(), t_end, e.steps());
  }

  /// Runs `f` (a step, a frame); an instability, an output error or memory
  /// running out ends the run with its status and is rethrown. In a
  /// distributed run an allocation that fails on one rank ends every rank
  /// with the same DeferredOutOfMemory: inside a stage of a step the rank
  /// defers it to the next reduction; anywhere else (a halo or migration
  /// buffer, a frame's rows, a sum) it tells the others at once
  /// (stop_every_rank), which leave the operation they wait in.
  template <class F> void stopping_on_failure(F&& f) {
    try {
      try {
        f();
      } catch (const std::bad_alloc&) {
        if (distributed::Comm::world().size() == 1) throw;
        const std::string what = "rank " + std::to_string(distributed::Comm::world().rank()) +
                                 " could not get the memory it needed";
        throw DeferredOutOfMemory(distributed::stop_every_rank(diagnosis(what, e.steps(), e.time())));
      }
    } catch (const InstabilityError& err) {
      stop_unstable(err);
      throw;
    } catch (const OutputError& err) {
      stop_output_error(err);
      throw;
    } catch (const DeferredOutOfMemory& err) {
      stop(kOutOfMemoryStatus + (": " + diagnosis(err.what(), e.steps(), e.time()) + " (" + memory_note(scene) + ")"),
           kOutputErrorExit);
      throw;
    } catch (const std::bad_alloc&) {
      if (distributed::Comm::world().size() == 1)
        stop(kOutOfMemoryStatus + (": " + diagnosis("the run needed more memory than this process could get (" +
                                               memory_note(scene) + ")", e.steps(), e.time())),
             kOutputErrorExit);
      throw;
    }
  }

  /// Ends the run on an instability: status "unstable: step N, t = T: ...", exit code 1.
  void stop_unstable(const InstabilityError& err) {
    rec.sample_energy(); // a runaway stop has the energy that tripped the monitor
    stop("unstable: " + diagnosis(err.what(), e.steps(), e.time()), 1);
  }

  /// Ends the run on a result or checkpoint that could not be written: status
  /// "output error: step N, t = T: ...", exit code kOutputErrorExit; the
  /// result file keeps what was written before.
  void stop_output_error(const OutputError& err) {
    stop("output error: " + diagnosis(err.what(), e.steps(), e.time()), kOutputErrorExit);
  }

  void stop(const std::string& status, int exit_code) {
    summary.status = status;
    summary.exit_code = exit_code;
    rec.set_status(summary.status);
    finished = true;
  }

  void write_frame() override {
    stopping_on_failure([&] { rec.maybe_record(true); });
  }

  void interrupt() override {
    try {
      rec.checkpoint(seconds_since(start));
    } catch (const OutputError& err) {
      stop_output_error(err);
      return;
    } catch (const InstabilityError& err) { // reported by the writer thread
      stop_unstable(err);
      return;
    }
    stop_interrupted();
  }

  /// Ends the run as interrupted: status "interrupted", kInterruptedExit.
  void stop_interrupted() {
    stop("interrupted", kInterruptedExit);
    summary.interrupted = true;
  }

  void finish() override {
    try { // the last output time may still be in flight on the writer thread
      rec.wait_for_output();
    } catch (const InstabilityError& err) {
      if (summary.exit_code == 0) stop_unstable(err);
    } catch (const OutputError& err) {
      if (summary.exit_code == 0) stop_output_error(err);
    }
    if (summary.exit_code == 0 && distributed::Comm::world().size() == 1) {
      try { // every step ends checked; a state changed by hand since (a writable view) is checked here
        e.check_particles_inside();
      } catch (const InstabilityError& err) {
        stop_unstable(err);
      }
    }
    if (summary.exit_code == 0) summary.status = "ok";
    summary.steps = e.steps();
    summary.time = e.time();
    summary.timers = e.timers();
    summary.wall_seconds = rec.wall_before() + seconds_since(start);
    const distributed::GlobalView<D> view(e); // the slowest rank's times (the same on every rank)
    summary.wall_seconds = view.max(summary.wall_seconds);
    for (double& t : summary.timers.seconds) t = view.max(t);
    rec.finish(summary);
    finished = true;
    closed = true;
  }
};

void EnergySummary::sample(double energy, double work, double balance_error) {
  if (!std::isfinite(energy) || !std::isfinite(work) || !std::isfinite(balance_error)) return;
  max_energy = std::max(max_energy, energy);
  max_work = std::max(max_work, std::abs(work));
  max_balance_error = std::max(max_balance_error, std::abs(balance_error));
}

double EnergySummary::reference() const { return std::max(initial + max_work, energy_reference_floor); }
double EnergySummary::max_energy_ratio() const { return max_energy / reference(); }
double EnergySummary::energy_drift() const { return max_balance_error / reference(); }

std::unique_ptr<Simulation::Runner> Simulation::make(const Scene& scene, const RunOptions& options,
                                                     const Checkpoint* resume) {
  const int dim = scene.simulation.dimension;
  require_same_inputs(scene, options, resume);
  // A Scene built in code meets the reader's checks too; the ranks agree
  // (the memory a process may use can differ from node to node).
  if (dim >= 1 && dim <= 3)
    distributed::agree_on(distributed::Comm::world(),
                          [&] { check_before_allocating(scene, dim, distributed::Comm::world().size()); });
  try {
    switch (scene.simulation.dimension) {
    case 1: return std::make_unique<DimRunner<1>>(scene, options, resume);
    case 2: return std::make_unique<DimRunner<2>>(scene, options, resume);
    case 3: return std::make_unique<DimRunner<3>>(scene, options, resume);
    default: break;
    }
  } catch (const std::bad_alloc&) { // the estimate let it start, the machine could not give it
    throw InputError(shortened(scene.file) + ": out of memory while setting up the run (" + memory_note(scene) + ")");
  }
  input_error(scene.locate("simulation.dimension"),
              "dimension must be 1, 2 or 3, got " + std::to_string(scene.simulation.dimension));
}

Simulation::Simulation(const Scene& scene, const RunOptions& options) : run_(make(scene, options, nullptr)) {}
Simulation::Simulation(const Checkpoint& checkpoint, const RunOptions& options)
    : run_(make(checkpoint_scene(checkpoint), options, &checkpoint)) {}
Simulation::Simulation(Simulation&&) noexcept = default;
Simulation& Simulation::operator=(Simulation&&) noexcept = default;
Simulation::~Simulation() {
  // A run dropped without finish() (an exception, a forgotten call) gets a
  // final status, as finish() after interrupt() gives it, instead of keeping
  // "running" for ever. Not in a distributed run: the other ranks may not be here.
  if (!run_ || run_->closed || distributed::Comm::world().size() > 1) return;
  try {
    if (!finished()) run_->interrupt();
    run_->finish();
  } catch (const std::exception&) { // nothing can be reported from a destructor; the status is what it could be
  }
}

const Scene& Simulation::scene() const { return run_->scene; }
int Simulation::dimension() const { return run_->dimension(); }
double Simulation::time() const { return run_->time(); }
double Simulation::t_end() const { return run_->scene.simulation.t_end; }
long Simulation::steps() const { return run_->steps(); }
bool Simulation::finished() const { return run_->finished || time() >= t_end() * (1.0 - time_slack); }
bool Simulation::unstable() const { return run_->summary.exit_code == 1; }
const std::string& Simulation::status() const { return run_->summary.status; }

void Simulation::step() {
  if (finished()) throw std::logic_error("Simulation::step: the run is finished (" + status() + ")");
  run_->step();
}

void Simulation::advance_to(double t) {
  while (!finished() && time() < t * (1.0 - time_slack)) step();
}

void Simulation::require_open(const char* what) const {
  if (run_->closed)
    throw std::logic_error(std::string("Simulation::") + what +
                           ": the run is finished (finish() was called)");
}

void Simulation::write_frame() {
  require_open("write_frame");
  run_->write_frame();
}

void Simulation::interrupt() {
  require_open("interrupt");
  if (finished()) throw std::logic_error("Simulation::interrupt: the run is finished (" + status() + ")");
  run_->interrupt();
}

RunSummary Simulation::finish() {
  require_open("finish");
  run_->finish();
  return run_->summary;
}

template <int D> Engine<D>& Simulation::engine() {
  auto* r = dynamic_cast<DimRunner<D>*>(run_.get());
  require<std::invalid_argument>(r != nullptr, "Simulation::engine<", D, ">: the run is ", dimension(), "D");
  return r->e;
}
template <int D> const Engine<D>& Simulation::engine() const { return const_cast<Simulation*>(this)->engine<D>(); }

template Engine<1>& Simulation::engine<1>();
template Engine<2>& Simulation::engine<2>();
template Engine<3>& Simulation::engine<3>();
template const Engine<1>& Simulation::engine<1>() const;
template const Engine<2>& Simulation::engine<2>() const;
template const Engine<3>& Simulation::engine<3>() const;

namespace {
/// Steps a simulation to t_end; an instability ends it with its status, a
/// request through options.interrupt (checked before each step) with status
/// "interrupted" and a last checkpoint.
RunSummary run_to_end(Simulation& sim, const RunOptions& options) {
  try {
    while (!sim.finished()) {
      if (interrupt_requested(options)) {
        sim.interrupt();
        break;
      }
      sim.step();
    }
  } catch (const InstabilityError&) { // the status is in the summary
  } catch (const OutputError&) {
  } catch (const DeferredOutOfMemory&) { // every rank of a distributed run, with the same status
  } catch (const std::bad_alloc&) {
    if (!sim.finished()) throw; // a distributed run: no status could be agreed on
  }
  return sim.finish();
}

/// The summary of a run that did not start at step `step`, time `t` (0 for
/// a new run, the checkpoint's for a restart), with `status` and `exit_code`.
RunSummary not_started(const Scene& scene, long step, double t, const std::string& status, int exit_code) {
  RunSummary s;
  s.mode = scene.simulation.mode;
  s.integrator = scene.simulation.integrator;
  s.basis = scene.basis.kind;
  s.steps = step;
  s.time = t;
  s.status = status;
  s.exit_code = exit_code;
  s.interrupted = exit_code == kInterruptedExit;
  return s;
}

/// Sets up a simulation (make(sim)) that starts at step `step`, time `t`
/// and runs it to the end - unless options.interrupt asked to stop before
/// the set-up (status "interrupted", no result file) or the result file
/// could not even be created (no room for its first bytes: "output error:
/// ...", kOutputErrorExit). scene_of() gives the scene for the summary of
/// a run that did not start.
template <class SceneOf, class Make>
RunSummary set_up_and_run(long step, double t, const RunOptions& options, SceneOf&& scene_of, Make&& make) {
  if (interrupt_requested(options)) return not_started(scene_of(), step, t, "interrupted", kInterruptedExit);
  std::optional<Simulation> sim;
  try {
    make(sim);
  } catch (const OutputError& err) {
    return not_started(scene_of(), step, t, "output error: " + diagnosis(err.what(), step, t), kOutputErrorExit);
  } catch (const InterruptedError&) { // inside the set-up's loops (DimRunner::build): nothing was written
    return not_started(scene_of(), step, t, "interrupted", kInterruptedExit);
  }
  return run_to_end(*sim, options);
}
} // namespace

RunSummary run_scene(const Scene& scene, const RunOptions& options) {
  return set_up_and_run(
      0, 0.0, options, [&] { return scene; }, [&](std::optional<Simulation>& sim) { sim.emplace(scene, options); });
}

RunSummary restart_run(const Checkpoint& checkpoint, const RunOptions& options) {
  const StateGroup& g = checkpoint.group("engine");
  return set_up_and_run(
      static_cast<long>(g.integer("step")), g.real("t"), options, [&] { return checkpoint_scene(checkpoint); },
      [&](std::optional<Simulation>& sim) { sim.emplace(checkpoint, options); });
}

std::string summary_line(const RunSummary& s) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s %s %s: %ld steps, t = %.6g s, %.3f s wall, %.3g particle-steps/s",
                s.mode.c_str(), s.integrator.c_str(), s.basis.c_str(), s.steps, s.time, s.wall_seconds,
                s.particle_steps_per_second());
  const bool memory = s.status.rfind(kOutOfMemoryStatus, 0) == 0;
  const char* head = s.interrupted                     ? "INTERRUPTED: "
                     : memory                          ? "OUT OF MEMORY: "
                     : s.exit_code == kOutputErrorExit ? "OUTPUT FAILED: "
                     : s.exit_code != 0                ? "UNSTABLE: "
                                                       : "ok: ";
  std::string line = head + std::string(buf);
  for (const auto& [name, value] : s.errors) {
    std::snprintf(buf, sizeof buf, ", %s = %.4g", name.c_str(), value);
    line += buf;
  }
  std::snprintf(buf, sizeof buf, ", max_energy_ratio = %.4g, energy_drift = %.3g", s.energy.max_energy_ratio(),
                s.energy.energy_drift());
  line += buf;
  if (s.impact != 0.0) {
    std::snprintf(buf, sizeof buf, ", impact = %.3g J", s.impact);
    line += buf;
  }
  for (const auto& [name, value] : s.diagnostics)
    if (value != 0.0) {
      std::snprintf(buf, sizeof buf, ", %s = %.0f", name.c_str(), value);
      line += buf;
    }
  return line;
}

void check_output_names(const Scene& scene, const std::string& out_file) {
  if (out_file.empty() && scene.output.file.empty()) return;
  RunOptions opt;
  opt.out_file = out_file;
  checked_output_files(output_request(scene, "", opt, nullptr));
}

} // namespace otmpm
