#!/usr/bin/env python3
"""Where the error of `mocomp interpolate --evaluate` is, on one clip.

    mocomp interpolate CLIP.y4m --evaluate -o REBUILT.y4m
    python3 benches/interpolate_floor.py CLIP.y4m REBUILT.y4m

REBUILT holds every other frame (1, 3, 5 ...) rebuilt from its two
neighbours. Printed, over the rebuilt frames (luma; "still" blocks are
16x16 blocks whose two neighbours differ by under 4 in mean squared
difference):

- still: the mean squared difference there between the rebuilt frame and
  the rounded mean of its two neighbours (how far from the plain mean
  the interpolation's still background is);
- rounding: the mean PSNR of the plain mean of the two neighbours
  everywhere, unrounded and rounded to 8 bits (what eight bits cost);
- farther frames: the mean squared error over the frames with the four
  frames' mean (the two neighbours and the frames two further away) in
  place of the rebuilt frame wherever the nearer and the farther pairs'
  means agree as noise would, in 8x8 blocks, against the rebuilt frame;
- oracle: the mean PSNR of the rebuilt frames, and with each 16x16 block
  taken from whichever of them and the rounded plain mean is closer to
  the truth (a choice made knowing the truth: a bound, not a method).

Needs numpy; reads 4:2:0 8-bit Y4M.
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from y4m_split import split  # noqa: E402


def luma_frames(path):
    _, w, h, frames = split(path)
    planes = []
    for frame in frames:
        start = frame.index(b"\n") + 1
        y = np.frombuffer(frame[start : start + w * h], np.uint8).reshape(h, w)
        planes.append(y.astype(np.float64))
    return planes


def block_means(x, b):
    h, w = (x.shape[0] // b) * b, (x.shape[1] // b) * b
    return x[:h, :w].reshape(h // b, b, w // b, b).mean(axis=(1, 3))


def psnr(mse):
    return 10 * np.log10(255.0**2 / max(mse, 1e-10))


def main(clip, rebuilt):
    truth, rebuilt = luma_frames(clip), luma_frames(rebuilt)
    still_d, plain, rounded, mc, best = [], [], [], [], []
    four_gain, mc_err = 0.0, 0.0
    for d in range(1, min(len(truth), len(rebuilt)) - 1, 2):
        t, m, a, b = truth[d], rebuilt[d], truth[d - 1], truth[d + 1]
        mean = (a + b) / 2
        round_mean = np.floor(mean + 0.5)
        still = block_means((a - b) ** 2, 16) < 4
        if still.any():
            still_d.append(block_means((m - round_mean) ** 2, 16)[still].mean())
        plain.append(psnr(((mean - t) ** 2).mean()))
        rounded.append(psnr(((round_mean - t) ** 2).mean()))
        err_m, err_p = block_means((m - t) ** 2, 16), block_means((round_mean - t) ** 2, 16)
        mc.append(psnr(err_m.mean()))
        best.append(psnr(np.minimum(err_m, err_p).mean()))
        if 3 <= d < len(truth) - 3:
            far = (truth[d - 3] + truth[d + 3]) / 2
            near_d, far_d = block_means((a - b) ** 2, 8), block_means((truth[d - 3] - truth[d + 3]) ** 2, 8)
            agree = block_means((mean - far) ** 2, 8) <= 1.5 * (near_d + far_d) / 4
            four = np.floor((mean + far) / 2 + 0.5)
            gain = np.where(agree, block_means((m - t) ** 2, 8) - block_means((four - t) ** 2, 8), 0.0)
            four_gain += gain.mean()
            mc_err += ((m - t) ** 2).mean()
    print(f"still: rebuilt against the rounded plain mean, mean squared difference {np.mean(still_d):.4f}")
    print(f"rounding: plain mean {np.mean(plain):.3f} dB unrounded, {np.mean(rounded):.3f} dB rounded")
    if mc_err > 0:
        print(f"farther frames: {psnr(mc_err - four_gain) - psnr(mc_err):+.3f} dB (mean squared error over the frames)")
    print(f"oracle: rebuilt {np.mean(mc):.3f} dB, best block of it and the rounded plain mean {np.mean(best):.3f} dB")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    main(sys.argv[1], sys.argv[2])
