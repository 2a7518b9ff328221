"""Stabilisation from Python against a known shake: a still picture seen
through windows at random offsets (exact truth), and the bicubic warp
against exact shifts."""

import numpy as np
import pytest

import mocomp
from conftest import textured


def shaken_windows(img, offsets, size):
    """Each frame: the size[0] x size[1] window of img shifted by an offset."""
    h, w = size
    y0, x0 = (img.shape[0] - h) // 2, (img.shape[1] - w) // 2
    return [img[y0 + dy : y0 + dy + h, x0 + dx : x0 + dx + w].copy() for dx, dy in offsets]


def test_stabilize_path_undoes_a_known_shake():
    img = textured(240, 320, seed=4)
    rng = np.random.default_rng(5)
    offsets = [tuple(int(v) for v in rng.integers(-6, 7, 2)) for _ in range(24)]
    frames = shaken_windows(img, offsets, (200, 280))
    out = mocomp.stabilize_path(frames, model="translation", l1=True, coverage=1.0, threads=1)
    warps = out["warps"]
    assert warps.shape == (24, 3, 3) and warps.dtype == np.float64
    assert out["zoom"].shape == (24,) and out["cuts"] == []
    # Where each output's centre lands in the still picture: the same place
    # in every frame (the L1 path is still where it can be), to a fraction
    # of the shake.
    centre = np.array([139.5, 99.5, 1.0])
    seen = np.array([(warps[t] @ centre)[:2] + offsets[t] for t in range(24)])
    spread = np.abs(seen - seen.mean(axis=0)).max()
    shake = np.abs(np.array(offsets) - np.mean(offsets, axis=0)).max()
    assert shake >= 5 and spread < 0.5, (spread, shake)
    # The Gaussian path drifts slowly instead: small steps frame to frame.
    gauss = mocomp.stabilize_path(frames, model="translation", coverage=1.0, threads=1)["warps"]
    seen = np.array([(gauss[t] @ centre)[:2] + offsets[t] for t in range(24)])
    assert np.abs(np.diff(seen, axis=0)).max() < 1.0
    # And each frame warped by its matrix shows the still picture.
    still = [mocomp.warp_matrix(f, warps[t]) for t, f in enumerate(frames)]
    core = np.s_[40:160, 60:220]
    diff = np.abs(still[3][core].astype(int) - still[17][core].astype(int))
    assert diff.mean() < 2.0, diff.mean()


def test_warp_matrix_shifts_exactly_and_checks_its_input():
    img = textured(60, 80, seed=2)
    shift = np.array([[1.0, 0, 3], [0, 1.0, -2], [0, 0, 1]])
    out = mocomp.warp_matrix(img, shift, border=0)
    assert np.array_equal(out[2:, :-3], img[:-2, 3:])
    assert (out[:2] == 0).all() and (out[:, -3:] == 0).all()
    small = mocomp.warp_matrix(img, np.eye(3), size=(40, 30))
    assert small.shape == (30, 40) and np.array_equal(small, img[:30, :40])
    with pytest.raises(ValueError, match="3 x 3"):
        mocomp.warp_matrix(img, np.eye(2))
    with pytest.raises(ValueError, match="border"):
        mocomp.warp_matrix(img, np.eye(3), border="wrap")
    with pytest.raises(ValueError, match="empty"):
        mocomp.stabilize_path([])
    with pytest.raises(ValueError, match="not 80x60"):
        mocomp.stabilize_path([img, img[:50]])
    with pytest.raises(ValueError, match="zoom"):
        mocomp.stabilize_path([img, img], zoom="big")
