#!/usr/bin/env bash
# motion_side_by_side.sh WORK CLIP.y4m [...]: motion estimation beside its
# peers in one run on this machine, the two tables of the README's
# "Exhaustive search" and "DIS presets" sections:
#   1. exhaustive block matching (range 16, 16x16 blocks, SAD) beside
#      ffmpeg's mestimate esa, on each clip scaled to CIF (30 frames);
#      benches/me_side_by_side.sh;
#   2. mocomp's DIS presets beside OpenCV's DIS, on a pair with exact
#      ground truth made from each clip (a known affine motion over its
#      frame 5) and on ../shared/data/flowpair; benches/flow_side_by_side.py.
# Needs the peers' setup (../shared/peers/setup.sh: ffmpeg, OpenCV-python)
# and a release build. Env: BIN=target/release/mocomp  ROUNDS=3 (block
# matching; the flow script's own default is 5)  PEERS=../shared/peers
set -euo pipefail
[ $# -gt 1 ] || { echo "usage: $0 WORK CLIP.y4m [...]" >&2; exit 2; }
HERE=$(cd "$(dirname "$0")" && pwd)
work=$1; shift
BIN=${BIN:-target/release/mocomp}
PEERS=${PEERS:-$HERE/../../shared/peers}
mkdir -p "$work/cif"
cif=()
for clip in "$@"; do
  out="$work/cif/$(basename "$clip")"
  [ -s "$out" ] || ffmpeg -hide_banner -loglevel error -nostdin -y -i "$clip" -frames:v 30 \
    -vf scale=352:288 -pix_fmt yuv420p -strict -1 "$out"
  cif+=("$out")
done
echo "## Exhaustive search beside mestimate (CIF, range 16, 16x16, SAD, one thread)"
echo
BIN=$BIN ROUNDS=${ROUNDS:-3} METHODS=esa PARAMS=16 bash "$HERE/me_side_by_side.sh" "${cif[@]}"
echo
echo "## DIS presets beside OpenCV's DIS (one thread)"
echo
python3 "$HERE/flow_side_by_side.py" "$work/flow" "$@" --pair "$PEERS/../data/flowpair" \
  --mocomp "$BIN" --peers "$PEERS"
