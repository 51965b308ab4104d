#!/bin/bash
# One shard of a vizsim sweep per Slurm array task.
#   sbatch --array=0-(N-1) scripts/slurm-sweep.sh EXPERIMENT.toml OUT_DIR N
# then: vizsim merge OUT_DIR/shard-* --out OUT_DIR/merged
# A node with fewer than the 4 CPUs asked below never runs a task (squeue: PartitionConfig):
# there, override on the command line, e.g. sbatch -c 1 --array=... (scripts/cluster-test.sh).
# A cancelled or failed task resumes when requeued: scontrol requeue JOB_I (it then waits two
# minutes, BeginTime, unless: scontrol update JobId=JOB_I StartTime=now).
#SBATCH --job-name=vizsim-sweep
#SBATCH --cpus-per-task=4
#SBATCH --time=04:00:00
#SBATCH --output=vizsim-sweep-%A_%a.log
set -euo pipefail
EXPERIMENT=${1:?experiment file}
OUT=${2:?output folder}
SHARDS=${3:?number of shards (the array size)}
VIZSIM=${VIZSIM:-vizsim}
I=${SLURM_ARRAY_TASK_ID:?run as a Slurm array job}
exec "$VIZSIM" --threads "${SLURM_CPUS_PER_TASK:-1}" sweep "$EXPERIMENT" \
    --out "$OUT/shard-$I" --shard "$I/$SHARDS" --quiet
