#!/usr/bin/env bash
# What two cores give two independent runs against what they give one run on
# two threads (docs/performance.md, "Threads"):
#
#   bash scripts/bench-pair.sh [--bench BENCH_STEP] [--rounds R] [BENCH_STEP ARGS...]
#
# Each round runs bench_step (default build-bench/bench/bench_step, which
# scripts/bench.sh builds) with the given arguments on one thread alone, then
# two one-thread copies side by side, then one copy on two threads, and prints
# the three rates (particle-steps/s, bench_step's own medians). The copies
# share no data: their sum over the rate alone is what the machine's two
# cores give; the two-thread rate over it what the threaded step keeps.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bench=$root/build-bench/bench/bench_step
rounds=3
while [ $# -gt 0 ]; do
  case "$1" in
    --bench) bench=$2; shift 2 ;;
    --rounds) rounds=$2; shift 2 ;;
    *) break ;;
  esac
done
[ -x "$bench" ] || { echo "bench-pair.sh: no $bench (build the bench_step target)" >&2; exit 2; }
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "bench-pair.sh: --rounds must be a whole number >= 1" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# rate THREADS: bench_step's median particle-steps/s
rate() {
  OMP_NUM_THREADS=$1 "$bench" "${args[@]}" | sed -n 's/.*median \([0-9.e+]*\) particle-steps.*/\1/p'
}
args=("$@")
echo "bench_step ${args[*]}: particle-steps/s"
echo "| round | one thread alone | two one-thread copies side by side | their sum / alone | two threads | two threads / alone |"
echo "|---|---|---|---|---|---|"
for r in $(seq "$rounds"); do
  alone=$(rate 1)
  rate 1 > "$work/a" &
  b=$(rate 1)
  wait
  a=$(cat "$work/a")
  two=$(rate 2)
  awk -v r="$r" -v s="$alone" -v a="$a" -v b="$b" -v t="$two" \
    'BEGIN { printf "| %d | %.3g | %.3g + %.3g | %.2f | %.3g | %.2f |\n", r, s, a, b, (a + b) / s, t, t / s }'
done
