#!/usr/bin/env bash
# interpolate_side_by_side.sh IN.y4m [...]
# Frame interpolation beside ffmpeg's minterpolate, in one run on this
# machine. From each input, every other frame is dropped (frames 0, 2, 4 ...
# kept at half the rate, benches/halve_rate.py); both tools double the rate
# again and the rebuilt frames (1, 3, 5 ...) are compared with the dropped
# originals: mean PSNR-Y over the frames both made.
#   minterpolate: ffmpeg -vf minterpolate=fps=<double>:mi_mode=mci:mc_mode=aobmc:me_mode=bidir
#   mocomp:       mocomp interpolate --factor 2 (ARGS adds flags)
# Time is the whole process, median of RUNS interleaved runs (GNU time).
# Prints a Markdown table, a row per input.
# Needs the peers' setup (ffmpeg, GNU time, Python with numpy) and a release build.
# Env: BIN=target/release/mocomp  RUNS=3  ARGS=""
set -euo pipefail
[ $# -gt 0 ] || { echo "usage: $0 IN.y4m [...]" >&2; exit 2; }
HERE=$(cd "$(dirname "$0")" && pwd)
BIN=$(realpath "${BIN:-target/release/mocomp}")
RUNS=${RUNS:-3}; ARGS=${ARGS:-}
TMP=$(mktemp -d); trap 'rm -rf "$TMP"' EXIT

seconds() { /usr/bin/time -f %e -o "$TMP/t" "$@" >/dev/null 2>&1; cat "$TMP/t"; }
median() { sort -g | awk '{v[NR]=$1} END {print v[int((NR+1)/2)]}'; }

echo "| input | rebuilt frames | minterpolate PSNR-Y | mocomp PSNR-Y | gain dB | minterpolate s | mocomp s | time ratio |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for in in "$@"; do
  name=$(basename "$in" .y4m)
  python3 "$HERE/halve_rate.py" "$in" "$TMP/half.y4m"
  fps=$(head -c 200 "$in" | head -1 | sed 's/.* F\([0-9]*:[0-9]*\).*/\1/' | tr : /)
  : > "$TMP/mi.t"; : > "$TMP/ours.t"
  for run in $(seq "$RUNS"); do
    seconds ffmpeg -hide_banner -loglevel error -nostdin -y -i "$TMP/half.y4m" \
      -vf "minterpolate=fps=$fps:mi_mode=mci:mc_mode=aobmc:me_mode=bidir" -strict -1 "$TMP/mi.y4m" >> "$TMP/mi.t"
    seconds "$BIN" interpolate "$TMP/half.y4m" -o "$TMP/ours.y4m" --factor 2 $ARGS >> "$TMP/ours.t"
  done
  read -r n pm po <<< "$(python3 - "$in" "$TMP/mi.y4m" "$TMP/ours.y4m" <<'PY'
import re, sys
import numpy as np

def lumas(path):
    data = open(path, "rb").read()
    end = data.index(b"\n")
    head = data[:end].decode()
    w, h = (int(re.search(p, head).group(1)) for p in (r" W(\d+)", r" H(\d+)"))
    size = w * h + 2 * ((w + 1) // 2) * ((h + 1) // 2)
    out, at = [], end + 1
    while at < len(data):
        start = data.index(b"\n", at) + 1
        out.append(np.frombuffer(data[start:start + w * h], np.uint8).reshape(h, w).astype(np.float64))
        at = start + size
    return out

orig, mi, ours = (lumas(p) for p in sys.argv[1:4])
odd = range(1, min(len(orig), len(mi), len(ours)), 2)
psnr = lambda a, b: 10 * np.log10(255.0 ** 2 / max(((a - b) ** 2).mean(), 1e-10))
print(len(odd), np.mean([psnr(orig[k], mi[k]) for k in odd]), np.mean([psnr(orig[k], ours[k]) for k in odd]))
PY
)"
  tm=$(median < "$TMP/mi.t"); to=$(median < "$TMP/ours.t")
  awk -v name="$name" -v n="$n" -v pm="$pm" -v po="$po" -v tm="$tm" -v to="$to" \
    'BEGIN { printf "| %s | %d | %.3f | %.3f | %+.3f | %.2f | %.2f | %.2f |\n", name, n, pm, po, po - pm, tm, to, to / tm }'
done
