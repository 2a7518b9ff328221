#!/usr/bin/env bash
# Regenerates the second real test pair (192x176, large enough for
# MS-SSIM's five scales) and the reference figures of the metrics that
# AWCY reports, computed by libvmaf (the implementation AWCY uses):
#   - MS-SSIM: libvmaf's float_ms_ssim (luma);
#   - PSNR-HVS: libvmaf's psnr_hvs (Daala's), per plane and combined;
#   - CIEDE2000: libvmaf's ciede (Daala's);
#   - VMAF: libvmaf's default model (the figure mocomp reads from ffmpeg).
# for both pairs (tree_qcif and tree_176; MS-SSIM only for the larger one,
# which libvmaf requires).
# Needs ffmpeg (for the pair) and an ffmpeg built with libvmaf as
# $FFMPEG_VMAF; without it, the one that `pip install imageio-ffmpeg`
# brings is used. Run from the repository root with the peers' data folder
# as $1 (default ../shared/data).
set -euo pipefail
DATA=${1:-../shared/data}
S=samples
if [ -z "${FFMPEG_VMAF:-}" ]; then
  FFMPEG_VMAF=$(python3 -c 'import imageio_ffmpeg; print(imageio_ffmpeg.get_ffmpeg_exe())' 2>/dev/null) || {
    echo "needs an ffmpeg with libvmaf: set FFMPEG_VMAF or pip install imageio-ffmpeg" >&2; exit 1; }
fi
TMP=$(mktemp -d); trap 'rm -rf "$TMP"' EXIT
ffmpeg -v error -y -i "$DATA/tree_qvga.y4m" -vf crop=192:176:64:32 -frames:v 3 \
  -pix_fmt yuv420p -f yuv4mpegpipe "$S/tree_176.y4m"
ffmpeg -v error -y -i "$S/tree_176.y4m" -c:v mpeg4 -q:v 8 -bf 0 -flags:v +bitexact \
  -fflags +bitexact -f m4v "$TMP/t.m4v"
ffmpeg -v error -y -i "$TMP/t.m4v" -pix_fmt yuv420p -f yuv4mpegpipe "$S/tree_176_mpeg4.y4m"
measure() { # test reference features log
  "$FFMPEG_VMAF" -v error -nostdin -i "$1" -i "$2" \
    -lavfi "[0][1]libvmaf=feature=$3:log_fmt=csv:log_path=$4" -f null -
}
measure "$S/tree_qcif_mpeg4.y4m" "$S/tree_qcif.y4m" "name=psnr_hvs|name=ciede" "$TMP/qcif.csv"
measure "$S/tree_176_mpeg4.y4m" "$S/tree_176.y4m" \
  "name=psnr_hvs|name=ciede|name=float_ms_ssim" "$TMP/176.csv"
python3 - "$TMP/qcif.csv" "$TMP/176.csv" "$("$FFMPEG_VMAF" -hide_banner -version | head -1)" \
  > "$S/reference/libvmaf_metrics.json" <<'PY'
import csv, json, sys
def columns(path):
    rows = list(csv.DictReader(open(path)))
    keep = ("psnr_hvs_y", "psnr_hvs_cb", "psnr_hvs_cr", "psnr_hvs", "ciede2000", "float_ms_ssim", "vmaf")
    return {k: [float(r[k]) for r in rows] for k in keep if k in rows[0]}
json.dump({
    "made_by": sys.argv[3],
    "pairs": [
        {"reference": "tree_qcif.y4m", "test": "tree_qcif_mpeg4.y4m", **columns(sys.argv[1])},
        {"reference": "tree_176.y4m", "test": "tree_176_mpeg4.y4m", **columns(sys.argv[2])},
    ],
}, sys.stdout, indent=1)
print()
PY
echo "wrote $S/tree_176.y4m $S/tree_176_mpeg4.y4m $S/reference/libvmaf_metrics.json"
