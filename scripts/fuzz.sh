#!/usr/bin/env bash
# Fuzzes the scene reader and whole runs with libFuzzer (clang from Debian),
# ASan and UBSan.
#
#   bash scripts/fuzz.sh [SECONDS] [RUN_SECONDS] [PYTHON_SECONDS]     (defaults 60, 30 and 20)
#
# Installs clang-14 and libclang-rt-14-dev if missing, builds build-fuzz/
# (OTMPM_FUZZ=ON: the library, the otmpm command and the three targets) and
# runs fuzz/fuzz_scene.cpp (scene text) for 3/4 of SECONDS and
# fuzz/fuzz_set.cpp (--set overrides) for the rest, each with the dictionary
# fuzz/scene.dict, then fuzz/fuzz_run.cpp (short scenes run end to end by the
# instrumented otmpm in a temporary directory, with fuzzed output, checkpoint
# and probe settings) for RUN_SECONDS. Seeds: every examples/**/*.toml and
# tests/scenes/**/*.toml (copied into build-fuzz/seeds/ on each run) and
# fuzz/set.seeds; what the fuzzer learns is kept in build-fuzz/corpus/ for the
# next run. Then, when the Python package of the ordinary build is there
# (build/python, or $OTMPM_BUILD_DIR/python: scripts/test.sh builds it), the
# Python API fuzzer python/tests/fuzz_api.py for PYTHON_SECONDS with a new
# seed (random call sequences on Scene, Simulation, otmpm.results and
# otmpm.basis; the pytest python/tests/test_fuzz.py runs it with fixed seeds).
# A finding - a crash, a sanitizer report, a leak, an input taking more than
# 5 s (60 s for fuzz_run) or more than 2 GB of memory, an exception other than
# an InputError, an InputError not starting with FILE:LINE: or --set KEY:, a
# resolved scene text that does not read back to itself; for fuzz_run an exit
# status outside {0, 1, 2}, a signal, a result file unreadable or still
# "running", a file otmpm was not told to replace changed, a lock file left
# behind or a file outside the temporary directory touched - makes the script
# print the saved input and exit 1.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
seconds=${1:-60}
run_seconds=${2:-30}
python_seconds=${3:-20}
build=${OTMPM_FUZZ_BUILD_DIR:-$root/build-fuzz}
cd "$root"

bash "$root/scripts/install-deps.sh" clang-14 libclang-rt-14-dev

# OpenMP off: clang would need libomp, and the reader is serial anyway.
CC=clang-14 CXX=clang++-14 cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" -DOTMPM_FUZZ=ON \
  -DOTMPM_OPENMP=OFF -DOTMPM_WERROR=ON -DOTMPM_BUILD_TESTS=OFF -DOTMPM_BUILD_BENCH=OFF >/dev/null
cmake --build "$build" -j2 --target fuzz_scene fuzz_set fuzz_run otmpm_cli

seeds=$build/seeds
rm -rf "$seeds"
mkdir -p "$seeds/fuzz_scene" "$seeds/fuzz_set" "$seeds/fuzz_run" "$build/corpus/fuzz_scene" "$build/corpus/fuzz_set" \
  "$build/corpus/fuzz_run" "$build/findings"
for n in 0 1 2 3 4 5 6 7; do head -c 64 /dev/urandom > "$seeds/fuzz_run/seed_$n"; done
find examples tests/scenes -name '*.toml' | while read -r f; do cp "$f" "$seeds/fuzz_scene/$(echo "$f" | tr / _)"; done
n=0
while IFS= read -r line; do
  printf '%s' "$line" > "$seeds/fuzz_set/seed_$n"
  n=$((n + 1))
done < fuzz/set.seeds

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export OMP_NUM_THREADS=1

# run TARGET SECONDS: fuzzes one target; returns libFuzzer's exit status.
run() {
  local target=$1 secs=$2 options=(-dict=fuzz/scene.dict -timeout=5)
  [ "$target" = fuzz_run ] && options=(-timeout=60 -max_len=256)
  echo "== $target for $secs s"
  "$build/fuzz/$target" "$build/corpus/$target" "$seeds/$target" "${options[@]}" \
    -max_total_time="$secs" -rss_limit_mb=2048 -print_final_stats=1 -print_funcs=0 \
    -artifact_prefix="$build/findings/$target-"
}

scene_time=$(( seconds * 3 / 4 ))
set_time=$(( seconds - scene_time ))
status=0
for target in fuzz_scene fuzz_set fuzz_run; do
  case $target in
    fuzz_scene) secs=$scene_time ;;
    fuzz_set) secs=$set_time ;;
    *) secs=$run_seconds ;;
  esac
  run "$target" "$(( secs > 0 ? secs : 1 ))" || status=$?
  if [ "$status" -ne 0 ]; then
    input=$(ls -t "$build"/findings/"$target"-* 2>/dev/null | head -1)
    echo "fuzz: FINDING in $target (libFuzzer exit status $status): ${input:-no input saved}" >&2
    echo "reproduce: OTMPM_FUZZ_VERBOSE=1 $build/fuzz/$target ${input:-INPUT}" >&2
    exit 1
  fi
done
package=${OTMPM_BUILD_DIR:-$root/build}/python
if [ -f "$package/otmpm/__init__.py" ]; then
  seed=$(od -An -N4 -tu4 /dev/urandom | tr -d ' ')
  echo "== Python API for $python_seconds s (seed $seed)"
  log=$build/findings/fuzz_api-$seed.log
  if ! PYTHONPATH=$package OTMPM_SOURCE_DIR=$root /usr/bin/python3 python/tests/fuzz_api.py --seed "$seed" \
      --seconds "$python_seconds" >"$log" 2>&1; then
    tail -20 "$log" >&2
    echo "fuzz: FINDING in the Python API (log: $log)" >&2
    echo "reproduce: PYTHONPATH=$package /usr/bin/python3 python/tests/fuzz_api.py --seed $seed --seconds $python_seconds" >&2
    exit 1
  fi
  tail -1 "$log"
  rm -f "$log"
else
  echo "== Python API: skipped ($package has no otmpm package: build it with scripts/test.sh first)"
fi
echo "fuzz: no finding in $seconds s of the scene reader, $run_seconds s of whole runs and the Python API"
