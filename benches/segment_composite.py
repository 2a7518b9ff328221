"""segment_composite.py REAL.y4m OBJECT.y4m OUT.y4m MASKS_DIR [FRAMES]

Test material for moving-object segmentation with known truth: REAL seen
by a camera that pans (a window sliding 2 px right and 1 px down a frame
over REAL's frames), with a disc cut from OBJECT's first frame pasted on
top, moving 3 px left and 2 px down a frame across the view (its diameter a
third of the view's smaller side; DISC=N in the environment: 2/N). The disc's
mask is the truth: MASKS_DIR/00000.png ... (255 inside), in the labels of
CDnet 2014. What REAL itself moves (people in the footage) is not in the
truth: where REAL's own luma changes from the frame before or to the frame
after (at the same place in the scene, so the pan does not count: a 5x5
mean of the difference above four times its noise and at least 6 levels,
grown by 8 px), the truth says 170, "unknown motion", which CDnet and
`mocomp segment --truth` do not score. With --no-unknown it says 0 there.
4:2:0 8-bit Y4M in and out; numpy only (PNGs written with zlib)."""
import os
import re
import struct
import sys
import zlib
from pathlib import Path

import numpy as np


def read_y4m(path, limit):
    data = Path(path).read_bytes()
    end = data.index(b"\n")
    head = data[:end].decode()
    w, h = (int(re.search(p, head).group(1)) for p in (r" W(\d+)", r" H(\d+)"))
    cw, ch = (w + 1) // 2, (h + 1) // 2
    frames, at = [], end + 1
    while at < len(data) and len(frames) < limit:
        start = data.index(b"\n", at) + 1
        y = np.frombuffer(data[start : start + w * h], np.uint8).reshape(h, w)
        u = np.frombuffer(data[start + w * h : start + w * h + cw * ch], np.uint8).reshape(ch, cw)
        v = np.frombuffer(data[start + w * h + cw * ch : start + w * h + 2 * cw * ch], np.uint8).reshape(ch, cw)
        frames.append((y, u, v))
        at = start + w * h + 2 * cw * ch
    return head, frames


def write_png(path, mask):
    h, w = mask.shape
    raw = b"".join(b"\x00" + mask[r].tobytes() for r in range(h))
    chunk = lambda kind, body: struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")
    Path(path).write_bytes(png)


UNKNOWN = 170  # CDnet 2014's "unknown motion": not scored
GROW = 8


def box_mean(a, r):
    """The mean of each (2r+1)^2 window of `a` (edges repeated)."""
    p = np.pad(a.astype(np.float64), r, mode="edge")
    c = np.cumsum(np.cumsum(p, 0), 1)
    c = np.pad(c, ((1, 0), (1, 0)))
    k = 2 * r + 1
    return (c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]) / (k * k)


def grow(mask, r):
    """`mask` dilated by a (2r+1)^2 square."""
    out = mask.copy()
    for axis in (0, 1):
        grown = out.copy()
        for d in range(1, r + 1):
            grown[tuple(slice(d, None) if a == axis else slice(None) for a in (0, 1))] |= \
                out[tuple(slice(None, -d) if a == axis else slice(None) for a in (0, 1))]
            grown[tuple(slice(None, -d) if a == axis else slice(None) for a in (0, 1))] |= \
                out[tuple(slice(d, None) if a == axis else slice(None) for a in (0, 1))]
        out = grown
    return out


def own_motion(lumas, t, window):
    """Where the footage itself changes around frame t, in its window."""
    oy, ox, h, w = window
    here = lumas[t][oy : oy + h, ox : ox + w].astype(np.int16)
    diffs = [np.abs(here - lumas[s][oy : oy + h, ox : ox + w].astype(np.int16))
             for s in (t - 1, t + 1) if 0 <= s < len(lumas)]
    moved = np.zeros((h, w), bool)
    for d in diffs:
        noise = 1.4826 * np.median(d) + 0.5
        moved |= box_mean(d, 2) > max(6.0, 4.0 * noise)
    return grow(moved, GROW)


def main():
    args = [a for a in sys.argv[1:] if a != "--no-unknown"]
    with_unknown = "--no-unknown" not in sys.argv
    real, obj, out, masks = args[:4]
    n = int(args[4]) if len(args) > 4 else 40
    head, frames = read_y4m(real, n)
    _, (donor, *_) = read_y4m(obj, 1)
    H, W = frames[0][0].shape
    w, h = (W - 2 * n - 8) & ~1, (H - n - 8) & ~1  # room for the pan
    r = min(w, h) // int(os.environ.get("DISC", "6")) & ~1  # the disc's radius
    dy_, dx_ = donor[0].shape
    patch = [p[: 2 * r, : 2 * r] if i == 0 else p[:r, :r] for i, p in enumerate(donor)]
    patch[0] = donor[0][(dy_ - 2 * r) // 2 : (dy_ + 2 * r) // 2, (dx_ - 2 * r) // 2 : (dx_ + 2 * r) // 2]
    patch[1] = donor[1][(dy_ // 2 - r) // 2 : (dy_ // 2 + r) // 2, (dx_ // 2 - r) // 2 : (dx_ // 2 + r) // 2]
    patch[2] = donor[2][(dy_ // 2 - r) // 2 : (dy_ // 2 + r) // 2, (dx_ // 2 - r) // 2 : (dx_ // 2 + r) // 2]
    yy, xx = np.mgrid[0 : 2 * r, 0 : 2 * r]
    disc = (yy - r + 0.5) ** 2 + (xx - r + 0.5) ** 2 <= r * r
    cdisc = disc[::2, ::2]
    Path(masks).mkdir(parents=True, exist_ok=True)
    head = re.sub(r" W\d+", f" W{w}", re.sub(r" H\d+", f" H{h}", head))
    lumas = [y for y, _, _ in frames]
    unknown_share = []
    with open(out, "wb") as f:
        f.write(head.encode() + b"\n")
        for t, (y, u, v) in enumerate(frames):
            ox, oy = 4 + 2 * t, 4 + t  # the camera's window (even: chroma aligned)
            ox -= ox % 2
            oy -= oy % 2
            planes = [y[oy : oy + h, ox : ox + w].copy(), u[oy // 2 : (oy + h) // 2, ox // 2 : (ox + w) // 2].copy(),
                      v[oy // 2 : (oy + h) // 2, ox // 2 : (ox + w) // 2].copy()]
            px, py = (w - 2 * r - 8 - 3 * t) & ~1, (h // 8 + 2 * t) & ~1  # the disc's corner, even
            mask = np.zeros((h, w), np.uint8)
            if with_unknown:
                mask[own_motion(lumas, t, (oy, ox, h, w))] = UNKNOWN
                unknown_share.append(float((mask == UNKNOWN).mean()))
            if 0 <= px and px + 2 * r <= w and 0 <= py and py + 2 * r <= h:
                planes[0][py : py + 2 * r, px : px + 2 * r][disc] = patch[0][disc]
                for k in (1, 2):
                    planes[k][py // 2 : py // 2 + r, px // 2 : px // 2 + r][cdisc] = patch[k][cdisc]
                mask[py : py + 2 * r, px : px + 2 * r][disc] = 255
            f.write(b"FRAME\n" + b"".join(p.tobytes() for p in planes))
            write_png(Path(masks) / f"{t:05d}.png", mask)
    if unknown_share:
        print(f"{Path(real).stem}: unknown (the footage's own motion) {100 * np.mean(unknown_share):.1f} % "
              f"of the pixels", file=sys.stderr)


main()
