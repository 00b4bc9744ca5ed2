#!/usr/bin/env bash
# The output row of the methods table (docs/performance-log-2026.md, "Result file size and
# write time"): the 3D elastic block of scripts/bench-mpi.sh --dim 3 (N^3
# cells of the unit cube, 2 x 2 x 2 particles per cell, linear fe, mpm, base
# fixed, gravity), 20 frames one every S steps, fields x, v, stress; run with
# the default output and with output.precision = "single" and
# output.symmetric_tensors = true. Prints per configuration the result file's
# bytes, the wall time, the stepping thread's output phase (seconds_output:
# what the run waits for) and the writer thread's busy time
# (seconds_output_thread), and the output share of the wall time; last, the
# two rows of the methods table (bytes single/symmetric over default; the
# output share of the wall time of the single/symmetric run) with target,
# measured value and met or not.
#
#   bash scripts/bench-output.sh BUILD/bin/otmpm [--cells 64] [--every 5] [--threads 2] [--compression L]
#
# --compression L (1..9): also both configurations with output.compression = L
# (rows double+zL and single+zL) and, last, their bytes over the uncompressed
# file's and their output shares.
#
# The files (5 GB and 2 GB at 64^3) go to a temporary folder that is removed.
set -euo pipefail
bin=$(realpath "${1:?usage: bench-output.sh OTMPM_BINARY [--cells N] [--every STEPS] [--threads T] [--compression L]}")
shift
cells=64 every=5 threads=2 compression=0
while [ $# -gt 0 ]; do
  case $1 in
    --cells) cells=$2; shift 2 ;;
    --every) every=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --compression) compression=$2; shift 2 ;;
    *) echo "unknown option $1" >&2; exit 2 ;;
  esac
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
/usr/bin/python3 - "$cells" "$every" >"$work/block.toml" <<'PY'
import sys
n, every_steps = int(sys.argv[1]), int(sys.argv[2])
h = 1.0 / n
lo, hi = -2 * h, 1 + 2 * h
M = 1e7 * (1 - 0.3) / ((1 + 0.3) * (1 - 2 * 0.3))
dt = 0.3 * h / (M / 1000.0) ** 0.5  # cfl h / c_P
every = every_steps * dt * 0.99999
t_end = 19 * every * 1.000001  # frames at 0, every, ..., 19 every: 20
print(f'''[simulation]
dimension = 3
mode = "mpm"
integrator = "fe"
t_end = {t_end!r}
cfl = 0.3
[basis]
kind = "linear"
[grid]
lower = [{lo!r}, {lo!r}, 0.0]
upper = [{hi!r}, {hi!r}, {hi!r}]
cells = [{n + 4}, {n + 4}, {n + 2}]
[[material]]
name = "m"
model = "linear_elastic"
density = 1000.0
young = 1.0e7
poisson = 0.3
[[body]]
name = "block"
material = "m"
lower = [0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0]
particles_per_cell = 2
velocity = [0.0, 0.0, 0.0]
[[boundary]]
name = "base"
lower = [{lo!r}, {lo!r}, 0.0]
upper = [{hi!r}, {hi!r}, 0.0]
fix = [true, true, true]
[body_force]
value = [0.0, 0.0, -9.81]
[output]
every = {every!r}
fields = ["x", "v", "stress"]''')
PY
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
configs=(double single)
[ "$compression" -gt 0 ] && configs+=("double+z$compression" "single+z$compression")
for cfg in "${configs[@]}"; do
  sets=()
  case $cfg in single*) sets=(--set output.precision=single --set output.symmetric_tensors=true) ;; esac
  case $cfg in *+z*) sets+=(--set "output.compression=$compression") ;; esac
  env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT OMP_NUM_THREADS=$threads "$bin" run "$work/block.toml" --quiet --out "$work/$cfg.h5" "${sets[@]}" >/dev/null
  /usr/bin/python3 - "$work/$cfg.h5" "$cfg" <<'PY'
import os, sys
import h5py
path, cfg = sys.argv[1], sys.argv[2]
with h5py.File(path, "r") as f:
    a = f.attrs
    thread = a.get("seconds_output_thread", float("nan"))
    print(f"{cfg:7s} frames {len(f['frames'])} steps {a['steps']} particles {a['particles']} bytes {os.path.getsize(path)} "
          f"wall {a['wall_seconds']:.1f} s output {a['seconds_output']:.2f} s ({100 * a['seconds_output'] / a['wall_seconds']:.1f} %) "
          f"writer thread {thread:.1f} s")
    with open(os.path.join(os.path.dirname(path), "summary.csv"), "a") as out:
        out.write(f"{cfg},{os.path.getsize(path)},{a['wall_seconds']!r},{a['seconds_output']!r}\n")
PY
  rm -f "$work/$cfg.h5" "$work/$cfg.xdmf"
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
/usr/bin/python3 - "$work/summary.csv" "$cells" "$threads" <<'PY'
import sys
rows = {r[0]: r[1:] for r in (line.strip().split(",") for line in open(sys.argv[1]))}
n, threads = sys.argv[2], sys.argv[3]
ratio = int(rows["single"][0]) / int(rows["double"][0])
share = float(rows["single"][2]) / float(rows["single"][1])
met = lambda ok: "met" if ok else "**not met**"
print(f"\n| method figure | target | measured | met |\n|---|---|---|---|")
print(f"| result file of the 3D block ({n}^3 cells), 20 frames: bytes with precision single + symmetric tensors "
      f"/ default | <= 0.5 | {ratio:.3f} | {met(ratio <= 0.5)} |")
print(f"| same, single + symmetric, {threads} OpenMP thread(s): output time of the stepping thread / wall time "
      f"| < 5% | {100 * share:.1f}% | {met(share < 0.05)} |")
for cfg in ("double", "single"):
    z = [k for k in rows if k.startswith(cfg + "+z")]
    if z:
        b, wall, out = int(rows[z[0]][0]), float(rows[z[0]][1]), float(rows[z[0]][2])
        print(f"| {z[0]}: bytes / {cfg} bytes | {b / int(rows[cfg][0]):.3f} | output share {100 * out / wall:.1f}% "
              f"(uncompressed {100 * float(rows[cfg][2]) / float(rows[cfg][1]):.1f}%) |")
PY
