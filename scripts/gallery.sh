#!/usr/bin/env bash
# The gallery (docs/gallery.md): every example scene (examples/*.toml and
# examples/geometry/*.toml) run to its own t_end, then one frame drawn with
# `otmpm render` into docs/figures/gallery/SCENE.png. A scene missing from
# the list below, or from docs/gallery.md, is an error: the gallery cannot
# leave one out.
#
#   bash scripts/gallery.sh [BUILD_DIR]            # redraws the pictures (default build: build)
#   bash scripts/gallery.sh --check [BUILD_DIR]    # CI: draws them into a temporary folder and compares
#                                                  # each with the committed picture (exit 1 when one differs)
#
# Two pictures agree when at most 1% of their pixels differ by more than 0.1
# in a colour channel (the runs are deterministic: what differs is a scene,
# the engine or the renderer that changed).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
check=""
if [ "${1:-}" = "--check" ]; then check=1; shift; fi
otmpm=${1:-$root/build}/bin/otmpm
committed=$root/docs/figures/gallery
work=$(mktemp -d /tmp/otmpm-gallery.XXXXXX)
trap 'rm -rf "$work"' EXIT
out=$committed
[ -n "$check" ] && out=$work/pictures
mkdir -p "$out"

# scene (relative to examples/, without .toml) | render options
list='andersen_block|--field stress --component yy
column_collapse|--field plastic_strain
column_collapse_mu_i|--field plastic_strain
disks|--field v
dyka|--field v
dyka_2d|--field stress --component xx
dyka_3d|--field v --view xz
fixed_bar|--field displacement --frame 5
mms_plate|--field displacement --component x
plate_impact|--field v
sliding_block|--field x --component x
stretch_bar|--field stress --component xx
taylor_bar|--field plastic_strain --view xz
terzaghi|--field pore_pressure --frame 4
mandel|--field pore_pressure --frame 8
dike|--field pore_pressure
dike_rising|--field plastic_strain
traction_bar|--field stress
geometry/impactor|--field plastic_strain --view xz
geometry/embankment|--field plastic_strain
geometry/bracket|--field plastic_strain --view xz'

status=0
# every example scene is in the list, and in docs/gallery.md
for f in "$root"/examples/*.toml "$root"/examples/geometry/*.toml; do
  scene=${f#"$root"/examples/}
  scene=${scene%.toml}
  if ! grep -q "^$scene|" <<<"$list"; then echo "gallery: examples/$scene.toml is not in scripts/gallery.sh"; status=1; fi
  if ! grep -q "figures/gallery/$(basename "$scene").png" "$root/docs/gallery.md"; then
    echo "gallery: docs/gallery.md shows no picture of examples/$scene.toml"; status=1
  fi
done
[ $status -eq 0 ] || exit $status

while IFS='|' read -r scene options; do
  name=$(basename "$scene")
  start=$(date +%s)
  rc=0
  "$otmpm" run "$root/examples/$scene.toml" --out "$work/$name.h5" --quiet --threads "$(nproc 2>/dev/null || echo 2)" ||
    rc=$?
  # an unstable run (exit 1) keeps its frames: drawn, and said (docs/gallery.md says it too)
  [ $rc -eq 0 ] || [ $rc -eq 1 ] || { echo "gallery: examples/$scene.toml: exit $rc"; exit 1; }
  [ $rc -eq 0 ] || echo "gallery: examples/$scene.toml: UNSTABLE (exit 1): the picture shows its last frame"
  # shellcheck disable=SC2086
  "$otmpm" render "$work/$name.h5" $options --out "$out/$name.png" >/dev/null
  echo "== $scene: $(( $(date +%s) - start )) s"
done <<<"$list"

[ -n "$check" ] || exit 0
/usr/bin/python3 - "$out" "$committed" <<'PY'
import os, sys
import matplotlib.image as mpimg
import numpy as np
new_dir, old_dir = sys.argv[1:]
bad = 0
for name in sorted(os.listdir(new_dir)):
    old = os.path.join(old_dir, name)
    if not os.path.exists(old):
        print(f"gallery: {name}: no committed picture (docs/figures/gallery/{name}): run scripts/gallery.sh")
        bad += 1
        continue
    a, b = mpimg.imread(os.path.join(new_dir, name))[..., :3], mpimg.imread(old)[..., :3]
    if a.shape != b.shape:
        print(f"gallery: {name}: {a.shape[1]}x{a.shape[0]} pixels, the committed one {b.shape[1]}x{b.shape[0]}")
        bad += 1
        continue
    share = float(np.mean(np.any(np.abs(a - b) > 0.1, axis=2)))
    print(f"gallery: {name}: {100 * share:.2f}% of the pixels differ" + (" (more than 1%)" if share > 0.01 else ""))
    bad += share > 0.01
if bad:
    print(f"gallery: {bad} pictures differ from docs/figures/gallery: run bash scripts/gallery.sh and commit them")
sys.exit(1 if bad else 0)
PY
