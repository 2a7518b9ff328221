#!/usr/bin/env bash
# segment_composite.sh OBJECT.y4m REAL.y4m [...]
# Moving-object segmentation on real footage with a known mask: each REAL
# clip seen by a panning camera with a disc cut from OBJECT moving across
# it (benches/segment_composite.py, 40 frames), segmented by `mocomp
# segment`, its masks scored against the disc's (IoU per frame). What the
# footage itself moves (people) is labelled "unknown motion" (CDnet's 170)
# and not scored; NO_UNKNOWN=1 labels it static instead, so that it counts
# against the masks. DISC=14 makes the disc a seventh of the picture high
# (a third by default).
# Prints a Markdown table, a row per clip. Needs Python with numpy and a
# release build. Env: BIN=target/release/mocomp  FRAMES=40
set -euo pipefail
[ $# -gt 1 ] || { echo "usage: $0 OBJECT.y4m REAL.y4m [...]" >&2; exit 2; }
HERE=$(cd "$(dirname "$0")" && pwd)
BIN=$(realpath "${BIN:-target/release/mocomp}")
FRAMES=${FRAMES:-40}
TMP=$(mktemp -d); trap 'rm -rf "$TMP"' EXIT
object=$1; shift
echo "| clip | frames | not scored (own motion) | mean IoU | frames with IoU >= 0.8 | ms per frame |"
echo "|---|---:|---:|---:|---:|---:|"
for in in "$@"; do
  rm -rf "$TMP/truth"
  python3 "$HERE/segment_composite.py" "$in" "$object" "$TMP/comp.y4m" "$TMP/truth" "$FRAMES" \
    ${NO_UNKNOWN:+--no-unknown} 2> "$TMP/share.txt"
  "$BIN" segment "$TMP/comp.y4m" --truth "$TMP/truth" --json > "$TMP/out.json"
  python3 - "$(basename "$in" .y4m)" "$TMP/out.json" "$TMP/share.txt" <<'PY'
import json, re, sys
d = json.load(open(sys.argv[2]))
share = re.search(r"([0-9.]+) %", open(sys.argv[3]).read())
share = f"{share.group(1)} %" if share else "0 %"
good = sum(1 for r in d["iou"] if r["iou"] >= 0.8)
print(f"| {sys.argv[1]} | {d['frames']} | {share} | {d['mean_iou']:.3f} | {good} | {d['ms_per_frame']:.0f} |")
PY
done
