"""Dense flow, warping, .flo files and flow errors against known motion."""

import numpy as np
import pytest

import mocomp
from conftest import textured


def test_flow_on_the_bundled_sample_is_within_the_rust_tests_bounds(synth_frames, samples):
    # Frames 4 -> 5 of the bundled scene, exact ground truth with
    # occlusions marked unknown (NaN when read).
    gt = mocomp.read_flo(samples / "synth_qcif" / "forward_0004.flo")
    assert gt.shape == (144, 176, 2) and gt.dtype == np.float32
    assert np.isnan(gt).any()
    a, b = synth_frames[4][0], synth_frames[5][0]
    for method, bound in [("dis", 0.15), ("lk", 0.35), ("hs", 0.35), ("tvl1", 0.15)]:
        f = mocomp.flow(a, b, method=method)
        assert f.shape == (144, 176, 2) and f.dtype == np.float32
        e = mocomp.flow_errors(f, gt)
        assert e["epe"] < bound and e["r3"] < 2.0, (method, e)


def test_a_known_shift_is_found_and_warping_by_it_reproduces_the_first_picture():
    img = textured(96, 128)
    shifted = np.roll(img, (2, -3), axis=(0, 1))  # content moves 3 left, 2 down
    f = mocomp.flow(shifted, img, preset="accurate")
    inner = f[16:-16, 16:-16]
    assert np.allclose(inner[..., 0], 3.0, atol=0.15)
    assert np.allclose(inner[..., 1], -2.0, atol=0.15)
    back = mocomp.warp(img, f)
    assert back.dtype == np.uint8 and back.shape == img.shape
    diff = np.abs(back[16:-16, 16:-16].astype(int) - shifted[16:-16, 16:-16])
    assert diff.mean() < 2.0


def test_one_thread_and_the_default_give_the_same_flow(synth_frames):
    a, b = synth_frames[0][0], synth_frames[1][0]
    for method in ("dis", "lk"):
        assert np.array_equal(mocomp.flow(a, b, method=method, threads=1), mocomp.flow(a, b, method=method))


def test_rgb_float_and_luma_inputs(synth_frames):
    a, b = synth_frames[0][0], synth_frames[1][0]
    grey = mocomp.flow(a, b, method="lk", preset="fast")
    as_float = mocomp.flow(a.astype(np.float32), b.astype(np.float32), method="lk", preset="fast")
    assert np.array_equal(grey, as_float)
    rgb = mocomp.flow(np.dstack([a] * 3), np.dstack([b] * 3), method="lk", preset="fast")
    assert np.array_equal(grey, rgb)
    # A non-contiguous view is read as it is.
    big = np.zeros((144, 352), np.uint8)
    big[:, ::2] = a
    assert np.array_equal(mocomp.flow(big[:, ::2], b, method="lk", preset="fast"), grey)


@pytest.mark.parametrize("preset", ["ultrafast", "fast", "medium"])
def test_dis_reads_bytes_floats_and_views_alike(synth_frames, preset):
    # DIS reads uint8 in place (no float copy): every form of the same
    # pictures gives the same flow, bit for bit.
    a, b = synth_frames[0][0], synth_frames[1][0]
    grey = mocomp.flow(a, b, preset=preset)
    assert grey.shape == (144, 176, 2) and grey.dtype == np.float32 and grey.flags.c_contiguous
    assert np.isfinite(grey).all() and np.abs(grey).max() > 0.5
    forms = {
        "float32": (a.astype(np.float32), b.astype(np.float32)),
        "rgb": (np.dstack([a] * 3), np.dstack([b] * 3)),
        "fortran order": (np.asfortranarray(a), np.asfortranarray(b)),
        "strided view": (np.repeat(a, 2, axis=1)[:, ::2], b),
    }
    for name, (x, y) in forms.items():
        assert np.array_equal(mocomp.flow(x, y, preset=preset), grey), name


def test_calls_that_change_size_options_or_thread_give_fresh_results(synth_frames):
    # flow keeps its estimator and picture buffers between calls: a call
    # after others of another size, method or thread gives what it gives
    # first.
    import threading

    a, b = synth_frames[0][0], synth_frames[1][0]
    first = mocomp.flow(a, b, preset="fast")
    small = textured(40, 56)
    small_first = mocomp.flow(small, np.roll(small, 1, axis=1), preset="fast")
    mocomp.flow(a, b, method="lk")
    assert np.array_equal(mocomp.flow(a, b, preset="fast"), first)
    assert np.array_equal(mocomp.flow(small, np.roll(small, 1, axis=1), preset="fast"), small_first)
    out = {}
    thread = threading.Thread(target=lambda: out.update(f=mocomp.flow(a, b, preset="fast")))
    thread.start()
    thread.join()
    assert np.array_equal(out["f"], first)


def test_a_dense_flow_object_gives_what_flow_gives_call_after_call(synth_frames):
    # Made once, as cv2.DISOpticalFlow_create: each call on a new pair (and
    # on pairs of another size) equals the function's result with the same
    # settings, and a known shift is found.
    for method, preset in [("dis", "ultrafast"), ("dis", "medium"), ("lk", "fast"), ("hs", "fast")]:
        estimator = mocomp.DenseFlow(method=method, preset=preset, threads=1)
        assert (estimator.method, estimator.preset) == (method, preset)
        assert method in repr(estimator)
        for k in range(3):
            a, b = synth_frames[k][0], synth_frames[k + 1][0]
            assert np.array_equal(estimator.calc(a, b), mocomp.flow(a, b, method=method, preset=preset))
        small = textured(40, 56)
        assert np.array_equal(estimator(small, np.roll(small, 1, axis=1)),
                              mocomp.flow(small, np.roll(small, 1, axis=1), method=method, preset=preset))
    img = textured(96, 128)
    f = mocomp.DenseFlow(preset="accurate", levels=4)(np.roll(img, (2, -3), axis=(0, 1)), img)
    assert np.allclose(f[16:-16, 16:-16, 0], 3.0, atol=0.15)
    assert np.allclose(f[16:-16, 16:-16, 1], -2.0, atol=0.15)
    with pytest.raises(ValueError, match="method"):
        mocomp.DenseFlow(method="farneback")
    with pytest.raises(ValueError, match="alpha"):
        mocomp.DenseFlow(method="hs", alpha=-1.0)
    with pytest.raises(ValueError, match="threads"):
        mocomp.DenseFlow(threads=0)
    with pytest.raises(ValueError, match="differ in size"):
        mocomp.DenseFlow().calc(img, img[:10])


def test_dense_flow_writes_into_the_array_it_is_given(synth_frames):
    # As OpenCV's calc(I0, I1, flow): the flow lands in the caller's array,
    # which is returned; stale content is overwritten everywhere, for DIS
    # (written in place) and for a method that fills a field first.
    for method in ("dis", "lk"):
        estimator = mocomp.DenseFlow(method=method, preset="fast", threads=1)
        a, b, c = (synth_frames[k][0] for k in range(3))
        out = np.full(a.shape + (2,), 1e6, np.float32)
        got = estimator.calc(a, b, out)
        assert got is out
        assert np.array_equal(out, mocomp.flow(a, b, method=method, preset="fast"))
        assert estimator(b, c, flow=out) is out
        assert np.array_equal(out, mocomp.flow(b, c, method=method, preset="fast"))
    estimator = mocomp.DenseFlow(preset="ultrafast")
    h, w = a.shape
    with pytest.raises(ValueError, match=f"{h} x {w} x 2"):
        estimator.calc(a, b, np.zeros((h, w - 1, 2), np.float32))
    with pytest.raises(ValueError, match="float32"):
        estimator.calc(a, b, np.zeros((h, w, 2), np.float64))
    with pytest.raises(ValueError, match="C-contiguous"):
        estimator.calc(a, b, np.zeros((w, h, 2), np.float32).transpose(1, 0, 2))
    frozen = np.zeros((h, w, 2), np.float32)
    frozen.flags.writeable = False
    with pytest.raises(ValueError):
        estimator.calc(a, b, frozen)


def test_flo_round_trip_keeps_values_and_unknowns(tmp_path):
    f = np.random.default_rng(3).normal(size=(7, 9, 2)).astype(np.float32)
    f[2, 3] = np.nan
    path = tmp_path / "x.flo"
    mocomp.write_flo(path, f)
    g = mocomp.read_flo(str(path))
    assert np.array_equal(np.isnan(g), np.isnan(f))
    assert np.array_equal(g[~np.isnan(g)], f[~np.isnan(f)])


def test_flow_errors_of_a_hand_computed_case():
    gt = np.zeros((4, 4, 2), np.float32)
    gt[..., 0] = 1.0
    est = gt.copy()
    est[..., 1] = 2.0
    e = mocomp.flow_errors(est, gt)
    assert (e["epe"], e["r1"], e["r3"], e["pixels"]) == (2.0, 100.0, 0.0, 16)


def test_flow_to_color():
    f = np.zeros((5, 6, 2), np.float32)
    f[..., 0] = np.linspace(-1, 1, 6)
    f[0, 0] = np.nan
    rgb = mocomp.flow_to_color(f)
    assert rgb.shape == (5, 6, 3) and rgb.dtype == np.uint8
    assert (rgb[0, 0] == 0).all()
    # Zero motion is white; opposite directions differ.
    assert (mocomp.flow_to_color(np.zeros((2, 2, 2), np.float32)) == 255).all()
    assert not np.array_equal(rgb[1, 0], rgb[1, 5])


def test_bad_arguments_raise_clear_errors(synth_frames, tmp_path):
    a = synth_frames[0][0]
    with pytest.raises(ValueError, match="differ in size"):
        mocomp.flow(a, a[:, :-1])
    with pytest.raises(TypeError, match="img1: expected"):
        mocomp.flow(a.astype(np.int16), a)
    with pytest.raises(TypeError):
        mocomp.flow([1, 2, 3], a)
    with pytest.raises(ValueError, match="img2: expected"):
        mocomp.flow(a, np.zeros((4, 4, 2), np.uint8))
    with pytest.raises(ValueError, match="unknown flow method"):
        mocomp.flow(a, a, method="farneback")
    with pytest.raises(ValueError, match="preset"):
        mocomp.flow(a, a, preset="slow")
    with pytest.raises(ValueError, match="sigma"):
        mocomp.flow(a, a, method="lk", sigma=-1.0)
    with pytest.raises(ValueError, match="threads"):
        mocomp.flow(a, a, threads=0)
    with pytest.raises(ValueError):
        mocomp.flow(np.zeros((0, 5), np.uint8), np.zeros((0, 5), np.uint8))
    with pytest.raises(ValueError, match="H x W x 2"):
        mocomp.warp(a, np.zeros((144, 176, 3), np.float32))
    with pytest.raises(ValueError, match="flow is"):
        mocomp.flow_errors(np.zeros((4, 4, 2), np.float32), np.zeros((4, 5, 2), np.float32))
    with pytest.raises(OSError):
        mocomp.read_flo(tmp_path / "missing.flo")
    bad = tmp_path / "bad.flo"
    bad.write_bytes(b"not a flow file")
    with pytest.raises(ValueError):
        mocomp.read_flo(bad)


def test_fine_on_small_computes_finer_and_closer_on_a_small_picture():
    # A known sub-pixel shift on a small picture: the finer levels find it
    # more closely than the preset's own levels, and finest overrides both.
    img = textured(96, 128).astype(np.float32)
    shifted = np.roll(img, (1, -2), axis=(0, 1))
    inner = (slice(16, -16), slice(16, -16))
    err = {}
    for fine in (False, True):
        f = mocomp.flow(shifted, img, preset="fast", fine_on_small=fine)
        err[fine] = np.hypot(f[inner][..., 0] - 2.0, f[inner][..., 1] + 1.0).mean()
        est = mocomp.DenseFlow(preset="fast", fine_on_small=fine)
        assert np.array_equal(est.calc(shifted, img), f)
    assert err[True] < err[False], err
    assert np.array_equal(
        mocomp.flow(shifted, img, preset="fast", fine_on_small=True, finest=2),
        mocomp.flow(shifted, img, preset="fast", finest=2),
    )
