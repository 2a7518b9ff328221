#!/usr/bin/env bash
# stabilize_side_by_side.sh STILL.y4m [...]
# Stabilisation beside ffmpeg's vid.stab, in one run on this machine. Each
# input is a still-camera clip; `mocomp shake` adds a known shake to it
# (up to SHAKE_T pixels and SHAKE_R degrees per frame, seed 1), then:
#   vid.stab: ffmpeg vidstabdetect, then vidstabtransform with optzoom=1
#             (its defaults otherwise: smoothing 10, bicubic... see below);
#   mocomp:   `mocomp stabilize` with its defaults (ARGS adds flags).
# Both outputs are scored by `mocomp stabscore` against the shaken input
# and the shake's truth: cropping ratio, distortion, stability (Liu et al.
# 2013) and residual jitter (px/frame). Time is the whole process (both
# passes), the median of RUNS runs with GNU time, interleaved.
# A third row per input checks the scorer itself: the shaken input shaken
# again (up to 8 px and 1 degree, seed 2: a similarity, whose distortion is
# 1) and padded back to its size, scored against it; a distortion well
# under 1 there is the scorer's error on that footage, not a stabiliser's.
# Prints a Markdown table, a row per input and tool.
# Needs the peers' setup (ffmpeg with vid.stab, GNU time) and a release build.
# Env: BIN=target/release/mocomp  RUNS=3  SHAKE_T=12  SHAKE_R=1.5  ARGS=""  THREADS=""
set -euo pipefail
[ $# -gt 0 ] || { echo "usage: $0 STILL.y4m [...]" >&2; exit 2; }
BIN=$(realpath "${BIN:-target/release/mocomp}")
RUNS=${RUNS:-3}; SHAKE_T=${SHAKE_T:-12}; SHAKE_R=${SHAKE_R:-1.5}; ARGS=${ARGS:-}
TMP=$(mktemp -d); trap 'rm -rf "$TMP"' EXIT
cd "$TMP"

# seconds CMD...: wall seconds of one run
seconds() { /usr/bin/time -f %e -o "$TMP/t" "$@" >/dev/null 2>&1; cat "$TMP/t"; }
median() { sort -g | awk '{v[NR]=$1} END {print v[int((NR+1)/2)]}'; }
vidstab() {
  ffmpeg -hide_banner -loglevel error -nostdin -y -i "$1" -vf vidstabdetect=result="$TMP/v.trf" -f null - &&
  ffmpeg -hide_banner -loglevel error -nostdin -y -i "$1" -vf vidstabtransform=input="$TMP/v.trf":optzoom=1 \
    -pix_fmt yuv420p -strict -1 "$2"
}
ours() { "$BIN" stabilize "$1" -o "$2" $ARGS; }
export -f vidstab ours; export BIN TMP ARGS

echo "| input | frames | tool | s per run | ms per frame | cropping | distortion | stability | jitter px | shake px |"
echo "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|"
for in in "$@"; do
  name=$(basename "$in" .y4m)
  "$BIN" shake "$in" -o shaken.y4m --translation "$SHAKE_T" --rotation "$SHAKE_R" --seed 1 --truth truth.csv >/dev/null
  : > vidstab.t; : > ours.t
  for run in $(seq "$RUNS"); do
    seconds bash -c 'vidstab shaken.y4m vidstab.y4m' >> vidstab.t
    seconds bash -c 'ours shaken.y4m ours.y4m' >> ours.t
  done
  "$BIN" shake shaken.y4m -o again.y4m --translation 8 --rotation 1 --seed 2 >/dev/null
  size=$(head -1 shaken.y4m | sed 's/.* W\([0-9]*\) H\([0-9]*\).*/\1:\2/')
  ffmpeg -hide_banner -loglevel error -nostdin -y -i again.y4m -vf "pad=$size:(ow-iw)/2:(oh-ih)/2" \
    -pix_fmt yuv420p -strict -1 check.y4m
  for tool in vidstab ours check; do
    score=$("$BIN" stabscore shaken.y4m $tool.y4m --shake truth.csv --json)
    field() { sed "s/.*\"$1\":\([0-9.e+-]*\|null\).*/\1/; s/null/nan/" <<< "$score"; }
    if [ $tool = check ]; then
      # Its time, stability and jitter are not a stabiliser's.
      printf "| %s | %s | scorer on a known similarity | - | - | %.4f | %.4f | - | - | - |\n" "$name" "$(field frames)" \
        "$(field cropping)" "$(field distortion)"
      continue
    fi
    s=$(median < $tool.t)
    frames=$(field frames)
    label=$([ $tool = ours ] && echo "mocomp $ARGS" || echo "vid.stab (optzoom=1)")
    printf "| %s | %s | %s | %.2f | %.1f | %.4f | %.4f | %.4f | %.3f | %.2f |\n" "$name" "$frames" "$label" "$s" \
      "$(awk -v s="$s" -v n="$frames" 'BEGIN{print 1000*s/n}')" \
      "$(field cropping)" "$(field distortion)" "$(field stability)" "$(field jitter)" "$(field input_jitter)"
  done
done
