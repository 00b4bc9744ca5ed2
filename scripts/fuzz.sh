#!/usr/bin/env bash
# Fuzzes the scene reader with libFuzzer (clang from Debian), ASan and UBSan.
#
#   bash scripts/fuzz.sh [SECONDS]     (default 60)
#
# Builds build-fuzz/ (clang-14, OTMPM_FUZZ=ON: only the library and the two
# targets) and runs fuzz/fuzz_scene.cpp (scene text) for 3/4 of SECONDS and
# fuzz/fuzz_set.cpp (--set overrides) for the rest, each with the dictionary
# fuzz/scene.dict. Seeds: every examples/**/*.toml and tests/scenes/**/*.toml
# (copied into build-fuzz/seeds/ on each run) and fuzz/set.seeds; what the
# fuzzer learns is kept in build-fuzz/corpus/ for the next run.
# A finding - a crash, a sanitizer report, an input taking more than 5 s, more
# than 2 GB of memory, or an exception other than an InputError naming the
# file or --set key - makes the script print the saved input and exit 1.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
seconds=${1:-60}
build=${OTMPM_FUZZ_BUILD_DIR:-$root/build-fuzz}
cd "$root"

pkgs=(clang-14 libclang-rt-14-dev)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# OpenMP off: clang would need libomp, and the reader is serial anyway.
CC=clang-14 CXX=clang++-14 cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DOTMPM_FUZZ=ON \
  -DOTMPM_OPENMP=OFF -DOTMPM_WERROR=ON -DOTMPM_BUILD_TESTS=OFF -DOTMPM_BUILD_BENCH=OFF >/dev/null
cmake --build "$build" -j2 --target fuzz_scene fuzz_set

seeds=$build/seeds
rm -rf "$seeds"
mkdir -p "$seeds/fuzz_scene" "$seeds/fuzz_set" "$build/corpus/fuzz_scene" "$build/corpus/fuzz_set" "$build/findings"
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
  local target=$1 time=$2
  echo "== $target for $time s"
  "$build/fuzz/$target" "$build/corpus/$target" "$seeds/$target" -dict=fuzz/scene.dict \
    -max_total_time="$time" -timeout=5 -rss_limit_mb=2048 -print_final_stats=1 -print_funcs=0 \
    -artifact_prefix="$build/findings/$target-"
}

scene_time=$(( seconds * 3 / 4 ))
status=0
run fuzz_scene "$(( scene_time > 0 ? scene_time : 1 ))" || status=$?
if [ "$status" -eq 0 ]; then
  run fuzz_set "$(( seconds - scene_time > 0 ? seconds - scene_time : 1 ))" || status=$?
fi
if [ "$status" -ne 0 ]; then
  echo "fuzz: FINDING (libFuzzer exit status $status); saved inputs:" >&2
  ls -t "$build"/findings/* 2>/dev/null | head -5 >&2
  echo "reproduce: $build/fuzz/<target> <input>" >&2
  exit 1
fi
echo "fuzz: no finding in $seconds s"
