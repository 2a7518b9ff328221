#!/usr/bin/env bash
# An RD study as a Slurm job array: array task I runs shard I/N of the
# (sequence, predictor, QP) jobs with `mocomp rd --shard I/N`, writing
# OUT/part_I.csv a row at a time, its log in OUT/logs/part_I.log. The
# shard count N is fixed at submission (the third argument, or SHARDS),
# never read from the array's bounds, so one task run again alone is
# still shard I of N:
#
#   sbatch --array=1-16 examples/slurm/rd_array.sh SEQ_DIR OUT 16
#   sbatch --array=2 examples/slurm/rd_array.sh SEQ_DIR OUT 16   # task 2 again: it
#       # skips the rows part_2.csv holds; a part is resumed only by its own shard
#   mocomp rd merge OUT/part_*.csv -o OUT/rd.csv --plot OUT/rd.svg
#
# On every node: the mocomp binary (on PATH, or MOCOMP=/path/to/mocomp
# where the nodes see it), SEQ_DIR and OUT on a filesystem all nodes share.
# Env: PREDICTORS, QPS (mocomp rd's --predictors and --qp), RD_ARGS (more
# options, e.g. "--preset slow --frames 60"), SHARDS, MOCOMP.
# --cpus-per-task=2 on 2-CPU nodes runs one task per node at a time.
#SBATCH --job-name=mocomp-rd
#SBATCH --cpus-per-task=2
#SBATCH --mem=2G
#SBATCH --time=08:00:00
# Only what goes wrong before the task's own log opens lands here.
#SBATCH --output=mocomp-rd_%A_%a.log
set -euo pipefail
usage="usage: sbatch --array=1-N rd_array.sh SEQ_DIR OUT N (or SHARDS=N)"
seqs=${1:?$usage}
out=${2:?$usage}
shards=${3:-${SHARDS:-}}
: "${shards:?$usage}"
shard=${SLURM_ARRAY_TASK_ID:?run it with sbatch --array}
if ! [[ $shards =~ ^[1-9][0-9]*$ && $shard =~ ^[0-9]+$ ]] || ((shard < 1 || shard > shards)); then
  echo "array task $shard is not a shard of 1..$shards: submit --array within 1-$shards" >&2
  exit 2
fi
mkdir -p "$out/logs"
exec >>"$out/logs/part_$shard.log" 2>&1
echo "$(date -u +%FT%TZ) job ${SLURM_ARRAY_JOB_ID:-?} task $shard/$shards on $(hostname)"
# shellcheck disable=SC2086
"${MOCOMP:-mocomp}" rd "$seqs"/*.y4m \
  --predictors "${PREDICTORS:-block:esa,block,flow-block:lk,obmc}" \
  --qp "${QPS:-22,27,32,37}" \
  --threads "${SLURM_CPUS_PER_TASK:-1}" \
  --shard "$shard/$shards" -o "$out/part_$shard.csv" ${RD_ARGS:-}
