#!/usr/bin/env bash
# The main job: the Dyka bar (LME gamma_lme = 4, NPC) run on a fixed grid (MPM)
# and with advected nodes (UL/OTM-style), side by side: errors against the
# exact solution, wall time, steps and particle-steps per second.
# It runs the pair at three mesh sizes, h = L/13, L/40 and L/133, so that the
# error can be read against the run time of each mode.
# Usage: bash scripts/main-job.sh [extra otmpm pair options, e.g. --set basis.gamma_lme=3]
# The build is the one scripts/test.sh makes (same folder, same options), so
# that either command builds only what the other has not.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/install-deps.sh"
build=${OTMPM_BUILD_DIR:-$root/build}
echo "== building the otmpm command in $build (a first build compiles the library: minutes; then only what changed)"
bash "$root/scripts/configure.sh" "$build" >/dev/null
cmake --build "$build" -j"$(nproc 2>/dev/null || echo 2)" --target otmpm_cli 2>&1 |
  { grep --line-buffered -E '^\[ *[0-9]+%\] (Building|Linking)|error|warning' || true; }
mkdir -p "$root/out"
cd "$root/out"
cat <<'TEXT'
The Dyka bar: a steel bar of length L = 0.1333 m, free at x = 0, fixed at x = L;
its left quarter starts at -5 m/s. SI units. Errors against the exact solution:
  history_error_A [m/s]        RMS over the output times of the velocity error of point A,
                               the bar's free end (its leftmost particle)
  rms_velocity_error [m/s], rms_displacement_error [m], rms_stress_error [Pa]
                               RMS over the particles at t_end = 1e-4 s
Result files: out/dyka_nN_mpm.h5 and out/dyka_nN_ul.h5.

TEXT
status=0
for n in 13 40 133; do
  echo "== Dyka bar, h = L/$n, LME gamma_lme = 4, NPC: MPM (fixed grid) vs UL (advected nodes)"
  OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} "$build/bin/otmpm" pair "$root/examples/dyka/dyka_n$n.toml" --quiet "$@" || status=$?
  echo
done
exit $status
