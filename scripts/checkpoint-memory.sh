#!/usr/bin/env bash
# Peak resident memory per rank of a distributed run that writes a
# checkpoint, and of its restart (docs/performance.md, "Memory at scale"):
# the 3D block of scripts/bench-mpi.sh --dim 3 (N^3 cells
# of the unit cube, 2 x 2 x 2 particles per cell, linear fe, mpm, its base
# held, under gravity; bench-mpi.sh --write-scene) run for S steps under
# mpirun -np R, one OpenMP thread per rank, each rank under /usr/bin/time:
#
#   1. the run without a checkpoint, 2. the same run writing one checkpoint
#   (at step S - 1), 3. its restart on R ranks (the last step), 4. its
#   restart on R2 ranks
#
# and prints per case each rank's peak (MB), the largest over the mean and
# the wall time (the slowest rank's, set-up and output included).
# With --agreement the runs also write VTK files (vtp, by every rank) and
# every output time, and the script runs the scene in one process and prints
# the largest relative difference per field (scripts/compare_results.py) of
# the R-rank run and of both restarts against it; exit 1 above 1e-12.
#
#   bash scripts/checkpoint-memory.sh [--cells N] [--ranks R] [--restart-ranks R2] [--steps S] [--agreement]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${OTMPM_BIN:-$root/build/bin/otmpm}
cells=64 ranks=2 ranks2=3 steps=4 agreement=0
while [ $# -gt 0 ]; do
  case "$1" in
    --cells) cells=$2; shift 2 ;;
    --ranks) ranks=$2; shift 2 ;;
    --restart-ranks) ranks2=$2; shift 2 ;;
    --steps) steps=$2; shift 2 ;;
    --agreement) agreement=1; shift ;;
    *) echo "usage: bash scripts/checkpoint-memory.sh [--cells N] [--ranks R] [--restart-ranks R2] [--steps S] [--agreement]" >&2; exit 2 ;;
  esac
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1
bash "$root/scripts/bench-mpi.sh" --dim 3 --cells "$cells" --write-scene "$work/block.toml"
# t_end of S steps (cfl h / c_P)
t_end=$(/usr/bin/python3 -c "
E,nu,rho=1e7,0.3,1000.0
M=E*(1-nu)/((1+nu)*(1-2*nu))
print($steps*0.3*(1.0/$cells)/(M/rho)**0.5*0.9999)")
measure() { # label ranks otmpm-arguments... -> one line: label, each rank's peak MB, largest / mean
  local label=$1 n=$2
  shift 2
  rm -f "$work"/peak.*
  (cd "$work" && mpirun -q --oversubscribe -np "$n" sh -c \
    'exec /usr/bin/time -o "peak.$OMPI_COMM_WORLD_RANK" -f "%M %e" "$@" > /dev/null' sh "$bin" "$@" 2> "$work/err.txt") || {
    cat "$work/err.txt" >&2
    exit 1
  }
  /usr/bin/python3 - "$label" "$n" "$work" <<'PY'
import sys
label, n, work = sys.argv[1], int(sys.argv[2]), sys.argv[3]
rows = [open(f"{work}/peak.{r}").read().split()[-2:] for r in range(n)]
mb = [int(r[0]) / 1000.0 for r in rows]
wall = max(float(r[1]) for r in rows)
print(f"{label:40s} " + " ".join(f"{m:8.1f}" for m in mb) + f"   max/mean {max(mb) / (sum(mb) / len(mb)):.3f}"
      + f"   wall {wall:.1f} s")
PY
}
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc --all) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "3D block, $cells^3 cells, $((8 * cells * cells * cells)) particles, $steps steps; peak RSS per rank in MB (rank 0 first)"
outputs=()
if [ "$agreement" = 1 ]; then
  outputs=(--set 'output.format=["hdf5", "vtp"]' --set "output.every=$t_end")
fi
measure "run on $ranks ranks, no checkpoint" "$ranks" run block.toml --quiet --out a.h5 --set simulation.t_end="$t_end" \
  "${outputs[@]}"
measure "run on $ranks ranks, checkpoint at step $((steps - 1))" "$ranks" run block.toml --quiet --out b.h5 \
  --set simulation.t_end="$t_end" --set output.checkpoint_every="$((steps - 1))" "${outputs[@]}"
ls -l "$work/b.checkpoint.h5" | awk '{printf "checkpoint file: %.1f MB\n", $5 / 1e6}'
measure "restart on $ranks ranks" "$ranks" run --restart b.checkpoint.h5 --quiet --out c.h5
measure "restart on $ranks2 ranks" "$ranks2" run --restart b.checkpoint.h5 --quiet --out d.h5
if [ "$agreement" = 1 ]; then
  (cd "$work" && OMP_NUM_THREADS=2 "$bin" run block.toml --quiet --out serial.h5 --set simulation.t_end="$t_end" \
    "${outputs[@]}")
  for f in b c d; do
    echo "largest difference of $f.h5 from the run in one process:"
    /usr/bin/python3 "$root/scripts/compare_results.py" "$work/serial.h5" "$work/$f.h5" --tol 1e-12
  done
  echo "VTK pieces of the $ranks-rank run: $(ls "$work"/b_vtk | wc -l) files"
fi
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
