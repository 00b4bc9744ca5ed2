#!/usr/bin/env bash
# Runs every row of the issue-7 performance table and prints it (see
# docs/performance.md):  bash scripts/bench.sh [--repeat R] [--native]
#
# Builds build-bench (Release, benchmarks, no tests, the portable default
# flags; with --native build-bench-native with -march=native), runs
# bench/bench_table with OMP_NUM_THREADS=2 (the single-thread rows set one
# thread themselves) and draws the scaling plot into out/scaling.png
# (out/scaling-native.png with --native).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
repeat=5
native=OFF
while [ $# -gt 0 ]; do
  case "$1" in
    --repeat) repeat="$2"; shift 2 ;;
    --native) native=ON; shift ;;
    *) echo "usage: bash scripts/bench.sh [--repeat R] [--native]" >&2; exit 2 ;;
  esac
done
bash scripts/install-deps.sh >/dev/null
build=build-bench suffix=""
[ "$native" = ON ] && build=build-bench-native suffix="-native"
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DOTMPM_BUILD_TESTS=OFF -DOTMPM_BUILD_BENCH=ON \
  -DOTMPM_NATIVE="$native" >/dev/null
cmake --build "$build" -j"$(nproc)" --target bench_table bench_step bench_basis >/dev/null
mkdir -p out
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg); build $build (OTMPM_NATIVE=$native)"
OMP_NUM_THREADS=2 OMP_WAIT_POLICY=passive "$build"/bench/bench_table --repeat "$repeat" --scaling-csv "out/scaling$suffix.csv"
/usr/bin/python3 scripts/plot_scaling.py "out/scaling$suffix.csv" "out/scaling$suffix.png"
