"""Global motion from correspondences and from pictures, against known
camera motion."""

import numpy as np
import pytest

import mocomp
from conftest import textured


def test_estimate_global_recovers_an_affine_map_and_its_outliers():
    rng = np.random.default_rng(3)
    src = rng.uniform(0, 640, (200, 2))
    truth = np.array([[1.02, 0.03, -5.0], [-0.01, 0.97, 8.0], [0.0, 0.0, 1.0]])
    dst = src @ truth[:2, :2].T + truth[:2, 2]
    wrong = rng.uniform(size=200) < 0.3
    dst[wrong] += rng.uniform(20, 60, (wrong.sum(), 2))
    for dtype in (np.float64, np.float32):
        matrix, inliers = mocomp.estimate_global(src.astype(dtype), dst.astype(dtype), model="affine")
        assert matrix.shape == (3, 3) and matrix.dtype == np.float64
        tolerance = 1e-6 if dtype == np.float64 else 1e-3
        assert np.allclose(matrix, truth, atol=tolerance)
        assert inliers.dtype == np.bool_ and np.array_equal(inliers, ~wrong)
    with pytest.raises(ValueError, match="needs at least 4"):
        mocomp.estimate_global(src[:3], dst[:3], model="homography")
    with pytest.raises(ValueError, match="unknown model"):
        mocomp.estimate_global(src, dst, model="projective")
    with pytest.raises(ValueError, match="N x 2"):
        mocomp.estimate_global(src[:, :1], dst[:, :1])


def test_global_motion_of_a_shifted_picture_from_each_source():
    img = textured(160, 224)
    shifted = np.roll(img, (3, -5), axis=(0, 1))  # content moves 5 left, 3 down
    for source in ("auto", "flow", "blocks", "matches"):
        out = mocomp.global_motion(img, shifted, model="translation", source=source, threads=1)
        assert out["matrix"][0, 2] == pytest.approx(-5.0, abs=0.2), source
        assert out["matrix"][1, 2] == pytest.approx(3.0, abs=0.2), source
        assert out["inliers"] > out["points"] // 2 > 10, (source, out)
        # Blocks fit a textured picture: auto needs no flow.
        assert out["source"] == ("blocks" if source == "auto" else source)
    with pytest.raises(ValueError, match="source"):
        mocomp.global_motion(img, shifted, source="sift")
