#!/bin/bash
# scripts/slurm-job.sh run as SLURM runs a batch script (its SLURM_*
# variables set, 2 ranks on one node) with mpiexec as the launcher: the
# plan printed on the job's ranks with each rank's share of the node's
# memory as its limit, the run with its checkpoints, and a requeued job
# continuing from the checkpoint; a job of one rank with two threads keeps a
# CPU per thread under the script's thread binding.
# Usage: check_slurm_job.sh OTMPM_BINARY SOURCE_DIR MPIEXEC WORK_DIR PYTHON3 (with h5py)
set -euo pipefail
otmpm=$1 src=$2 mpiexec=$3 work=$4 python=$5
rm -rf "$work" && mkdir -p "$work" && cd "$work"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
export SLURM_JOB_ID=1 SLURM_NTASKS=2 SLURM_NTASKS_PER_NODE=2 SLURM_CPUS_PER_TASK=1 SLURM_MEM_PER_NODE=3000
export OTMPM=$otmpm LAUNCH="$mpiexec -q -np 2" SCENE=$src/examples/dyka_2d.toml OUT=dyka.h5 CHECKPOINT_EVERY=100

fail() { echo "check_slurm_job: $*" >&2; exit 1; }

out=$(bash "$src/scripts/slurm-job.sh" 2>&1) || fail "the job failed: $out"
grep -q "ok (the scene reads and divides over 2 ranks" <<<"$out" || fail "no plan on the job's ranks: $out"
grep -q "limit 1.5 GB per rank" <<<"$out" || fail "the rank's memory limit is not its share of the node's: $out"
[[ -f dyka.h5 && -f dyka.checkpoint.h5 ]] || fail "no result file or checkpoint: $(ls)"
ranks=$("$python" -c "import h5py; print(int(h5py.File('dyka.h5','r').attrs['ranks']))")
[[ $ranks == 2 ]] || fail "the result file was written by $ranks ranks, not 2"

out=$(bash "$src/scripts/slurm-job.sh" 2>&1) || fail "the requeued job failed: $out"
grep -q "continuing from dyka.checkpoint.h5" <<<"$out" || fail "the requeued job did not continue: $out"
status=$("$python" -c "import h5py; s=h5py.File('dyka.h5','r').attrs['status']; print(s.decode() if isinstance(s, bytes) else s)")
[[ $status == ok ]] || fail "the continued result file's status is '$status'"
# A job of one rank with two CPUs: the job script binds the threads
# (OMP_PLACES=cores OMP_PROC_BIND=close); both threads must keep a CPU each
# (the plan's line), not share the first place.
if (( $(nproc) >= 2 )); then
  rm -f dyka.h5 dyka.checkpoint.h5
  out=$(SLURM_NTASKS=1 SLURM_NTASKS_PER_NODE=1 SLURM_CPUS_PER_TASK=2 LAUNCH="$mpiexec -q -np 1 --bind-to none" \
        bash "$src/scripts/slurm-job.sh" 2>&1) || fail "the two-thread job failed: $out"
  grep -q "threads    2 OpenMP threads on [2-9][0-9]* CPUs this process may use$" <<<"$out" ||
    fail "the two-thread job's rank does not have a CPU per thread: $out"
fi
echo "check_slurm_job: ok"
