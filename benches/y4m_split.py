"""The pieces of a 4:2:0 8-bit Y4M file, for the bench scripts: its header
line, its width and height, and each frame's FRAME line and samples."""
import re


def split(path):
    """(header, width, height, frames): the header line without its
    newline, and per frame its bytes from the FRAME line (with its
    parameters and newline) to its last sample."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"\n")
    header = data[:end].decode()
    w = int(re.search(r" W(\d+)", header).group(1))
    h = int(re.search(r" H(\d+)", header).group(1))
    size = w * h + 2 * ((w + 1) // 2) * ((h + 1) // 2)
    frames, at = [], end + 1
    while at < len(data):
        stop = data.index(b"\n", at) + 1
        frames.append(data[at : stop + size])
        at = stop + size
    return header, w, h, frames
