#!/usr/bin/env bash
# rd_side_by_side.sh [OUT_DIR]
#
# The encoder beside ffmpeg's MPEG-4 Part 2, x264 restricted to simple
# tools (x264_simple) and x264 medium, in one run on one machine, on the
# whole development set: the three shared sequences and the ones
# benches/seqbench/make.sh builds (static camera with noise, cuts, fast pan,
# dark, light change, hand-held, cartoon, ffmpeg's testsrc2, 720p).
#   - the peers' RD points (../shared/peers/rd_ffmpeg.sh: IPPP, one
#     thread), kept in OUT_DIR and reused by later runs (they do not change);
#   - ours for PREDICTORS at QP 22/27/32/37 (`mocomp rd`, RD_ARGS added:
#     e.g. RD_ARGS="--ipratio 1" to measure a tool off);
#   - per sequence, BD-rate (luma PSNR, mean of frames, cubic) of every
#     predictor against mpeg4, x264_simple and x264;
#   - a summary: the default (block:epzs) against x264_simple and x264 on
#     every sequence, and the mean;
#   - encode time of every preset, whole process, one thread, on pan_cif,
#     beside x264_simple and x264 medium (medians of RUNS interleaved
#     rounds, default 10).
# Env: SEQS (Y4M paths; default the set above), DEV (where make.sh builds
# its sequences, default OUT_DIR/dev), PREDICTORS (default every one; the
# summary needs block:epzs), RD_ARGS, SPEED=0 to skip the timing, MOCOMP
# (a binary to measure instead of building this tree's).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
SHARED=${SHARED:-$ROOT/../shared}
OUT=${1:-rd-side-by-side}
mkdir -p "$OUT"
DEV=${DEV:-$OUT/dev}
# MOCOMP: a mocomp binary to measure (default: this tree's, built now).
if [ -z "${MOCOMP:-}" ]; then
  cargo build --release --manifest-path "$ROOT/Cargo.toml" -q
fi
M=${MOCOMP:-$ROOT/target/release/mocomp}
if [ -z "${SEQS:-}" ]; then
  bash "$ROOT/benches/seqbench/make.sh" "$DEV" > /dev/null
  SEQS="$(ls "$SHARED"/data/{pan_cif,cup_vga_30,tree_qvga}.y4m) $(ls "$DEV"/*.y4m)"
fi
PREDICTORS=${PREDICTORS:-"zero block:esa block:tss flow-block:lk flow-block:hs flow-block:dis flow-block:tvl1 dense-lk dense-hs dense-dis dense-tvl1 obmc block:epzs"}
DEFAULT=block:epzs
bd() {  # ANCHOR_CSV:CODEC TEST_CSV:CODEC -> BD-rate cubic, % (n/a when the curves do not overlap)
  local j
  j=$("$M" bdrate "$1" "$2" --json 2> /dev/null) || { echo n/a; return; }
  echo "$j" | sed -n 's/.*"bd_rate_cubic":\([-0-9.e]*\).*/\1/p' | awk '{printf "%+.1f", $1}'
}
summary="| sequence | vs x264_simple | vs x264 medium |"$'\n'"|---|---:|---:|"
sums="0 0"
n=0
for IN in $SEQS; do
  s=$(basename "$IN" .y4m)
  [ -s "$OUT/peers_$s.csv" ] || bash "$SHARED/peers/rd_ffmpeg.sh" "$IN" "$OUT/peers_$s.csv" > /dev/null
  # shellcheck disable=SC2086
  "$M" rd "$IN" --predictors "$(echo $PREDICTORS | tr ' ' ,)" -o "$OUT/ours_$s.csv" \
    --anchor-csv "$OUT/peers_$s.csv:x264_simple" ${RD_ARGS:-} > "$OUT/table_$s.md"
  for anchor in mpeg4 x264_simple x264; do
    echo "## $s against $anchor" >> "$OUT/table_$s.md"
    for p in $PREDICTORS; do
      echo "$p $(bd "$OUT/peers_$s.csv:$anchor" "$OUT/ours_$s.csv:$p")" >> "$OUT/table_$s.md"
    done
  done
  if [[ " $PREDICTORS " == *" $DEFAULT "* ]]; then
    a=$(bd "$OUT/peers_$s.csv:x264_simple" "$OUT/ours_$s.csv:$DEFAULT")
    b=$(bd "$OUT/peers_$s.csv:x264" "$OUT/ours_$s.csv:$DEFAULT")
    summary+=$'\n'"| $s | $a % | $b % |"
    sums=$(echo "$sums" | awk -v a="$a" -v b="$b" '{print $1 + a, $2 + b}')
    n=$((n + 1))
  fi
done
cat "$OUT"/table_*.md > "$OUT/tables.md" 2> /dev/null || true
if [ "$n" -gt 0 ]; then
  mean=$(echo "$sums" | awk -v n="$n" '{printf "| **mean of %d** | **%+.1f %%** | **%+.1f %%** |", n, $1 / n, $2 / n}')
  summary+=$'\n'"$mean"
  echo "BD-rate of the default ($DEFAULT${RD_ARGS:+ $RD_ARGS}), luma PSNR, cubic:"
  echo "$summary" | tee "$OUT/summary.md"
fi
[ "${SPEED:-1}" = 0 ] && exit 0
# Speed: every preset and the two x264 settings, whole process, one
# thread, QP 28 on pan_cif, interleaved over RUNS rounds (default 10);
# the median of each (the preset table of docs/results/encoder.md).
IN="$SHARED/data/pan_cif.y4m"
X264="ffmpeg -hide_banner -nostdin -loglevel error -y -i $IN -c:v libx264 -preset medium -tune psnr -qp 28 -threads 1"
for i in $(seq "${RUNS:-10}"); do
  for p in ultrafast fast medium slow; do
    # shellcheck disable=SC2086
    /usr/bin/time -f "$p %e" "$M" encode "$IN" -o "$OUT/$p.mcv" --threads 1 --quiet --preset $p ${RD_ARGS:-} > /dev/null
  done
  /usr/bin/time -f "x264_simple %e" $X264 \
    -x264-params keyint=infinite:scenecut=0:bframes=0:threads=1:cabac=0:8x8dct=0:ref=1:no-deblock=1:subme=1:me=dia \
    -f h264 "$OUT/x264_simple.264"
  /usr/bin/time -f "x264_medium %e" $X264 \
    -x264-params keyint=infinite:scenecut=0:bframes=0:threads=1 -f h264 "$OUT/x264.264"
done 2> "$OUT/times.txt"
echo "encode time, pan_cif, one thread, median of ${RUNS:-10} (s):"
for k in ultrafast fast medium slow x264_simple x264_medium; do
  awk -v k="$k" '$1 == k {print $2}' "$OUT/times.txt" | sort -n |
    awk -v k="$k" '{v[NR] = $1} END {printf "  %-12s %.2f\n", k, v[int((NR + 1) / 2)]}'
done
