#!/usr/bin/env bash
# Instructions per particle-step of the LME rows of the methods table,
# counted by valgrind's callgrind (deterministic: the machine's load does not
# change them), one thread:
#
#   bash scripts/bench-instructions.sh [BENCH_STEP]
#
# BENCH_STEP defaults to build-bench/bench/bench_step (bash scripts/bench.sh
# builds it). Each case runs twice, over S1 and S2 steps; the difference of
# the two counts over (S2 - S1) steps and the particles is the cost of a step
# without the set-up. The cases: the 2D block of 60 x 60 cells (14 400
# particles; LME gamma_lme = 3 npc and linear fe, mpm) over 10 and 20 steps,
# and the 3D block of 12^3 cells (13 824 particles) over 3 and 6 steps; for
# reference the cubic B-spline with npc (a product of 1D functions over the
# 4^D nodes of a box, about as many as an LME support cut to the box of its
# lattice lines would hold: 16 in 2D, 64 in 3D). At
# these sizes the blocks stay in the caches: the counts are the instruction
# side of a step, not its memory traffic.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bench=${1:-$root/build-bench/bench/bench_step}
[ -x "$bench" ] || { echo "bench-instructions.sh: no $bench (build the bench_step target)" >&2; exit 2; }
command -v valgrind >/dev/null || { echo "bench-instructions.sh: valgrind is not installed" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# instructions DIM CELLS BASIS INTEGRATOR STEPS: the callgrind count of one run
instructions() {
  OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive valgrind --tool=callgrind --callgrind-out-file="$work/out" \
    "$bench" --dim "$1" --cells "$2" --basis "$3" --integrator "$4" --mode mpm --steps "$5" --repeat 1 \
    >/dev/null 2>"$work/log"
  sed -n 's/.*Collected : *\([0-9]*\).*/\1/p' "$work/log"
}

# per_step DIM CELLS BASIS INTEGRATOR S1 S2: instructions per particle-step
per_step() {
  local i1 i2 particles
  i1=$(instructions "$1" "$2" "$3" "$4" "$5")
  i2=$(instructions "$1" "$2" "$3" "$4" "$6")
  particles=$(( $1 == 3 ? 8 * $2 ** 3 : 4 * $2 ** 2 ))
  echo $(( (i2 - i1) / (($6 - $5) * particles) ))
}

lme2=$(per_step 2 60 lme npc 10 20)
lin2=$(per_step 2 60 linear fe 10 20)
lme3=$(per_step 3 12 lme npc 3 6)
lin3=$(per_step 3 12 linear fe 3 6)
bs2=$(per_step 2 60 bspline3 npc 10 20)
bs3=$(per_step 3 12 bspline3 npc 3 6)
echo "instructions per particle-step (callgrind, one thread):"
echo "  2D block 60^2, LME gamma_lme = 3 npc: $lme2, linear fe: $lin2, ratio $(awk "BEGIN{printf \"%.2f\", $lme2/$lin2}")"
echo "  3D block 12^3, LME gamma_lme = 3 npc: $lme3, linear fe: $lin3, ratio $(awk "BEGIN{printf \"%.2f\", $lme3/$lin3}")"
echo "  bspline3 npc: 2D $bs2 (ratio to linear fe $(awk "BEGIN{printf \"%.2f\", $bs2/$lin2}")), 3D $bs3 (ratio $(awk "BEGIN{printf \"%.2f\", $bs3/$lin3}"))"
