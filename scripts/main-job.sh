#!/usr/bin/env bash
# The main job: the Dyka bar (LME gamma_lme = 4, NPC) run on a fixed grid (MPM)
# and with advected nodes (UL/OTM-style), side by side: errors against the
# exact solution, wall time, steps and particle-steps per second.
# Usage: bash scripts/main-job.sh [extra otmpm pair options, e.g. --set grid.cells=[135]]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/install-deps.sh"
build=${OTMPM_BUILD_DIR:-$root/build}
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc 2>/dev/null || echo 2)" --target otmpm_cli >/dev/null
mkdir -p "$root/out"
cd "$root/out"
"$build/bin/otmpm" pair "$root/examples/dyka.toml" --quiet "$@"
