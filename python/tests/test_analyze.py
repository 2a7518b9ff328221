"""Stream analysis as numpy arrays, and the quality metrics AWCY reports."""

import numpy as np
import pytest

import mocomp


def test_analysis_agrees_with_the_encoder_and_the_decoder(synth_frames):
    source = synth_frames[:3]
    stream, stats = mocomp.encode(source, qp=26, refs=1)
    frames = mocomp.analyze(stream)
    decoded = mocomp.decode(stream)
    assert len(frames) == 3
    for f, s, d in zip(frames, stats, decoded):
        assert (f["type"], f["qp"], f["bytes"]) == (s["type"], s["qp"], s["bytes"])
        assert (f["bits_header"], f["bits_motion"], f["bits_residual"]) == (
            s["bits_header"], s["bits_motion"], s["bits_residual"])
        assert f["kind"].shape == (9, 11) and f["vectors"].shape == (18, 22, 2)
        counts = [int((f["kind"] == k).sum()) for k in range(3)]
        assert counts == [s["skip_mbs"], s["inter_mbs"], s["intra_mbs"]]
        for pf, pd in zip(f["picture"], d):
            assert np.array_equal(pf, pd)
        # Intra macroblocks have no vectors; the others do, in every 8x8 block.
        intra = np.kron(f["kind"] == 2, np.ones((2, 2), bool))
        assert np.array_equal(f["has_vector"], ~intra)
        # One reference (refs=1): index 0 wherever there is a vector, -1
        # for intra.
        assert np.array_equal(f["refs"], np.where(intra, -1, 0))
    assert (frames[0]["kind"] == 2).all() and frames[0]["grid"] is None
    assert all(f["luma_filter"] in ("sharp", "smooth") for f in frames)
    smooth, _ = mocomp.encode(source, qp=26, refs=1, luma_filter="smooth")
    assert [f["luma_filter"] for f in mocomp.analyze(smooth)] == ["sharp", "smooth", "smooth"]
    # The sample pans: the P frames' vectors are mostly not zero.
    moving = np.abs(frames[2]["vectors"]).sum(-1)[frames[2]["has_vector"]] > 0
    assert moving.mean() > 0.5


def test_deblocking_offsets_as_x264s_reach_every_header(synth_frames):
    stream, _ = mocomp.encode(synth_frames[:3], qp=30, deblock="2:-1")
    frames = mocomp.analyze(stream)
    assert all(f["deblock"] and f["deblock_offsets"] == (4, -2) for f in frames)
    off, _ = mocomp.encode(synth_frames[:3], qp=30, deblock=False)
    assert all(not f["deblock"] and f["deblock_offsets"] == (0, 0) for f in mocomp.analyze(off))
    with pytest.raises(ValueError):
        mocomp.encode(synth_frames[:2], qp=30, deblock="7:0")


def test_grid_frames_carry_their_grid(synth_frames):
    stream, _ = mocomp.encode(synth_frames[:2], qp=30, predictor="dense-hs")
    frames = mocomp.analyze(stream)
    grid = frames[1]["grid"]
    assert frames[1]["tool"] == "grid" and grid.ndim == 3 and grid.shape[2] == 2


def test_a_damaged_stream_is_a_value_error(synth_frames):
    stream, _ = mocomp.encode(synth_frames[:2], qp=30)
    with pytest.raises(ValueError):
        mocomp.analyze(stream[: len(stream) // 2])


def test_quality_metrics_rank_distortions(synth_frames):
    ref = synth_frames[0]
    noisy = tuple(np.clip(p.astype(int) + (np.indices(p.shape).sum(0) % 7 - 3) * k, 0, 255).astype(np.uint8)
                  for p, k in zip(ref, (2, 1, 1)))
    q = mocomp.quality(ref, noisy, metrics="all")
    assert set(q) == {"psnr_y", "psnr_u", "psnr_v", "mse", "ssim", "ms_ssim", "psnr_hvs", "psnr_hvs_y", "ciede2000"}
    same = mocomp.quality(ref, ref, metrics="ms-ssim,ciede2000")
    assert same["ciede2000"] == 100.0 and abs(same["ms_ssim"] - 1.0) < 1e-12
    assert q["ms_ssim"] < 1.0 and q["ciede2000"] < 100.0
    assert "ssim" not in same
    with pytest.raises(ValueError):
        mocomp.quality(ref, noisy, metrics="butteraugli")


def test_reference_indices_stay_below_the_references_given(synth_frames):
    source = synth_frames[:5]
    stream, _, recon = mocomp.encode(source, qp=30, refs=3, reconstruction=True)
    assert all(np.array_equal(a, b) for d, r in zip(mocomp.decode(stream), recon) for a, b in zip(d, r))
    for i, f in enumerate(mocomp.analyze(stream)):
        # Frame i has i earlier frames (at most 3) to predict from.
        assert f["refs"].max() < min(i, 3) or f["type"] == "I"
