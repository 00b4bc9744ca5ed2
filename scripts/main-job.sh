#!/usr/bin/env bash
# The main job: the Dyka bar (LME gamma_lme = 4, NPC) run on a fixed grid (MPM)
# and with advected nodes (UL/OTM-style), side by side: errors against the
# exact solution, wall time, steps and particle-steps per second.
# It runs the pair at three mesh sizes, h = L/13, L/40 and L/133, so that the
# error can be read against the run time of each mode.
# Usage: bash scripts/main-job.sh [extra otmpm pair options, e.g. --set basis.gamma_lme=3]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/install-deps.sh"
build=${OTMPM_BUILD_DIR:-$root/build}
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc 2>/dev/null || echo 2)" --target otmpm_cli >/dev/null
mkdir -p "$root/out"
cd "$root/out"
status=0
for n in 13 40 133; do
  echo "== Dyka bar, h = L/$n, LME gamma_lme = 4, NPC: MPM (fixed grid) vs UL (advected nodes)"
  OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} "$build/bin/otmpm" pair "$root/examples/dyka/dyka_n$n.toml" --quiet "$@" || status=$?
  echo
done
exit $status
