#!/usr/bin/env bash
# rd_tool_gain.sh WITHOUT_DIR WITH_DIR [CODEC]: what a coding tool buys.
# Two output folders of benches/rd_side_by_side.sh on the same sequences,
# one run without the tool (e.g. RD_ARGS="--no-deblock"), one with it;
# prints the BD-rate (luma PSNR, cubic) of CODEC (default block:epzs) with
# the tool against without, per sequence and on the mean, as markdown.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
without=${1:?usage: rd_tool_gain.sh WITHOUT_DIR WITH_DIR [CODEC]}
with=${2:?usage: rd_tool_gain.sh WITHOUT_DIR WITH_DIR [CODEC]}
codec=${3:-block:epzs}
M=${MOCOMP:-$ROOT/target/release/mocomp}
echo "| sequence | BD-rate |"
echo "|---|---:|"
for f in "$with"/ours_*.csv; do
  s=$(basename "$f" .csv)
  s=${s#ours_}
  [ -f "$without/ours_$s.csv" ] || continue
  v=$("$M" bdrate "$without/ours_$s.csv:$codec" "$f:$codec" --json |
    sed -n 's/.*"bd_rate_cubic":\([-0-9.e]*\).*/\1/p')
  printf '| %s | %+.1f %% |\n' "$s" "$v"
  echo "$v" >> "$with/.gain_values"
done
awk '{s += $1; n++} END {if (n) printf "| **mean of %d** | **%+.1f %%** |\n", n, s / n}' "$with/.gain_values"
rm -f "$with/.gain_values"
