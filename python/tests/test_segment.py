"""Moving-object masks from Python: a textured square moving against a
panning textured background (both shifts exact), its mask known."""

import numpy as np
import pytest

import mocomp
from conftest import textured


def frame(background, patch, t):
    """The background panned by (2t, t); the patch pasted at (60 - 3t, 40 + 2t)."""
    h, w = 120, 160
    img = background[t : t + h, 2 * t : 2 * t + w].copy()
    x, y = 60 - 3 * t, 40 + 2 * t
    img[y : y + 36, x : x + 36] = patch
    mask = np.zeros((h, w), bool)
    mask[y : y + 36, x : x + 36] = True
    return img, mask


def test_motion_mask_finds_an_object_moving_against_the_camera():
    background, patch = textured(140, 200, seed=7), textured(36, 36, seed=8)
    frames = [frame(background, patch, t) for t in range(3)]
    found = mocomp.motion_mask(frames[1][0], [frames[0][0], frames[2][0]])
    assert found.shape == (120, 160) and found.dtype == np.uint8
    assert set(np.unique(found)) <= {0, 255}
    truth = frames[1][1]
    moving = found > 0
    iou = (moving & truth).sum() / (moving | truth).sum()
    assert iou > 0.75, iou
    with pytest.raises(ValueError, match="neighbours"):
        mocomp.motion_mask(frames[1][0], [])
    with pytest.raises(ValueError, match="size"):
        mocomp.motion_mask(frames[1][0], [frames[0][0][:50]])


def test_motion_masks_segment_a_sequence_in_time():
    background, patch = textured(140, 200, seed=7), textured(36, 36, seed=8)
    frames = [frame(background, patch, t) for t in range(5)]
    found = mocomp.motion_masks([img for img, _ in frames])
    assert len(found) == 5
    for masks, (_, truth) in zip(found, frames):
        assert masks.shape == (120, 160) and masks.dtype == np.uint8
        moving = masks > 0
        iou = (moving & truth).sum() / (moving | truth).sum()
        assert iou > 0.75, iou
    with pytest.raises(ValueError, match="two or more"):
        mocomp.motion_masks([frames[0][0]])
    with pytest.raises(ValueError, match="size"):
        mocomp.motion_masks([frames[0][0], frames[1][0][:50]])
