#!/usr/bin/env bash
# An RD study as a Slurm job array: each array task runs its share of the
# (sequence, predictor, QP) jobs with `mocomp rd --shard I/N`, writing
# OUT/part_I.csv a row at a time. A task that fails or is preempted is
# simply run again (sbatch --array=I ...): it skips the rows already
# written. When every task is done:
#   mocomp rd merge OUT/part_*.csv -o OUT/rd.csv --plot OUT/rd.svg
#
#   sbatch --array=1-16 examples/slurm/rd_array.sh SEQ_DIR OUT
#
# Env: PREDICTORS, QPS (mocomp rd's --predictors and --qp), RD_ARGS (more
# options, e.g. "--preset slow --frames 60"), MOCOMP (the binary).
#SBATCH --job-name=mocomp-rd
#SBATCH --cpus-per-task=2
#SBATCH --mem=2G
#SBATCH --time=08:00:00
#SBATCH --output=mocomp-rd_%A_%a.log
set -euo pipefail
seqs=${1:?usage: sbatch --array=1-N rd_array.sh SEQ_DIR OUT}
out=${2:?usage: sbatch --array=1-N rd_array.sh SEQ_DIR OUT}
: "${SLURM_ARRAY_TASK_ID:?run it with sbatch --array}"
# Shards are 1-based: task IDs are mapped from the array's own range.
first=${SLURM_ARRAY_TASK_MIN:-1}
count=${SLURM_ARRAY_TASK_COUNT:?run it with sbatch --array}
shard=$((SLURM_ARRAY_TASK_ID - first + 1))
mkdir -p "$out"
# shellcheck disable=SC2086
"${MOCOMP:-mocomp}" rd "$seqs"/*.y4m \
  --predictors "${PREDICTORS:-block:esa,block,flow-block:lk,obmc}" \
  --qp "${QPS:-22,27,32,37}" \
  --threads "${SLURM_CPUS_PER_TASK:-1}" \
  --shard "$shard/$count" -o "$out/part_$shard.csv" ${RD_ARGS:-}
