#!/usr/bin/env bash
# Distributed runs on this machine (docs/performance.md, "Distributed runs"):
# the 2D block of the throughput table (bench/bench_scenes.hpp: N x N cells of
# the unit square, 2 x 2 particles per cell, plane strain, under gravity with
# its base fixed; linear basis, fe, mpm) run with the otmpm command
#
#   serial, 1 OpenMP thread | serial, 2 threads | mpirun -np 2, 1 thread each
#   (and -np 3, 4 with --ranks 4: oversubscribed on 2 cores)
#
# interleaved (one run of each configuration in turn, R rounds), each for a
# short and a long number of steps; time per step = (wall_long - wall_short) /
# (steps_long - steps_short), so set-up (assembly, decomposition) and the
# result file drop out. Prints per configuration the median time per step,
# the speed-up over serial 1 thread, and from the result file's attributes
# the halo bytes and communication seconds per step and rank.
#
# With --dim 3 the block is the 3D cube of N^3 cells, 2 x 2 x 2 particles per
# cell, under gravity along z with its base fixed. --write-scene FILE writes
# the block's scene to FILE and runs nothing (scripts/checkpoint-memory.sh).
#
#   bash scripts/bench-mpi.sh [--repeat R] [--cells N] [--ranks MAX] [--basis linear] [--integrator fe] [--dim 2|3]
#                             [--write-scene FILE]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${OTMPM_BIN:-$root/build/bin/otmpm}
repeat=5 cells=200 ranks=2 basis=linear integrator=fe short=10 long=60 dim=2 scene_out=
while [ $# -gt 0 ]; do
  case "$1" in
    --repeat) repeat=$2; shift 2 ;;
    --cells) cells=$2; shift 2 ;;
    --ranks) ranks=$2; shift 2 ;;
    --basis) basis=$2; shift 2 ;;
    --integrator) integrator=$2; shift 2 ;;
    --steps) short=$2; long=$3; shift 3 ;;
    --dim) dim=$2; shift 2 ;;
    --write-scene) scene_out=$2; shift 2 ;;
    *) echo "usage: bash scripts/bench-mpi.sh [--repeat R] [--cells N] [--ranks MAX] [--basis B] [--integrator I] [--steps SHORT LONG]" >&2; exit 2 ;;
  esac
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
unset OMP_WAIT_POLICY GOMP_SPINCOUNT # otmpm's own OpenMP wait (otmpm/openmp_wait.hpp)
h=$(/usr/bin/python3 -c "print(repr(1.0/$cells))")
lo=$(/usr/bin/python3 -c "print(-2*$h)") hi=$(/usr/bin/python3 -c "print(1+2*$h)")
if [ "$dim" = 3 ]; then
  grid="lower = [$lo, $lo, 0.0]
upper = [$hi, $hi, $hi]
cells = [$((cells + 4)), $((cells + 4)), $((cells + 2))]"
  body="lower = [0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0]
particles_per_cell = 2
velocity = [0.0, 0.0, 0.0]"
  base="lower = [$lo, $lo, 0.0]
upper = [$hi, $hi, 0.0]
fix = [true, true, true]"
  gravity="[0.0, 0.0, -9.81]"
else
  grid="lower = [$lo, 0.0]
upper = [$hi, $hi]
cells = [$((cells + 4)), $((cells + 2))]"
  body="lower = [0.0, 0.0]
upper = [1.0, 1.0]
particles_per_cell = 2
velocity = [0.0, 0.0]"
  base="lower = [$lo, 0.0]
upper = [$hi, 0.0]
fix = [true, true]"
  gravity="[0.0, -9.81]"
fi
cat > "$work/block.toml" <<EOF
[simulation]
dimension = $dim
mode = "mpm"
integrator = "$integrator"
t_end = 1.0
cfl = 0.3
[basis]
kind = "$basis"
gamma_lme = 3.0
[grid]
$grid
[[material]]
name = "m"
model = "linear_elastic"
density = 1000.0
young = 1.0e7
poisson = 0.3
[[body]]
name = "block"
material = "m"
$body
[[boundary]]
name = "base"
$base
[body_force]
value = $gravity
[output]
every = 0.0
fields = ["x"]
EOF
if [ -n "$scene_out" ]; then
  cp "$work/block.toml" "$scene_out"
  exit 0
fi
# dt of the scene (cfl h / c_P), for t_end = steps * dt
dt=$(/usr/bin/python3 -c "
E,nu,rho=1e7,0.3,1000.0
M=E*(1-nu)/((1+nu)*(1-2*nu))
print(0.3*(1.0/$cells)/(M/rho)**0.5)")
configs=("serial1" "serial2")
for n in $(seq 2 "$ranks"); do configs+=("np$n"); done
run() { # config steps out -> wall seconds
  local cfg=$1 steps=$2 out=$3 t_end
  t_end=$(/usr/bin/python3 -c "print($steps*$dt*0.9999)")
  local cmd=("$bin" run "$work/block.toml" --quiet --out "$out" --set simulation.t_end="$t_end")
  case $cfg in
    serial1) OMP_NUM_THREADS=1 "${cmd[@]}" ;;
    serial2) OMP_NUM_THREADS=2 "${cmd[@]}" ;;
    np*) OMP_NUM_THREADS=1 mpirun -q --oversubscribe -np "${cfg#np}" "${cmd[@]}" < /dev/null ;;
  esac | sed -n 's/.* \([0-9.]*\) s wall.*/\1/p'
}
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "block ${dim}D, $cells cells per side, $(( (dim == 3 ? 8 * cells : 4) * cells * cells)) particles, $basis $integrator mpm; steps $short and $long; $repeat rounds"
declare -A per_step
for r in $(seq 1 "$repeat"); do
  for cfg in "${configs[@]}"; do
    a=$(run "$cfg" "$short" "$work/$cfg-s.h5")
    b=$(run "$cfg" "$long" "$work/$cfg-l.h5")
    per_step[$cfg]+="$(/usr/bin/python3 -c "print(($b - $a) / ($long - $short))") "
  done
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
/usr/bin/python3 - "$work" "$short" "$long" "${configs[@]}" <<PY
import statistics, sys, h5py
work, short, long_, configs = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4:]
times = {$(for c in "${configs[@]}"; do echo "'$c': [${per_step[$c]// /, }],"; done)}
base = statistics.median(times["serial1"])
print(f"{'config':10s} {'ms/step':>9s} {'speed-up':>9s} {'halo B/step/rank':>17s} {'comm ms/step/rank':>18s} {'reductions/step':>16s}")
for c in configs:
    t = statistics.median(times[c])
    halo = comm = red = float("nan")
    if c.startswith("np"):
        ranks = int(c[2:])
        with h5py.File(f"{work}/{c}-l.h5") as fl, h5py.File(f"{work}/{c}-s.h5") as fs:
            d = lambda k: (fl.attrs[k] - fs.attrs[k]) / (long_ - short)
            halo = d("halo_bytes") / ranks
            comm = 1e3 * d("communication_seconds_mean")
            red = d("reductions")
    print(f"{c:10s} {1e3*t:9.3f} {base/t:9.2f} {halo:17.0f} {comm:18.3f} {red:16.1f}   (runs: {', '.join(f'{1e3*x:.2f}' for x in times[c])})")
PY
