#!/bin/bash
# A SLURM batch job for a distributed otmpm run. Copy it, set the #SBATCH
# lines for your cluster and your scene, then submit:
#
#     sbatch --export=ALL,SCENE=big.toml,OUT=big.h5 scripts/slurm-job.sh
#
# What it does, in order:
#  1. gives each rank its share of the node's memory as its limit
#     (simulation.memory_limit: the job's memory per node over the ranks per
#     node; without it every rank would count on the whole node's memory);
#  2. `otmpm run --check` on the job's own ranks: the decomposition, each
#     rank's particles, nodes and memory, and a calibrated step time, before
#     anything is allocated - a scene the ranks cannot hold stops here, in
#     seconds, with exit 2;
#  3. the run, writing a checkpoint every CHECKPOINT_EVERY steps; or, when
#     the job was requeued and OUT's checkpoint exists, its continuation
#     (`otmpm run --restart`, on whatever rank count this job has).
# SLURM sends SIGTERM to the ranks 10 minutes before the time limit
# (--signal below): otmpm ends the step it is in, writes a last checkpoint
# and exits 143; with REQUEUE=1 the job then requeues itself to continue.
#
# Plan a job before asking for it, on any machine, without starting ranks:
#     otmpm run --check --ranks 1000 big.toml --set simulation.memory_limit=4e9
#
#SBATCH --job-name=otmpm
#SBATCH --nodes=2
#SBATCH --ntasks-per-node=4
#SBATCH --cpus-per-task=8
#SBATCH --time=12:00:00
#SBATCH --signal=TERM@600
#SBATCH --open-mode=append
set -euo pipefail

: "${SCENE:?set SCENE to the scene file (sbatch --export=ALL,SCENE=big.toml ...)}"
OTMPM=${OTMPM:-otmpm}
OUT=${OUT:-$(basename "${SCENE%.toml}").h5}
CHECKPOINT_EVERY=${CHECKPOINT_EVERY:-1000}
REQUEUE=${REQUEUE:-0}
# The launcher of the ranks: srun with OpenMPI's PMIx plug-in; some sites
# use `mpirun` inside the allocation instead (LAUNCH=mpirun).
LAUNCH=${LAUNCH:-srun --mpi=pmix}

export OMP_NUM_THREADS=${SLURM_CPUS_PER_TASK:-1}
export OMP_PLACES=${OMP_PLACES:-cores} OMP_PROC_BIND=${OMP_PROC_BIND:-close}

# 1. each rank's memory limit, in bytes (SLURM_MEM_PER_NODE is in MB; 0 or
#    unset: the whole node, shared by its ranks)
sets=(--set "output.checkpoint_every=$CHECKPOINT_EVERY")
per_node_mb=${SLURM_MEM_PER_NODE:-0}
if [[ $per_node_mb == 0 ]]; then
  per_node_mb=$(awk '/^MemTotal:/ {print int($2 / 1024)}' /proc/meminfo)
fi
ranks_per_node=${SLURM_NTASKS_PER_NODE:-1}
ranks_per_node=${ranks_per_node%%(*} # "4(x2)" on a heterogeneous job: the first figure
sets+=(--set "simulation.memory_limit=$((per_node_mb * 1000000 / ranks_per_node))")

checkpoint="${OUT%.h5}.checkpoint.h5"
status=0
if [[ -f $checkpoint ]]; then
  # 3'. a requeued job: continue from the last checkpoint
  echo "otmpm job: continuing from $checkpoint on ${SLURM_NTASKS:-?} ranks"
  $LAUNCH "$OTMPM" run --restart "$checkpoint" --quiet || status=$?
else
  # 2. the plan on these ranks, nothing allocated
  $LAUNCH "$OTMPM" run --check "$SCENE" --out "$OUT" "${sets[@]}"
  # 3. the run
  $LAUNCH "$OTMPM" run "$SCENE" --out "$OUT" "${sets[@]}" --quiet || status=$?
fi

if [[ $status == 143 && $REQUEUE == 1 && -n ${SLURM_JOB_ID:-} ]]; then
  echo "otmpm job: stopped at the time limit; requeued to continue from $checkpoint"
  scontrol requeue "$SLURM_JOB_ID"
fi
exit "$status"
