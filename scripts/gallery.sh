#!/usr/bin/env bash
# Draws docs/gallery.md's pictures: every example scene (examples/*.toml) run
# to its own t_end, then one frame drawn with `otmpm render`.
# Usage: bash scripts/gallery.sh [BUILD_DIR]        (default: build; after scripts/test.sh)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
otmpm=${1:-$root/build}/bin/otmpm
out=$root/docs/figures/gallery
work=$(mktemp -d /tmp/otmpm-gallery.XXXXXX)
trap 'rm -rf "$work"' EXIT
mkdir -p "$out"
# scene | render options
while IFS='|' read -r scene options; do
  [ -z "$scene" ] && continue
  echo "== $scene"
  "$otmpm" run "$root/examples/$scene.toml" --out "$work/$scene.h5" --quiet
  # shellcheck disable=SC2086
  "$otmpm" render "$work/$scene.h5" $options --out "$out/$scene.png"
done <<'LIST'
andersen_block|--field stress --component yy
dyka|--field v
dyka_2d|--field stress --component xx
dyka_3d|--field v --view xz
fixed_bar|--field displacement --frame 5
mms_plate|--field displacement --component x
plate_impact|--field v
traction_bar|--field stress
LIST
