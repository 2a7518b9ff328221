"""mocomp.flow from Python against the CLI's own timing of the same preset
and against OpenCV-python's DIS, one thread each, in one run.

    python python/examples/flow_overhead.py PAIR.y4m [RUNS] [MOCOMP_BINARY]

Times are medians over RUNS calls (default 9) of the flow alone: for the
CLI, `mocomp flow --threads 1 --runs RUNS --json` (its own median);
CLI and Python alternate over 3 rounds and each reports the median of its
rounds (a 2-core virtual machine drifts by several percent between runs);
for Python, the call to mocomp.flow and to a mocomp.DenseFlow object's
calc, made once (conversion of the arrays included);
for OpenCV, DISOpticalFlow.calc on the same luma (cv2.setNumThreads(1)).
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


print(f"{src.name} {a.shape[1]}x{a.shape[0]}, one thread, median of {runs}")
print("| preset | CLI ms | mocomp.flow ms | flow / CLI | DenseFlow.calc ms | DenseFlow / CLI | OpenCV DIS ms |")
print("|---|---:|---:|---:|---:|---:|---:|")
def cli_ms(preset):
    cli = subprocess.run(
        [binary, "flow", str(src), "--frames", "0:1", "--preset", preset, "--threads", "1",
         "--runs", str(runs), "--json"],
        check=True, capture_output=True, text=True,
    )
    return json.loads(cli.stdout)["ms"]


for preset in ("ultrafast", "fast", "medium"):
    estimator = mocomp.DenseFlow(preset=preset, threads=1)
    rounds = [
        (
            cli_ms(preset),
            median_ms(lambda: mocomp.flow(a, b, preset=preset, threads=1)),
            median_ms(lambda: estimator.calc(a, b)),
        )
        for _ in range(3)
    ]
    cli, py, obj = (statistics.median(r[k] for r in rounds) for k in range(3))
    cv_ms = float("nan")
    if preset in cv_presets:
        dis = cv2.DISOpticalFlow_create(cv_presets[preset])
        cv_ms = median_ms(lambda: dis.calc(a, b, None))
    print(f"| {preset} | {cli:.2f} | {py:.2f} | {py / cli:.3f} | {obj:.2f} | {obj / cli:.3f} | {cv_ms:.2f} |")
