#!/usr/bin/env bash
# me_side_by_side.sh [IN.y4m]
# Block matching speed beside ffmpeg's mestimate, in one run on this machine:
# ../shared/peers/me_ffmpeg.sh times mestimate (single thread, per pass);
# `mocomp me --threads 1` is timed on the same input (median of 3 runs of
# its own per-pass search time). Prints a Markdown table with the ratio.
# Needs the peers' setup (ffmpeg, GNU time) and a release build.
set -euo pipefail
IN=${1:-../shared/data/pan_cif.y4m}
METHODS=${METHODS:-"esa tss ds hexbs epzs"}
PARAMS=${PARAMS:-"7 16"}
BIN=${BIN:-target/release/mocomp}
TMP=$(mktemp -d); trap 'rm -rf "$TMP"' EXIT
METHODS="$METHODS" PARAMS="$PARAMS" ../shared/peers/me_ffmpeg.sh "$IN" "$TMP/ffmpeg.csv" > "$TMP/ffmpeg.log" 2>&1
grep '^#' "$TMP/ffmpeg.csv"
echo "| method | range | mestimate ms/pass | mocomp ms/pass | ratio | mocomp mean SAD/px |"
echo "|---|---|---|---|---|---|"
for m in $METHODS; do
  for p in $PARAMS; do
    theirs=$(grep -v '^#' "$TMP/ffmpeg.csv" | awk -F, -v m="$m" -v p="$p" \
      'NR==1{for(i=1;i<=NF;i++)c[$i]=i; next} $c["method"]==m && $c["search_param"]==p {print $c["ms_per_pass"]}')
    ours=""; cost=""
    for run in 1 2 3; do
      j=$("$BIN" me "$IN" --method "$m" --range "$p" --block 16 --threads 1 --json)
      ours="$ours $(sed 's/.*"ms_per_frame":\([0-9.e-]*\).*/\1/' <<< "$j")"
      cost=$(sed 's/.*"mean_cost":\([0-9.e-]*\).*/\1/' <<< "$j")
    done
    med=$(tr ' ' '\n' <<< "$ours" | grep . | sort -g | sed -n 2p)
    awk -v m="$m" -v p="$p" -v t="$theirs" -v o="$med" -v c="$cost" \
      'BEGIN { printf "| %s | %s | %.2f | %.3f | %.0fx | %.4f |\n", m, p, t, o, t / o, c }'
  done
done
