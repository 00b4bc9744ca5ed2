#!/usr/bin/env bash
# Checks an installed otmpm with nothing of the source or build tree in reach:
#   1. `cmake --install` into a fresh prefix; no internal header is installed;
#   2. examples/consumer (find_package(otmpm)) builds - compiling every
#      installed header on its own - and runs;
#   3. the source tree (which holds the build tree) is moved away, and the
#      installed binary runs: --version, --help, a short run, `otmpm render`,
#      a study whose plots come from PREFIX/share/otmpm, and (when built with
#      OTMPM_PYTHON) the installed Python package: import, a run, a study;
#   4. the source tree is moved back (also when a step fails).
# Usage: bash scripts/check-install.sh     (after scripts/test.sh; OTMPM_BUILD_DIR as there)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${OTMPM_BUILD_DIR:-$root/build}
jobs=$(nproc 2>/dev/null || echo 2)
tmp=$(mktemp -d /tmp/otmpm-check-install.XXXXXX)
prefix=$tmp/prefix
work=$tmp/work
moved="$root.moved-away-$$"
mkdir -p "$work"

restore() {
  if [ -d "$moved" ]; then mv "$moved" "$root"; fi
  rm -rf "$tmp"
}
trap restore EXIT

echo "== install into $prefix"
cmake --install "$build" --prefix "$prefix" >/dev/null
for internal in hdf5.hpp parallel.hpp channel_walls.hpp simd.hpp lme.hpp linear.hpp toml_reader.hpp scatter.hpp nodal_ops.hpp; do
  if [ -n "$(find "$prefix/include" -name "$internal")" ]; then
    echo "FAIL: internal header $internal was installed" >&2
    exit 1
  fi
done
for script in render.py plot_study.py plot_stability.py; do
  test -f "$prefix/share/otmpm/$script" || { echo "FAIL: $prefix/share/otmpm/$script missing" >&2; exit 1; }
done

echo "== consumer (find_package(otmpm), every installed header compiled alone)"
cmake -S "$root/examples/consumer" -B "$work/consumer" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$work/consumer" -j"$jobs"
"$work/consumer/consumer"

# What the installed binary needs besides itself: a scene and a study file.
cp "$root/examples/dyka.toml" "$work/dyka.toml"
cat >"$work/study.toml" <<'EOF'
scene = "dyka.toml"
jobs = 2
set = ["simulation.t_end=2e-5", "output.every=1e-5"]
[sweep]
"simulation.integrator" = ["fe", "npc"]
[[mesh]]
name = "n13"
h = 0.010253846
set = ["grid.cells=[15]", "grid.lower=[-0.020507692]"]
EOF

python_built=0
if grep -q '^OTMPM_PYTHON:BOOL=ON' "$build/CMakeCache.txt"; then python_built=1; fi

echo "== source tree moved away: $root -> $moved"
mv "$root" "$moved"
otmpm=$prefix/bin/otmpm
cd "$work"
"$otmpm" --version
"$otmpm" run --help >/dev/null
"$otmpm" run dyka.toml --set simulation.t_end=2e-5 --out run.h5 --quiet --threads 1
"$otmpm" render run.h5 --field v --out run.png
test -s run.png
"$otmpm" study study.toml
test -s study.csv
test -s study_work_precision.png
if [ "$python_built" = 1 ]; then
  echo "== installed Python package (docs/python.md: PREFIX/lib/pythonX.Y/dist-packages)"
  pyver=$(/usr/bin/python3 -c 'import sys; print("python%d.%d" % sys.version_info[:2])')
  env -u OTMPM_CLI PYTHONPATH="$prefix/lib/$pyver/dist-packages" /usr/bin/python3 -c '
import os, sys, otmpm
assert otmpm.__file__.startswith(sys.argv[1]), otmpm.__file__
s = otmpm.run(otmpm.Scene.from_toml("dyka.toml", overrides={"simulation.t_end": 2e-5}), out="py.h5")
print(otmpm.__file__, s, sep="\n")
r = otmpm.study("study.toml")
assert len(r.rows) == 2, r.rows
sys.exit(s.exit_code)' "$prefix"
fi
echo "== moving the source tree back"
mv "$moved" "$root"
echo "installed otmpm OK (prefix $prefix, removed on exit)"
