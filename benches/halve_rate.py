"""halve_rate.py IN.y4m OUT.y4m: every other frame of IN (0, 2, 4 ...) at
half the frame rate, as 4:2:0 8-bit Y4M (the input must be that)."""
import re
import sys

src, dst = sys.argv[1], sys.argv[2]
with open(src, "rb") as f:
    data = f.read()
end = data.index(b"\n")
header = data[:end].decode()
w = int(re.search(r" W(\d+)", header).group(1))
h = int(re.search(r" H(\d+)", header).group(1))
num, den = map(int, re.search(r" F(\d+):(\d+)", header).group(1, 2))
size = w * h + 2 * ((w + 1) // 2) * ((h + 1) // 2)
header = re.sub(r" F\d+:\d+", f" F{num}:{den * 2}", header)
frames, at = [], end + 1
while at < len(data):
    stop = data.index(b"\n", at) + 1  # FRAME line (with any parameters)
    frames.append(data[at : stop + size])
    at = stop + size
with open(dst, "wb") as f:
    f.write(header.encode() + b"\n")
    for frame in frames[::2]:
        f.write(frame)
