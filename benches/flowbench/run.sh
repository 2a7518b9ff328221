#!/usr/bin/env bash
# run.sh [WORKDIR]: the flow benchmark, mocomp's methods and presets beside
# OpenCV's (DIS, Farneback, DualTVL1, DeepFlow), one thread each, same run.
#   1. photographs (photos.sh), 2. pairs with exact ground truth
#   (mocomp flowbench), 3. every method on every pair (.flo per method),
#   4. evaluate.py: EPE / AE / R1 / R3, on visible and occluded pixels,
#   per case kind, and motion-compensated PSNR on the real Middlebury
#   pairs of ../shared/data/pairs (no ground truth).
# Env: PEERS (default ../shared/peers), METHODS (mocomp method:preset[:flag]
# list; a flag is passed as --flag),
# CV_FAST / CV_SLOW (OpenCV method lists), REPEATS (timing runs, median taken, default 10: steady state, as a library caller on a sequence sees it),
# ONLY (a regex of pair names). Pairs already in WORKDIR/pairs are reused:
# delete that folder after changing the generator or the photographs.
# Results of methods not run this time stay in WORKDIR/est (so one method
# can be rerun alone: METHODS=tvl1:medium CV_FAST= CV_SLOW=); delete that
# folder to start over.
set -euo pipefail
cd "$(dirname "$0")/../.."
work=${1:-/tmp/mocomp-flowbench}
peers=${PEERS:-../shared/peers}
methods=${METHODS:-"dis:ultrafast dis:fast dis:medium dis:accurate dis:medium:global-search lk:fast lk:medium lk:accurate hs:medium tvl1:medium"}
cv_fast=${CV_FAST-dis_ultrafast,dis_fast,dis_medium,farneback}
# DualTVL1 takes about 30 s a 640x480 pair here: CV_SLOW=dualtvl1,deepflow adds it.
cv_slow=${CV_SLOW-deepflow}
repeats=${REPEATS:-10}
benches/flowbench/photos.sh "$work/photos"
cargo build --release --quiet
bin=target/release/mocomp
[ -f "$work/pairs/cases.csv" ] || $bin flowbench --out "$work/pairs" "$work"/photos/*.png >/dev/null
cases=$(ls -d "$work"/pairs/*/)
if [ -d "$peers/../data/pairs" ]; then cases="$cases $(ls -d "$peers"/../data/pairs/*/)"; fi
for c in $cases; do
  name=$(basename "$c")
  [[ -n "${ONLY:-}" && ! "$name" =~ $ONLY ]] && continue
  out="$work/est/$name"
  mkdir -p "$out"
  if [ -f "$c/frame1.png" ]; then f1=$c/frame1.png; f2=$c/frame2.png; else f1=$c/frame10.png; f2=$c/frame11.png; fi
  for m in $methods; do
    IFS=: read -r method preset flag <<< "$m"
    label=mocomp_${method}_${preset}${flag:+_$flag}
    # Horn-Schunck and TV-L1 take a second or more a pair: timed once.
    runs=$repeats; [[ "$method" = hs || "$method" = tvl1 ]] && runs=1
    $bin flow "$f1" "$f2" --method "$method" --preset "$preset" ${flag:+--$flag} --threads 1 --runs "$runs" \
      --json -o "$out/$label.flo" | sed "s/^{/{\"name\":\"$label\",/" > "$out/$label.json"
  done
  [ -n "$cv_fast" ] && python3 "$peers/flow_opencv.py" --img1 "$f1" --img2 "$f2" --threads 1 --repeats "$repeats" \
    --methods "$cv_fast" --save-flo "$out" --csv "$out/opencv_fast.csv" >/dev/null
  [ -n "$cv_slow" ] && python3 "$peers/flow_opencv.py" --img1 "$f1" --img2 "$f2" --threads 1 --repeats 1 \
    --methods "$cv_slow" --save-flo "$out" --csv "$out/opencv_slow.csv" >/dev/null
  echo "$name done" >&2
done
python3 benches/flowbench/evaluate.py "$work"
