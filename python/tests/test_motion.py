"""Block matching and sparse tracking against known shifts."""

import numpy as np
import pytest

import mocomp
from conftest import textured


@pytest.mark.parametrize("method", ["esa", "epzs", "ds"])
def test_block_match_finds_known_shifts(method):
    ref = textured(128, 160)
    for dx, dy in [(3, -2), (-5, 4), (0, 6)]:
        cur = np.roll(ref, (dy, dx), axis=(0, 1))  # cur(p) = ref(p - d)
        v = mocomp.block_match(cur, ref, method=method, search_range=8, subpel="none")
        assert v.shape == (8, 10, 2) and v.dtype == np.float32
        inner = v[1:-1, 1:-1]
        assert (inner[..., 0] == -dx).all() and (inner[..., 1] == -dy).all(), (method, dx, dy)


def test_block_match_costs_and_subpel():
    ref = textured(64, 64, seed=5)
    cur = np.roll(ref, (1, 2), axis=(0, 1))
    v, costs = mocomp.block_match(cur, ref, method="esa", search_range=4, return_costs=True)
    assert costs.shape == (4, 4) and costs.dtype == np.uint32
    assert costs[1:-1, 1:-1].max() == 0
    assert np.all(v[1:-1, 1:-1] == [-2.0, -1.0])
    with pytest.raises(ValueError, match="block"):
        mocomp.block_match(cur, ref, block=12)
    with pytest.raises(ValueError, match="differ in size"):
        mocomp.block_match(cur, ref[:32])


def test_tracks_follow_a_known_translation():
    base = textured(120, 160, seed=7)
    frames = [np.roll(base, (t, 2 * t), axis=(0, 1)) for t in range(4)]
    pts = mocomp.good_features(frames[0], max_corners=40)
    assert pts.shape[1] == 2 and 10 <= len(pts) <= 40
    paths = mocomp.track(frames, points=pts)
    assert paths.shape == (4, len(pts), 2)
    inside = (pts[:, 0] > 12) & (pts[:, 0] < 140) & (pts[:, 1] > 12) & (pts[:, 1] < 100)
    for t in range(4):
        moved = paths[t, inside] - pts[inside]
        ok = ~np.isnan(moved[:, 0])
        assert ok.mean() > 0.9
        assert np.allclose(moved[ok], [2 * t, t], atol=0.1)
    with pytest.raises(ValueError, match="empty"):
        mocomp.track([])
