#include "otmpm/engine/run.hpp"

#include "otmpm/engine/engine.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/io/results.hpp"
#include "otmpm/reference/exact.hpp"
#include "otmpm/scene/resources.hpp"
#include "otmpm/scene/validate.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <array>
#include <filesystem>
#include <memory>
#include <optional>

namespace otmpm {

namespace {

/// Relative slack when comparing the simulated time with output times.
constexpr double time_slack = 1e-9;
/// Floor of EnergySummary::reference(), so a body at rest with no load has ratio 0, not 0/0.
constexpr double energy_reference_floor = 1e-300;

/// What the run's output files are and where their names came from (prepare_outputs).
OutputRequest output_request(const Scene& scene, const RunOptions& opt, const Checkpoint* resume) {
  OutputRequest r;
  const std::string previous = resume ? resume->group("recorder").string("result_file") : "";
  if (!opt.out_file.empty()) {
    r.result = opt.out_file;
    r.result_origin = "RunOptions::out_file, otmpm run --out";
  } else if (resume) {
    r.result = previous;
    r.result_origin = "the interrupted run's result file, from " + resume->file;
  } else {
    r.result = scene.output.file;
    r.result_origin = scene.locate("output.file").describe();
  }
  if (scene.output.checkpoint_every > 0) {
    r.checkpoint = checkpoint_path(scene, r.result);
    r.checkpoint_origin = scene.output.checkpoint_file.empty() ? "the default beside the result file"
                                                               : scene.locate("output.checkpoint_file").describe();
  }
  r.vtk_format = vtk_format(scene.output);
  r.scene_text = scene.text;
  r.force = opt.force;
  if (resume) {
    r.continued_run = resume->run_id;
    r.previous_result = previous;
    r.previous_frames = static_cast<int>(resume->group("recorder").integer("frames"));
  }
  return r;
}

/// The particle a probe follows: the leftmost/rightmost by initial position
/// (ties: lowest index) or the one nearest to a point.
template <int D> int probe_particle(const Particles<D>& P, const ProbeSection& probe) {
  int best = 0;
  Vec<D> at;
  for (int k = 0; k < D; ++k) at[k] = probe.at[k];
  for (int p = 1; p < P.size(); ++p) {
    if (probe.particle == "leftmost" ? P.X[p][0] < P.X[best][0]
        : probe.particle == "rightmost" ? P.X[p][0] > P.X[best][0]
                                        : (P.X[p] - at).norm() < (P.X[best] - at).norm())
      best = p;
  }
  return best;
}

/// Copies DxD matrices into row-major rows of D*D doubles.
template <int D> std::vector<double> row_major(const AlignedVector<Mat<D>>& A) {
  std::vector<double> out(A.size() * D * D);
  for (std::size_t p = 0; p < A.size(); ++p)
    for (int i = 0; i < D; ++i)
      for (int j = 0; j < D; ++j) out[p * D * D + i * D + j] = A[p](i, j);
  return out;
}

// A member added to EnergySummary must be saved and restored here.
static_assert(sizeof(EnergySummary) == 4 * sizeof(double), "EnergySummary changed: update the checkpoint");

/// The members of an EnergySummary (const or not) by checkpoint name.
template <class S> auto summary_fields(S& s) {
  return std::array{std::pair{"energy_initial", &s.initial}, std::pair{"max_energy", &s.max_energy},
                    std::pair{"max_work", &s.max_work}, std::pair{"max_balance_error", &s.max_balance_error}};
}

template <int D> class Recorder {
public:
  /// `resume`: the checkpoint a restarted run continues (null for a new run).
  Recorder(const Scene& scene, const RunOptions& opt, Engine<D>& e, const ExactSolution<D>* exact,
           const Checkpoint* resume)
      : scene_(scene), e_(e), exact_(exact) {
    for (const ProbeSection& pr : scene.output.probes) probes_.push_back({pr.name, probe_particle(e.particles(), pr), 0.0, 0});
    if (resume) restore_accumulators(resume->group("recorder"));
    if (!opt.write_results) return;
    outputs_ = prepare_outputs(output_request(scene, opt, resume));
    path_ = outputs_.files.result;
    checkpoint_path_ = outputs_.files.checkpoint;
    writer_ = std::make_unique<ResultWriter>(path_, scene.text, D,
                                             ResultOptions{outputs_.run_id, outputs_.files.vtk_extension});
    if (outputs_.previous) continue_results(*outputs_.previous, resume->group("recorder"));
  }

  /// Writes a checkpoint after every output.checkpoint_every steps (not after
  /// the last step); `wall_seconds` is the wall time of this process so far.
  void maybe_checkpoint(double wall_seconds, bool last) {
    const long every = scene_.output.checkpoint_every;
    if (!writer_ || every <= 0 || last || e_.steps() % every != 0) return;
    ScopedPhase timer(e_.timers(), Phase::output);
    Checkpoint ck;
    ck.scene = scene_.text;
    ck.run_id = writer_->run_id();
    e_.save_state(ck);
    StateGroup& g = ck.group("recorder");
    g.reals["next_output_time"] = next_;
    g.reals["wall_seconds"] = wall_before_ + wall_seconds;
    g.integers["frames"] = writer_->frames();
    g.strings["result_file"] = std::filesystem::absolute(path_).string();
    g.put_reals(summary_fields(energy_));
    StateArray<double>& sum_sq = g.real_arrays["probe_sum_sq"];
    StateArray<std::int64_t>& samples = g.integer_arrays["probe_samples"];
    for (const Probe& pr : probes_) {
      sum_sq.values.push_back(pr.sum_sq);
      samples.values.push_back(pr.samples);
    }
    write_checkpoint(checkpoint_path_, ck);
  }

  /// Wall time of the interrupted run up to its checkpoint (0 for a new run).
  double wall_before() const { return wall_before_; }

  /// Adds the engine's current energy balance to the run's EnergySummary (every step).
  void sample_energy() {
    const EnergyBalance& E = e_.energy();
    energy_.initial = E.initial;
    energy_.sample(E.total(), E.work(), E.balance_error());
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
    for (const Probe& pr : probes_)
      if (exact_ && pr.samples > 0) s.errors["history_error_" + pr.name] = std::sqrt(pr.sum_sq / pr.samples);
    if (exact_ && s.exit_code == 0) final_errors(s);
    if (!writer_) return;
    s.out_file = path_;
    if (!writer_->writable()) return; // an HDF5 write failed: the file is left as it is
    try {
      write_summary(s);
    } catch (const OutputError& err) {
      s.status = std::string("output error: ") + err.what();
      s.exit_code = kExitOutputError;
    }
  }

  /// Marks the file with a diagnosis (the file stays valid). An output error
  /// here changes nothing more: the diagnosis is in the summary anyway.
  void set_status(const std::string& status) {
    if (!writer_ || !writer_->writable()) return;
    try {
      writer_->set_attribute("status", status);
      writer_->publish();
    } catch (const OutputError&) {
    }
  }

private:
  struct Probe {
    std::string name;
    int particle;
    double sum_sq;
    int samples;
  };

  /// The final status and summary attributes.
  void write_summary(const RunSummary& s) {
    writer_->set_attribute("status", s.status);
    writer_->set_attribute("steps", static_cast<long long>(s.steps));
    writer_->set_attribute("t_end", s.time);
    writer_->set_attribute("wall_seconds", s.wall_seconds);
    writer_->set_attribute("particles", static_cast<long long>(s.particles));
    writer_->set_attribute("nodes", static_cast<long long>(s.nodes));
    for (const auto& [name, value] : s.errors) writer_->set_attribute(name, value);
    writer_->set_attribute("max_energy_ratio", s.energy.max_energy_ratio());
    writer_->set_attribute("energy_drift", s.energy.energy_drift());
    for (std::size_t i = 0; i < phase_names.size(); ++i)
      writer_->set_attribute("seconds_" + std::string(phase_names[i]), s.timers.seconds[i]);
    writer_->publish();
  }

  void restore_accumulators(const StateGroup& g) {
    next_ = g.real("next_output_time");
    wall_before_ = g.real("wall_seconds");
    g.get_reals(summary_fields(energy_));
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
    h.push_back({"energy", false, {"kinetic", "strain", "external_work", "reaction_work"}});
    return h;
  }

  /// Copies the frames and history samples written before the checkpoint.
  void continue_results(const PreviousResults& previous, const StateGroup& g) {
    copy_results(previous.path, *writer_, static_cast<int>(g.integer("frames")), histories(), scene_.output.fields);
    release_previous_results(previous);
  }

  void record(double t) {
    const Particles<D>& P = e_.particles();
    for (Probe& pr : probes_) {
      const int p = pr.particle;
      if (exact_) {
        pr.sum_sq += (P.v[p] - exact_->velocity(P.X[p], t)).squaredNorm();
        ++pr.samples;
      }
      if (writer_) {
        std::vector<double> x(P.x[p].data(), P.x[p].data() + D), v(P.v[p].data(), P.v[p].data() + D);
        std::vector<double> sig(P.sigma[p].data(), P.sigma[p].data() + D * D);
        writer_->append_probe(pr.name, t, {{"x", x}, {"v", v}, {"stress", sig}});
      }
    }
    if (writer_) {
      const EnergyBalance& E = e_.energy();
      writer_->append_series("energy", t,
                             {{"kinetic", E.kinetic},
                              {"strain", E.strain},
                              {"external_work", E.external_work},
                              {"reaction_work", E.reaction_work}});
      write_frame(t);
    }
  }

  void write_frame(double t) {
    const Particles<D>& P = e_.particles();
    const int n = P.size();
    std::vector<FieldView> fields;
    std::vector<std::vector<double>> buffers;
    buffers.reserve(8);
    for (const std::string& f : scene_.output.fields) {
      if (f == "x") fields.push_back({"x", n, D, P.x.front().data()});
      else if (f == "v") fields.push_back({"v", n, D, P.v.front().data()});
      else if (f == "a") fields.push_back({"a", n, D, P.a.front().data()});
      else if (f == "stress") fields.push_back({"stress", n, D * D, (buffers.push_back(row_major<D>(P.sigma)), buffers.back().data())});
      else if (f == "strain") fields.push_back({"strain", n, D * D, (buffers.push_back(row_major<D>(P.eps)), buffers.back().data())});
      else if (f == "F") fields.push_back({"F", n, D * D, (buffers.push_back(row_major<D>(P.F)), buffers.back().data())});
      else if (f == "density") fields.push_back({"density", n, 1, P.rho.data()});
      else if (f == "volume") fields.push_back({"volume", n, 1, P.V.data()});
      else if (f == "mass") fields.push_back({"mass", n, 1, P.m.data()});
      else if (f == "displacement") {
        std::vector<double> u(static_cast<std::size_t>(n) * D);
        for (int p = 0; p < n; ++p)
          for (int k = 0; k < D; ++k) u[p * D + k] = P.x[p][k] - P.X[p][k];
        buffers.push_back(std::move(u));
        fields.push_back({"displacement", n, D, buffers.back().data()});
      }
    }
    writer_->write_frame(t, fields);
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
    s.errors["rms_velocity_error"] = rms_error(ev);
    s.errors["rms_displacement_error"] = rms_error(eu);
    s.errors["rms_stress_error"] = rms_error(es);
  }

  const Scene& scene_;
  Engine<D>& e_;
  const ExactSolution<D>* exact_;
  std::vector<Probe> probes_;
  PreparedOutputs outputs_; ///< paths and otmpm's locks, held for the whole run
  std::string path_;
  std::unique_ptr<ResultWriter> writer_;
  double next_ = 0.0;
  EnergySummary energy_;
  std::string checkpoint_path_;
  double wall_before_ = 0.0;
};

/// A diagnosis that names step and time: `what` as it is when it does (the
/// engine's start with "step N, t = T"), else prefixed with them.
std::string diagnosis(const std::string& what, long step, double t) {
  if (what.rfind("step ", 0) == 0) return what;
  return "step " + std::to_string(step) + ", t = " + format_number(t) + ": " + what;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// Runs the scene from t = 0, or from the checkpoint `resume` when not null.
template <int D> RunSummary run_dim(const Scene& scene, const RunOptions& opt, const Checkpoint* resume) {
  const auto start = std::chrono::steady_clock::now();
  RunSummary s;
  Engine<D> e(scene);
  const auto exact = make_exact_solution<D>(scene);
  if (resume) e.restore_state(*resume);
  s.mode = scene.simulation.mode;
  s.integrator = scene.simulation.integrator;
  s.basis = scene.basis.kind;
  s.particles = e.particles().size();
  s.nodes = e.basis().nodes().size();
  std::optional<Recorder<D>> recorder;
  try {
    recorder.emplace(scene, opt, e, exact.get(), resume);
  } catch (const OutputError& err) { // no room for the result file's first bytes
    s.status = "output error: " + diagnosis(err.what(), e.steps(), e.time());
    s.exit_code = kExitOutputError;
    return s;
  }
  Recorder<D>& rec = *recorder;
  const double t_end = scene.simulation.t_end;
  try {
    if (!resume) {
      rec.sample_energy();
      rec.maybe_record(true); // inside: an initial state that cannot be written is a diagnosis too
    }
    while (e.time() < t_end * (1.0 - time_slack)) {
      e.step();
      rec.sample_energy();
      const bool last = e.time() >= t_end * (1.0 - time_slack);
      rec.maybe_record(last);
      rec.maybe_checkpoint(seconds_since(start), last);
      if (opt.progress) opt.progress(e.time(), t_end, e.steps());
    }
  } catch (const InstabilityError& err) {
    rec.sample_energy(); // a runaway stop has the energy that tripped the monitor
    s.status = "unstable: " + diagnosis(err.what(), e.steps(), e.time());
    s.exit_code = 1;
    rec.set_status(s.status);
  } catch (const OutputError& err) {
    s.status = "output error: " + diagnosis(err.what(), e.steps(), e.time());
    s.exit_code = kExitOutputError;
    rec.set_status(s.status);
  }
  s.steps = e.steps();
  s.time = e.time();
  s.timers = e.timers();
  s.wall_seconds = rec.wall_before() + seconds_since(start);
  rec.finish(s);
  return s;
}

RunSummary run_any(const Scene& scene, const RunOptions& options, const Checkpoint* resume) {
  const int dim = scene.simulation.dimension;
  if (dim >= 1 && dim <= 3) {
    validate_scene(scene, dim); // a Scene built in code: every check of the reader, before the estimates
    check_resources(scene);     // before anything is allocated
  }
  switch (scene.simulation.dimension) {
  case 1: return run_dim<1>(scene, options, resume);
  case 2: return run_dim<2>(scene, options, resume);
  case 3: return run_dim<3>(scene, options, resume);
  default:
    input_error(scene.locate("simulation.dimension"),
                "dimension must be 1, 2 or 3, got " + std::to_string(scene.simulation.dimension));
  }
}

} // namespace

void EnergySummary::sample(double energy, double work, double balance_error) {
  if (!std::isfinite(energy) || !std::isfinite(work) || !std::isfinite(balance_error)) return;
  max_energy = std::max(max_energy, energy);
  max_work = std::max(max_work, std::abs(work));
  max_balance_error = std::max(max_balance_error, std::abs(balance_error));
}

double EnergySummary::reference() const { return std::max(initial + max_work, energy_reference_floor); }
double EnergySummary::max_energy_ratio() const { return max_energy / reference(); }
double EnergySummary::energy_drift() const { return max_balance_error / reference(); }

RunSummary run_scene(const Scene& scene, const RunOptions& options) { return run_any(scene, options, nullptr); }

RunSummary restart_run(const Checkpoint& checkpoint, const RunOptions& options) {
  const Scene scene = checkpoint_scene(checkpoint);
  return run_any(scene, options, &checkpoint);
}

std::string summary_line(const RunSummary& s) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s %s %s: %ld steps, t = %.6g s, %.3f s wall, %.3g particle-steps/s",
                s.mode.c_str(), s.integrator.c_str(), s.basis.c_str(), s.steps, s.time, s.wall_seconds,
                s.particle_steps_per_second());
  const char* prefix = s.exit_code == 0 ? "ok: " : s.exit_code == kExitOutputError ? "OUTPUT FAILED: " : "UNSTABLE: ";
  std::string line = prefix + std::string(buf);
  for (const auto& [name, value] : s.errors) {
    std::snprintf(buf, sizeof buf, ", %s = %.4g", name.c_str(), value);
    line += buf;
  }
  std::snprintf(buf, sizeof buf, ", max_energy_ratio = %.4g, energy_drift = %.3g", s.energy.max_energy_ratio(),
                s.energy.energy_drift());
  return line + buf;
}

} // namespace otmpm
