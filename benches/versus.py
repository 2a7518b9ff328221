#!/usr/bin/env python3
"""mocomp against x264 with the same tools turned on in both, rung by rung:
where a BD-rate gap opens.

    python3 benches/versus.py OUT SEQ.y4m [SEQ.y4m ...] -- "MOCOMP ARGS" "X264 ARGS" [...]

Each pair of argument strings after `--` is one rung: every sequence is
encoded at QP 22/27/32/37 (QPS) by `mocomp encode --preset medium ARGS`
and by x264's own command line as benches/front.py runs it (`x264
--preset medium --tune psnr --qp Q --bframes 0 --keyint infinite
--scenecut 0 --threads 1 ARGS`), the first FRAMES (30) frames, each
PSNR measured on the decoded stream as front.py measures it (x264's
settings SEI not counted). Printed per rung: the BD-rate of mocomp
against x264 on each sequence (luma PSNR, cubic, `mocomp bdrate`) and
its mean. A rung's arguments must not repeat an option the preset line
gives twice (mocomp's parser refuses a repeated option). OUT gets each
rung's points. MOCOMP: a binary (default this tree's, built now).

Example (the partitions turned on in both, the other tools off):

    python3 benches/versus.py /tmp/v samples/tree_qcif.y4m -- \\
        "--partitions none --refs 1 --no-rdoq --no-8x8dct --no-weightp --no-fast-pskip" \\
        "--partitions none --ref 1 --trellis 0 --no-8x8dct --weightp 0 --no-fast-pskip --no-dct-decimate" \\
        "--partitions p8x8 --refs 1 --no-rdoq --no-8x8dct --no-weightp --no-fast-pskip" \\
        "--partitions p8x8,i8x8,i4x4 --ref 1 --trellis 0 --no-8x8dct --weightp 0 --no-fast-pskip --no-dct-decimate"
"""
import csv
import os
import shlex
import sys

import front


def rung(binary, seq, out_dir, mocomp_args, x264_args):
    """The BD-rate of mocomp with `mocomp_args` against x264 with `x264_args` on `seq`."""
    fps = front.y4m_fps(seq)
    rows = []
    for qp in front.QPS:
        for codec, encode, args, stream in [("x264", front.encode_x264, x264_args, "v.264"),
                                            ("mocomp", front.encode_mocomp, mocomp_args, "v.mcv")]:
            size, frames, psnr, _ = encode(binary, seq, "medium", qp, os.path.join(out_dir, stream), extra=args)
            rows.append(dict(codec=codec, q=qp, bytes=size, frames=frames,
                             kbps=size * 8 / (frames / fps) / 1000, psnr_y=psnr))
    name = os.path.splitext(os.path.basename(seq))[0]
    path = os.path.join(out_dir, f"points_{name}.csv")
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=["codec", "q", "bytes", "frames", "kbps", "psnr_y"])
        writer.writeheader()
        writer.writerows(rows)
    return front.bd_rate(binary, path, "x264", "mocomp")


def main(argv):
    if "--" not in argv or len(argv) < 2:
        raise SystemExit(__doc__)
    split = argv.index("--")
    out, seqs, rungs = argv[0], argv[1:split], argv[split + 1:]
    if not seqs or not rungs or len(rungs) % 2:
        raise SystemExit(__doc__)
    binary = front.mocomp_binary()
    for k in range(0, len(rungs), 2):
        mocomp_args, x264_args = shlex.split(rungs[k]), shlex.split(rungs[k + 1])
        rung_dir = os.path.join(out, f"rung{k // 2}")
        os.makedirs(rung_dir, exist_ok=True)
        print(f"rung {k // 2}: mocomp {rungs[k]} | x264 {rungs[k + 1]}")
        bds = []
        for seq in seqs:
            bd = rung(binary, seq, rung_dir, mocomp_args, x264_args)
            bds.append(bd)
            shown = "n/a" if bd is None else f"{bd:+.2f} %"
            print(f"  {os.path.splitext(os.path.basename(seq))[0]:20s} {shown}")
        known = [b for b in bds if b is not None]
        if known:
            print(f"  mean of {len(known)}: {sum(known) / len(known):+.2f} %")


if __name__ == "__main__":
    main(sys.argv[1:])
