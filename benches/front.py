#!/usr/bin/env python3
"""The speed/compression front: mocomp's presets beside x264's.

    python3 benches/front.py OUT_DIR SEQ.y4m [SEQ.y4m ...]
    python3 benches/front.py OUT_DIR --coverage   # the coverage table of a run again

Every sequence is encoded at QP 22/27/32/37 by every mocomp preset and by
x264's own command line at every x264 preset from ultrafast to slower
(`x264 --preset P --tune psnr --qp Q --bframes 0 --keyint infinite
--scenecut 0 --threads 1`), IPPP, one thread, the first FRAMES
frames (default 60, as issue 35's own measure: x264's start-up, about
30 ms an encode against mocomp's 6, weighs twice as much at 30 frames;
a sequence with fewer is coded whole). Each encode is timed as a whole process; encodes are
interleaved per sequence and QP so that the machine's drift falls on all
encoders alike. Neither encoder measures quality in the timed process
(x264 without --psnr, mocomp with --metrics none): each PSNR is measured
after, on the stream decoded (x264's by ffmpeg, mocomp's by `mocomp
decode`), by `mocomp quality` (per-frame luma PSNR). x264's settings SEI
is not counted in its size.

Per sequence: BD-rate (luma PSNR, mean over frames, cubic, `mocomp
bdrate`) of every preset against x264 medium and x264 superfast. Over the
set: the mean BD-rate and the mean time per encode, and the time as a
ratio to x264 medium's (ratio of the sums: every encode of the set counts
once). Then each x264 preset but ultrafast beside the mocomp presets no
slower per encode, BD-rate measured against it directly: the one with
the fewest bits, and the fastest with no more bits (`covered` where there
is one: issue 35's goal). Written to OUT_DIR: points.csv (every encode), front.md (the
table), front.json, front.svg (time per encode against BD-rate).

Threads: with THREADS_PRESET (e.g. medium), every sequence of at least
THREADS_MIN_WIDTH (1280) pixels across is also encoded by that preset at
QP 27 on 1 and on 2 threads (x264 beside it: --threads 1 and 2), in
THREADS_RUNS (5) rounds, each encoder's two runs side by side in a round
(mocomp 1, mocomp 2, x264 1, x264 2); the table gives each time's median
and the median of the rounds' 2-thread / 1-thread ratios (a pair's two
runs see the same state of the machine, which drifts between rounds);
every round's four times in threads.csv. x264's own ratio is the
machine's control: a round where it is above TWO_CPU_RATIO (0.85) had,
in effect, one processor (something else was using the other: a cargo
build beside a run gave 0.84-1.13 for both encoders while it lasted),
and the last column
gives mocomp's median ratio over the other rounds (how many of them
beside it). Every round stays in the medians before it.

Env: FRAMES (60), QPS ("22 27 32 37"), MOCOMP_PRESETS, X264_PRESETS (medium among them),
MOCOMP (a binary; default this tree's, built now), RUNS (timing rounds per
encode, the median kept; default 1), MOCOMP_ARGS (added to every mocomp
encode, e.g. "--refs 2"), THREADS_PRESET, THREADS_MIN_WIDTH, THREADS_RUNS.
"""
import csv
import json
import math
import os
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
QPS = [int(q) for q in os.environ.get("QPS", "22 27 32 37").split()]
FRAMES = int(os.environ.get("FRAMES", "60"))
RUNS = int(os.environ.get("RUNS", "1"))
MOCOMP_PRESETS = os.environ.get(
    "MOCOMP_PRESETS", "ultrafast superfast veryfast faster fast medium slow slower"
).split()
X264_PRESETS = os.environ.get(
    "X264_PRESETS", "ultrafast superfast veryfast faster fast medium slow slower"
).split()
MOCOMP_ARGS = os.environ.get("MOCOMP_ARGS", "").split()
ANCHORS = ["x264:medium", "x264:superfast"]


def mocomp_binary():
    if os.environ.get("MOCOMP"):
        return os.environ["MOCOMP"]
    subprocess.run(
        ["cargo", "build", "--release", "-q", "--manifest-path", os.path.join(ROOT, "Cargo.toml")],
        check=True,
    )
    return os.path.join(ROOT, "target", "release", "mocomp")


def y4m_fps(path):
    with open(path, "rb") as f:
        header = f.readline().decode("ascii", "replace").split()
    for token in header:
        if token.startswith("F"):
            num, den = token[1:].split(":")
            return int(num) / int(den)
    raise SystemExit(f"{path}: no frame rate in the Y4M header")


def timed(cmd):
    """Runs cmd RUNS times; its stdout+stderr of the last run and the median wall time."""
    times = []
    for _ in range(RUNS):
        start = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True)
        times.append(time.perf_counter() - start)
        if done.returncode != 0:
            raise SystemExit(f"failed: {' '.join(cmd)}\n{done.stderr}")
    return done.stdout + done.stderr, statistics.median(times)


def annexb_bytes_without_sei(path):
    """Bytes of an H.264 Annex-B stream less its SEI NAL units (x264's settings text)."""
    data = open(path, "rb").read()
    starts = []
    i = data.find(b"\x00\x00\x01")
    while i >= 0:
        starts.append(i + 3)
        i = data.find(b"\x00\x00\x01", i + 3)
    sei = 0
    for k, s in enumerate(starts):
        end = starts[k + 1] - 3 if k + 1 < len(starts) else len(data)
        if data[s] & 0x1F == 6:
            sei += end - s + 3
    return len(data) - sei


def encode_x264(binary, seq, preset, qp, out, threads=1, measure=True, extra=()):
    """Times x264 alone (no --psnr); the PSNR is measured after, on its
    decoded output (not when `measure` is false: the time alone). `extra`:
    x264 options after the front's own."""
    cmd = ["x264", "--preset", preset, "--tune", "psnr", "--qp", str(qp), "--bframes", "0",
           "--keyint", "infinite", "--scenecut", "0", "--threads", str(threads),
           "--frames", str(FRAMES), *extra, "-o", out, seq]
    _, seconds = timed(cmd)
    if not measure:
        return None, None, None, seconds
    decoded = out + ".y4m"
    # Every frame as decoded, in its own range: no frame rate or pixel
    # format conversion (a full-range source would otherwise be scaled).
    subprocess.run(["ffmpeg", "-v", "error", "-y", "-nostdin", "-i", out, "-fps_mode", "passthrough",
                    "-f", "yuv4mpegpipe", "-strict", "-1", decoded], check=True)
    frames, psnr = quality_of(binary, seq, decoded)
    return annexb_bytes_without_sei(out), frames, psnr, seconds


def quality_of(binary, seq, decoded):
    """Frames and mean luma PSNR of `decoded` against `seq` (removed after)."""
    done = subprocess.run([binary, "quality", seq, decoded, "--metrics", "psnr", "--json"],
                          capture_output=True, text=True, check=True)
    quality = json.loads(done.stdout)
    os.remove(decoded)
    return quality["frames"], quality["psnr_y"]


def encode_mocomp(binary, seq, preset, qp, out, threads=1, measure=True, extra=()):
    """Times mocomp alone (--metrics none, as x264 without --psnr); the
    PSNR is measured after, on the stream decoded (not when `measure` is
    false: the time alone). `extra`: options after MOCOMP_ARGS."""
    cmd = [binary, "encode", seq, "-o", out, "--preset", preset, "--qp", str(qp), "--threads", str(threads),
           "--frames", str(FRAMES), "--metrics", "none", "--json", "--quiet"] + MOCOMP_ARGS + list(extra)
    log, seconds = timed(cmd)
    summary = json.loads(log.strip().splitlines()[-1])
    if not measure:
        return summary["bytes"], summary["frames"], None, seconds
    decoded = out + ".y4m"
    subprocess.run([binary, "decode", out, "-o", decoded], check=True, capture_output=True)
    frames, psnr = quality_of(binary, seq, decoded)
    return summary["bytes"], frames, psnr, seconds


def bd_rate(binary, csv_path, anchor, test):
    done = subprocess.run(
        [binary, "bdrate", f"{csv_path}:{anchor}", f"{csv_path}:{test}", "--json"],
        capture_output=True, text=True,
    )
    if done.returncode != 0:
        return None
    value = json.loads(done.stdout).get("bd_rate_cubic")
    return None if value is None or not math.isfinite(value) else value


def run_sequence(binary, seq, out_dir):
    name = os.path.splitext(os.path.basename(seq))[0]
    fps = y4m_fps(seq)
    rows = []
    for qp in QPS:
        for family, preset in [("x264", p) for p in X264_PRESETS] + [("mocomp", p) for p in MOCOMP_PRESETS]:
            if family == "x264":
                stream = os.path.join(out_dir, "x264.264")
                size, frames, psnr, secs = encode_x264(binary, seq, preset, qp, stream)
            else:
                stream = os.path.join(out_dir, "mocomp.mcv")
                size, frames, psnr, secs = encode_mocomp(binary, seq, preset, qp, stream)
            codec = f"{family}:{preset}"
            kbps = size * 8 / (frames / fps) / 1000
            rows.append(dict(sequence=name, codec=codec, q=qp, bytes=size, frames=frames,
                             kbps=kbps, psnr_y=psnr, seconds=secs))
    path = os.path.join(out_dir, f"points_{name}.csv")
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=["codec", "q", "bytes", "frames", "kbps", "psnr_y", "seconds"])
        writer.writeheader()
        for r in rows:
            writer.writerow({k: r[k] for k in writer.fieldnames})
    bd = {}
    for codec in [f"x264:{p}" for p in X264_PRESETS] + [f"mocomp:{p}" for p in MOCOMP_PRESETS]:
        bd[codec] = {a: (0.0 if a == codec else bd_rate(binary, path, a, codec)) for a in ANCHORS}
    return rows, bd


def mean(values):
    values = [v for v in values if v is not None]
    return sum(values) / len(values) if values else None


def summarise(rows, bds, names):
    codecs = [f"mocomp:{p}" for p in MOCOMP_PRESETS] + [f"x264:{p}" for p in X264_PRESETS]
    seconds = {c: [r["seconds"] for r in rows if r["codec"] == c] for c in codecs}
    ref_total = sum(seconds["x264:medium"])
    out = []
    for c in codecs:
        per_seq = [bds[n][c] for n in names]
        entry = dict(codec=c, time_per_encode=mean(seconds[c]), time_vs_x264_medium=sum(seconds[c]) / ref_total)
        for a in ANCHORS:
            values = [s[a] for s in per_seq]
            entry[f"bd_vs_{a}"] = mean(values)
            entry[f"missing_vs_{a}"] = sum(v is None for v in values)
        out.append(entry)
    return out


def fmt(v, spec="+.1f", unit=" %"):
    return "n/a" if v is None else f"{v:{spec}}{unit}"


def markdown(summary, bds, names):
    lines = [f"Speed/compression front, {len(names)} sequences, QP {'/'.join(map(str, QPS))}, "
             f"first {FRAMES} frames, IPPP, one thread, time per encode of the whole process.", "",
             "| encoder:preset | time per encode | time vs x264 medium | BD-rate vs x264 medium | BD-rate vs x264 superfast |",
             "|---|---:|---:|---:|---:|"]
    for e in summary:
        lines.append(f"| {e['codec']} | {e['time_per_encode']:.3f} s | {e['time_vs_x264_medium']:.2f}x | "
                     f"{fmt(e['bd_vs_x264:medium'])} | {fmt(e['bd_vs_x264:superfast'])} |")
    lines += ["", "BD-rate against x264 medium per sequence:", "",
              "| sequence | " + " | ".join(f"mocomp:{p}" for p in MOCOMP_PRESETS) + " |",
              "|---|" + "---:|" * len(MOCOMP_PRESETS)]
    for n in names:
        lines.append(f"| {n} | " + " | ".join(fmt(bds[n][f'mocomp:{p}']['x264:medium']) for p in MOCOMP_PRESETS) + " |")
    return "\n".join(lines) + "\n"


def time_table(rows, names):
    """Time per encode per sequence (mean over the QPs), each mocomp preset
    also as a ratio to x264 medium's and, where it ran, x264 ultrafast's:
    a mean over a set of small and large pictures hides where an encoder
    is slow (the large real clips)."""
    def per_encode(name, codec):
        t = [r["seconds"] for r in rows if r["sequence"] == name and r["codec"] == codec]
        return sum(t) / len(t)
    anchors = [a for a in ("x264:medium", "x264:ultrafast") if a.split(":")[1] in X264_PRESETS]
    head = [f"mocomp:{p}" for p in MOCOMP_PRESETS]
    lines = ["Time per encode per sequence (mean over the QPs), each mocomp preset as a ratio to "
             + " and ".join(anchors) + ":", "",
             "| sequence | " + " | ".join(anchors) + " | " + " | ".join(head) + " |",
             "|---|" + "---:|" * (len(anchors) + len(head))]
    for n in names:
        ref = {a: per_encode(n, a) for a in anchors}
        cells = [f"{ref[a]:.3f} s" for a in anchors]
        for c in head:
            t = per_encode(n, c)
            cells.append(f"{t:.3f} s (" + ", ".join(f"{t / ref[a]:.2f}x" for a in anchors) + ")")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def svg_plot(summary):
    """Time per encode (log axis) against BD-rate vs x264 medium, one point per preset."""
    pts = [(e["time_per_encode"], e["bd_vs_x264:medium"], e["codec"]) for e in summary
           if e["bd_vs_x264:medium"] is not None]
    w, h, m = 720, 480, 70
    t_lo, t_hi = min(p[0] for p in pts) / 1.3, max(p[0] for p in pts) * 1.3
    b_lo, b_hi = min(min(p[1] for p in pts), 0) - 5, max(p[1] for p in pts) + 5
    x = lambda t: m + (math.log(t) - math.log(t_lo)) / (math.log(t_hi) - math.log(t_lo)) * (w - 2 * m)
    y = lambda b: h - m - (b - b_lo) / (b_hi - b_lo) * (h - 2 * m)
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">',
             f'<rect width="{w}" height="{h}" fill="white"/>',
             f'<line x1="{m}" y1="{h - m}" x2="{w - m}" y2="{h - m}" stroke="black"/>',
             f'<line x1="{m}" y1="{m}" x2="{m}" y2="{h - m}" stroke="black"/>',
             f'<text x="{w / 2}" y="{h - 25}" text-anchor="middle">time per encode (s, log scale)</text>',
             f'<text x="18" y="{h / 2}" transform="rotate(-90 18 {h / 2})" text-anchor="middle">BD-rate vs x264 medium (%)</text>']
    tick = 10 ** math.floor(math.log10(t_lo))
    while tick < t_hi:
        for k in (1, 2, 5):
            t = tick * k
            if t_lo <= t <= t_hi:
                parts.append(f'<line x1="{x(t):.1f}" y1="{h - m}" x2="{x(t):.1f}" y2="{h - m + 5}" stroke="black"/>'
                             f'<text x="{x(t):.1f}" y="{h - m + 18}" text-anchor="middle">{t:g}</text>')
        tick *= 10
    step = 10 if b_hi - b_lo > 40 else 5
    b = math.ceil(b_lo / step) * step
    while b <= b_hi:
        parts.append(f'<line x1="{m - 5}" y1="{y(b):.1f}" x2="{w - m}" y2="{y(b):.1f}" stroke="#ddd"/>'
                     f'<text x="{m - 8}" y="{y(b) + 4:.1f}" text-anchor="end">{b:+g}</text>')
        b += step
    for family, colour in (("mocomp", "#c03020"), ("x264", "#2050b0")):
        line = [(x(t), y(bd), c) for t, bd, c in sorted(pts) if c.startswith(family)]
        parts.append('<polyline fill="none" stroke="%s" points="%s"/>'
                     % (colour, " ".join(f"{px:.1f},{py:.1f}" for px, py, _ in line)))
        for px, py, c in line:
            parts.append(f'<circle cx="{px:.1f}" cy="{py:.1f}" r="4" fill="{colour}"/>'
                         f'<text x="{px + 6:.1f}" y="{py - 6:.1f}" fill="{colour}">{c}</text>')
    parts.append("</svg>")
    return "\n".join(parts) + "\n"


def coverage(binary, out_dir, rows, names):
    """For each x264 preset but ultrafast (the issue's goal: superfast to
    slow), the mocomp presets no slower per encode (the mean over the set)
    with their BD-rate measured against that x264 preset directly (the
    mean over the sequences of each one's BD-rate): the one with the
    fewest bits, and the fastest with no more bits (the widest time
    margin); where none is as fast, the fastest mocomp preset."""
    times = {}
    for r in rows:
        times.setdefault(r["codec"], []).append(r["seconds"])
    per_encode = {c: sum(v) / len(v) for c, v in times.items()}
    mocomp = [f"mocomp:{p}" for p in MOCOMP_PRESETS if f"mocomp:{p}" in per_encode]

    def bd_against(anchor, test):
        values = [bd_rate(binary, os.path.join(out_dir, f"points_{n}.csv"), anchor, test) for n in names]
        return mean(values), sum(v is None for v in values)

    def cell(x, c, bd, missing):
        note = f" ({missing} sequences without a BD-rate)" if missing else ""
        return f"{c} ({per_encode[c] / per_encode[x]:.2f}x, {bd:+.1f} %{note})"

    lines = ["Each x264 preset against the mocomp presets no slower per encode (time ratio, BD-rate "
             "measured against that x264 preset, mean over the sequences): the one with the fewest "
             "bits, and the fastest with no more bits than the x264 preset; where none is as fast, "
             "the fastest mocomp preset:", "",
             "| x264 preset | time per encode | fewest bits | fastest with no more bits | covered |",
             "|---|---:|---|---|---|"]
    for p in X264_PRESETS:
        x = f"x264:{p}"
        if p == "ultrafast" or x not in per_encode or not mocomp:
            continue
        no_slower = [c for c in mocomp if per_encode[c] <= per_encode[x]]
        scored = [(c, *bd_against(x, c)) for c in (no_slower or [min(mocomp, key=per_encode.get)])]
        scored = [t for t in scored if t[1] is not None]
        if not scored:
            continue
        fewest = min(scored, key=lambda t: t[1])
        covering = [t for t in scored if t[1] <= 0] if no_slower else []
        fastest = min(covering, key=lambda t: per_encode[t[0]]) if covering else None
        lines.append(f"| {x} | {per_encode[x]:.3f} s | {cell(x, *fewest)} | "
                     f"{cell(x, *fastest) if fastest else '-'} | {'yes' if fastest else 'no'} |")
    return "\n".join(lines) + "\n"


def coverage_of_run(out_dir):
    """`front.py OUT --coverage`: the coverage table of a finished run, from
    its points files (an older run, or one whose sequences took long)."""
    rows = []
    with open(os.path.join(out_dir, "points.csv")) as f:
        for r in csv.DictReader(f):
            r["seconds"] = float(r["seconds"])
            rows.append(r)
    names = list(dict.fromkeys(r["sequence"] for r in rows))
    print(coverage(mocomp_binary(), out_dir, rows, names))


def y4m_width(path):
    with open(path, "rb") as f:
        header = f.readline().decode("ascii", "replace").split()
    return next(int(t[1:]) for t in header if t.startswith("W"))


# Above this, x264's own 2-thread / 1-thread time says the round ran on
# one processor in effect (x264 medium's frame threads took 0.48-0.72 of
# their one-thread time on garden_720p, cockatoo_720p and dog_1080p in a
# quiet 15-round run on a 2-vCPU AMD EPYC, 2026-12-06).
TWO_CPU_RATIO = 0.85


def thread_scaling(binary, seqs, out_dir):
    """1- and 2-thread times of THREADS_PRESET and of x264 at the same preset name."""
    preset = os.environ.get("THREADS_PRESET")
    if not preset:
        return ""
    min_width = int(os.environ.get("THREADS_MIN_WIDTH", "1280"))
    runs = int(os.environ.get("THREADS_RUNS", "5"))
    lines = [f"Threads: preset {preset}, QP 27, first {FRAMES} frames, {runs} rounds: median times, "
             f"median of the rounds' ratios; the last column over the rounds where x264's own ratio "
             f"was at most {TWO_CPU_RATIO} (two processors in effect).", "",
             "| sequence | mocomp 1 thread | 2 threads | 2 / 1 | x264 1 thread | 2 threads | 2 / 1 "
             "| mocomp 2 / 1, two processors (rounds) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    rounds = []
    for seq in seqs:
        if y4m_width(seq) < min_width:
            continue
        times = {k: [] for k in ("m1", "m2", "x1", "x2")}
        for _ in range(runs):
            for t in (1, 2):
                times[f"m{t}"].append(encode_mocomp(binary, seq, preset, 27, os.path.join(out_dir, "t.mcv"), t, measure=False)[3])
            for t in (1, 2):
                times[f"x{t}"].append(
                    encode_x264(binary, seq, preset, 27, os.path.join(out_dir, "t.264"), t, measure=False)[3]
                )
        m = {k: statistics.median(v) for k, v in times.items()}
        ratio = {e: statistics.median(b / a for a, b in zip(times[f"{e}1"], times[f"{e}2"])) for e in "mx"}
        name = os.path.splitext(os.path.basename(seq))[0]
        two = [m2 / m1 for m1, m2, x1, x2 in zip(times["m1"], times["m2"], times["x1"], times["x2"])
               if x2 / x1 <= TWO_CPU_RATIO]
        two_cpu = f"{statistics.median(two):.3f} ({len(two)})" if two else "- (0)"
        lines.append(f"| {name} | {m['m1']:.3f} s | {m['m2']:.3f} s | {ratio['m']:.3f} | "
                     f"{m['x1']:.3f} s | {m['x2']:.3f} s | {ratio['x']:.3f} | {two_cpu} |")
        rounds.extend((name, r, times["m1"][r], times["m2"][r], times["x1"][r], times["x2"][r]) for r in range(runs))
    with open(os.path.join(out_dir, "threads.csv"), "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["sequence", "round", "mocomp_1", "mocomp_2", "x264_1", "x264_2"])
        writer.writerows(rounds)
    return "\n".join(lines) + "\n"


def main():
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    out_dir, seqs = sys.argv[1], sys.argv[2:]
    if seqs == ["--coverage"]:
        return coverage_of_run(out_dir)
    if "medium" not in X264_PRESETS:
        # Checked before any encode: the table's times and BD-rates are
        # against x264 medium.
        raise SystemExit("front.py: X264_PRESETS must include medium (the table's anchor)")
    os.makedirs(out_dir, exist_ok=True)
    binary = mocomp_binary()
    # Warm the page cache with both binaries and the first sequence, so
    # the first timed encode does not pay for loading them.
    subprocess.run(["x264", "--version"], capture_output=True)
    subprocess.run([binary, "--version"], capture_output=True)
    rows, bds, names = [], {}, []
    for seq in seqs:
        name = os.path.splitext(os.path.basename(seq))[0]
        print(f"{name} ...", file=sys.stderr, flush=True)
        seq_rows, bd = run_sequence(binary, seq, out_dir)
        rows += seq_rows
        bds[name] = bd
        names.append(name)
    with open(os.path.join(out_dir, "points.csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        writer.writeheader()
        writer.writerows(rows)
    summary = summarise(rows, bds, names)
    table = markdown(summary, bds, names)
    table += "\n" + coverage(binary, out_dir, rows, names)
    table += "\n" + time_table(rows, names)
    table += "\n" + thread_scaling(binary, seqs, out_dir)
    open(os.path.join(out_dir, "front.md"), "w").write(table)
    json.dump(dict(summary=summary, per_sequence=bds), open(os.path.join(out_dir, "front.json"), "w"), indent=1)
    open(os.path.join(out_dir, "front.svg"), "w").write(svg_plot(summary))
    print(table)


if __name__ == "__main__":
    main()
