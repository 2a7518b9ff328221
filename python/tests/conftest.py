"""Shared fixtures: the repository's bundled samples (never ../shared)."""

import pathlib

import numpy as np
import pytest

SAMPLES = pathlib.Path(__file__).resolve().parents[2] / "samples"


@pytest.fixture(scope="session")
def samples():
    return SAMPLES


@pytest.fixture(scope="session")
def synth_frames():
    """The bundled synthetic QCIF sequence as (Y, U, V) arrays."""
    import mocomp

    return mocomp.read_y4m(SAMPLES / "synth_qcif.y4m")


def textured(h, w, seed=1):
    """A smooth random texture (sum of blurred noise octaves), uint8."""
    rng = np.random.default_rng(seed)
    img = np.zeros((h, w))
    for scale in (16, 8, 4):
        small = rng.normal(size=(h // scale + 2, w // scale + 2))
        up = np.kron(small, np.ones((scale, scale)))[:h, :w]
        k = np.ones(scale) / scale
        up = np.apply_along_axis(lambda r: np.convolve(r, k, mode="same"), 1, up)
        up = np.apply_along_axis(lambda c: np.convolve(c, k, mode="same"), 0, up)
        img += up * scale
    img = (img - img.min()) / (img.max() - img.min()) * 200 + 28
    return img.astype(np.uint8)
