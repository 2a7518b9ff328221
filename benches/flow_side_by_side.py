#!/usr/bin/env python3
"""mocomp's DIS presets beside OpenCV's DIS presets, one thread, same run.

Usage:
  flow_side_by_side.py WORK [CLIP.y4m ...] [--pair DIR ...] [--repeats N]
                       [--rounds R] [--mocomp BIN] [--peers DIR] [--csv OUT]

Each CLIP gives one pair with an exact ground truth: its frame 5, and that
frame under a known affine motion (rotation and zoom about the centre, then
a translation; `peers/flow_opencv.py --synth`, bicubic). The motion of a
clip the script knows is the one below (large motion, as the issue's real
pairs); any other clip gets a translation of 6 % of its width and 3 % of
its height, 1 degree and zoom 1.01. A `--pair DIR` is a ready pair
(frame1.png, frame2.png, gt.flo), such as ../shared/data/flowpair.

Per pair and preset (ultrafast, fast, medium) both tools run `--repeats`
calls after a warm-up and report their median (OpenCV through
cv2.DISOpticalFlow_create(preset), cv2.setNumThreads(1); mocomp through
`mocomp flow --preset P --threads 1 --warmup 1 --runs N`), one tool right after the
other, which goes first alternating; this is done `--rounds` times. The
time ratio is the median over rounds of each round's ratio (a pair of runs
seconds apart sees the same machine: single times here drift by 1.5x
between minutes), the times the medians over rounds. Both flows are scored
by this script with one code: EPE over every pixel (printed), and in the
CSV also over the pixels whose true destination is inside frame 2 and
over those whose content leaves it (`peer_*` columns: the OpenCV method each
preset runs beside).

Printed: per pair and preset, mocomp's and DIS's ms and EPE, the time
ratio, and whether mocomp is no slower and no less accurate (the bar of
issue 36); then per preset the geometric mean of the time ratios and the
mean EPE of both.

With `--accurate`, mocomp's accurate preset also runs beside OpenCV's
DeepFlow (optflow.DeepFlow, its defaults), whose bar is no larger EPE in
a quarter of DeepFlow's time; one call each per round (DeepFlow takes
seconds a pair), `--accurate-rounds` rounds.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "flowbench"))
from evaluate import read_flo  # noqa: E402  (the flow benchmark's reader)

PRESETS = ("ultrafast", "fast", "medium")
# The OpenCV method each mocomp preset runs beside, and the share of that
# method's time the preset may take.
PEERS = {"ultrafast": ("dis_ultrafast", 1.0), "fast": ("dis_fast", 1.0), "medium": ("dis_medium", 1.0),
         "accurate": ("deepflow", 0.25)}

# tx, ty (px), rotation (degrees), zoom: the motions of the earlier notes.
MOTIONS = {
    "fish_1160": (40, -25, 2.0, 1.03),
    "talk_vga": (30, 12, 1.0, 1.02),
    "launch_360p": (-35, 10, 0.5, 1.0),
    "room_400": (25, 20, 1.5, 0.98),
    "smile_360p": (12, -8, 0.8, 1.01),
    # 1280x720, the largest motion: a photograph of the development set
    # (benches/seqbench/make.sh), moved 180 px as the largest.
    "garden_720p": (180, -50, 1.0, 1.02),
}


def epe(est, gt, mask=None):
    d = np.hypot(est[..., 0] - gt[..., 0], est[..., 1] - gt[..., 1])
    return float(d[mask].mean() if mask is not None else d.mean())


def inside_mask(gt, margin=2.0):
    h, w = gt.shape[:2]
    xs, ys = np.meshgrid(np.arange(w), np.arange(h))
    dx, dy = xs + gt[..., 0], ys + gt[..., 1]
    return (dx >= margin) & (dx <= w - 1 - margin) & (dy >= margin) & (dy <= h - 1 - margin)


def make_pair(clip, work, peers):
    name = os.path.splitext(os.path.basename(clip))[0]
    out = os.path.join(work, name)
    if not os.path.exists(os.path.join(out, "gt.flo")):
        with open(clip, "rb") as f:
            header = f.readline().decode()
        w = int(next(t[1:] for t in header.split() if t.startswith("W")))
        h = int(next(t[1:] for t in header.split() if t.startswith("H")))
        tx, ty, rot, zoom = MOTIONS.get(name, (round(0.06 * w), round(0.03 * h), 1.0, 1.01))
        subprocess.run([sys.executable, os.path.join(peers, "flow_opencv.py"), "--synth", out,
                        "--src-y4m", clip, "--src-frame", "5", "--tx", str(tx), "--ty", str(ty),
                        "--rot", str(rot), "--zoom", str(zoom), "--methods", "dis_ultrafast",
                        "--repeats", "1"], check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
    return name, out


def run_opencv(pair, peers, repeats, preset):
    method = PEERS[preset][0]
    est = os.path.join(pair, "est")
    table = os.path.join(est, "opencv_%s.csv" % preset)
    subprocess.run([sys.executable, os.path.join(peers, "flow_opencv.py"),
                    "--img1", os.path.join(pair, "frame1.png"), "--img2", os.path.join(pair, "frame2.png"),
                    "--threads", "1", "--repeats", str(repeats), "--methods", method,
                    "--save-flo", est, "--csv", table], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    row = next(csv.DictReader(open(table)))
    return float(row["time_ms"]), os.path.join(est, "%s.flo" % method)


def run_mocomp(pair, binary, repeats, preset):
    flo = os.path.join(pair, "est", "mocomp_%s.flo" % preset)
    out = subprocess.run([binary, "flow", os.path.join(pair, "frame1.png"),
                          os.path.join(pair, "frame2.png"), "--preset", preset, "--threads", "1",
                          "--warmup", "1", "--runs", str(repeats), "--json", "-o", flo],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])["ms"], flo


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("work")
    ap.add_argument("clips", nargs="*")
    ap.add_argument("--pair", action="append", default=[])
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--mocomp", default="target/release/mocomp")
    ap.add_argument("--peers", default=os.path.join(os.path.dirname(__file__), "..", "..", "shared", "peers"))
    ap.add_argument("--csv")
    ap.add_argument("--accurate", action="store_true", help="also accurate beside DeepFlow")
    ap.add_argument("--accurate-rounds", type=int, default=2)
    a = ap.parse_args()
    presets = PRESETS + (("accurate",) if a.accurate else ())
    os.makedirs(a.work, exist_ok=True)
    pairs = [make_pair(c, a.work, a.peers) for c in a.clips]
    pairs += [(os.path.basename(os.path.normpath(d)), d) for d in a.pair]
    rows = []
    for name, d in pairs:
        os.makedirs(os.path.join(d, "est"), exist_ok=True)
        times = {p: {"mocomp": [], "peer": []} for p in presets}
        flows = {}
        for r in range(a.rounds):
            for k, p in enumerate(presets):
                if p == "accurate" and r >= a.accurate_rounds:
                    continue
                repeats = 1 if p == "accurate" else a.repeats
                order = ["mocomp", "peer"] if (r + k) % 2 == 0 else ["peer", "mocomp"]
                for tool in order:
                    if tool == "mocomp":
                        ms, flows[("mocomp", p)] = run_mocomp(d, a.mocomp, repeats, p)
                    else:
                        ms, flows[("peer", p)] = run_opencv(d, a.peers, repeats, p)
                    times[p][tool].append(ms)
        gt = read_flo(os.path.join(d, "gt.flo"))
        inside = inside_mask(gt)
        h, w = gt.shape[:2]
        for p in presets:
            fm, fp = read_flo(flows[("mocomp", p)]), read_flo(flows[("peer", p)])
            tm, tp = times[p]["mocomp"], times[p]["peer"]
            rows.append(dict(pair=name, size="%dx%d" % (w, h), max_motion=float(np.hypot(gt[..., 0], gt[..., 1]).max()),
                             preset=p, mocomp_ms=float(np.median(tm)), peer_ms=float(np.median(tp)),
                             ratio=float(np.median([m / c for m, c in zip(tm, tp)])),
                             mocomp_epe=epe(fm, gt), peer_epe=epe(fp, gt),
                             mocomp_epe_inside=epe(fm, gt, inside), peer_epe_inside=epe(fp, gt, inside),
                             mocomp_epe_leaving=epe(fm, gt, ~inside), peer_epe_leaving=epe(fp, gt, ~inside),
                             leaving_share=float(1 - inside.mean())))
        print("%s done" % name, file=sys.stderr, flush=True)
    report(rows)
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            wr = csv.DictWriter(f, fieldnames=list(rows[0]))
            wr.writeheader()
            wr.writerows(rows)


def meets(r):
    return r["ratio"] <= PEERS[r["preset"]][1] and r["mocomp_epe"] <= r["peer_epe"]


def report(rows):
    print("| pair | size | max motion | preset | mocomp ms | peer | peer ms | time ratio | mocomp EPE | peer EPE | bar |")
    print("|---|---|---:|---|---:|---|---:|---:|---:|---:|---|")
    for r in rows:
        print("| %s | %s | %.0f px | %s | %.2f | %s | %.2f | %.2fx | %.3f | %.3f | %s |" % (
            r["pair"], r["size"], r["max_motion"], r["preset"], r["mocomp_ms"], PEERS[r["preset"]][0],
            r["peer_ms"], r["ratio"], r["mocomp_epe"], r["peer_epe"], "met" if meets(r) else "not met"))
    print()
    print("| preset | peer | time ratio (geometric mean) | bar | mocomp EPE (mean) | peer EPE (mean) | pairs meeting the bar |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for p in PEERS:
        sel = [r for r in rows if r["preset"] == p]
        if not sel:
            continue
        ratio = math.exp(sum(math.log(r["ratio"]) for r in sel) / len(sel))
        met = sum(meets(r) for r in sel)
        print("| %s | %s | %.2fx | <= %.2fx | %.3f | %.3f | %d of %d |" % (
            p, PEERS[p][0], ratio, PEERS[p][1], np.mean([r["mocomp_epe"] for r in sel]),
            np.mean([r["peer_epe"] for r in sel]), met, len(sel)))


if __name__ == "__main__":
    main()
