#pragma once
/// \file timers.hpp
/// Wall time spent in each phase of a step (docs/theory.md sect. 12).
#include <array>
#include <chrono>
#include <string_view>

namespace otmpm {

/// The phases every run reports. A constitutive update fused into a
/// transfer pass counts in that pass: fe/unified in to_particles, npc in
/// to_nodes (ToNodes::stress_from); `constitutive` times the separate
/// update_stress passes (musl, otm, explicit_alpha) and stays 0 in the
/// other runs (the run summary then leaves it out).
enum class Phase { basis, to_nodes, nodal_update, to_particles, constitutive, output, count };

constexpr std::array<std::string_view, 6> phase_names{"basis", "to_nodes", "nodal_update",
                                                      "to_particles", "constitutive", "output"};

/// Accumulated seconds per phase.
struct PhaseTimers {
  std::array<double, static_cast<int>(Phase::count)> seconds{};
  bool open = false; ///< a ScopedPhase is timing (the stepping thread's)
  double& operator[](Phase p) { return seconds[static_cast<int>(p)]; }
  double operator[](Phase p) const { return seconds[static_cast<int>(p)]; }
};

/// Adds the lifetime of the guard to one phase. A guard made while another
/// is open adds nothing: a stage that another stage calls counts in the
/// caller's phase, and no time counts twice.
class ScopedPhase {
public:
  ScopedPhase(PhaseTimers& timers, Phase phase)
      : timers_(timers), slot_(timers[phase]), outer_(!timers.open),
        start_(std::chrono::steady_clock::now()) {
    timers_.open = true;
  }
  ~ScopedPhase() {
    if (!outer_) return;
    slot_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    timers_.open = false;
  }
  ScopedPhase(const ScopedPhase&) = delete;
  ScopedPhase& operator=(const ScopedPhase&) = delete;

private:
  PhaseTimers& timers_;
  double& slot_;
  bool outer_;
  std::chrono::steady_clock::time_point start_;
};

} // namespace otmpm
