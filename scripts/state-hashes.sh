#!/usr/bin/env bash
# Bit-for-bit regression check of the engine: runs a fixed set of 21 short
# scenes (every integrator, lumped and consistent mass, mpm and ul, 1D/2D/3D,
# every basis family, body force, traction, manufactured solution) with the
# given otmpm binary and prints one SHA-256 per scene over every dataset of
# its result file (frames with all particle fields, probes, energy series).
# Wall times and other attributes are not hashed, nor the /xdmf group (the
# sidecar's Polyvertex connectivity: an index, not state). Two builds give the same
# bits when the two outputs are identical:
#
#   bash scripts/state-hashes.sh build/bin/otmpm > new.txt
#   bash scripts/state-hashes.sh /path/to/old/otmpm > old.txt && diff old.txt new.txt
#
# One thread (results do not depend on it; tests/test_threads.cpp checks that).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bin=$(realpath "${1:?usage: state-hashes.sh OTMPM_BINARY [WORKDIR]}")
work=${2:-$(mktemp -d)}
mkdir -p "$work"
ex="$root/examples"
fields='output.fields=["x","v","stress","strain","density","volume","displacement"]'
finite='output.fields=["x","v","stress","strain","F","density","volume","displacement"]'

# name | scene | --set overrides (space separated, no spaces inside a value)
cases=(
  "dyka_mpm_npc_lme|$ex/dyka.toml|simulation.t_end=3e-5"
  "dyka_mpm_fe_linear|$ex/dyka.toml|simulation.t_end=3e-5 simulation.integrator=fe basis.kind=linear"
  "dyka_mpm_musl_ugimp|$ex/dyka.toml|simulation.t_end=3e-5 simulation.integrator=musl basis.kind=ugimp body.bar.placement=cell_centres"
  "dyka_mpm_npc_bspline2_consistent|$ex/dyka.toml|simulation.t_end=2e-5 simulation.mass=consistent basis.kind=bspline2"
  "dyka_mpm_fe_maxent|$ex/dyka.toml|simulation.t_end=2e-5 simulation.integrator=fe basis.kind=maxent"
  "dyka_ul_npc_lme|$ex/dyka.toml|simulation.t_end=3e-5 simulation.mode=ul"
  "dyka_ul_otm_lme|$ex/dyka.toml|simulation.t_end=3e-5 simulation.mode=ul simulation.integrator=otm"
  "dyka_ul_musl_linear|$ex/dyka.toml|simulation.t_end=3e-5 simulation.mode=ul simulation.integrator=musl basis.kind=linear"
  "dyka_ul_unified_bspline2|$ex/dyka.toml|simulation.t_end=3e-5 simulation.mode=ul simulation.integrator=unified basis.kind=bspline2"
  "dyka2d_mpm_npc_lme|$ex/dyka_2d.toml|simulation.t_end=2e-5"
  "dyka3d_mpm_fe_lme|$ex/dyka_3d.toml|simulation.t_end=1e-5 simulation.integrator=fe"
  "dyka3d_ul_npc_linear|$ex/dyka_3d.toml|simulation.t_end=1e-5 simulation.mode=ul basis.kind=linear"
  "fixed_bar_mpm_fe_linear|$ex/fixed_bar.toml|simulation.t_end=3e-4"
  "fixed_bar_ul_otm_linear|$ex/fixed_bar.toml|simulation.t_end=3e-4 simulation.mode=ul simulation.integrator=otm"
  "fixed_bar_mpm_npc_bspline3_consistent|$ex/fixed_bar.toml|simulation.t_end=3e-4 simulation.integrator=npc basis.kind=bspline3 simulation.mass=consistent"
  "traction_bar_mpm_neohooke|$ex/traction_bar.toml|simulation.t_end=0.05 $finite"
  "traction_bar_ul_unified|$ex/traction_bar.toml|simulation.t_end=0.05 simulation.mode=ul simulation.integrator=unified basis.kind=bspline2 $finite"
  "mms_plate_ul_otm_maxent|$ex/mms_plate.toml|simulation.t_end=5e-4 basis.kind=maxent simulation.integrator=otm $finite"
  "andersen_mpm_npc_lme_ramp|$ex/andersen_block.toml|simulation.t_end=1.0"
  "plate_impact_mpm_fe_perturbed|$ex/plate_impact.toml|simulation.t_end=0.2 simulation.integrator=fe grid.kind=perturbed grid.perturbation=0.2 grid.upper=[56.0,52.0] grid.cells=[56,54] body.plate.lower=[1.0,0.0] body.plate.upper=[51.0,50.0]"
  "andersen_ul_musl_bspline2|$ex/andersen_block.toml|simulation.t_end=1.0 simulation.mode=ul simulation.integrator=musl basis.kind=bspline2"
)

for c in "${cases[@]}"; do
  IFS='|' read -r name scene sets <<<"$c"
  args=()
  for s in $sets; do args+=(--set "$s"); done
  case "$sets" in *output.fields*) ;; *) args+=(--set "$fields") ;; esac
  out="$work/$name.h5"
  status=0
  OMP_NUM_THREADS=1 "$bin" run "$scene" --quiet --out "$out" --set output.every=0 "${args[@]}" >/dev/null 2>&1 || status=$?
  hash=$(/usr/bin/python3 - "$out" <<'EOF'
import hashlib, sys, h5py
h = hashlib.sha256()
def visit(name, obj):
    if isinstance(obj, h5py.Dataset) and not name.startswith(("x3", "xdmf/")) and not name.endswith("/x3"):
        h.update(name.encode()); h.update(obj[()].tobytes())
with h5py.File(sys.argv[1], "r") as f:
    f.visititems(visit)
print(h.hexdigest()[:16])
EOF
)
  echo "$name exit=$status $hash"
done
