#!/usr/bin/env python3
"""One change measured against its parent: BD-rate and time of mocomp builds
or options against the first of them, on a set of sequences.

    python3 benches/pair.py OUT NAME=BINARY:PRESET[:ARG,ARG...] ... -- SEQ.y4m ...

Every sequence is encoded at QP 22/27/32/37 (QPS) by every variant in
turn (`mocomp encode --preset PRESET --qp Q --threads 1 --frames FRAMES
--metrics psnr --json`, then the variant's ARGs), the first FRAMES (30)
frames, one thread, the variants interleaved per sequence and QP so that
the machine's drift falls on all alike. Printed per sequence: each
variant's BD-rate against the first (luma PSNR, cubic, `mocomp bdrate`;
PSNR=yuv takes the PSNR of Y, U and V weighted 6:1:1 instead), with the
piecewise-cubic (pchip) one beside it where the two differ by more than a
point (a curve that bends hard between two QPs: fish_1160's flickering
light made a third reference's -3.5 % read +5.0 % by the cubic fit);
over the set: the mean BD-rate (and pchip's) and the ratio of the summed `encode_ms`
(the encoder's own time, reading and start-up left out) and of the wall
time. OUT gets one CSV of points per sequence.

Example (a build of the parent beside this tree's, and an option):

    python3 benches/pair.py /tmp/ab base=../parent/target/release/mocomp:medium \\
        new=target/release/mocomp:medium fast=target/release/mocomp:medium:--decision,fast \\
        -- ../shared/data/pan_cif.y4m DEV/*.y4m REAL/*.y4m
"""
import csv
import json
import math
import os
import subprocess
import sys
import time


def parse_variants(args):
    variants = []
    for v in args:
        name, rest = v.split("=", 1)
        parts = rest.split(":")
        if len(parts) < 2:
            raise SystemExit(f"{v}: expected NAME=BINARY:PRESET[:ARG,ARG...]")
        extra = parts[2].split(",") if len(parts) > 2 and parts[2] else []
        variants.append((name, parts[0], parts[1], extra))
    if len(variants) < 2:
        raise SystemExit("two variants at least: the first is the anchor")
    return variants


def encode(binary, preset, extra, seq, qp, frames, out):
    cmd = [binary, "encode", seq, "-o", out, "--preset", preset, "--qp", str(qp), "--threads", "1",
           "--frames", frames, "--metrics", "psnr", "--json", "--quiet"] + extra
    start = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{done.stderr}")
    return json.loads(done.stdout.strip().splitlines()[-1]), wall


def bd_rate(binary, path, anchor, test):
    """The cubic and the pchip BD-rate, or None."""
    done = subprocess.run([binary, "bdrate", f"{path}:{anchor}", f"{path}:{test}", "--json"],
                          capture_output=True, text=True)
    if done.returncode != 0:
        return None
    result = json.loads(done.stdout)
    values = (result.get("bd_rate_cubic"), result.get("bd_rate_pchip"))
    return values if all(v is not None and math.isfinite(v) for v in values) else None


def shown(values):
    """A BD-rate as printed: the cubic one, pchip's beside it where they part."""
    if values is None:
        return "n/a"
    cubic, pchip = values
    apart = f" (pchip {pchip:+.2f} %)" if abs(cubic - pchip) > 1.0 else ""
    return f"{cubic:+.2f} %{apart}"


def main():
    if "--" not in sys.argv or len(sys.argv) < 5:
        raise SystemExit(__doc__)
    out = sys.argv[1]
    split = sys.argv.index("--")
    variants = parse_variants(sys.argv[2:split])
    seqs = sys.argv[split + 1:]
    qps = [int(q) for q in os.environ.get("QPS", "22 27 32 37").split()]
    frames = os.environ.get("FRAMES", "30")
    # The CSV's quality column (named as `mocomp bdrate` reads it).
    quality = {"y": "psnr_y", "yuv": "psnr_yuv"}[os.environ.get("PSNR", "y")]
    os.makedirs(out, exist_ok=True)
    names = [v[0] for v in variants]
    encode_ms = dict.fromkeys(names, 0.0)
    wall = dict.fromkeys(names, 0.0)
    bds = {n: [] for n in names[1:]}
    for seq in seqs:
        name = os.path.splitext(os.path.basename(seq))[0]
        rows = []
        for qp in qps:
            for vname, binary, preset, extra in variants:
                summary, seconds = encode(binary, preset, extra, seq, qp, frames, os.path.join(out, "x.mcv"))
                encode_ms[vname] += summary["encode_ms"]
                wall[vname] += seconds
                rows.append(dict(codec=vname, q=qp, bytes=summary["bytes"], frames=summary["frames"],
                                 kbps=summary["kbps"], psnr_y=summary[quality]))
        path = os.path.join(out, f"{name}.csv")
        with open(path, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=["codec", "q", "bytes", "frames", "kbps", "psnr_y"])
            writer.writeheader()
            writer.writerows(rows)
        line = [f"{name:18}"]
        for vname in names[1:]:
            values = bd_rate(variants[0][1], path, names[0], vname)
            if values is not None:
                bds[vname].append(values)
            line.append(f"{vname} {shown(values)}")
        print("  ".join(line), flush=True)
    anchor = names[0]
    for vname in names[1:]:
        values = bds[vname]
        mean, pchip = (sum(v[i] for v in values) / len(values) if values else float("nan") for i in (0, 1))
        print(f"{vname:12} BD-rate {mean:+.2f} % (mean of {len(values)}; pchip {pchip:+.2f} %)  "
              f"encode_ms x{encode_ms[vname] / encode_ms[anchor]:.3f}  wall x{wall[vname] / wall[anchor]:.3f}")
    print(f"{anchor:12} (anchor) encode_ms {encode_ms[anchor]:.0f}  wall {wall[anchor]:.1f} s")


if __name__ == "__main__":
    main()
