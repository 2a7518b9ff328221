#!/usr/bin/env bash
# app_pictures.sh [OUT_DIR]: the README's pictures of stabilisation,
# interpolation and segmentation, made from the bundled synth_cif sample
# (needs a release build and ffmpeg to cut single frames out as PNG).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-docs}; BIN=${BIN:-target/release/mocomp}
mkdir -p "$OUT"; TMP=$(mktemp -d); trap 'rm -rf "$TMP"' EXIT
frame() { ffmpeg -hide_banner -loglevel error -nostdin -y -i "$1" -vf "select=eq(n\,$2)" -frames:v 1 "$3"; }
# Stabilisation: a known shake on the sample, the camera path and the smoothed one.
"$BIN" shake samples/synth_cif.y4m -o "$TMP/shaky.y4m" --translation 8 --rotation 1 --truth "$TMP/truth.csv"
"$BIN" stabilize "$TMP/shaky.y4m" -o "$TMP/steady.y4m" --plot "$OUT/stabilize_path.png" --report --shake "$TMP/truth.csv"
# Interpolation: frame 5 rebuilt from frames 4 and 6, beside the original.
"$BIN" interpolate samples/synth_cif.y4m --evaluate -o "$TMP/rebuilt.y4m"
frame "$TMP/rebuilt.y4m" 5 "$OUT/interpolated_frame5.png"
frame samples/synth_cif.y4m 5 "$OUT/original_frame5.png"
# Segmentation: the masks over the video (moving pixels tinted red).
"$BIN" segment samples/synth_cif.y4m --masks "$TMP/masks" --overlay "$TMP/overlay.y4m"
frame "$TMP/overlay.y4m" 5 "$OUT/segment_overlay5.png"
cp "$TMP/masks/00005.png" "$OUT/segment_mask5.png"
