#!/usr/bin/env bash
# Runs every row of the issue-7 performance table and prints it (see
# docs/performance.md):  bash scripts/bench.sh [--repeat R] [--native]
#
# Builds build-bench (Release, benchmarks, no tests), runs bench/bench_table
# with OMP_NUM_THREADS=2 (the single-thread rows set one thread themselves)
# and draws the scaling plot into out/scaling.png.
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
cmake -S . -B build-bench -DCMAKE_BUILD_TYPE=Release -DOTMPM_BUILD_TESTS=OFF -DOTMPM_BUILD_BENCH=ON \
  -DOTMPM_NATIVE="$native" >/dev/null
cmake --build build-bench -j"$(nproc)" --target bench_table bench_step bench_basis >/dev/null
mkdir -p out
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
OMP_NUM_THREADS=2 OMP_WAIT_POLICY=passive build-bench/bench/bench_table --repeat "$repeat" --scaling-csv out/scaling.csv
/usr/bin/python3 scripts/plot_scaling.py out/scaling.csv out/scaling.png
