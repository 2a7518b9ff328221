#!/usr/bin/env bash
# Regenerates the real test pair and the reference figures the tests compare
# mocomp's metrics against, computed by independent implementations:
#   - PSNR by ffmpeg's psnr filter (per-frame psnr_y/u/v from its stats file,
#     and its summary line, the PSNR of the frame-averaged MSE);
#   - SSIM by scikit-image's structural_similarity with Wang et al.'s
#     parameters (Gaussian window sigma 1.5, population covariance, L = 255);
#   - SSIM as encoders report it, by ffmpeg's ssim filter (x264's 8x8
#     windows at 4-pixel steps), luma per frame; again with both pictures'
#     luma divided by 32 (truncated), where x264's small luminance constant
#     shows.
# Needs ffmpeg and Python with numpy and scikit-image. Run from the repository
# root with the peers' data folder as $1 (default ../shared/data).
set -euo pipefail
DATA=${1:-../shared/data}
S=samples
ffmpeg -v error -y -i "$DATA/tree_qvga.y4m" -vf crop=176:144:72:48 -frames:v 6 \
  -pix_fmt yuv420p -f yuv4mpegpipe "$S/tree_qcif.y4m"
TMP=$(mktemp -d); trap 'rm -rf "$TMP"' EXIT
ffmpeg -v error -y -i "$S/tree_qcif.y4m" -c:v mpeg4 -q:v 8 -bf 0 -flags:v +bitexact \
  -fflags +bitexact -f m4v "$TMP/t.m4v"
ffmpeg -v error -y -i "$TMP/t.m4v" -pix_fmt yuv420p -f yuv4mpegpipe "$S/tree_qcif_mpeg4.y4m"
summary=$(ffmpeg -hide_banner -nostdin -i "$S/tree_qcif_mpeg4.y4m" -i "$S/tree_qcif.y4m" \
  -lavfi "psnr=stats_file=$TMP/psnr.log" -f null - 2>&1 | grep -o 'PSNR y:.*')
ffmpeg -v error -nostdin -i "$S/tree_qcif_mpeg4.y4m" -i "$S/tree_qcif.y4m" \
  -lavfi "ssim=stats_file=$TMP/ssim.log" -f null -
ffmpeg -v error -nostdin -i "$S/tree_qcif_mpeg4.y4m" -i "$S/tree_qcif.y4m" \
  -lavfi "[0]lutyuv=y=trunc(val/32)[a];[1]lutyuv=y=trunc(val/32)[b];[a][b]ssim=stats_file=$TMP/ssim_dark.log" -f null -
python3 - "$S" "$TMP/psnr.log" "$summary" "$TMP/ssim.log" "$TMP/ssim_dark.log" > "$S/reference/tree_qcif_mpeg4.json" <<'PY'
import json, re, sys
import numpy as np
from skimage.metrics import structural_similarity

def y4m_luma(path):
    data = open(path, "rb").read()
    header, _, rest = data.partition(b"\n")
    tags = dict((t[:1], t[1:]) for t in header.split()[1:])
    w, h = int(tags[b"W"]), int(tags[b"H"])
    frame = w * h + 2 * ((w + 1) // 2) * ((h + 1) // 2)
    frames = []
    while rest:
        line, _, rest = rest.partition(b"\n")
        assert line.startswith(b"FRAME")
        frames.append(np.frombuffer(rest[: w * h], np.uint8).reshape(h, w))
        rest = rest[frame:]
    return frames

sdir, stats, summary, ssim_log, ssim_dark_log = sys.argv[1:6]
ref = y4m_luma(f"{sdir}/tree_qcif.y4m")
test = y4m_luma(f"{sdir}/tree_qcif_mpeg4.y4m")
ssim = [structural_similarity(a, b, gaussian_weights=True, sigma=1.5,
                              use_sample_covariance=False, data_range=255)
        for a, b in zip(ref, test)]
frames = []
for line in open(stats):
    f = dict(kv.split(":") for kv in line.split())
    frames.append({k: float(f[k]) for k in ("psnr_y", "psnr_u", "psnr_v", "mse_y")})
def ffmpeg_ssim_y(log):
    return [float(dict(kv.split(":") for kv in line.split()[:4])["Y"]) for line in open(log)]
avg = dict(re.findall(r"(\w+):([0-9.]+)", summary))
json.dump({
    "reference": "tree_qcif.y4m", "test": "tree_qcif_mpeg4.y4m",
    "ffmpeg_psnr_per_frame": frames,
    "ffmpeg_psnr_of_mean_mse": {k: float(avg[k]) for k in ("y", "u", "v")},
    "skimage_ssim_y_per_frame": ssim,
    "ffmpeg_ssim_y_per_frame": ffmpeg_ssim_y(ssim_log),
    "ffmpeg_ssim_y_dark_per_frame": ffmpeg_ssim_y(ssim_dark_log),
}, sys.stdout, indent=1)
print()
PY
echo "wrote $S/tree_qcif.y4m $S/tree_qcif_mpeg4.y4m $S/reference/tree_qcif_mpeg4.json"
