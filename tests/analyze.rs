//! Stream analysis against the encoder's own statistics, for every
//! predictor and the partition and intra tools; `mocomp analyze`'s files.

use std::path::Path;

use assert_cmd::Command;
use mocomp::analyze::{Analyzer, CSV_HEADER};
use mocomp::codec::Frame;
use mocomp::encode::{Encoder, EncoderConfig, FrameStats, Predictor};
use mocomp::io::y4m::Y4mReader;

fn sample_frames(n: usize) -> Vec<Frame> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/synth_qcif.y4m");
    let mut frames = Y4mReader::open(&path).unwrap().read_all().unwrap();
    frames.truncate(n);
    frames
}

/// The stream, the encoder's per-frame statistics and reconstructions.
fn encode(frames: &[Frame], config: EncoderConfig) -> (Vec<u8>, Vec<FrameStats>, Vec<Frame>) {
    let mut enc = Encoder::new(frames[0].width(), frames[0].height(), (25, 1), config).unwrap();
    let mut stream = enc.header();
    let (mut stats, mut recons) = (Vec::new(), Vec::new());
    for f in frames {
        let coded = enc.encode(f).unwrap();
        stream.extend_from_slice(&coded.bytes);
        stats.push(coded.stats);
        recons.push(coded.recon.expect("a reconstruction by default"));
    }
    stream.extend_from_slice(&Encoder::trailer());
    (stream, stats, recons)
}

#[test]
fn analysis_agrees_with_the_encoders_statistics_for_every_predictor() {
    let frames = sample_frames(4);
    for name in ["zero", "block", "flow-block", "dense-hs", "dense-lk", "obmc"] {
        let predictor: Predictor = name.parse().unwrap();
        let config = EncoderConfig::new().qp(30).predictor(predictor);
        let (stream, stats, recons) = encode(&frames, config);
        let analysed: Vec<_> = Analyzer::new(&stream[..]).unwrap().map(Result::unwrap).collect();
        assert_eq!(analysed.len(), stats.len(), "{name}");
        for ((a, s), r) in analysed.iter().zip(&stats).zip(&recons) {
            let what = format!("{name}, frame {}", a.index);
            assert_eq!(a.frame_type, s.frame_type, "{what}");
            assert_eq!(a.qp, s.qp, "{what}");
            assert_eq!(a.bytes, s.bytes, "{what}");
            assert_eq!(
                [a.bits.header, a.bits.motion, a.bits.residual],
                [s.bits_header, s.bits_motion, s.bits_residual],
                "{what}"
            );
            assert_eq!(a.kinds(), [s.skip_mbs, s.inter_mbs, s.intra_mbs], "{what}");
            assert_eq!(&a.picture, r, "{what}: the decoded picture");
            // Without a grid, the macroblocks' bins are the whole range-coded
            // partition: their cost is the frame's bits to the coder's
            // precision (framing, header and the coder's flush aside).
            assert_eq!(
                a.grid.is_some(),
                name.starts_with("dense") && a.frame_type == 'P',
                "{what}"
            );
            if a.grid.is_none() {
                let mb_bits: f64 = a
                    .mbs
                    .iter()
                    .map(|m| m.bits_header + m.bits_motion + m.bits_residual)
                    .sum();
                let coded = (a.bits.header + a.bits.motion + a.bits.residual) as f64;
                assert!(
                    (mb_bits - coded).abs() <= 0.05 * coded + 80.0,
                    "{what}: {mb_bits} of {coded}"
                );
            }
        }
    }
}

#[test]
fn partitions_intra_modes_and_vectors_are_reported_as_coded() {
    let frames = sample_frames(3);
    // Three QPs: which intra sizes one QP's I frame chooses moves with
    // every change of the mode decision.
    let analysed: Vec<_> = [24, 30, 36]
        .into_iter()
        .flat_map(|qp| {
            let (stream, _, _) = encode(&frames, EncoderConfig::new().qp(qp));
            let frames = Analyzer::new(&stream[..]).unwrap().map(Result::unwrap);
            frames.collect::<Vec<_>>()
        })
        .collect();
    let intra_frames = || analysed.iter().filter(|f| f.frame_type == 'I');
    let all: Vec<_> = analysed
        .iter()
        .flat_map(|f| f.mbs.iter().map(move |m| (f, m)))
        .collect();
    // I frame: intra only, 16x16, 8x8 or 4x4 with as many modes as
    // blocks; 8x8 blocks in the 8x8 transform.
    for m in intra_frames().flat_map(|f| &f.mbs) {
        assert_eq!(m.kind, "intra");
        let luma = m.intra_modes.split(',').next().unwrap();
        let want = match m.partition {
            "4x4" => 16,
            "8x8" => 4,
            _ => 1,
        };
        assert_eq!(luma.split('/').count(), want, "{m:?}");
        assert_eq!(m.vectors, [None; 4]);
        assert_eq!(m.transform == 8, m.partition == "8x8", "{m:?}");
    }
    // Every intra size is chosen somewhere in the I frames.
    for size in ["16x16", "8x8", "4x4"] {
        assert!(
            intra_frames().any(|f| f.mbs.iter().any(|m| m.partition == size)),
            "no intra {size}"
        );
    }
    // P frames: split macroblocks carry partition vectors consistent with
    // their shape; whole ones one vector four times.
    for (f, m) in all.iter().filter(|(f, _)| f.frame_type == 'P') {
        match (m.kind, m.partition) {
            ("inter", "16x8") => assert!(
                m.vectors[0] == m.vectors[1] && m.vectors[2] == m.vectors[3],
                "{m:?}"
            ),
            ("inter", "8x16") => assert!(
                m.vectors[0] == m.vectors[2] && m.vectors[1] == m.vectors[3],
                "{m:?}"
            ),
            ("inter", "8x8") => {}
            ("inter" | "skip", "16x16") => {
                assert!(m.vectors.iter().all(|v| *v == m.vectors[0] && v.is_some()))
            }
            ("intra", _) => assert_eq!(m.vectors, [None; 4]),
            other => panic!("frame {}: unexpected {other:?}", f.index),
        }
        if m.kind == "skip" {
            assert_eq!(
                (m.coded_luma_blocks, m.coded_chroma_blocks, m.bits_residual),
                (0, 0, 0.0)
            );
        }
        // The 8x8 transform: inter with luma levels, or intra in 8x8
        // blocks; levels in whole 8x8 blocks (four 4x4 blocks each).
        assert!(m.transform == 4 || m.transform == 8, "{m:?}");
        if m.transform == 8 {
            assert_eq!(m.coded_luma_blocks % 4, 0, "{m:?}");
            match m.kind {
                "inter" => assert!(m.coded_luma_blocks > 0, "{m:?}"),
                _ => assert_eq!((m.kind, m.partition), ("intra", "8x8"), "{m:?}"),
            }
        }
    }
    assert!(
        all.iter().any(|(_, m)| m.partition == "4x4"),
        "4x4 intra appears at QP 24-36"
    );
    assert!(
        all.iter().any(|(_, m)| m.transform == 8),
        "the 8x8 transform appears at QP 24-36"
    );
    // The sample pans: most inter vectors are not zero.
    let moving = all
        .iter()
        .filter(|(_, m)| m.kind == "inter" && m.vectors[0] != Some((0, 0)))
        .count();
    assert!(moving > 20, "{moving}");
}

#[test]
fn bad_streams_are_errors_not_panics() {
    let frames = sample_frames(2);
    let (stream, _, _) = encode(&frames, EncoderConfig::new());
    for cut in [3, stream.len() / 2, stream.len() - 1] {
        let result: Result<Vec<_>, _> = match Analyzer::new(&stream[..cut]) {
            Ok(a) => a.collect(),
            Err(e) => Err(e),
        };
        assert!(result.is_err(), "cut at {cut}");
    }
}

#[test]
fn the_command_writes_csv_json_and_overlays_of_the_right_size() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/synth_qcif.y4m");
    let bin = || Command::new(assert_cmd::cargo::cargo_bin!("mocomp"));
    bin()
        .args([
            "encode",
            src.to_str().unwrap(),
            "-o",
            &p("s.mcv"),
            "--frames",
            "3",
        ])
        .args(["--stats", &p("stats.csv"), "--quiet"])
        .assert()
        .success();
    let out = bin()
        .args([
            "analyze",
            &p("s.mcv"),
            "--csv",
            &p("mb.csv"),
            "--overlay",
            &p("ov"),
        ])
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    let table = String::from_utf8(out).unwrap();
    assert_eq!(table.lines().count(), 4, "{table}");
    // The per-frame table repeats the encoder's byte and bit counts.
    let stats = std::fs::read_to_string(p("stats.csv")).unwrap();
    for (row, line) in stats.lines().skip(1).zip(table.lines().skip(1)) {
        let s: Vec<&str> = row.split(',').collect();
        let t: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(
            (t[3], t[4], t[5], t[6]),
            (s[3], s[4], s[5], s[6]),
            "{row} / {line}"
        );
    }
    let csv = std::fs::read_to_string(p("mb.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some(CSV_HEADER));
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 3 * 99);
    let columns = CSV_HEADER.split(',').count();
    assert!(rows.iter().all(|r| r.split(',').count() == columns));
    // The table's last two columns count each frame's intra macroblocks in
    // 8x8 and in 4x4 blocks, as the per-macroblock rows say.
    let header: Vec<&str> = table.lines().next().unwrap().split_whitespace().collect();
    assert_eq!(header[header.len() - 2..], ["i8x8", "i4x4"]);
    for (i, line) in table.lines().skip(1).enumerate() {
        let t: Vec<&str> = line.split_whitespace().collect();
        for (column, size) in [(t.len() - 2, "8x8"), (t.len() - 1, "4x4")] {
            let counted = rows
                .iter()
                .filter(|r| {
                    let c: Vec<&str> = r.split(',').collect();
                    c[0] == i.to_string() && c[4] == "intra" && c[5] == size
                })
                .count();
            assert_eq!(t[column], counted.to_string(), "frame {i} intra {size}");
        }
    }
    for i in 0..3 {
        let img = image::open(p(&format!("ov/frame_{i:04}.png"))).unwrap();
        assert_eq!((img.width(), img.height()), (176, 144));
    }
    // JSON: every macroblock, and a Y4M overlay as long as the stream.
    let out = bin()
        .args(["analyze", &p("s.mcv"), "--json", "--overlay", &p("ov.y4m")])
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    let v: serde_json::Value = serde_json::from_slice(&out).unwrap();
    assert_eq!(v["frames"].as_array().unwrap().len(), 3);
    assert_eq!(v["frames"][1]["mbs"].as_array().unwrap().len(), 99);
    assert_eq!(v["frames"][0]["type"], "I");
    assert!(v["frames"]
        .as_array()
        .unwrap()
        .iter()
        .all(|f| f["luma_filter"] == "sharp" || f["luma_filter"] == "smooth"));
    let overlay = Y4mReader::open(Path::new(&p("ov.y4m")))
        .unwrap()
        .read_all()
        .unwrap();
    assert_eq!(overlay.len(), 3);
    assert_eq!((overlay[0].width(), overlay[0].height()), (176, 144));
    // A stream that is not one: one error line.
    std::fs::write(p("bad.mcv"), b"not a stream").unwrap();
    let out = bin().args(["analyze", &p("bad.mcv")]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).starts_with("mocomp: error: "));
}
