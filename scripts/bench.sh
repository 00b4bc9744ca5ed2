#!/usr/bin/env bash
# Runs every row of the performance tables (throughput, methods, plastic) and prints
# them with target, measured value and met or not (see docs/performance.md):
#
#   bash scripts/bench.sh [--repeat R] [--native] [--table throughput|methods|lme|plastic|threads|targets|all] [--quick] [--no-output]
#
# Builds build-bench (Release, benchmarks, no tests, the portable default
# flags; with --native build-bench-native with -march=native), runs
# bench/bench_table with OMP_NUM_THREADS=2 (the single-thread rows set one
# thread themselves), draws the scaling plots into out/scaling.png (2D block)
# and out/scaling3d.png (3D block) (out/scaling-native.png ... with --native),
# and for the methods table's output row runs scripts/bench-output.sh on the 64^3
# block with one OpenMP thread (the writer thread; it writes 5 GB and 2 GB
# into a temporary folder; --no-output skips it). --quick: small sizes,
# short runs, one repetition - a smoke test of every row in about a minute,
# whose figures mean nothing. --table lme: only the methods table's LME
# rows (the 2D and the 3D block, lme npc and lme_box npc / linear fe), no
# plots. --table
# threads: each case of the performance targets on one and on two threads,
# interleaved, and the speed-up (not part of "all"), no plots. --table
# targets: every target of the current round (docs/performance.md, "The
# targets"): the 10^6-particle block in fe and musl, the LME ratios, the
# plastic and the threads tables, then scripts/roofline.sh for the bytes per
# particle-step (cachegrind; skipped with --quick) - not part of "all", no plots.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
repeat=5
native=OFF
table=all
quick=0
output=1
usage="usage: bash scripts/bench.sh [--repeat R] [--native] [--table throughput|methods|lme|plastic|threads|targets|all] [--quick] [--no-output]"
while [ $# -gt 0 ]; do
  case "$1" in
    --repeat) repeat="$2"; shift 2 ;;
    --native) native=ON; shift ;;
    --table) table="$2"; shift 2 ;;
    --quick) quick=1; shift ;;
    --no-output) output=0; shift ;;
    *) echo "$usage" >&2; exit 2 ;;
  esac
done
case "$table" in throughput|methods|lme|plastic|threads|targets|all) ;; *) echo "$usage" >&2; exit 2 ;; esac
bash scripts/install-deps.sh >/dev/null
build=build-bench suffix=""
[ "$native" = ON ] && build=build-bench-native suffix="-native"
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DOTMPM_BUILD_TESTS=OFF -DOTMPM_BUILD_BENCH=ON \
  -DOTMPM_NATIVE="$native" >/dev/null
cmake --build "$build" -j"$(nproc)" --target bench_table bench_step bench_basis bench_machine otmpm_cli >/dev/null
mkdir -p out
args=(--repeat "$repeat" --table "$table" --scaling-csv "out/scaling$suffix.csv" --scaling3d-csv "out/scaling3d$suffix.csv")
cells3=64
if [ "$quick" = 1 ]; then
  args=(--quick --repeat 1 --table "$table" --scaling-csv "out/scaling$suffix.csv" --scaling3d-csv "out/scaling3d$suffix.csv")
  cells3=12
fi
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg); build $build (OTMPM_NATIVE=$native); $(date -u '+%Y-%m-%d %H:%M UTC')"
# otmpm's own OpenMP wait (otmpm/openmp_wait.hpp), whatever the caller set
env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT OMP_NUM_THREADS=2 "$build"/bench/bench_table "${args[@]}"
case "$table" in throughput|all) /usr/bin/python3 scripts/plot_scaling.py "out/scaling$suffix.csv" "out/scaling$suffix.png" ;; esac
if [ "$table" = methods ] || [ "$table" = all ]; then
  /usr/bin/python3 scripts/plot_scaling.py "out/scaling3d$suffix.csv" "out/scaling3d$suffix.png" \
    "3D block, 8 particles per cell, linear basis, fe, mpm, one thread"
  if [ "$output" = 1 ]; then
    echo
    echo "methods table, output row (scripts/bench-output.sh --cells $cells3 --threads 1):"
    bash scripts/bench-output.sh "$build/bin/otmpm" --cells "$cells3" --threads 1
  fi
fi
if [ "$table" = targets ] && [ "$quick" = 0 ]; then
  echo
  echo "roofline (scripts/roofline.sh --build $build --repeat $repeat):"
  bash scripts/roofline.sh --build "$build" --repeat "$repeat" | tee "out/roofline$suffix.md" # its last row: the bytes target
fi
echo "load at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
