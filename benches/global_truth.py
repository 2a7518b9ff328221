#!/usr/bin/env python3
"""Global motion against a known camera motion over real footage.

Each input is a still-camera clip; `mocomp shake` moves a window over it
(up to SHAKE_T pixels and SHAKE_R degrees per frame, seed 1: a
similarity per frame, independent from frame to frame) and writes the
truth. `mocomp globalmotion --csv` then fits one model per frame pair,
from each source and model asked for, and each fit is compared with the
true motion of the pair at the four corners of the picture: the mean
distance between where the two put each corner, pixels. The people and
things that move in the footage are not the camera's motion, and a
robust fit has to leave them out.

The truth is computed here from the shake's own definition (a window
turned by `angle` about the picture's centre and shifted by (dx, dy),
centred coordinates), not by the code under test.

Usage: python3 benches/global_truth.py CLIP.y4m [...]
Env: BIN=target/release/mocomp  SHAKE_T=12  SHAKE_R=1.5
     SOURCES="flow blocks matches"  MODELS="similarity affine homography"
     FLOW_PRESETS="fast medium" (DIS presets tried with the flow source)
     THRESHOLD (globalmotion's --threshold, pixels; its default if unset)
Prints a Markdown table: a row per clip, source and model, with the
median and 90th percentile over pairs of the corner error, and the share
of pairs fitted.
"""

import csv
import math
import os
import statistics
import subprocess
import sys
import tempfile

BIN = os.path.realpath(os.environ.get("BIN", "target/release/mocomp"))
SHAKE_T = os.environ.get("SHAKE_T", "12")
SHAKE_R = os.environ.get("SHAKE_R", "1.5")
SOURCES = os.environ.get("SOURCES", "flow blocks matches").split()
MODELS = os.environ.get("MODELS", "similarity affine homography").split()
FLOW_PRESETS = os.environ.get("FLOW_PRESETS", "fast medium").split()
THRESHOLD = os.environ.get("THRESHOLD")


def matmul(a, b):
    return [[sum(a[r][k] * b[k][c] for k in range(3)) for c in range(3)] for r in range(3)]


def apply(m, x, y):
    w = m[2][0] * x + m[2][1] * y + m[2][2]
    return ((m[0][0] * x + m[0][1] * y + m[0][2]) / w, (m[1][0] * x + m[1][1] * y + m[1][2]) / w)


def pose(dx, dy, degrees):
    """The shaken window's pose: its centred coordinates to the still
    picture's centred coordinates."""
    a = math.radians(degrees)
    return [[math.cos(a), -math.sin(a), dx], [math.sin(a), math.cos(a), dy], [0.0, 0.0, 1.0]]


def pose_inverse(dx, dy, degrees):
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    # R^T (p - t)
    return [[c, s, -(c * dx + s * dy)], [-s, c, -(-s * dx + c * dy)], [0.0, 0.0, 1.0]]


def true_motion(prev, cur, width, height):
    """Pixel coordinates of frame t-1 to those of frame t: a scene point
    seen at q in t-1 is S_(t-1) q in the picture and S_t^-1 S_(t-1) q in t
    (centred coordinates, the centre at ((w-1)/2, (h-1)/2))."""
    cx, cy = (width - 1) / 2, (height - 1) / 2
    to_centred = [[1, 0, -cx], [0, 1, -cy], [0, 0, 1]]
    to_pixels = [[1, 0, cx], [0, 1, cy], [0, 0, 1]]
    centred = matmul(pose_inverse(*cur), pose(*prev))
    return matmul(to_pixels, matmul(centred, to_centred))


def corner_error(fit, truth, width, height):
    corners = [(0, 0), (width - 1, 0), (0, height - 1), (width - 1, height - 1)]
    total = 0.0
    for x, y in corners:
        (ax, ay), (bx, by) = apply(fit, x, y), apply(truth, x, y)
        total += math.hypot(ax - bx, ay - by)
    return total / 4


def size_of(y4m):
    with open(y4m, "rb") as f:
        header = f.readline().decode().split()
    width = int(next(t[1:] for t in header if t.startswith("W")))
    height = int(next(t[1:] for t in header if t.startswith("H")))
    return width, height


def percentile(values, p):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(p * (len(ordered) - 1) + 0.5))]


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    print("| clip | source | model | pairs fitted | median corner error px | 90th percentile px |")
    print("|---|---|---|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for clip in sys.argv[1:]:
            name = os.path.splitext(os.path.basename(clip))[0]
            shaken, truth_csv = os.path.join(tmp, "s.y4m"), os.path.join(tmp, "t.csv")
            subprocess.run([BIN, "shake", clip, "-o", shaken, "--translation", SHAKE_T, "--rotation", SHAKE_R,
                            "--seed", "1", "--truth", truth_csv], check=True, capture_output=True)
            with open(truth_csv) as f:
                poses = [(float(r["dx"]), float(r["dy"]), float(r["angle_deg"])) for r in csv.DictReader(f)]
            width, height = size_of(shaken)
            runs = [(s, p) for s in SOURCES for p in (FLOW_PRESETS if s == "flow" else [None])]
            for source, preset in runs:
                label = f"{source} ({preset})" if preset else source
                for model in MODELS:
                    fits_csv = os.path.join(tmp, "g.csv")
                    subprocess.run([BIN, "globalmotion", shaken, "--model", model, "--source", source,
                                    *(["--preset", preset] if preset else []),
                                    *(["--threshold", THRESHOLD] if THRESHOLD else []), "--csv", fits_csv],
                                   check=True, capture_output=True)
                    errors = []
                    with open(fits_csv) as f:
                        for row in csv.DictReader(f):
                            t = int(row["frame"])
                            if not row["h11"]:
                                continue  # no model fitted to the pair
                            h = [float(row[f"h{r}{c}"]) for r in (1, 2, 3) for c in (1, 2, 3)]
                            if not all(math.isfinite(v) for v in h):
                                continue
                            fit = [h[0:3], h[3:6], h[6:9]]
                            truth = true_motion(poses[t - 1], poses[t], width, height)
                            errors.append(corner_error(fit, truth, width, height))
                    pairs = len(poses) - 1
                    if not errors:
                        print(f"| {name} | {label} | {model} | 0 of {pairs} | - | - |")
                        continue
                    print(f"| {name} | {label} | {model} | {len(errors)} of {pairs} | "
                          f"{statistics.median(errors):.3f} | {percentile(errors, 0.9):.3f} |", flush=True)


if __name__ == "__main__":
    main()
