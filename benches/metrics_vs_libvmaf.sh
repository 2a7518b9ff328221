#!/usr/bin/env bash
# mocomp's MS-SSIM, PSNR-HVS and CIEDE2000 against libvmaf's on encodes of
# other sequences (the development set): the largest per-frame gap of each.
# Usage: FFMPEG_VMAF=/path/to/ffmpeg-with-libvmaf benches/metrics_vs_libvmaf.sh A.y4m [B.y4m ...]
# (FRAMES frames of each, default 4, encoded at QP 34 with the default preset.)
set -euo pipefail
: "${FFMPEG_VMAF:?an ffmpeg built with libvmaf (pip install imageio-ffmpeg)}"
MOCOMP=${MOCOMP:-target/release/mocomp}
FRAMES=${FRAMES:-4}
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
for f in "$@"; do
  "$MOCOMP" encode "$f" -o "$T/a.mcv" --frames "$FRAMES" --qp 34 --recon "$T/r.y4m" --quiet
  ffmpeg -v error -y -i "$f" -frames:v "$FRAMES" -f yuv4mpegpipe "$T/s.y4m"
  "$FFMPEG_VMAF" -v error -nostdin -i "$T/r.y4m" -i "$T/s.y4m" -lavfi \
    "[0][1]libvmaf=feature=name=psnr_hvs|name=ciede|name=float_ms_ssim:log_fmt=csv:log_path=$T/l.csv" -f null -
  "$MOCOMP" quality "$T/s.y4m" "$T/r.y4m" --metrics ms-ssim,psnr-hvs,ciede2000 --csv "$T/m.csv" > /dev/null
  python3 - "$(basename "$f")" "$T/l.csv" "$T/m.csv" <<'PY'
import csv, sys
name, lv, mc = sys.argv[1:4]
l, m = list(csv.DictReader(open(lv))), list(csv.DictReader(open(mc)))
gap = lambda a, b: max(abs(float(x[a]) - float(y[b])) for x, y in zip(l, m))
print(f"| {name} | {gap('float_ms_ssim', 'ms_ssim'):.1e} | {gap('psnr_hvs_y', 'psnr_hvs_y'):.1e} | "
      f"{gap('psnr_hvs', 'psnr_hvs'):.1e} | {gap('ciede2000', 'ciede2000'):.1e} |")
PY
done
