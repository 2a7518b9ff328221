#!/usr/bin/env bash
# me_side_by_side.sh [IN.y4m ...]
# Block matching speed beside ffmpeg's mestimate, in one run on this machine:
# ../shared/peers/me_ffmpeg.sh times mestimate (single thread, per pass);
# `mocomp me --threads 1` is timed on the same input (median of 3 runs of
# its own per-pass search time), and for esa also with --no-elimination
# (every position evaluated: what successive elimination saves). Prints a
# Markdown table, a row per input, method and range, with the ratio.
# Needs the peers' setup (ffmpeg, GNU time) and a release build.
# Env: METHODS="esa tss ds hexbs epzs"  PARAMS="7 16"  BIN=target/release/mocomp
set -euo pipefail
[ $# -gt 0 ] || set -- ../shared/data/pan_cif.y4m
METHODS=${METHODS:-"esa tss ds hexbs epzs"}
PARAMS=${PARAMS:-"7 16"}
BIN=${BIN:-target/release/mocomp}
TMP=$(mktemp -d); trap 'rm -rf "$TMP"' EXIT

# ours IN METHOD RANGE [FLAGS]: the median ms per pass of 3 runs
ours() {
  local in=$1 m=$2 p=$3; shift 3
  for run in 1 2 3; do
    "$BIN" me "$in" --method "$m" --range "$p" --block 16 --threads 1 --json "$@" |
      sed 's/.*"ms_per_frame":\([0-9.e-]*\).*/\1/'
  done | sort -g | sed -n 2p
}

echo "| input | method | range | mestimate ms/pass | mocomp ms/pass | ratio | mocomp without elimination | mocomp mean SAD/px |"
echo "|---|---|---|---|---|---|---|---|"
for in in "$@"; do
  METHODS="$METHODS" PARAMS="$PARAMS" ../shared/peers/me_ffmpeg.sh "$in" "$TMP/ffmpeg.csv" > "$TMP/ffmpeg.log" 2>&1
  grep '^#' "$TMP/ffmpeg.csv" >&2
  for m in $METHODS; do
    for p in $PARAMS; do
      theirs=$(grep -v '^#' "$TMP/ffmpeg.csv" | awk -F, -v m="$m" -v p="$p" \
        'NR==1{for(i=1;i<=NF;i++)c[$i]=i; next} $c["method"]==m && $c["search_param"]==p {print $c["ms_per_pass"]}')
      mine=$(ours "$in" "$m" "$p")
      plain="-"
      [ "$m" = esa ] && plain=$(ours "$in" "$m" "$p" --no-elimination)
      cost=$("$BIN" me "$in" --method "$m" --range "$p" --block 16 --threads 1 --json |
        sed 's/.*"mean_cost":\([0-9.e-]*\).*/\1/')
      awk -v f="$(basename "$in" .y4m)" -v m="$m" -v p="$p" -v t="$theirs" -v o="$mine" -v q="$plain" -v c="$cost" \
        'BEGIN { printf "| %s | %s | %s | %.2f | %.3f | %.0fx | %s | %.4f |\n", f, m, p, t, o, t / o, (q == "-" ? q : sprintf("%.3f", q)), c }'
    done
  done
done
