#!/usr/bin/env bash
# intra_only.sh IN.y4m [FRAMES]: BD-rate of mocomp's intra coding against
# x264 medium's (tune psnr), every frame an I frame, on the first FRAMES
# (default 4) frames of IN: mocomp with `--gop 1 --ipratio 1` at QP
# 20-40, x264 with keyint=1, one thread; luma PSNR the mean of frames
# (ffmpeg's psnr filter, frames aligned by index). Needs ffmpeg with
# libx264; MOCOMP=path/to/mocomp (default: target/release/mocomp).
set -euo pipefail
in=${1:?usage: intra_only.sh IN.y4m [FRAMES]}
n=${2:-4}
mocomp=${MOCOMP:-target/release/mocomp}
ff="ffmpeg -v error -y -nostdin"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
$ff -i "$in" -frames:v "$n" -f yuv4mpegpipe -strict -1 "$tmp/src.y4m"
psnr() {  # mean over frames of the luma PSNR of $1 against the source
  $ff -i "$1" -i "$tmp/src.y4m" -lavfi \
    "[0:v]settb=1/30,setpts=N[d];[1:v]settb=1/30,setpts=N[r];[d][r]psnr=stats_file=$tmp/ps.log" -f null -
  sed -n 's/.*psnr_y:\([0-9.]*\).*/\1/p' "$tmp/ps.log" | awk '{s += $1; k++} END {printf "%.4f", s / k}'
}
for codec in x264 mocomp; do
  echo "codec,q,bytes,frames,kbps,psnr_y" > "$tmp/$codec.csv"
  for qp in 20 24 28 32 36 40; do
    if [ "$codec" = x264 ]; then
      out=$tmp/x.264
      $ff -i "$tmp/src.y4m" -c:v libx264 -preset medium -tune psnr -qp "$qp" \
        -x264-params keyint=1:threads=1 -f h264 "$out"
      dec=$out
    else
      out=$tmp/o.mcv
      "$mocomp" encode "$tmp/src.y4m" -o "$out" --qp "$qp" --gop 1 --ipratio 1 --quiet
      "$mocomp" decode "$out" -o "$tmp/o.y4m"
      dec=$tmp/o.y4m
    fi
    b=$(stat -c %s "$out")
    echo "$codec,$qp,$b,$n,$((b * 8)),$(psnr "$dec")" >> "$tmp/$codec.csv"
  done
done
"$mocomp" bdrate "$tmp/x264.csv" "$tmp/mocomp.csv" | grep -i 'bd-rate'
