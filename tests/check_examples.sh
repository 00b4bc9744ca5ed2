#!/usr/bin/env bash
# The example drivers do what their header comments say:
#  - example_stepping_loop (a run stepped by hand with a hook and extra
#    frames) gives the errors of `otmpm run` on the same scene: the hook and
#    the extra frames only look at the state;
#  - example_custom_seeding (a spinning disk on rings of particles) keeps its
#    angular momentum to 0.5 % and loses at most 5 % of its kinetic energy
#    in 0.05 s (2.5 turns' worth of 1/8), in mpm and in ul mode.
# usage: check_examples.sh STEPPING_LOOP CUSTOM_SEEDING OTMPM SOURCE_DIR
set -euo pipefail
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive} # the examples do not set it as otmpm does (busy machines)
stepping=$1 seeding=$2 otmpm=$3 src=$4
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
errors() { grep -o 'rms_velocity_error = [^,]*'; }
by_hand=$("$stepping" "$src/examples/dyka.toml" "$tmp/hand.h5" | errors)
by_run=$("$otmpm" run "$src/examples/dyka.toml" --quiet --out "$tmp/run.h5" | errors)
echo "stepping loop: $by_hand; otmpm run: $by_run"
[ -n "$by_hand" ] && [ "$by_hand" = "$by_run" ] || { echo "MISMATCH"; exit 1; }
for mode in mpm ul; do
  out=$("$seeding" 32 "$mode")
  echo "$out"
  echo "$out" | awk '/angular momentum/ {
      gsub(/[(%),]/, " "); L = $8; K = $15;
      if (L < -0.5 || L > 0.5) { print "angular momentum changed by " L "%"; exit 1 }
      if (K < -5 || K > 0) { print "kinetic energy changed by " K "%"; exit 1 } }'
done
