"""halve_rate.py IN.y4m OUT.y4m: every other frame of IN (0, 2, 4 ...) at
half the frame rate, as 4:2:0 8-bit Y4M (the input must be that)."""
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from y4m_split import split  # noqa: E402

src, dst = sys.argv[1], sys.argv[2]
header, _, _, frames = split(src)
num, den = map(int, re.search(r" F(\d+):(\d+)", header).group(1, 2))
header = re.sub(r" F\d+:\d+", f" F{num}:{den * 2}", header)
with open(dst, "wb") as f:
    f.write(header.encode() + b"\n")
    for frame in frames[::2]:
        f.write(frame)
