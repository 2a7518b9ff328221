#!/usr/bin/env python3
"""Instructions of mocomp builds or options against the first of them, on a
set of sequences: a speed figure that a noisy machine does not move.

    python3 benches/instructions.py NAME=BINARY:PRESET[:ARG,ARG...] ... -- SEQ.y4m ...

Each variant encodes each sequence at QP 22 and 32 (QPS), the first FRAMES
(10) frames, one thread, no metrics, under valgrind's cachegrind
(`--cache-sim=no`: instructions only), JOBS (2) encodes at a time. Printed
per sequence: each variant's instructions and stream bytes as ratios to
the first's; then each variant's total. Instructions are not time (memory
stalls and instruction mixes are not counted), but they are exact from run
to run: a change that is meant to leave the streams as they are shows
bytes x1.000. Ten frames give the I frame more weight than a 30-frame
encode does.

Example (a build of the parent beside this tree's):

    python3 benches/instructions.py base=../parent/target/release/mocomp:ultrafast \\
        new=target/release/mocomp:ultrafast -- DIR/dog_1080p.y4m DIR/talk_vga.y4m
"""
import os
import re
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

from pair import parse_variants  # the same NAME=BINARY:PRESET[:ARGS] syntax

QPS = os.environ.get("QPS", "22 32").split()
FRAMES = os.environ.get("FRAMES", "10")
JOBS = int(os.environ.get("JOBS", "2"))


def parse(argv):
    if "--" not in argv:
        raise SystemExit(__doc__)
    split = argv.index("--")
    return parse_variants(argv[:split]), argv[split + 1:]


def count(job):
    """Instructions and stream bytes of one encode."""
    (name, binary, preset, extra), seq, qp, work = job
    out = os.path.join(work, f"{name}_{os.path.basename(seq)}_{qp}.mcv")
    cmd = ["valgrind", "--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null",
           binary, "encode", seq, "-o", out, "--preset", preset, "--qp", qp, "--frames", FRAMES,
           "--threads", "1", "--metrics", "none", "--quiet"] + extra
    done = subprocess.run(cmd, capture_output=True, text=True)
    found = re.search(r"I\s+refs:\s+([\d,]+)", done.stderr)
    if done.returncode != 0 or not found:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{done.stderr[-2000:]}")
    return name, os.path.basename(seq), int(found.group(1).replace(",", "")), os.path.getsize(out)


def main():
    variants, seqs = parse(sys.argv[1:])
    with tempfile.TemporaryDirectory() as work, ThreadPoolExecutor(JOBS) as pool:
        jobs = [(v, s, q, work) for s in seqs for q in QPS for v in variants]
        results = list(pool.map(count, jobs))
    per = {}
    for name, seq, instructions, size in results:
        entry = per.setdefault(seq, {}).setdefault(name, [0, 0])
        entry[0] += instructions
        entry[1] += size
    names = [v[0] for v in variants]
    anchor = names[0]
    for seq, by in per.items():
        cells = [f"{n} {by[n][0] / 1e9:.2f} G x{by[n][0] / by[anchor][0]:.3f} bytes x{by[n][1] / by[anchor][1]:.3f}"
                 for n in names]
        print(f"{seq:22s}", "  ".join(cells))
    totals = {n: sum(by[n][0] for by in per.values()) for n in names}
    for n in names:
        print(f"{n:10s} {totals[n] / 1e9:.2f} G instructions, x{totals[n] / totals[anchor]:.4f}")


if __name__ == "__main__":
    main()
