"""mocomp.flow from Python against the CLI's own timing of the same preset
and against OpenCV-python's DIS, one thread each, in one run.

    python python/examples/flow_overhead.py PAIR.y4m [RUNS] [MOCOMP_BINARY] [ROUNDS]

Times are medians over RUNS calls (default 9) of the flow alone, each
tool's after a warm-up call: for the CLI, `mocomp flow --threads 1
--warmup 1 --runs RUNS --json` (its own median); for
Python, the call to mocomp.flow and to a mocomp.DenseFlow object's calc
(reading the arrays included), the latter writing into the flow array of
the call before as a frame loop does (`calc(a, b, flow)`, as OpenCV's); for
OpenCV,
DISOpticalFlow.calc on the same luma (cv2.setNumThreads(1)).

One tool's time alone drifts by up to 1.5x between minutes on a 2-core
virtual machine, so the ratios are paired: each of ROUNDS rounds (default
7) times the CLI and both Python calls back to back (the order alternating
between rounds), and a ratio is the median over rounds of that round's
ratio, printed with the least and greatest. The ms columns are medians over
rounds.
"""

import json
import pathlib
import statistics
import subprocess
import sys
import time

import mocomp

src = pathlib.Path(sys.argv[1])
runs = int(sys.argv[2]) if len(sys.argv) > 2 else 9
binary = sys.argv[3] if len(sys.argv) > 3 else "target/release/mocomp"
n_rounds = int(sys.argv[4]) if len(sys.argv) > 4 else 7
frames = mocomp.read_y4m(src, frames=2)
a, b = frames[0][0], frames[1][0]

try:
    import cv2

    cv2.setNumThreads(1)
except ImportError:
    cv2 = None
cv_presets = {"ultrafast": 0, "fast": 1, "medium": 2} if cv2 else {}


def median_ms(f):
    f()  # warm-up
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        f()
        times.append((time.perf_counter() - t) * 1e3)
    return statistics.median(times)


print(f"{src.name} {a.shape[1]}x{a.shape[0]}, one thread, median of {runs} calls, {n_rounds} paired rounds")
print("| preset | CLI ms | mocomp.flow ms | flow / CLI (min-max) | DenseFlow.calc ms | DenseFlow / CLI (min-max) | OpenCV DIS ms |")
print("|---|---:|---:|---:|---:|---:|---:|")


def cli_ms(preset):
    cli = subprocess.run(
        [binary, "flow", str(src), "--frames", "0:1", "--preset", preset, "--threads", "1",
         "--warmup", "1", "--runs", str(runs), "--json"],
        check=True, capture_output=True, text=True,
    )
    return json.loads(cli.stdout)["ms"]


def paired_round(k, preset, estimator):
    """(CLI, mocomp.flow, DenseFlow.calc) ms, the CLI first in even rounds."""
    py = lambda: median_ms(lambda: mocomp.flow(a, b, preset=preset, threads=1))
    out = estimator.calc(a, b)
    obj = lambda: median_ms(lambda: estimator.calc(a, b, out))
    if k % 2 == 0:
        c = cli_ms(preset)
        return c, py(), obj()
    p, o = py(), obj()
    return cli_ms(preset), p, o


def spread(ratios):
    return f"{statistics.median(ratios):.3f} ({min(ratios):.3f}-{max(ratios):.3f})"


for preset in ("ultrafast", "fast", "medium", "accurate"):
    estimator = mocomp.DenseFlow(preset=preset, threads=1)
    rounds = [paired_round(k, preset, estimator) for k in range(n_rounds)]
    cli, py, obj = (statistics.median(r[k] for r in rounds) for k in range(3))
    py_ratio = spread([r[1] / r[0] for r in rounds])
    obj_ratio = spread([r[2] / r[0] for r in rounds])
    cv_ms = float("nan")
    if preset in cv_presets:
        dis = cv2.DISOpticalFlow_create(cv_presets[preset])
        cv_out = dis.calc(a, b, None)
        cv_ms = median_ms(lambda: dis.calc(a, b, cv_out))
    print(f"| {preset} | {cli:.2f} | {py:.2f} | {py_ratio} | {obj:.2f} | {obj_ratio} | {cv_ms:.2f} |")
