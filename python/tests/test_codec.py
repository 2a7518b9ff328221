"""Encode, decode, RD sweeps, quality metrics and BD-rate."""

import numpy as np
import pytest

import mocomp


@pytest.mark.parametrize("predictor", ["block", "obmc", "dense-lk"])
def test_decode_equals_the_encoders_reconstruction(synth_frames, predictor):
    source = synth_frames[:4]
    stream, stats, recon = mocomp.encode(source, qp=30, predictor=predictor, reconstruction=True)
    assert isinstance(stream, bytes) and len(stats) == 4
    assert [s["type"] for s in stats] == ["I", "P", "P", "P"]
    assert sum(s["bytes"] for s in stats) < len(stream)
    decoded = mocomp.decode(stream)
    assert len(decoded) == 4
    for d, r in zip(decoded, recon):
        for pd, pr in zip(d, r):
            assert pd.dtype == np.uint8 and np.array_equal(pd, pr)
    # The stats' PSNR is that of the reconstruction.
    assert abs(mocomp.psnr(source[1][0], recon[1][0]) - stats[1]["psnr_y"]) < 1e-9


def test_coding_tools_by_keyword(synth_frames, samples):
    source = synth_frames[:3]
    _, stats = mocomp.encode(source, qp=30, ipratio=2.0)
    assert [s["qp"] for s in stats] == [24, 30, 30]
    tools_off = ({"deblock": False}, {"weightp": False}, {"partitions": False}, {"partitions": "i4x4"}, {"partitions": "i8x8"},
                 {"ipratio": 1.0},
                 {"dct8x8": False})
    for tools in tools_off:
        stream, stats, recon = mocomp.encode(source, qp=30, reconstruction=True, **tools)
        assert all(np.array_equal(a, b) for d, r in zip(mocomp.decode(stream), recon) for a, b in zip(d, r))
    on, _ = mocomp.encode(source, qp=30)
    off, _ = mocomp.encode(source, qp=30, deblock=False)
    assert on != off
    with pytest.raises(ValueError):
        mocomp.encode(source, ipratio=0.5)
    # Partitions by x264's names or as a flag: True is "all". They are P
    # frames' (as x264's): over a cut, where a P frame codes intra, fewer
    # differ. The default preset's are all but 4x4 intra (from slow).
    assert mocomp.encode(source, qp=30, partitions="p8x8,i8x8")[0] == on
    cut = list(source[:2]) + list(mocomp.read_y4m(samples / "tree_qcif.y4m")[:1])
    assert mocomp.encode(cut, qp=30, partitions="p8x8,i4x4")[0] != mocomp.encode(cut, qp=30)[0]
    all_named = mocomp.encode(source, qp=30, partitions="p8x8,i8x8,i4x4")[0]
    assert mocomp.encode(source, qp=30, partitions=True)[0] == all_named
    assert mocomp.encode(source, qp=30, partitions="none")[0] == mocomp.encode(source, qp=30, partitions=False)[0]
    # I frames' intra blocks apart: False is 16x16 intra only.
    first = source[:1]
    assert mocomp.encode(first, qp=30, i_partitions=True)[0] == mocomp.encode(first, qp=30)[0]
    assert mocomp.encode(first, qp=30, i_partitions=False)[0] == mocomp.encode(first, qp=30, i_partitions="none")[0]
    assert mocomp.encode(first, qp=30, i_partitions=False)[0] != mocomp.encode(first, qp=30)[0]
    with pytest.raises(ValueError):
        mocomp.encode(source, partitions="p4x4")
    # The 8x8 transform: on in the default preset, off on request.
    assert mocomp.encode(source, qp=30, dct8x8=True)[0] == on
    assert mocomp.encode(source, qp=30, dct8x8=False)[0] != on
    # References: two in the default preset (medium's); 0 or 9 are errors.
    assert mocomp.encode(source, qp=30, refs=2)[0] == on
    assert mocomp.encode(source, qp=30, refs=1)[0] != on
    for refs in (0, 9):
        with pytest.raises(ValueError, match="references"):
            mocomp.encode(source, refs=refs)
    # Presets, and options that override them: fast with the fast decision
    # and faster's lambda scale is faster; the default is medium.
    fast, _ = mocomp.encode(source, qp=30, preset="fast")
    assert fast != on
    assert mocomp.encode(source, qp=30, preset="medium")[0] == on
    faster, _ = mocomp.encode(source, qp=30, preset="faster")
    as_faster = mocomp.encode(source, qp=30, preset="fast", decision="fast", lambda_scale=1.4)
    assert as_faster[0] == faster
    with pytest.raises(ValueError):
        mocomp.encode(source, preset="placebo")


def test_every_encoder_option_by_keyword_as_the_command_line_names_it(synth_frames):
    source = synth_frames[:3]
    names = [name for name, _ in mocomp.encoder_options()]
    assert {"subpel-rd", "fast-pskip", "refs", "metrics", "partitions", "8x8dct"} <= set(names)
    # Sub-pel RD (x264's subme 8): off in medium, on in slow; by keyword
    # it changes what medium codes.
    on, _ = mocomp.encode(source, qp=30)
    assert mocomp.encode(source, qp=30, subpel_rd=True)[0] != on
    assert mocomp.encode(source, qp=30, subpel_rd=False)[0] == on
    assert "chroma-me" in names
    assert mocomp.encode(source, qp=30, chroma_me=False)[0] == on
    assert mocomp.encode(source, qp=30, adaptive_pricing=True)[0] == on
    assert mocomp.encode(source, qp=30, adaptive_pricing=False)[0] != on
    # Each P frame's deblocking chosen (on by default): grain of its own
    # in every frame at QP 34, which the filter takes for blocking, goes
    # undeblocked after the first frames; off, every frame is deblocked.
    grain = [
        (np.random.default_rng(t).integers(100, 157, (64, 96), dtype=np.uint8),
         np.full((32, 48), 128, np.uint8), np.full((32, 48), 128, np.uint8))
        for t in range(6)
    ]
    assert "deblock-choice" in names
    chosen, _ = mocomp.encode(grain, qp=34)
    assert mocomp.encode(grain, qp=34, deblock_choice=True)[0] == chosen
    assert mocomp.encode(grain, qp=34, deblock_choice=False)[0] != chosen
    # Fast P-skip is on in every preset; off, the stream changes (in
    # ultrafast: medium's full decision codes this sample alike either
    # way).
    ultrafast, _ = mocomp.encode(source, qp=30, preset="ultrafast")
    assert mocomp.encode(source, qp=30, preset="ultrafast", fast_pskip=False)[0] != ultrafast
    # Search options follow the predictor, as on the command line: a
    # search range of one pel cannot follow the sample's motion.
    esa, _ = mocomp.encode(source, qp=30, predictor="block:esa")
    assert mocomp.encode(source, qp=30, predictor="block:esa", range=1)[0] != esa
    with pytest.raises(ValueError, match="does not apply to predictor 'zero'"):
        mocomp.encode(source, predictor="zero", range=8)
    with pytest.raises(ValueError, match="QP 52 is not in 0..=51"):
        mocomp.encode(source, qp=52)
    with pytest.raises(ValueError, match="unknown option 'colour'"):
        mocomp.encode(source, colour="red")
    # Metrics asked for are in the statistics, the others left out.
    _, stats = mocomp.encode(source, qp=30, metrics="ms-ssim")
    assert 0.5 < stats[1]["ms_ssim"] < 1.0 and "ciede2000" not in stats[1] and "ssim" not in stats[1]


def test_a_y4m_path_and_its_arrays_give_the_same_stream(synth_frames, samples):
    from_path, _ = mocomp.encode(samples / "synth_qcif.y4m", qp=32, frames=3, fps=(30, 1))
    from_arrays, _ = mocomp.encode(synth_frames[:3], qp=32, fps=(30, 1))
    assert from_path == from_arrays


def test_bad_streams_and_sources_raise():
    with pytest.raises(ValueError, match="stream"):
        mocomp.decode(b"\x00\x01garbage")
    with pytest.raises(TypeError):
        mocomp.encode(42)
    with pytest.raises(ValueError, match="3 planes"):
        mocomp.encode([(np.zeros((16, 16), np.uint8),)])
    with pytest.raises(ValueError):
        mocomp.encode([(np.zeros((16, 16), np.uint8), np.zeros((3, 3), np.uint8), np.zeros((8, 8), np.uint8))])
    with pytest.raises(ValueError, match="QP 60"):
        mocomp.encode([], qp=60)
    with pytest.raises(ValueError, match="predictor"):
        mocomp.encode([], predictor="nope")


def test_rd_rows_match_the_encoder(samples):
    rows = mocomp.rd([samples / "synth_qcif.y4m"], qps=[27, 37], predictors=["block:esa"], frames=3)
    assert [(r["codec"], r["q"]) for r in rows] == [("block:esa", 27.0), ("block:esa", 37.0)]
    assert rows[0]["kbps"] > rows[1]["kbps"] and rows[0]["psnr_y"] > rows[1]["psnr_y"]
    stream, _ = mocomp.encode(samples / "synth_qcif.y4m", qp=27, predictor="block:esa", frames=3)
    assert rows[0]["bytes"] == len(stream)


def test_bd_rate_of_the_four_point_example():
    ra, pa = [686.76, 309.58, 157.11, 85.95], [40.28, 37.18, 34.24, 31.42]
    rb, pb = [893.34, 407.8, 204.93, 112.75], [40.39, 37.21, 34.17, 31.24]
    assert abs(mocomp.bd_rate(ra, pa, rb, pb) - 31.397) < 5e-4
    assert abs(mocomp.bd_rate(ra, pa, rb, pb, method="pchip") - 31.380) < 5e-4
    with pytest.raises(ValueError, match="4"):
        mocomp.bd_rate(ra[:3], pa[:3], rb, pb)
    with pytest.raises(ValueError, match="method"):
        mocomp.bd_rate(ra, pa, rb, pb, method="linear")


def test_psnr_and_ssim_against_the_reference_figures(samples):
    import json

    ref = json.loads((samples / "reference" / "tree_qcif_mpeg4.json").read_text())
    a = mocomp.read_y4m(samples / "tree_qcif.y4m")
    b = mocomp.read_y4m(samples / "tree_qcif_mpeg4.y4m")
    for i, (fa, fb) in enumerate(zip(a, b)):
        assert abs(mocomp.psnr(fa[0], fb[0]) - ref["ffmpeg_psnr_per_frame"][i]["psnr_y"]) < 0.01
        assert abs(mocomp.ssim(fa[0], fb[0]) - ref["skimage_ssim_y_per_frame"][i]) < 1e-4
    assert mocomp.psnr(a[0][0], a[0][0]) == 100.0
    with pytest.raises(ValueError, match="shape"):
        mocomp.psnr(a[0][0], a[0][1])


def test_missing_and_bad_files(tmp_path):
    with pytest.raises(OSError):
        mocomp.read_y4m(tmp_path / "missing.y4m")
    bad = tmp_path / "bad.y4m"
    bad.write_bytes(b"YUV4MPEG2 W99999999 H2 F25:1\n")
    with pytest.raises(ValueError, match="bad.y4m"):
        mocomp.read_y4m(bad)
