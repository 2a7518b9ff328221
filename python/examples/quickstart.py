"""mocomp from Python in a page: read a video, estimate flow, show it in
colour, encode at several QPs with two predictors, compare them by
BD-rate and plot the RD curves (with matplotlib, if installed).

    python python/examples/quickstart.py [IN.y4m] [OUT_DIR]
"""

import pathlib
import sys

import numpy as np

import mocomp

root = pathlib.Path(__file__).resolve().parents[2]
src = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else root / "samples" / "synth_qcif.y4m"
out = pathlib.Path(sys.argv[2]) if len(sys.argv) > 2 else pathlib.Path("mocomp-out")
out.mkdir(parents=True, exist_ok=True)

frames = mocomp.read_y4m(src, frames=10)
y0, y1 = frames[0][0], frames[1][0]
print(f"{src.name}: {len(frames)} frames of {y0.shape[1]}x{y0.shape[0]}")

# Dense flow (DIS, medium preset) and how well it predicts frame 0 from frame 1.
flow = mocomp.flow(y0, y1)
speed = np.hypot(flow[..., 0], flow[..., 1])
print(f"flow: mean {speed.mean():.2f} px, max {speed.max():.2f} px")
predicted = mocomp.warp(y1, flow)
print(f"frame 0 predicted from frame 1 by the flow: {mocomp.psnr(y0, predicted):.2f} dB "
      f"(without motion {mocomp.psnr(y0, y1):.2f} dB)")
colour = mocomp.flow_to_color(flow)

# Block vectors of the same pair (EPZS, 16x16, quarter-pel).
vectors = mocomp.block_match(y1, y0)
print(f"block vectors: {vectors.shape[0]}x{vectors.shape[1]} blocks, "
      f"median ({np.median(vectors[..., 0]):.2f}, {np.median(vectors[..., 1]):.2f}) px")

# Encode at four QPs with two predictors; where the bits go.
curves = {}
for predictor in ("block", "flow-block:dis"):
    points = []
    for qp in (22, 27, 32, 37):
        stream, stats = mocomp.encode(frames, qp=qp, predictor=predictor)
        kbps = len(stream) * 8 * 25 / len(frames) / 1000
        psnr = float(np.mean([s["psnr_y"] for s in stats]))
        motion = sum(s["bits_motion"] for s in stats) / (8 * len(stream))
        points.append((kbps, psnr))
        print(f"{predictor:15s} QP {qp}: {kbps:8.1f} kbit/s  {psnr:.2f} dB  motion {motion:.1%} of the bits")
    curves[predictor] = points
(ra, pa), (rb, pb) = (zip(*curves["block"]), zip(*curves["flow-block:dis"]))
print(f"BD-rate of flow-block:dis against block: {mocomp.bd_rate(ra, pa, rb, pb):+.2f} %")

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("matplotlib is not installed: no plots")
else:
    plt.imsave(out / "flow.png", colour)
    fig, ax = plt.subplots()
    for name, pts in curves.items():
        ax.plot(*zip(*pts), marker="o", label=name)
    ax.set_xlabel("rate (kbit/s)")
    ax.set_ylabel("PSNR-Y (dB)")
    ax.legend()
    fig.savefig(out / "rd_python.png", dpi=120)
    print(f"wrote {out / 'flow.png'} and {out / 'rd_python.png'}")
