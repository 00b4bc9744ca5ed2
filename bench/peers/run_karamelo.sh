#!/usr/bin/env bash
# otmpm against Karamelo (github.com/adevaucorbeil/karamelo, updated-
# Lagrangian MPM, MPI-parallel C++) on the same scenes, one core each:
#
#   bash bench/peers/run_karamelo.sh --karamelo PATH [--otmpm PATH] [--repeat R] [--case block|taylor|all]
#
# PATH of --karamelo: Karamelo's executable (built as its install notes say:
# cmake -DCMAKE_BUILD_TYPE=release, which adds -march=native); --otmpm
# defaults to build/bin/otmpm. Cases (the inputs beside this script):
#   block   the 2D block of block_2d.toml (160 000 particles, linear basis,
#           dt 1e-5 s): otmpm `fe` against Karamelo `usl` (both update the
#           stress last), otmpm `musl` against Karamelo `musl`;
#   taylor  the full 3D Taylor bar (examples/taylor_bar/full_cylinder.toml,
#           dt 3.4e-8 s): otmpm `npc` and `musl` against Karamelo `musl`.
# A code's cost per particle-step is the difference of two runs (N1 and N2
# steps) over (N2 - N1) steps and its particles, so the set-up, the output
# and the start of MPI cancel; the runs of the codes alternate, R rounds,
# and the ratio printed is the median of the rounds' ratios. Then both codes
# run the check length once more with a particle dump, and compare_peer.py
# prints the same figures of the two results.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
karamelo="" otmpm="$root/build/bin/otmpm" repeat=5 case=all
while [ $# -gt 0 ]; do
  [ $# -ge 2 ] || { echo "run_karamelo.sh: $1 needs a value" >&2; exit 2; }
  case "$1" in
    --karamelo) karamelo=$2 ;;
    --otmpm) otmpm=$2 ;;
    --repeat) repeat=$2 ;;
    --case) case=$2 ;;
    *) echo "run_karamelo.sh: unknown option $1" >&2; exit 2 ;;
  esac
  shift 2
done
[ -x "$karamelo" ] || { echo "run_karamelo.sh: give Karamelo's executable with --karamelo" >&2; exit 2; }
[ -x "$otmpm" ] || { echo "run_karamelo.sh: no otmpm executable $otmpm (--otmpm)" >&2; exit 2; }
[[ "$repeat" =~ ^[1-9][0-9]*$ ]] || { echo "run_karamelo.sh: --repeat must be a whole number >= 1" >&2; exit 2; }
case "$case" in block|taylor|all) ;; *) echo "run_karamelo.sh: --case is block, taylor or all" >&2; exit 2 ;; esac
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMP_NUM_THREADS=1

# seconds CMD...: the wall time of one run of CMD (its output discarded)
seconds() {
  local t0 t1
  t0=$(date +%s.%N)
  "$@" >"$work/log" 2>&1 || { echo "run_karamelo.sh: failed: $*" >&2; tail -5 "$work/log" >&2; exit 1; }
  t1=$(date +%s.%N)
  awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.6f\n", b - a }'
}

# product A B: A x B, printed to 17 digits
product() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.17g\n", a * b }'; }

# karamelo_input FILE SCHEME STEPS: Karamelo's input with its placeholders set
karamelo_input() {
  sed -e "s/SCHEME/$2/g" -e "s/STEPS/$3/g" "$here/karamelo/$1" >"$work/k_$3.mpm"
  echo "$work/k_$3.mpm"
}

# karamelo_run FILE SCHEME STEPS: seconds of one Karamelo run, in $work/k
karamelo_run() {
  local input
  input=$(karamelo_input "$1" "$2" "$3")
  mkdir -p "$work/k"
  (cd "$work/k" && seconds "$karamelo" -i "$input")
}

# otmpm_run SCENE INTEGRATOR DT STEPS: seconds of one otmpm run
otmpm_run() {
  seconds "$otmpm" run "$1" "${extra[@]}" --threads 1 --quiet --set simulation.integrator="$2" --set simulation.dt="$3" \
    --set simulation.t_end="$(product "$3" "$4")" --set output.every=1 --out "$work/o.h5" --force
}

# karamelo_particles: the particle count Karamelo printed in its last run
karamelo_particles() {
  sed -n 's/.*[Ss]olid.* \([0-9][0-9]*\) particles.*/\1/p; s/^np_local *= *\([0-9]*\).*/\1/p' "$work/log" | head -1
}

# compare NAME SCENE PARTICLES DT N1 N2 FILE OURS THEIRS: R rounds of the
# four runs, the medians per particle-step and the median ratio
compare() {
  local name=$1 scene=$2 particles=$3 dt=$4 n1=$5 n2=$6 file=$7 ours=$8 theirs=$9 r o1 o2 k1 k2 kp
  : >"$work/rounds"
  for ((r = 0; r < repeat; r++)); do
    o1=$(otmpm_run "$scene" "$ours" "$dt" "$n1")
    o2=$(otmpm_run "$scene" "$ours" "$dt" "$n2")
    k1=$(karamelo_run "$file" "$theirs" "$n1")
    k2=$(karamelo_run "$file" "$theirs" "$n2")
    kp=$(karamelo_particles)
    echo "$o1 $o2 $k1 $k2 ${kp:-$particles}" >>"$work/rounds"
  done
  awk -v name="$name" -v p="$particles" -v steps=$((n2 - n1)) -v ours="$ours" -v theirs="$theirs" '
    function median(a, n,   i, j, t) {
      for (i = 1; i <= n; i++) for (j = i + 1; j <= n; j++) if (a[j] < a[i]) { t = a[i]; a[i] = a[j]; a[j] = t }
      return n % 2 ? a[(n + 1) / 2] : (a[n / 2] + a[n / 2 + 1]) / 2
    }
    { n++; o[n] = p * steps / ($2 - $1); k[n] = $5 * steps / ($4 - $3); q[n] = o[n] / k[n]; kp = $5 }
    END {
      printf "%s: otmpm %s %.3g particle-steps/s (%d particles), Karamelo %s %.3g (%d particles), ratio %.2f (rounds:", \
        name, ours, median(o, n), p, theirs, median(k, n), kp, median(q, n)
      for (i = 1; i <= n; i++) printf " %.2f", o[i] / k[i]
      print ")"
    }' "$work/rounds"
}

# check NAME SCENE DT STEPS FILE OURS THEIRS: both codes once more over
# STEPS with a dump, and compare_peer.py's figures
check() {
  local name=$1 scene=$2 dt=$3 steps=$4 file=$5 ours=$6 theirs=$7 dump
  echo "$name after $steps steps (dt $dt s): otmpm $ours, Karamelo $theirs"
  "$otmpm" run "$scene" "${extra[@]}" --threads 1 --quiet --set simulation.integrator="$ours" --set simulation.dt="$dt" \
    --set simulation.t_end="$(product "$dt" "$steps")" --set 'output.fields=["x", "v", "stress"]' \
    --set output.every=1 --out "$work/check.h5" --force >/dev/null
  rm -rf "$work/k" && karamelo_run "$file" "$theirs" "$steps" >/dev/null
  dump=$(ls "$work"/k/dump_p."$steps".LAMMPS* | head -1)
  case "$dump" in *.gz) gunzip -c "$dump" >"$work/dump.txt"; dump="$work/dump.txt" ;; esac
  /usr/bin/python3 "$here/compare_peer.py" "$name" "$work/check.h5" "$dump"
}

echo "otmpm $("$otmpm" --version 2>/dev/null | head -1); Karamelo $karamelo; $(nproc --all) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
# scene NAME SCENE PARTICLES DT N1 N2 CHECK_STEPS OURS1 THEIRS1 OURS2 THEIRS2:
# the two comparisons of a scene (the scene's Karamelo input is NAME's) and
# the check with the first pair of integrators
scene() {
  compare "$1" "$2" "$3" "$4" "$5" "$6" "$1".mpm "$8" "$9"
  compare "$1" "$2" "$3" "$4" "$5" "$6" "$1".mpm "${10}" "${11}"
  check "${1%%_*}" "$2" "$4" "$7" "$1".mpm "$8" "$9"
}

if [ "$case" != taylor ]; then
  # the particles at the centres of the cell's quarters, where Karamelo seeds them
  extra=(--set body.block.placement='"cell_centres"')
  scene block_2d "$here/block_2d.toml" 160000 1e-5 20 120 300 fe usl musl musl
fi
if [ "$case" != block ]; then
  # the particle volumes as seeded (h^3 / 8, as Karamelo's): the same mass
  extra=(--set body.bar.volume='"seeded"')
  scene taylor_bar "$root/examples/taylor_bar/full_cylinder.toml" 16848 3.4e-8 100 600 2353 musl musl npc musl
fi
