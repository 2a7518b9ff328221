"""Frame interpolation from Python: the bundled scene's frame 1 rebuilt
from frames 0 and 2 (its camera pans, objects move)."""

import numpy as np
import pytest

import mocomp


def psnr(a, b):
    mse = np.mean((a.astype(float) - b.astype(float)) ** 2)
    return 10 * np.log10(255.0**2 / mse)


def test_interpolate_rebuilds_a_middle_frame(synth_frames):
    f0, f1, f2 = synth_frames[0], synth_frames[1], synth_frames[2]
    made = mocomp.interpolate(f0, f2, times=[0.0, 0.5, 1.0])
    assert len(made) == 3 and all(len(m) == 3 for m in made)
    assert all(np.array_equal(a, b) for a, b in zip(made[0], f0))
    assert all(np.array_equal(a, b) for a, b in zip(made[2], f2))
    mid = made[1]
    assert mid[0].shape == f1[0].shape and mid[1].shape == f1[1].shape
    average = ((f0[0].astype(int) + f2[0]) // 2).astype(np.uint8)
    ours, plain = psnr(f1[0], mid[0]), psnr(f1[0], average)
    assert ours > plain + 3.0, (ours, plain)


def test_interpolate_bends_paths_through_the_frames_either_side(synth_frames):
    # Frame 3 from 2 and 4, with 0 and 6 known: the CLI's way on a sequence.
    f = synth_frames
    straight = mocomp.interpolate(f[2], f[4])[0]
    curved = mocomp.interpolate(f[2], f[4], before=f[0], after=f[6])[0]
    average = ((f[2][0].astype(int) + f[4][0]) // 2).astype(np.uint8)
    plain = psnr(f[3][0], average)
    assert psnr(f[3][0], curved[0]) > plain + 3.0
    # The scene moves steadily: the bend stays within the flows' noise.
    assert psnr(f[3][0], curved[0]) > psnr(f[3][0], straight[0]) - 0.5
    small = tuple(p[:20, :20] for p in f[0])
    with pytest.raises(ValueError, match="before"):
        mocomp.interpolate(f[2], f[4], before=small)


def test_interpolate_checks_its_input(synth_frames):
    f0 = synth_frames[0]
    with pytest.raises(ValueError, match=r"not in \[0, 1\]"):
        mocomp.interpolate(f0, f0, times=[1.5])
    small = tuple(p[:20, :20] for p in f0)
    with pytest.raises(ValueError):
        mocomp.interpolate(f0, small)
    with pytest.raises(ValueError, match="preset"):
        mocomp.interpolate(f0, f0, preset="turbo")
