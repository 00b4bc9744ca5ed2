#!/usr/bin/env bash
# The step of each performance target against the limits of one core
# (docs/performance.md, "Against the machine"), and after the table the
# bytes target's row (the 2D block's bytes beyond L1 against 400):
#
#   bash scripts/roofline.sh [--build DIR] [--repeat R]
#
# DIR must hold bench/bench_machine, bench/bench_step, bench/bench_one_pass
# and bin/otmpm; by
# default build-bench, configured and built here as scripts/bench.sh does. One thread
# throughout. For every case:
# - particle-steps/s: the median of R runs (bench_step's own median, or the
#   `otmpm run` line of the Taylor bar);
# - instructions and bytes per particle-step: cachegrind (one thread, its
#   own D1 of this machine and a last level set to 32 MB, 16-way), the
#   difference of two runs of S1 and S2 steps over the particle-steps
#   between them, so the set-up drops out. "beyond L1": (D1 read + write
#   misses) x 64 B, what the step streams from outside the first-level
#   cache; "beyond L3": the last level's misses x 64 B;
# - instructions per cycle: particle-steps/s x instructions per
#   particle-step over bench_machine's clock (to compare with its max_ipc,
#   the most simple adds the core retires per cycle), and the beyond-L1
#   bytes per second over its triad rate (an upper bound of the share of
#   the memory bandwidth: some of those lines come from L2 and L3).
# The cachegrind runs use smaller blocks than the throughput runs where the
# latter would take minutes under valgrind; per particle-step they count the
# same instructions, and the same beyond-L1 lines once the particles do not
# fit in L1.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=$root/build-bench
repeat=5
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$(cd "$2" && pwd); shift 2 ;;
    --repeat) repeat=$2; shift 2 ;;
    *) echo "usage: bash scripts/roofline.sh [--build DIR] [--repeat R]" >&2; exit 2 ;;
  esac
done
if [ "$build" = "$root/build-bench" ]; then # configured and built as scripts/bench.sh does
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DOTMPM_BUILD_TESTS=OFF -DOTMPM_BUILD_BENCH=ON >/dev/null
  cmake --build "$build" -j"$(nproc)" --target bench_machine bench_step bench_one_pass otmpm_cli >/dev/null
fi
for exe in bench/bench_machine bench/bench_step bench/bench_one_pass bin/otmpm; do
  [ -x "$build/$exe" ] || { echo "roofline.sh: no $build/$exe (build the bench_machine, bench_step, bench_one_pass and otmpm_cli targets)" >&2; exit 2; }
done
command -v valgrind >/dev/null || { echo "roofline.sh: valgrind is not installed" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
taylor="$root/examples/taylor_bar/full_cylinder.toml"
taylor_particles=16848 # the particles `otmpm run` seeds for that scene in `mpm` (its header says so)

"$build/bench/bench_machine" --repeat 3 > "$work/machine"
machine() { sed -n "s/^$1 //p" "$work/machine"; }
triad=$(machine triad_gb_s)
clock=$(machine clock_ghz)
echo "one core: triad $triad GB/s, clock $clock GHz, at most $(machine max_ipc) adds per cycle"

# cachegrind_summary CMD...: "Ir D1mr D1mw DLmr DLmw" of one run
cachegrind_summary() {
  valgrind --tool=cachegrind --cache-sim=yes --LL=33554432,16,64 --cachegrind-out-file="$work/cg" "$@" \
    >"$work/stdout" 2>"$work/log"
  awk '/^summary:/ {print $2, $6, $9, $7, $10}' "$work/cg"
}

# per_particle_step SUM1 SUM2 PARTICLE_STEPS: "instructions beyond_L1 beyond_L3" per particle-step
per_particle_step() {
  awk -v a="$1" -v b="$2" -v n="$3" 'BEGIN {
    split(a, x, " "); split(b, y, " ")
    printf "%.0f %.0f %.0f", (y[1] - x[1]) / n, 64 * (y[2] + y[3] - x[2] - x[3]) / n, 64 * (y[4] + y[5] - x[4] - x[5]) / n
  }'
}

# row NAME RATE "INSTR L1B L3B"
row() {
  read -r instr l1 l3 <<<"$3"
  awk -v name="$1" -v rate="$2" -v i="$instr" -v l1="$l1" -v l3="$l3" -v ghz="$clock" -v tr="$triad" 'BEGIN {
    printf "| %s | %.3g | %d | %.2f | %d | %d | %.2f |\n", name, rate, i, rate * i / (ghz * 1e9), l1, l3, rate * l1 / (tr * 1e9)
  }'
}

# block CELLS_RATE CELLS_CG S1 S2 ARGS...: the row of a bench_step block
block() {
  local name=$1 cells=$2 cells_cg=$3 s1=$4 s2=$5 dim=$6
  shift 6
  local rate particles sum1 sum2
  rate=$("$build/bench/bench_step" --dim "$dim" --cells "$cells" --steps 10 --repeat "$repeat" "$@" |
    sed -n 's/.*median \([0-9.e+]*\) particle-steps.*/\1/p')
  particles=$(( dim == 3 ? 8 * cells_cg ** 3 : 4 * cells_cg ** 2 ))
  sum1=$(cachegrind_summary "$build/bench/bench_step" --dim "$dim" --cells "$cells_cg" --steps "$s1" --repeat 1 "$@")
  sum2=$(cachegrind_summary "$build/bench/bench_step" --dim "$dim" --cells "$cells_cg" --steps "$s2" --repeat 1 "$@")
  row "$name" "$rate" "$(per_particle_step "$sum1" "$sum2" $(( (s2 - s1) * particles )))"
}

# one_pass CELLS_RATE CELLS_CG S1 S2 BATCH [LANES]: the row of bench_one_pass's model of the 2D linear fe
# step (one sweep over the particles, no basis table, its stages BATCH particles at a time, LANES particles
# per instruction: an upper bound of what fusing the passes gives)
one_pass() {
  local rate sum1 sum2 lanes=${6:-1}
  local args=(--repeat 1 --check 1 --engine 0 --batch "$5" --lanes "$lanes")
  rate=$("$build/bench/bench_one_pass" --cells "$1" --steps 10 --repeat "$repeat" --engine 0 --batch "$5" \
    --lanes "$lanes" | sed -n 's/.*rounds: \([0-9.e+]*\) particle-steps.*/\1/p')
  sum1=$(cachegrind_summary "$build/bench/bench_one_pass" --cells "$2" --steps "$3" "${args[@]}")
  sum2=$(cachegrind_summary "$build/bench/bench_one_pass" --cells "$2" --steps "$4" "${args[@]}")
  row "2D block, one-pass model of linear fe, batch $5, lanes $lanes (bench_one_pass; rate: 10^6 particles; counts: 200^2 cells)" \
    "$rate" "$(per_particle_step "$sum1" "$sum2" $(( ($4 - $3) * 4 * $2 ** 2 )))"
}

# taylor_cachegrind T_END: "summary steps" of a cachegrind run of the Taylor bar to T_END
taylor_cachegrind() {
  local sum
  sum=$(cachegrind_summary "$build/bin/otmpm" run "$taylor" --threads 1 --set output.every=0 \
    --set simulation.t_end="$1" --out "$work/taylor.h5" --force)
  echo "$sum $(sed -n 's/^ok: .* \([0-9]*\) steps, .*/\1/p' "$work/stdout")"
}

echo
echo "| case (one core) | particle-steps/s | instructions per particle-step | instructions per cycle | bytes beyond L1 | bytes beyond L3 | beyond-L1 bytes/s of the triad rate |"
echo "|---|---|---|---|---|---|---|"
block "2D block, linear fe (rate: 10^6 particles; counts: 200^2 cells)" 500 200 2 6 2 --basis linear --integrator fe
bytes_l1=$l1 bytes_l3=$l3 # row() leaves the row's bytes in l1 and l3: the bytes target's row, after the table
one_pass 500 200 2 6 1
one_pass 500 200 2 6 32
grep -qw avx2 /proc/cpuinfo && one_pass 500 200 2 6 32 4 # four particles per instruction: AVX2 only
block "2D block 200^2, LME gamma_lme = 3 npc" 200 200 2 4 2 --basis lme --integrator npc
block "3D block, linear fe (rate: 64^3 cells; counts: 24^3)" 64 24 2 4 3 --basis linear --integrator fe
block "3D block, LME gamma_lme = 3 npc (rate: 32^3 cells; counts: 16^3)" 32 16 2 4 3 --basis lme --integrator npc
rates=()
for _ in $(seq "$repeat"); do
  rates+=("$("$build/bin/otmpm" run "$taylor" --threads 1 --set output.every=0 --out "$work/taylor.h5" --force 2>/dev/null |
    sed -n 's/.* \([0-9.e+]*\) particle-steps\/s.*/\1/p')")
done
rate=$(printf '%s\n' "${rates[@]}" | sort -g | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}')
read -r i1 a1 b1 c1 d1 n1 <<<"$(taylor_cachegrind 1e-6)"
read -r i2 a2 b2 c2 d2 n2 <<<"$(taylor_cachegrind 3e-6)"
row "Taylor bar, full cylinder, j2, wall, npc linear" "$rate" \
  "$(per_particle_step "$i1 $a1 $b1 $c1 $d1" "$i2 $a2 $b2 $c2 $d2" $(( (n2 - n1) * taylor_particles )))"
echo
echo "| target figure | target | measured | met |"
echo "|---|---|---|---|"
echo "| 2D block, linear fe: bytes per particle-step beyond L1 (beyond L3) | <= 400 | $bytes_l1 ($bytes_l3) | $([ "$bytes_l1" -le 400 ] && echo met || echo "**not met**") |"
