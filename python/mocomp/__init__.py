"""mocomp: motion estimation, optical flow and motion-compensated video coding.

Arrays follow numpy's and OpenCV-python's conventions: pictures are uint8
H x W (luma) or H x W x 3 (RGB); flows are float32 H x W x 2, u (x motion)
then v, with ``img1(p) ~ img2(p + flow(p))``; block vectors are in pixels.
Every function releases the GIL while it computes, and raises ValueError
or TypeError for arrays of the wrong shape or dtype.

>>> import numpy as np, mocomp
>>> a = (np.indices((64, 80)).sum(0) * 7 % 251).astype(np.uint8)
>>> mocomp.flow(a, a).shape
(64, 80, 2)
"""

from ._mocomp import (
    DenseFlow,
    __version__,
    analyze,
    bd_rate,
    block_match,
    decode,
    encode,
    encoder_options,
    estimate_global,
    flow,
    flow_errors,
    flow_to_color,
    global_motion,
    good_features,
    interpolate,
    motion_mask,
    motion_masks,
    psnr,
    quality,
    rd,
    read_flo,
    read_y4m,
    ssim,
    stabilize_path,
    track,
    warp,
    warp_matrix,
    write_flo,
)

__all__ = [
    "DenseFlow",
    "analyze",
    "bd_rate",
    "block_match",
    "decode",
    "encode",
    "encoder_options",
    "estimate_global",
    "flow",
    "flow_errors",
    "flow_to_color",
    "global_motion",
    "good_features",
    "interpolate",
    "motion_mask",
    "motion_masks",
    "psnr",
    "quality",
    "rd",
    "read_flo",
    "read_y4m",
    "ssim",
    "stabilize_path",
    "track",
    "warp",
    "warp_matrix",
    "write_flo",
]
