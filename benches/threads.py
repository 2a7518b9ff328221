#!/usr/bin/env python3
"""One thread against two: dense flow's presets and block search, pair by pair.

Usage:
  threads.py CLIP.y4m ... [--mocomp BIN] [--rounds R] [--presets P,P]
             [--methods M,M]

Per clip: `mocomp flow CLIP --frames 3:4 --preset P --threads T --runs 9
--json` for each DIS preset and `mocomp me CLIP --frames 0:10 --method M
--range 16 --threads T --json` for each block search, one thread and two
right after each other (which goes first alternating), `--rounds` times.
The time is the tool's own (`ms`, the median of its calls; `ms_per_frame`
for block search), so reading and start-up are left out. Printed: the
median over rounds of each thread count's time and of the rounds' paired
2-thread / 1-thread ratios (a pair of runs seconds apart sees the same
machine; single times drift by 1.5x between minutes on a shared 2-vCPU
machine). The results themselves are equal for any thread count
(`cargo test --test integration` with `dis::`, `me::`, `flow::`).
"""
import argparse
import json
import os
import statistics
import subprocess


def run(cmd):
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    doc = json.loads(out.strip().splitlines()[-1])
    return doc.get("ms", doc.get("ms_per_frame"))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("clips", nargs="+")
    ap.add_argument("--mocomp", default="target/release/mocomp")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--presets", default="ultrafast,fast,medium")
    ap.add_argument("--methods", default="esa,epzs")
    a = ap.parse_args()
    jobs = []
    for clip in a.clips:
        name = os.path.splitext(os.path.basename(clip))[0]
        for p in filter(None, a.presets.split(",")):
            cmd = [a.mocomp, "flow", clip, "--frames", "3:4", "--preset", p, "--runs", "9", "--json"]
            jobs.append((name, f"flow dis {p}", cmd))
        for m in filter(None, a.methods.split(",")):
            cmd = [a.mocomp, "me", clip, "--frames", "0:10", "--method", m, "--range", "16", "--json"]
            jobs.append((name, f"me {m} r16", cmd))
    print("| what | input | 1 thread ms | 2 threads ms | 2 / 1 |")
    print("|---|---|---:|---:|---:|")
    for name, what, cmd in jobs:
        one, two, ratios = [], [], []
        for r in range(a.rounds):
            order = (1, 2) if r % 2 == 0 else (2, 1)
            t = {n: run(cmd + ["--threads", str(n)]) for n in order}
            one.append(t[1])
            two.append(t[2])
            ratios.append(t[2] / t[1])
        print(
            f"| {what} | {name} | {statistics.median(one):.2f} | {statistics.median(two):.2f} "
            f"| {statistics.median(ratios):.2f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
