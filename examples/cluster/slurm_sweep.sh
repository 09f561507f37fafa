#!/bin/bash
# A lay-up sweep spread over a Slurm job array: each array task runs one shard of the cases
# (`--shard I/N`), and a dependent job merges the shards into the directory a single-machine
# sweep would have written (summary.csv byte for byte the same).
#
#   mkdir -p sweep && sbatch examples/cluster/slurm_sweep.sh   # 8 tasks (--array below)
#   # when all tasks are done (or: sbatch --dependency=afterok:JOBID merge job):
#   flexsens merge sweep/shard_* -o sweep/all
#
# Each task uses the cores Slurm gives it (-j); the shards are deterministic, so a failed task
# can be re-run alone (sbatch --array=5 ...) before merging.
#SBATCH --job-name=flexsens-sweep
#SBATCH --array=1-8
#SBATCH --cpus-per-task=4
#SBATCH --time=02:00:00
#SBATCH --output=sweep/slurm_%A_%a.log
set -euo pipefail
mkdir -p sweep
flexsens sweep decks/slider_crank_beam.toml \
    --vary design.theta=-90:5:90 \
    --vary analysis.rtol=1e-6 \
    --shard "${SLURM_ARRAY_TASK_ID}/${SLURM_ARRAY_TASK_COUNT}" \
    -j "${SLURM_CPUS_PER_TASK:-1}" \
    -o "sweep/shard_${SLURM_ARRAY_TASK_ID}" \
    --quiet
