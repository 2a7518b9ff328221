#!/usr/bin/env bash
# me_side_by_side.sh [IN.y4m ...]
# Block matching speed beside ffmpeg's mestimate, in one run on this machine:
# ../shared/peers/me_ffmpeg.sh times mestimate (single thread, per pass);
# `mocomp me --threads 1` is timed on the same input (median of 3 runs of
# its own per-pass search time), and for esa also with --no-elimination
# (every position evaluated: what successive elimination saves). Prints a
# Markdown table, a row per input, method and range, with the ratio.
#
# Either tool's time alone drifts by up to 2x between minutes on a shared
# virtual machine, so the two are timed in ROUNDS paired rounds (default 3),
# mestimate right before mocomp; the ratio is the median of the rounds'
# ratios (least and greatest beside it), the times the medians of the
# rounds.
# Needs the peers' setup (ffmpeg, GNU time) and a release build.
# Env: METHODS="esa tss ds hexbs epzs"  PARAMS="7 16"  ROUNDS=3  BIN=target/release/mocomp
set -euo pipefail
[ $# -gt 0 ] || set -- ../shared/data/pan_cif.y4m
METHODS=${METHODS:-"esa tss ds hexbs epzs"}
PARAMS=${PARAMS:-"7 16"}
ROUNDS=${ROUNDS:-3}
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

# theirs IN METHOD RANGE: mestimate's ms per pass, one run
theirs() {
  local in=$1 m=$2 p=$3
  METHODS="$m" PARAMS="$p" RUNS=1 ../shared/peers/me_ffmpeg.sh "$in" "$TMP/ffmpeg.csv" > "$TMP/ffmpeg.log" 2>&1
  grep -v '^#' "$TMP/ffmpeg.csv" | awk -F, -v m="$m" -v p="$p" \
    'NR==1{for(i=1;i<=NF;i++)c[$i]=i; next} $c["method"]==m && $c["search_param"]==p {print $c["ms_per_pass"]}'
}

echo "| input | method | range | mestimate ms/pass | mocomp ms/pass | mestimate / mocomp (least-greatest) | mocomp without elimination | mocomp mean SAD/px |"
echo "|---|---|---|---|---|---|---|---|"
for in in "$@"; do
  for m in $METHODS; do
    for p in $PARAMS; do
      : > "$TMP/rounds"
      for round in $(seq "$ROUNDS"); do
        t=$(theirs "$in" "$m" "$p")
        o=$(ours "$in" "$m" "$p")
        echo "$t $o" >> "$TMP/rounds"
      done
      plain="-"
      [ "$m" = esa ] && plain=$(ours "$in" "$m" "$p" --no-elimination)
      cost=$("$BIN" me "$in" --method "$m" --range "$p" --block 16 --threads 1 --json |
        sed 's/.*"mean_cost":\([0-9.e-]*\).*/\1/')
      sort -g -k1 "$TMP/rounds" | awk '{print $1}' > "$TMP/t"
      sort -g -k2 "$TMP/rounds" | awk '{print $2}' > "$TMP/o"
      awk '{print $1 / $2}' "$TMP/rounds" | sort -g > "$TMP/r"
      median() { awk '{v[NR] = $1} END {print (NR % 2 ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2)}' "$1"; }
      awk -v f="$(basename "$in" .y4m)" -v m="$m" -v p="$p" -v t="$(median "$TMP/t")" -v o="$(median "$TMP/o")" \
        -v r="$(median "$TMP/r")" -v lo="$(head -1 "$TMP/r")" -v hi="$(tail -1 "$TMP/r")" -v q="$plain" -v c="$cost" \
        'BEGIN { printf "| %s | %s | %s | %.2f | %.3f | %.0fx (%.0f-%.0f) | %s | %.4f |\n", f, m, p, t, o, r, lo, hi, (q == "-" ? q : sprintf("%.3f", q)), c }'
    done
  done
done
