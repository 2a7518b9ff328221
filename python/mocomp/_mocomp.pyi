"""Type stubs of the extension module (the functions mocomp re-exports)."""

import os
from typing import Any, Literal, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

Picture = npt.NDArray[Any]
Flow = npt.NDArray[np.float32]
Yuv = Tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint8], npt.NDArray[np.uint8]]
PathLike = Union[str, "os.PathLike[str]"]

def flow(
    img1: Picture,
    img2: Picture,
    method: Optional[Literal["dis", "lk", "hs", "tvl1"]] = None,
    preset: Literal["ultrafast", "fast", "medium", "accurate"] = "medium",
    threads: Optional[int] = None,
    *,
    levels: Optional[int] = None,
    sigma: Optional[float] = None,
    iterations: Optional[int] = None,
    alpha: Optional[float] = None,
    gamma: Optional[float] = None,
    texture: Optional[float] = None,
    warps: Optional[int] = None,
    finest: Optional[int] = None,
    global_search: bool = False,
    matches: bool = False,
    fine_on_small: bool = False,
) -> Flow: ...
class DenseFlow:
    """A dense flow estimator made once and called per frame pair."""

    def __init__(
        self,
        method: Optional[Literal["dis", "lk", "hs", "tvl1"]] = None,
        preset: Literal["ultrafast", "fast", "medium", "accurate"] = "medium",
        threads: Optional[int] = None,
        *,
        levels: Optional[int] = None,
        sigma: Optional[float] = None,
        iterations: Optional[int] = None,
        alpha: Optional[float] = None,
        gamma: Optional[float] = None,
        texture: Optional[float] = None,
        warps: Optional[int] = None,
        finest: Optional[int] = None,
        global_search: bool = False,
        matches: bool = False,
        fine_on_small: bool = False,
    ) -> None: ...
    def calc(self, img1: Picture, img2: Picture, flow: Optional[Flow] = None) -> Flow: ...
    def __call__(self, img1: Picture, img2: Picture, flow: Optional[Flow] = None) -> Flow: ...
    @property
    def method(self) -> str: ...
    @property
    def preset(self) -> str: ...

def estimate_global(
    src: npt.NDArray[np.floating],
    dst: npt.NDArray[np.floating],
    model: Literal["translation", "similarity", "affine", "homography"] = "affine",
    threshold: float = 1.0,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_]]: ...
def global_motion(
    img1: Picture,
    img2: Picture,
    model: Literal["translation", "similarity", "affine", "homography"] = "similarity",
    source: Literal["auto", "flow", "blocks", "matches"] = "auto",
    threshold: Optional[float] = None,
    preset: Literal["ultrafast", "fast", "medium", "accurate"] = "medium",
    threads: Optional[int] = None,
) -> dict[str, Any]: ...
def warp(img: Picture, flow: Flow) -> Picture: ...
def stabilize_path(
    frames: list[Picture],
    smoothing: int = 10,
    l1: bool = False,
    zoom: Union[Literal["auto", "adaptive"], float, None] = None,
    coverage: float = 0.75,
    max_zoom: float = 1.5,
    model: Literal["translation", "similarity"] = "similarity",
    source: Literal["auto", "flow", "blocks", "matches"] = "auto",
    preset: Literal["ultrafast", "fast", "medium", "accurate"] = "ultrafast",
    threads: Optional[int] = None,
) -> dict[str, Any]: ...
def interpolate(
    frame0: Yuv,
    frame1: Yuv,
    times: Sequence[float] = (0.5,),
    preset: Literal["ultrafast", "fast", "medium", "accurate"] = "fast",
    before: Optional[Yuv] = None,
    after: Optional[Yuv] = None,
) -> list[Yuv]: ...
def motion_mask(
    img: Picture,
    neighbours: list[Picture],
    preset: Literal["ultrafast", "fast", "medium", "accurate"] = "fast",
    tolerance: float = 1.0,
) -> npt.NDArray[np.uint8]: ...
def motion_masks(
    frames: list[Picture],
    preset: Literal["ultrafast", "fast", "medium", "accurate"] = "fast",
    tolerance: float = 1.0,
) -> list[npt.NDArray[np.uint8]]: ...
def warp_matrix(
    image: Picture,
    matrix: npt.NDArray[np.float64],
    size: Optional[tuple[int, int]] = None,
    border: Union[Literal["replicate"], int, None] = None,
) -> npt.NDArray[np.uint8]: ...
def flow_to_color(flow: Flow, max_flow: Optional[float] = None) -> npt.NDArray[np.uint8]: ...
def read_flo(path: PathLike) -> Flow: ...
def write_flo(path: PathLike, flow: Flow) -> None: ...
def flow_errors(flow: Flow, gt: Flow) -> dict[str, float]: ...
@overload
def block_match(
    cur: Picture,
    ref: Picture,
    method: str = "epzs",
    block: int = 16,
    search_range: int = 16,
    subpel: Literal["none", "half", "quarter"] = "quarter",
    metric: Literal["sad", "ssd", "satd"] = "sad",
    qp: Optional[int] = None,
    return_costs: Literal[False] = False,
    threads: Optional[int] = None,
) -> npt.NDArray[np.float32]: ...
@overload
def block_match(
    cur: Picture,
    ref: Picture,
    method: str = "epzs",
    block: int = 16,
    search_range: int = 16,
    subpel: Literal["none", "half", "quarter"] = "quarter",
    metric: Literal["sad", "ssd", "satd"] = "sad",
    qp: Optional[int] = None,
    return_costs: Literal[True] = ...,
    threads: Optional[int] = None,
) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.uint32]]: ...
def good_features(
    img: Picture, max_corners: int = 200, quality: float = 0.01, min_distance: float = 8.0
) -> npt.NDArray[np.float32]: ...
def track(
    frames: Sequence[Picture],
    points: Optional[npt.NDArray[np.float32]] = None,
    max_corners: int = 200,
    fb_threshold: Optional[float] = None,
) -> npt.NDArray[np.float32]: ...
def encode(
    source: Union[PathLike, Sequence[Yuv]],
    qp: int = 28,
    predictor: str = "block",
    *,
    preset: Literal["ultrafast", "fast", "medium", "slow"] = "medium",
    frames: Optional[int] = None,
    fps: Tuple[int, int] = (25, 1),
    threads: Optional[int] = None,
    reconstruction: bool = False,
    gop: Optional[int] = None,
    me: Optional[str] = None,
    range: Optional[int] = None,
    subpel: Optional[Literal["none", "half", "quarter"]] = None,
    flow: Optional[str] = None,
    refine: Optional[int] = None,
    grid: Optional[int] = None,
    lambda_scale: Optional[float] = None,
    rdoq: Optional[bool] = None,
    decision: Optional[Literal["fast", "full"]] = None,
    ipratio: Optional[float] = None,
    deblock: Optional[Union[bool, str]] = None,
    deblock_choice: Optional[bool] = None,
    weightp: Optional[bool] = None,
    refs: Optional[int] = None,
    subpel_rd: Optional[bool] = None,
    chroma_me: Optional[bool] = None,
    adaptive_pricing: Optional[bool] = None,
    fast_pskip: Optional[bool] = None,
    early_pskip: Optional[bool] = None,
    dct8x8: Optional[bool] = None,
    luma_filter: Optional[Literal["auto", "sharp", "smooth"]] = None,
    partitions: Optional[Union[bool, str]] = None,
    i_partitions: Optional[Union[bool, str]] = None,
    metrics: Optional[str] = None,
    ssim: Optional[bool] = None,
) -> Union[Tuple[bytes, list[dict[str, Any]]], Tuple[bytes, list[dict[str, Any]], list[Yuv]]]: ...
def encoder_options() -> list[Tuple[str, str]]: ...
def read_y4m(path: PathLike, frames: Optional[int] = None) -> list[Yuv]: ...
def decode(stream: bytes) -> list[Yuv]: ...
def analyze(stream: bytes) -> list[dict[str, Any]]: ...
def quality(reference: Yuv, test: Yuv, metrics: str = "psnr,ssim") -> dict[str, float]: ...
def rd(
    sources: Sequence[PathLike],
    qps: Sequence[int] = (22, 27, 32, 37),
    predictors: Sequence[str] = ("block:esa", "block"),
    frames: Optional[int] = None,
    threads: Optional[int] = None,
    *,
    preset: Literal["ultrafast", "fast", "medium", "slow"] = "medium",
    **options: Any,
) -> list[dict[str, Any]]: ...
def psnr(a: npt.NDArray[np.uint8], b: npt.NDArray[np.uint8]) -> float: ...
def ssim(a: Picture, b: Picture) -> float: ...
def bd_rate(
    rate_a: Sequence[float],
    psnr_a: Sequence[float],
    rate_b: Sequence[float],
    psnr_b: Sequence[float],
    method: Literal["cubic", "pchip"] = "cubic",
) -> float: ...
