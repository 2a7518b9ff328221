#!/usr/bin/env bash
# rd_side_by_side.sh [OUT_DIR]
#
# The encoder beside ffmpeg's MPEG-4 Part 2 and x264 on the shared test
# sequences, in one run on one machine: the peers' RD points
# (../shared/peers/rd_ffmpeg.sh: IPPP, one thread), ours for every predictor
# and the default (block:epzs) at QP 22/27/32/37, then BD-rate tables against block:esa, mpeg4 and
# x264_simple (luma PSNR, mean of frames, as the peer script), and the
# encode time of the default setting, whole process, one thread, beside
# x264_simple's.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
SHARED=${SHARED:-$ROOT/../shared}
OUT=${1:-rd-side-by-side}
mkdir -p "$OUT"
cargo build --release --manifest-path "$ROOT/Cargo.toml" -q
M="$ROOT/target/release/mocomp"
SEQS=${SEQS:-"pan_cif cup_vga_30 tree_qvga"}
for s in $SEQS; do
  IN="$SHARED/data/$s.y4m"
  bash "$SHARED/peers/rd_ffmpeg.sh" "$IN" "$OUT/peers_$s.csv" > /dev/null
  PREDICTORS="zero block:esa block:tss flow-block:lk flow-block:hs flow-block:dis flow-block:tvl1 dense-lk dense-hs dense-dis dense-tvl1 obmc block:epzs"
  "$M" rd "$IN" --predictors "$(echo $PREDICTORS | tr ' ' ,)" -o "$OUT/ours_$s.csv" \
    --plot "$OUT/ours_$s.svg" --quiet > "$OUT/table_$s.md"
  for anchor in mpeg4 x264_simple; do
    echo "## $s against $anchor" >> "$OUT/table_$s.md"
    for p in $PREDICTORS; do
      printf '%s ' "$p" >> "$OUT/table_$s.md"
      "$M" bdrate "$OUT/peers_$s.csv:$anchor" "$OUT/ours_$s.csv:$p" --json >> "$OUT/table_$s.md"
    done
  done
  cat "$OUT/table_$s.md"
done
# Speed: the default setting, whole process, one thread, five runs each.
IN="$SHARED/data/pan_cif.y4m"
for i in 1 2 3 4 5; do
  /usr/bin/time -f "mocomp default %e s" "$M" encode "$IN" -o "$OUT/default.mcv" --threads 1 --quiet > /dev/null
  /usr/bin/time -f "x264_simple qp28 %e s" ffmpeg -hide_banner -nostdin -loglevel error -y -i "$IN" -c:v libx264 \
    -preset medium -tune psnr -qp 28 -threads 1 \
    -x264-params keyint=infinite:scenecut=0:bframes=0:threads=1:cabac=0:8x8dct=0:ref=1:no-deblock=1:subme=1:me=dia \
    -f h264 "$OUT/x264.264"
done
