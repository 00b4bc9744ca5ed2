#!/usr/bin/env bash
# The Dyka bar built in code (examples/dyka_in_code.cpp) gives the RMS
# velocity error of the same run from its scene file (examples/dyka.toml,
# h = L/40), in mpm and ul mode: usage check_dyka_in_code.sh EXAMPLE OTMPM SOURCE_DIR
set -euo pipefail
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive} # the examples do not set it as otmpm does (busy machines)
example=$1 otmpm=$2 src=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for mode in mpm ul; do
  code=$("$example" 40 npc "$mode" | grep -o 'rms_velocity_error = [^ ]*')
  scene=$("$otmpm" run "$src/examples/dyka.toml" --quiet --out "$tmp/$mode.h5" --set simulation.mode=$mode |
          grep -o 'rms_velocity_error = [^,]*')
  echo "$mode: in code: $code; from the scene: $scene"
  [ "$code" = "$scene" ] || { echo "MISMATCH in $mode mode"; exit 1; }
done
