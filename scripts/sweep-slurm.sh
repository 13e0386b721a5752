#!/usr/bin/env bash
# A sweep as a Slurm job array: array task i of N runs shard i/N of the sweep into
# OUT_DIR/shard-i.jsonl (substep sweep --shard); merge once every task is done:
#   sbatch --array=1-4 scripts/sweep-slurm.sh SPEC.json OUT_DIR
#   build/app/substep sweep merge OUT_DIR/shard-*.jsonl -o OUT_DIR/all.jsonl
# A task that is requeued resumes its shard (runs already in its file are skipped; its log says
# how many). $SUBSTEP names the substep program (default: build/app/substep in the submit folder,
# else substep on PATH, as installed). tests/sweeps/sweep_cluster_test.sh runs this under Slurm.
#SBATCH --job-name=substep-sweep
#SBATCH --array=1-4
#SBATCH --ntasks=1
#SBATCH --cpus-per-task=1
#SBATCH --time=02:00:00
#SBATCH --output=substep-sweep-%A_%a.log
set -euo pipefail
spec=${1:?usage: sbatch --array=1-N scripts/sweep-slurm.sh SPEC.json OUT_DIR}
out=${2:?usage: sbatch --array=1-N scripts/sweep-slurm.sh SPEC.json OUT_DIR}
: "${SLURM_ARRAY_TASK_ID:?not in a Slurm job array: submit with sbatch --array=1-N (or set SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT)}"
count=${SLURM_ARRAY_TASK_COUNT:?SLURM_ARRAY_TASK_COUNT is not set}
index=$((SLURM_ARRAY_TASK_ID - ${SLURM_ARRAY_TASK_MIN:-1} + 1))  # arrays may start at 0
substep=${SUBSTEP:-${SLURM_SUBMIT_DIR:-.}/build/app/substep}
[[ -n ${SUBSTEP:-} || -x $substep ]] || substep=substep
mkdir -p "$out"
exec "$substep" sweep "$spec" --shard "$index/$count" -o "$out/shard-$index.jsonl"
