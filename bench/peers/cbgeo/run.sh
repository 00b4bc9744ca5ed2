#!/bin/bash
# Time CB-Geo mpm (and optionally otmpm, interleaved) on otmpm's 2D block
# (make_block.py), one thread, as the difference of runs of N1 and N2 steps.
#
#   run.sh [N1] [N2] [ROUNDS]          (defaults 10 210 5)
#
# Environment:
#   MPM      CB-Geo's executable (required)
#   OTMPM    otmpm binary; if set, each round also runs otmpm on the same
#            block with the same fixed dt, N1O and N2O steps (default N1, N2)
#   WORK     scratch directory           (default: a new temporary directory)
#   LOCK     if set, every timed command runs under `flock $LOCK`
#   PYTHON   python 3                    (default python3)
#   CELLS    cells across the block      (default 200)
#   SCHEME   usl (otmpm's fe) or usf     (default usl)
#
# CB-Geo's own timer ("Explicit USL solver duration", the main loop, which
# includes its one HDF5 write of the particles, at step 0: output_steps is set
# beyond the run) is used; the per-step
# time is (loop(N2) - loop(N1)) / (N2 - N1). otmpm's is the "s wall" of its
# summary line, differenced the same way.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
N1=${1:-10}; N2=${2:-210}; ROUNDS=${3:-5}
N1O=${N1O:-$N1}; N2O=${N2O:-$N2}
MPM=${MPM:-}
[ -x "$MPM" ] || { echo "run.sh: set MPM to CB-Geo's executable" >&2; exit 2; }
WORK=${WORK:-$(mktemp -d)}
PYTHON=${PYTHON:-python3}
CELLS=${CELLS:-200}
SCHEME=${SCHEME:-usl}
NP=$((4 * CELLS * CELLS))
mkdir -p "$WORK"
lock() { if [ -n "${LOCK:-}" ]; then flock "$LOCK" "$@"; else "$@"; fi; }

DT=$("$PYTHON" -c "import math;E,nu,r=1e7,.3,1e3;print(repr(.3/$CELLS/math.sqrt(E*(1-nu)/((1+nu)*(1-2*nu)*r))))")
for n in "$N1" "$N2"; do
  "$PYTHON" "$here/make_block.py" "$WORK/cb-$n" --cells "$CELLS" --nsteps "$n" \
    --scheme "$SCHEME" --dt "$DT" --output-steps 100000000 >/dev/null
done

# otmpm: the block of ../block_2d.toml on this grid, with the same dt
lo=$("$PYTHON" -c "print(repr(-2/$CELLS))"); hi=$("$PYTHON" -c "print(repr(1+2/$CELLS))")
ot_scene=(--set "grid.lower=[$lo, 0.0]" --set "grid.upper=[$hi, $hi]"
  --set "grid.cells=[$((CELLS + 4)), $((CELLS + 2))]" --set "boundary.base.lower=[$lo, 0.0]"
  --set "boundary.base.upper=[$hi, 0.0]" --set simulation.dt="$DT" --set output.every=0.0)

cb_run() { # steps -> loop seconds
  local d="$WORK/cb-$1"
  rm -rf "$d/results"
  uptime >&2
  OMP_NUM_THREADS=1 lock "$MPM" -f "$d/" -i mpm.json -p 1 > "$d/log.txt" 2>&1
  local ms
  ms=$(grep -o 'solver duration: [0-9]* ms' "$d/log.txt" | grep -o '[0-9]*')
  echo "cbgeo steps=$1 loop_ms=$ms" >&2
  "$PYTHON" -c "print($ms/1000)"
}
ot_run() { # steps -> wall seconds of otmpm's summary line
  local t_end
  t_end=$("$PYTHON" -c "print(repr($1*$DT))")
  uptime >&2
  OMP_NUM_THREADS=1 lock "$OTMPM" run "$here/../block_2d.toml" "${ot_scene[@]}" --threads 1 --quiet --force \
    --set simulation.t_end="$t_end" --out "$WORK/ot-$1.h5" > "$WORK/ot-$1.log" 2>&1
  local line
  line=$(grep '^ok:' "$WORK/ot-$1.log")
  echo "otmpm $line" >&2
  echo "$line" | sed -E 's/.* ([0-9.e+-]+) s wall.*/\1/'
}

cb=(); ot=()
for r in $(seq "$ROUNDS"); do
  if [ -n "${OTMPM:-}" ]; then
    a=$(ot_run "$N1O"); b=$(ot_run "$N2O")
    ot+=("$("$PYTHON" -c "print(($b-$a)/($N2O-$N1O)/$NP)")")
    echo "round $r otmpm: ${ot[-1]} s per particle-step"
  fi
  a=$(cb_run "$N1"); b=$(cb_run "$N2")
  cb+=("$("$PYTHON" -c "print(($b-$a)/($N2-$N1)/$NP)")")
  echo "round $r cbgeo: ${cb[-1]} s per particle-step (loop of $N2 steps: $b s)"
done

"$PYTHON" - "${cb[*]}" "${ot[*]:-}" <<'EOF'
import statistics, sys
cb = [float(x) for x in sys.argv[1].split()]
ot = [float(x) for x in sys.argv[2].split()] if len(sys.argv) > 2 and sys.argv[2] else []
mc = statistics.median(cb)
print("cbgeo s/particle-step:", " ".join("%.4g" % x for x in cb),
      "median %.4g -> %.4g particle-steps/s" % (mc, 1 / mc))
if ot:
    mo = statistics.median(ot)
    print("otmpm s/particle-step:", " ".join("%.4g" % x for x in ot),
          "median %.4g -> %.4g particle-steps/s" % (mo, 1 / mo))
    print("ratio otmpm/cbgeo (particle-steps/s): %.3g" % (mc / mo))
EOF
