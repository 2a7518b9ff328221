#!/usr/bin/env python3
"""Evaluates every flow of a flow-benchmark run (run.sh) with one code:

  WORK/pairs/<case>/{frame1.png, frame2.png, gt.flo, occ.png}   (ground truth)
  WORK/est/<case>/<method>.flo, mocomp_*.json, opencv_*.csv       (estimates, times)

Errors over the pixels valid in the ground truth (EPE px, Middlebury AE deg,
R1/R3 = % of pixels with EPE over 1/3 px), split into visible and occluded
(hidden in frame 2 or leaving it); means over cases, per method, overall and
per kind of case. Cases without ground truth (the real Middlebury pairs)
get the motion-compensated PSNR: frame 2 warped back along the flow
(bilinear), against frame 1, over the pixels whose source is inside.
Times are each tool's own median of its timing runs (one thread).

Usage: evaluate.py WORK [--csv OUT.csv]
"""
import csv
import glob
import json
import math
import os
import sys

import numpy as np
import cv2

UNKNOWN = 1e9


def read_flo(path):
    with open(path, "rb") as f:
        if np.fromfile(f, "<f4", 1)[0] != np.float32(202021.25):
            raise ValueError(path + ": not a .flo")
        w, h = (int(x) for x in np.fromfile(f, "<i4", 2))
        return np.fromfile(f, "<f4", 2 * w * h).reshape(h, w, 2)


def errors(est, gt, mask):
    d = est[mask] - gt[mask]
    epe = np.hypot(d[:, 0], d[:, 1])
    u, v, ug, vg = est[mask][:, 0], est[mask][:, 1], gt[mask][:, 0], gt[mask][:, 1]
    cos = (u * ug + v * vg + 1) / np.sqrt((u * u + v * v + 1) * (ug * ug + vg * vg + 1))
    ae = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    return dict(epe=epe.mean(), ae=ae.mean(), r1=100 * (epe > 1).mean(), r3=100 * (epe > 3).mean())


def mc_psnr(f1, f2, flow):
    h, w = f1.shape
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    mx, my = xs + flow[..., 0], ys + flow[..., 1]
    warped = cv2.remap(f2.astype(np.float32), mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    inside = (mx >= 0) & (my >= 0) & (mx <= w - 1) & (my <= h - 1)
    mse = np.mean((warped[inside] - f1[inside].astype(np.float32)) ** 2)
    return 10 * math.log10(255 ** 2 / max(mse, 1e-10))


def times(est_dir):
    t = {}
    for p in glob.glob(os.path.join(est_dir, "mocomp_*.json")):
        for line in open(p):
            r = json.loads(line)
            t[r["name"]] = r["ms"]
    for p in glob.glob(os.path.join(est_dir, "opencv_*.csv")):
        for r in csv.DictReader(open(p)):
            t[r["method"]] = float(r["time_total_ms"])
    return t


def main():
    work = sys.argv[1]
    out_csv = sys.argv[sys.argv.index("--csv") + 1] if "--csv" in sys.argv else None
    rows = []
    for est_dir in sorted(glob.glob(os.path.join(work, "est", "*"))):
        case = os.path.basename(est_dir)
        gt_dir = os.path.join(work, "pairs", case)
        t = times(est_dir)
        has_gt = os.path.exists(os.path.join(gt_dir, "gt.flo"))
        if has_gt:
            gt = read_flo(os.path.join(gt_dir, "gt.flo"))
            valid = (np.abs(gt) < UNKNOWN).all(axis=2)
            occ = cv2.imread(os.path.join(gt_dir, "occ.png"), cv2.IMREAD_GRAYSCALE) > 127
        else:
            pair_dir = find_real_pair(case)
            if pair_dir is None:
                continue
            f1 = cv2.imread(os.path.join(pair_dir, "frame10.png"), cv2.IMREAD_GRAYSCALE)
            f2 = cv2.imread(os.path.join(pair_dir, "frame11.png"), cv2.IMREAD_GRAYSCALE)
        for flo in sorted(glob.glob(os.path.join(est_dir, "*.flo"))):
            method = os.path.splitext(os.path.basename(flo))[0]
            est = read_flo(flo)
            row = dict(case=case, kind=case.split("_", 1)[1] if has_gt else "real", method=method,
                       ms=t.get(method, float("nan")))
            if has_gt:
                row.update(errors(est, gt, valid))
                vis, hid = valid & ~occ, valid & occ
                row["epe_vis"] = errors(est, gt, vis)["epe"]
                row["epe_occ"] = errors(est, gt, hid)["epe"] if hid.any() else float("nan")
            else:
                row["mc_psnr"] = mc_psnr(f1, f2, est)
            rows.append(row)
    report(rows)
    if out_csv:
        keys = sorted({k for r in rows for k in r})
        with open(out_csv, "w", newline="") as f:
            w = csv.DictWriter(f, keys)
            w.writeheader()
            w.writerows(rows)


def find_real_pair(case):
    here = os.path.dirname(os.path.abspath(__file__))
    for root in (os.environ.get("PEERS", ""), os.path.join(here, "..", "..", "..", "shared", "peers")):
        d = os.path.join(root, "..", "data", "pairs", case)
        if root and os.path.exists(os.path.join(d, "frame10.png")):
            return d
    return None


def mean(xs):
    xs = [x for x in xs if not math.isnan(x)]
    return sum(xs) / len(xs) if xs else float("nan")


def report(rows):
    gt_rows = [r for r in rows if r["kind"] != "real"]
    methods = sorted({r["method"] for r in rows}, key=lambda m: (not m.startswith("mocomp"), m))
    kinds = sorted({r["kind"] for r in gt_rows})
    n_cases = len({r["case"] for r in gt_rows})
    print("Synthetic-motion pairs on photographs: %d pairs; means over pairs\n" % n_cases)
    print("| method | EPE | EPE visible | EPE occluded | AE | R1 % | R3 % | ms |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for m in methods:
        rs = [r for r in gt_rows if r["method"] == m]
        if not rs:
            continue
        print("| %s | %.2f | %.2f | %.2f | %.2f | %.1f | %.1f | %.1f |" % (
            m, mean([r["epe"] for r in rs]), mean([r["epe_vis"] for r in rs]), mean([r["epe_occ"] for r in rs]),
            mean([r["ae"] for r in rs]), mean([r["r1"] for r in rs]), mean([r["r3"] for r in rs]),
            mean([r["ms"] for r in rs])))
    print("\nEPE per kind of pair (mean over photographs)\n")
    print("| method | " + " | ".join(kinds) + " |")
    print("|---|" + "---:|" * len(kinds))
    for m in methods:
        cells = [mean([r["epe"] for r in gt_rows if r["method"] == m and r["kind"] == k]) for k in kinds]
        if all(math.isnan(c) for c in cells):
            continue
        print("| %s | " % m + " | ".join("%.2f" % c for c in cells) + " |")
    real = [r for r in rows if r["kind"] == "real"]
    if real:
        cases = sorted({r["case"] for r in real})
        print("\nReal pairs without ground truth: motion-compensated PSNR (dB), time (ms)\n")
        print("| method | " + " | ".join(cases) + " | mean | ms |")
        print("|---|" + "---:|" * (len(cases) + 2))
        for m in methods:
            rs = {r["case"]: r for r in real if r["method"] == m}
            if not rs:
                continue
            print("| %s | " % m + " | ".join("%.2f" % rs[c]["mc_psnr"] if c in rs else "-" for c in cases)
                  + " | %.2f | %.1f |" % (mean([r["mc_psnr"] for r in rs.values()]),
                                           mean([r["ms"] for r in rs.values()])))


if __name__ == "__main__":
    main()
