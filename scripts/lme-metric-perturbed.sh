#!/usr/bin/env bash
# Usage (from the repository root): bash scripts/lme-metric-perturbed.sh build/bin/otmpm [GAMMA_LME]
# node_spacing vs isotropic LME on perturbed grids: MMS plate, ul, npc, lumped mass
bin=$1
for cells in 16 32; do
for p in 0.0 0.1 0.2 0.3; do
for m in isotropic node_spacing; do
  kind=perturbed; [ "$p" = "0.0" ] && kind=cartesian
  out=$($bin run examples/mms_plate.toml --set basis.kind=lme --set simulation.integrator=npc \
    --set simulation.mass=lumped --set grid.kind=$kind --set grid.perturbation=$p --set "grid.cells=[$cells,$cells]" \
    --set basis.metric=$m --set basis.gamma_lme=${2:-4} --set output.file=mms_${cells}_${p}_$m.h5 2>&1 | grep -E "^(ok|UNSTABLE|otmpm: unstable)" | tr '\n' ' ')
  echo "$cells $p $m | $out"
done; done; done
