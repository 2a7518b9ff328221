//! The `mocomp` command line: each subcommand end to end, and errors as one
//! clear line with a non-zero exit, never a panic.

use std::path::{Path, PathBuf};

use assert_cmd::Command;
use predicates::prelude::*;

fn mocomp() -> Command {
    Command::new(assert_cmd::cargo::cargo_bin!("mocomp"))
}

/// Runs the command, which must succeed, and parses its standard output
/// as one JSON value.
fn json_stdout(cmd: &mut Command) -> serde_json::Value {
    let out = cmd.assert().success().get_output().stdout.clone();
    serde_json::from_slice(&out).expect("standard output is one JSON value")
}

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("samples").join(name)
}

/// Runs `args`, expects failure, and returns standard error, checked to be
/// one `mocomp: error:` line without a panic.
fn fails_cleanly(args: &[&str]) -> String {
    let out = mocomp().args(args).output().unwrap();
    assert_eq!(out.status.code(), Some(1), "{args:?}");
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.starts_with("mocomp: error: "), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        !err.contains("panicked") && !err.contains("internal error"),
        "{err}"
    );
    err
}

#[test]
fn help_lists_the_working_subcommands() {
    let out = mocomp()
        .arg("--help")
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    let text = String::from_utf8(out).unwrap();
    for cmd in ["compare", "encode", "decode", "info", "samples", "psnr"] {
        assert!(text.contains(cmd), "{cmd} missing from --help:\n{text}");
    }
}

#[test]
fn info_describes_y4m_flo_and_png() {
    mocomp()
        .args(["info", sample("synth_qcif.y4m").to_str().unwrap(), "--json"])
        .assert()
        .success()
        .stdout(predicate::str::contains(r#""width":176"#).and(predicate::str::contains(r#""frames":10"#)));
    mocomp()
        .args(["info", sample("synth_qcif/forward_0000.flo").to_str().unwrap()])
        .assert()
        .success()
        .stdout(predicate::str::contains("Middlebury .flo").and(predicate::str::contains("176")));
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("p.png");
    mocomp::io::image::write_plane(&png, &mocomp::codec::Plane::filled(9, 7, 3).unwrap()).unwrap();
    mocomp()
        .args(["info", png.to_str().unwrap(), "--json"])
        .assert()
        .success()
        .stdout(predicate::str::contains(r#""width":9,"height":7"#));
}

#[test]
fn info_reads_standard_input() {
    let bytes = std::fs::read(sample("tree_qcif.y4m")).unwrap();
    mocomp()
        .args(["info", "-", "--json"])
        .write_stdin(bytes)
        .assert()
        .success()
        .stdout(predicate::str::contains(r#""frames":6"#));
}

#[test]
fn psnr_json_has_the_documented_keys_and_ffmpeg_figures() {
    let v = json_stdout(mocomp().args([
        "psnr",
        sample("tree_qcif.y4m").to_str().unwrap(),
        sample("tree_qcif_mpeg4.y4m").to_str().unwrap(),
        "--json",
    ]));
    for key in [
        "frames",
        "psnr_y",
        "psnr_u",
        "psnr_v",
        "psnr_yuv",
        "ssim",
        "psnr_y_mse",
        "per_frame",
    ] {
        assert!(v.get(key).is_some(), "missing {key}: {v}");
    }
    assert_eq!(v["frames"], 6);
    assert_eq!(v["per_frame"].as_array().unwrap().len(), 6);
    // ffmpeg's psnr filter: mean of per-frame psnr_y 30.4917, summary y:30.465296.
    assert!((v["psnr_y"].as_f64().unwrap() - 30.4917).abs() < 0.01, "{v}");
    assert!(
        (v["psnr_y_mse"].as_f64().unwrap() - 30.465296).abs() < 1e-5,
        "{v}"
    );
}

#[test]
fn psnr_writes_a_csv_and_reads_stdin() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("per_frame.csv");
    let test = std::fs::read(sample("tree_qcif_mpeg4.y4m")).unwrap();
    mocomp()
        .args([
            "psnr",
            sample("tree_qcif.y4m").to_str().unwrap(),
            "-",
            "--csv",
            csv.to_str().unwrap(),
        ])
        .write_stdin(test)
        .assert()
        .success()
        .stdout(predicate::str::contains("mean"));
    let text = std::fs::read_to_string(&csv).unwrap();
    let lines: Vec<_> = text.lines().collect();
    assert_eq!(
        lines[0],
        "frame,psnr_y,psnr_u,psnr_v,psnr_yuv,ssim,mse_y,mse_u,mse_v"
    );
    assert_eq!(lines.len(), 7);
    assert!(lines[1].starts_with("0,31.59"), "{}", lines[1]);
}

#[test]
fn samples_writes_video_and_flow() {
    let dir = tempfile::tempdir().unwrap();
    mocomp()
        .args([
            "samples",
            "--out",
            dir.path().to_str().unwrap(),
            "--only",
            "synth_qcif",
            "--backward",
        ])
        .assert()
        .success()
        .stdout(predicate::str::contains("18 .flo files"));
    assert_eq!(
        std::fs::read(dir.path().join("synth_qcif.y4m")).unwrap(),
        std::fs::read(sample("synth_qcif.y4m")).unwrap(),
        "the command regenerates the committed sample byte for byte"
    );
    assert!(dir.path().join("synth_qcif/backward_0009.flo").exists());
    let err = fails_cleanly(&["samples", "--out", dir.path().to_str().unwrap(), "--only", "nope"]);
    assert!(err.contains("synth_qcif"), "{err}");
}

/// Reads a CSV into (header, rows of fields).
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines.map(|l| l.split(',').map(String::from).collect()).collect();
    (header, rows)
}

/// The number of line series in an SVG: polylines of three points or more
/// (legend swatches and cross markers have two).
fn polylines(svg: &str) -> usize {
    svg.split("<polyline")
        .skip(1)
        .filter(|e| {
            let points = e
                .split("points=\"")
                .nth(1)
                .and_then(|p| p.split('"').next())
                .unwrap_or("");
            points.split_whitespace().count() >= 3
        })
        .count()
}

#[test]
fn compare_runs_every_predictor_on_the_bundled_sample_from_anywhere() {
    let dir = tempfile::tempdir().unwrap();
    let out = mocomp()
        .current_dir(dir.path())
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    let text = String::from_utf8(out).unwrap();
    assert!(
        text.contains("| obmc |") && text.contains("mocomp-out/rd.csv"),
        "{text}"
    );
    let (header, rows) = read_csv(&dir.path().join("mocomp-out/rd.csv"));
    assert_eq!(header, mocomp::rd::CSV_COLUMNS);
    assert_eq!(rows.len(), 8 * 4, "8 predictors at 4 QPs");
    // For every predictor, bits fall as QP rises.
    for chunk in rows.chunks(4) {
        let bytes: Vec<u64> = chunk.iter().map(|r| r[2].parse().unwrap()).collect();
        assert!(
            bytes.windows(2).all(|w| w[0] > w[1]),
            "{}: {bytes:?}",
            chunk[0][0]
        );
    }
    // Plots: one line series per predictor, and the PNGs decode.
    let svg = std::fs::read_to_string(dir.path().join("mocomp-out/rd.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("PSNR-Y (dB)") && svg.contains("kbit/s"));
    assert_eq!(polylines(&svg), 8, "one series per predictor");
    for png in ["rd.png", "rd_bits.png"] {
        let img = image::open(dir.path().join("mocomp-out").join(png)).unwrap();
        assert!(img.width() >= 900 && img.height() >= 600, "{png}");
    }
    let bits = std::fs::read_to_string(dir.path().join("mocomp-out/rd_bits.svg")).unwrap();
    for part in ["header", "motion", "residual", "block:esa", "dense-hs"] {
        assert!(bits.contains(part), "{part} missing from the bit plot");
    }
    // Each plot's title names what it shows.
    assert!(svg.contains("synth_qcif: PSNR-Y against rate"));
    assert!(bits.contains("synth_qcif: bits per category") && !bits.contains("PSNR-Y against rate"));
}

#[test]
fn rd_sweeps_with_a_peer_csv_as_anchor_and_bdrate_reads_both() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_owned();
    let input = sample("tree_qcif.y4m");
    mocomp()
        .args([
            "rd",
            input.to_str().unwrap(),
            "--qp",
            "24,30,36,42",
            "--predictors",
            "zero,block:tss,obmc",
        ])
        .args([
            "--frames",
            "3",
            "-o",
            &p("rd.csv"),
            "--json",
            &p("rd.json"),
            "--plot",
            &p("p.svg"),
            "--threads",
            "2",
        ])
        .args(["--anchor", "block:tss"])
        .assert()
        .success()
        .stdout(predicate::str::contains("| zero |").and(predicate::str::contains("anchor: block:tss")));
    let (_, rows) = read_csv(Path::new(&p("rd.csv")));
    assert_eq!(rows.len(), 12);
    assert!(rows.iter().all(|r| r[6] == "tree_qcif" && r[3] == "3"));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(p("rd.json")).unwrap()).unwrap();
    assert_eq!(json["points"].as_array().unwrap().len(), 12);
    let tss = &json["comparison"].as_array().unwrap()[1];
    assert_eq!(tss["codec"], "block:tss");
    assert!(
        tss["bd_rate_cubic"].as_f64().unwrap().abs() < 1e-9,
        "the anchor against itself"
    );
    assert_eq!(polylines(&std::fs::read_to_string(p("p.svg")).unwrap()), 3);
    assert!(Path::new(&p("p.png")).exists() && Path::new(&p("p_bits.png")).exists());

    // The PSNR of the mean MSE is a column of its own, at most the mean
    // of frames' (Jensen), and BD figures can use it.
    let mse_col = mocomp::rd::CSV_COLUMNS
        .iter()
        .position(|c| *c == "psnr_y_mse")
        .unwrap();
    for r in &rows {
        let (mean, mse): (f64, f64) = (r[5].parse().unwrap(), r[mse_col].parse().unwrap());
        assert!(mse <= mean + 1e-3 && mse > mean - 3.0, "{mean} {mse}");
    }
    let tss = format!("{}:block:tss", p("rd.csv"));
    let zero = format!("{}:zero", p("rd.csv"));
    let by_mse = json_stdout(mocomp().args(["bdrate", &zero, &tss, "--psnr", "mse", "--json"]));
    let by_mean = json_stdout(mocomp().args(["bdrate", &zero, &tss, "--json"]));
    let (a, b) = (
        by_mse["bd_rate_cubic"].as_f64().unwrap(),
        by_mean["bd_rate_cubic"].as_f64().unwrap(),
    );
    assert!(a.is_finite() && a != b, "{a} {b}");

    // A peer-format CSV as the anchor: our block:tss rates times 1.25, so
    // block:tss needs exactly 20 % fewer bits.
    let mut peer = String::from("codec,q,bytes,frames,kbps,psnr_y\n");
    for r in rows.iter().filter(|r| r[0] == "block:tss") {
        let kbps: f64 = r[4].parse().unwrap();
        peer += &format!("mpeg4,{},{},{},{},{}\n", r[1], r[2], r[3], kbps * 1.25, r[5]);
    }
    std::fs::write(p("peer.csv"), peer).unwrap();
    let out = mocomp()
        .args([
            "bdrate",
            &format!("{}:mpeg4", p("peer.csv")),
            &format!("{}:block:tss", p("rd.csv")),
            "--json",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // Peer CSVs have no psnr_y_mse: asking for it is a clear error.
    let err = fails_cleanly(&[
        "bdrate",
        &format!("{}:mpeg4", p("peer.csv")),
        &tss,
        "--psnr",
        "mse",
    ]);
    assert!(err.contains("no psnr_y_mse"), "{err}");
    for key in ["bd_rate_cubic", "bd_rate_pchip"] {
        assert!((v[key].as_f64().unwrap() + 20.0).abs() < 1e-3, "{v}");
    }
    mocomp()
        .args([
            "rd",
            input.to_str().unwrap(),
            "--qp",
            "24,30,36,42",
            "--predictors",
            "block:tss",
        ])
        .args([
            "--frames",
            "2",
            "-o",
            &p("rd2.csv"),
            "--anchor-csv",
            &p("peer.csv"),
        ])
        .assert()
        .success()
        .stdout(predicate::str::contains("anchor: mpeg4"));

    // Errors: fewer than four points, no overlap, unknown codec, anchor
    // not swept.
    std::fs::write(
        p("three.csv"),
        "codec,q,bytes,frames,kbps,psnr_y\na,1,1,1,100,30\na,2,1,1,200,33\na,3,1,1,400,36\n",
    )
    .unwrap();
    assert!(fails_cleanly(&["bdrate", &p("three.csv"), &p("three.csv")]).contains("at least 4"));
    std::fs::write(
        p("far.csv"),
        "codec,q,bytes,frames,kbps,psnr_y\nb,1,1,1,100,50\nb,2,1,1,200,53\nb,3,1,1,400,56\nb,4,1,1,800,59\n",
    )
    .unwrap();
    assert!(
        fails_cleanly(&["bdrate", &format!("{}:mpeg4", p("peer.csv")), &p("far.csv")])
            .contains("do not overlap")
    );
    assert!(
        fails_cleanly(&["bdrate", &format!("{}:x265", p("rd.csv")), &p("far.csv")])
            .contains("no codec 'x265'")
    );
    // An anchor given must be among the predictors; with none given it is
    // block:esa when there, else the first, and stderr says which.
    let err = fails_cleanly(&[
        "rd",
        input.to_str().unwrap(),
        "--predictors",
        "zero",
        "--anchor",
        "block:esa",
        "-o",
        &p("x.csv"),
    ]);
    assert!(err.contains("anchor block:esa is not among"), "{err}");
    let out = mocomp()
        .args([
            "rd",
            input.to_str().unwrap(),
            "--predictors",
            "zero,block:tss",
            "--frames",
            "2",
        ])
        .args(["-o", &p("x.csv")])
        .output()
        .unwrap();
    assert!(out.status.success());
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(stdout.contains("(anchor: zero)"), "{stdout}");
    assert!(stderr.contains("anchor zero (block:esa is not among"), "{stderr}");
}

#[test]
fn quiet_leaves_only_errors_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_owned();
    let input = sample("tree_qcif.y4m");
    let input = input.to_str().unwrap();
    let silent = |args: &[&str]| {
        let out = mocomp().args(args).output().unwrap();
        assert!(out.status.success(), "{args:?}");
        assert_eq!((out.stdout.len(), out.stderr.len()), (0, 0), "{args:?}");
    };
    silent(&["encode", input, "-o", &p("a.mcv"), "--frames", "2", "--quiet"]);
    silent(&[
        "rd",
        input,
        "--predictors",
        "zero",
        "--frames",
        "2",
        "-o",
        &p("rd.csv"),
        "--quiet",
    ]);
    let (_, rows) = read_csv(Path::new(&p("rd.csv")));
    assert_eq!(rows.len(), 4, "the CSV is still written");
    // --json still prints its object.
    let v = json_stdout(mocomp().args([
        "encode",
        input,
        "-o",
        &p("b.mcv"),
        "--frames",
        "2",
        "--quiet",
        "--json",
    ]));
    assert_eq!(v["frames"], 2);
    // Errors still show.
    let out = mocomp()
        .args(["encode", "missing.y4m", "-o", &p("c.mcv"), "--quiet"])
        .output()
        .unwrap();
    assert!(!out.status.success() && out.stderr.starts_with(b"mocomp: error: "));
}

#[test]
fn errors_are_one_clear_line() {
    let missing = fails_cleanly(&["info", "/no/such/file.y4m"]);
    assert!(missing.contains("/no/such/file.y4m"), "{missing}");

    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, bytes: &[u8]| {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p.to_str().unwrap().to_owned()
    };
    let c422 = write("c422.y4m", b"YUV4MPEG2 W4 H4 F30:1 C422\nFRAME\n");
    let err = fails_cleanly(&["psnr", &c422, &c422]);
    assert!(
        err.contains("4:2:2") && err.contains("ffmpeg -i in -pix_fmt yuv420p"),
        "{err}"
    );

    let mut bytes = std::fs::read(sample("tree_qcif.y4m")).unwrap();
    bytes.truncate(bytes.len() - 100);
    let cut = write("cut.y4m", &bytes);
    let err = fails_cleanly(&["info", &cut]);
    assert!(err.contains("frame 5 is truncated"), "{err}");

    let empty = write("empty.y4m", b"");
    assert!(fails_cleanly(&["info", &empty]).contains("not a Y4M, .flo or image"));
    let empty_stdin = mocomp().args(["info", "-"]).output().unwrap();
    assert!(String::from_utf8_lossy(&empty_stdin.stderr).contains("empty input"));

    let flo = write("bad.flo", b"PIEH\x05\x00\x00\x00\x05\x00\x00\x00\x00");
    assert!(fails_cleanly(&["info", &flo]).contains("needs 212 bytes"));

    let small = write(
        "small.y4m",
        b"YUV4MPEG2 W2 H2 F30:1\nFRAME\n\x00\x00\x00\x00\x00\x00",
    );
    let err = fails_cleanly(&["psnr", sample("tree_qcif.y4m").to_str().unwrap(), &small]);
    assert!(err.contains("sizes differ"), "{err}");

    // Each cause said once (a wrapped error's message is not repeated by
    // its source in the chain).
    let huge = write("huge.y4m", b"YUV4MPEG2 W99999 H10 F25:1 C420jpeg\n");
    let err = fails_cleanly(&["info", &huge]);
    assert_eq!(err.matches("exceeds the maximum").count(), 1, "{err}");
    let err = fails_cleanly(&["info", "/no/such/file.flo"]);
    assert_eq!(err.matches("No such file").count(), 1, "{err}");
    let err = fails_cleanly(&["flow", &flo, &flo]);
    assert!(err.contains("takes two pictures or a Y4M"), "{err}");
}

#[test]
fn usage_errors_exit_with_two() {
    mocomp().args(["psnr"]).assert().code(2);
    mocomp().args(["no-such-command"]).assert().code(2);
}

#[test]
fn me_reports_speed_cost_and_error_against_ground_truth() {
    let v = json_stdout(
        mocomp()
            .args([
                "me",
                sample("synth_qcif.y4m").to_str().unwrap(),
                "--method",
                "esa",
                "--range",
                "8",
                "--json",
            ])
            .args(["--gt", sample("synth_qcif").to_str().unwrap(), "--threads", "2"]),
    );
    assert_eq!(v["frames"], 9);
    assert!(v["ms_per_frame"].as_f64().unwrap() > 0.0);
    let (cost, epe) = (v["mean_cost"].as_f64().unwrap(), v["epe"].as_f64().unwrap());
    // The sample moves 1-4 px a frame with noise sigma 1: SAD per pixel near
    // the noise level, block vectors within a pixel of the true flow
    // (measured 2.03 and 0.54 at range 16).
    assert!(cost > 0.5 && cost < 4.0, "{v}");
    assert!(epe < 1.0, "{v}");
}

#[test]
fn me_writes_vectors_and_overlays() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("mvs.csv");
    let overlay = dir.path().join("overlay");
    mocomp()
        .args([
            "me",
            sample("synth_qcif.y4m").to_str().unwrap(),
            "--method",
            "hexbs",
            "--block",
            "8",
        ])
        .args(["--frames", "3:5", "--subpel", "quarter", "--metric", "satd"])
        .args([
            "--mvs",
            csv.to_str().unwrap(),
            "--overlay",
            overlay.to_str().unwrap(),
        ])
        .assert()
        .success()
        .stdout(predicate::str::contains("frames searched      2"));
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("frame,x,y,w,h,dx,dy,cost"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 2 * 22 * 18);
    assert!(rows
        .iter()
        .all(|r| (r[0] == 4.0 || r[0] == 5.0) && r[3] == 8.0 && (r[5] * 4.0).fract() == 0.0));
    assert!(overlay.join("me_0004.png").exists() && overlay.join("me_0005.png").exists());
    fails_cleanly(&["me", sample("synth_qcif.y4m").to_str().unwrap(), "--block", "12"]);
    mocomp()
        .args(["me", "x.y4m", "--method", "nope"])
        .assert()
        .code(2);
}

#[test]
fn output_into_a_closed_pipe_is_not_a_crash() {
    // As `mocomp flow ... | head -0`: the reader is gone before the output
    // is written (each command works for milliseconds at least; the pipe
    // closes at once). Every command that prints a report.
    let y4m = sample("synth_qcif.y4m");
    let y4m = y4m.to_str().unwrap();
    let commands: [&[&str]; 5] = [
        &["flow", y4m, "--method", "dis"],
        &["info", y4m],
        &["psnr", y4m, y4m],
        &["me", y4m, "--frames", "0:2"],
        &["track", y4m],
    ];
    for args in commands {
        let mut child = std::process::Command::new(assert_cmd::cargo::cargo_bin!("mocomp"))
            .args(args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            out.status.success() && !stderr.contains("panicked") && !stderr.contains("internal error"),
            "{args:?}: {stderr}"
        );
    }
}

#[test]
fn flow_by_dense_inverse_search_and_the_benchmark_generator() {
    // Three small "photographs" (rendered texture), the benchmark's pairs
    // from them, and DIS on one of them against its exact ground truth.
    let dir = tempfile::tempdir().unwrap();
    let mut photos = Vec::new();
    for k in 0..3u64 {
        let s = mocomp::synth::Synth::new(mocomp::synth::SceneSpec::new("src", 200, 150, 1).seed(30 + k))
            .unwrap();
        let path = dir.path().join(format!("photo{k}.png"));
        mocomp::io::image::write_plane(&path, s.frame(0).y()).unwrap();
        photos.push(path);
    }
    let pairs = dir.path().join("pairs");
    mocomp()
        .args([
            "flowbench",
            "--out",
            pairs.to_str().unwrap(),
            "--width",
            "96",
            "--height",
            "64",
        ])
        .args(photos.iter().map(|p| p.to_str().unwrap()))
        .assert()
        .success();
    let csv = std::fs::read_to_string(pairs.join("cases.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 3 * 7, "{csv}");
    let case = pairs.join("p0_small");
    for f in ["frame1.png", "frame2.png", "gt.flo", "occ.png"] {
        assert!(case.join(f).exists(), "{f}");
    }
    let v = json_stdout(
        mocomp()
            .args([
                "flow",
                case.join("frame1.png").to_str().unwrap(),
                case.join("frame2.png").to_str().unwrap(),
            ])
            .args([
                "--preset",
                "medium",
                "--json",
                "--gt",
                case.join("gt.flo").to_str().unwrap(),
            ]),
    );
    // Dense inverse search is the default method.
    assert_eq!(v["method"], "dis");
    // A pan of (2.3, -1.4) px with zoom and rotation: measured EPE 0.13 px.
    assert!(v["epe"].as_f64().unwrap() < 0.3, "{v}");
    // --fine-on-small computes this 96x64 pair at full size, as --finest 0
    // does, instead of the fast preset's quarter size, and is more accurate
    // (not the same bytes as --finest 0: the finer mode keeps the full
    // damping at every level, DisParams::damping_falls).
    let fast = |extra: &[&str], out: &str| {
        json_stdout(
            mocomp()
                .args([
                    "flow",
                    case.join("frame1.png").to_str().unwrap(),
                    case.join("frame2.png").to_str().unwrap(),
                    "--preset",
                    "fast",
                    "--json",
                    "--gt",
                    case.join("gt.flo").to_str().unwrap(),
                    "-o",
                    dir.path().join(out).to_str().unwrap(),
                ])
                .args(extra),
        )["epe"]
            .as_f64()
            .unwrap()
    };
    let (plain, fine, full) = (
        fast(&[], "plain.flo"),
        fast(&["--fine-on-small"], "fine.flo"),
        fast(&["--finest", "0"], "full.flo"),
    );
    let read = |f: &str| std::fs::read(dir.path().join(f)).unwrap();
    assert_ne!(read("fine.flo"), read("plain.flo"));
    // Untimed calls first, then two timed ones: the estimator's kept
    // buffers leave the last call's flow as a lone call's.
    let warm = fast(&["--warmup", "2", "--runs", "2"], "warm.flo");
    assert!(warm == plain && read("warm.flo") == read("plain.flo"));
    assert!(
        fine < plain && full < plain && (fine - full).abs() < 0.25 * full,
        "fine {fine}, plain {plain}, full {full}"
    );
    mocomp()
        .args(["flowbench", "--out", pairs.to_str().unwrap(), "--width", "8"])
        .args(photos.iter().map(|p| p.to_str().unwrap()))
        .assert()
        .failure()
        .stderr(predicates::str::contains("outside 16..=4096"));
}

#[test]
fn flow_reports_errors_against_ground_truth_and_writes_its_pictures() {
    let dir = tempfile::tempdir().unwrap();
    let (flo, viz, warp) = (
        dir.path().join("f.flo"),
        dir.path().join("viz.png"),
        dir.path().join("warp.png"),
    );
    let v = json_stdout(
        mocomp()
            .args([
                "flow",
                sample("synth_qcif.y4m").to_str().unwrap(),
                "--frames",
                "0:1",
                "--json",
            ])
            .args(["--gt", sample("synth_qcif/forward_0000.flo").to_str().unwrap()])
            .args([
                "-o",
                flo.to_str().unwrap(),
                "--viz",
                viz.to_str().unwrap(),
                "--warp",
                warp.to_str().unwrap(),
            ])
            .args(["--arrows", dir.path().join("arrows.png").to_str().unwrap()]),
    );
    for key in ["ms", "mc_psnr", "epe", "ae", "r1", "r3"] {
        assert!(v[key].is_number(), "{key} missing: {v}");
    }
    // Measured 0.28 px EPE and 40.9 dB warped PSNR on this pair (noise sigma 1).
    assert!(
        v["epe"].as_f64().unwrap() < 0.35 && v["mc_psnr"].as_f64().unwrap() > 38.0,
        "{v}"
    );
    let back = mocomp::io::flo::read_flo(&flo).unwrap();
    assert_eq!((back.width(), back.height()), (176, 144));
    let img = image::open(&viz).unwrap();
    assert_eq!((img.width(), img.height()), (176, 144));
    assert!(warp.exists() && dir.path().join("arrows.png").exists());
    // Two images work too, and mismatched inputs are one-line errors.
    let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
    mocomp::io::image::write_plane(
        &a,
        &mocomp::codec::Plane::from_fn(40, 30, |x, y| (x * 9 + y * 5) as u8).unwrap(),
    )
    .unwrap();
    mocomp::io::image::write_plane(
        &b,
        &mocomp::codec::Plane::from_fn(40, 30, |x, y| (x * 9 + y * 5 + 9) as u8).unwrap(),
    )
    .unwrap();
    mocomp()
        .args([
            "flow",
            a.to_str().unwrap(),
            b.to_str().unwrap(),
            "--preset",
            "fast",
        ])
        .assert()
        .success();
    fails_cleanly(&["flow", a.to_str().unwrap()]);
    fails_cleanly(&[
        "flow",
        sample("synth_qcif.y4m").to_str().unwrap(),
        "--frames",
        "3:99",
    ]);
}

#[test]
fn track_follows_corners_through_a_sequence() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, overlay) = (dir.path().join("tracks.csv"), dir.path().join("ov"));
    let v = json_stdout(
        mocomp()
            .args(["track", sample("synth_qcif.y4m").to_str().unwrap(), "--json"])
            .args([
                "--out",
                csv.to_str().unwrap(),
                "--overlay",
                overlay.to_str().unwrap(),
            ]),
    );
    assert_eq!(v["frames"], 10);
    // Measured: about 157 of up to 300 points followed per frame, tracks of 5.6 frames.
    assert!(v["followed_per_frame"].as_f64().unwrap() > 80.0, "{v}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("frame,id,x,y,error"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert!(rows
        .iter()
        .all(|r| r.len() == 5 && r[2] >= 0.0 && r[2] < 176.0 && r[3] >= 0.0 && r[3] < 144.0));
    // The same id moves a few pixels a frame, as the scene does (1-4 px).
    let id0: Vec<&Vec<f64>> = rows.iter().filter(|r| r[1] == 0.0).collect();
    for pair in id0.windows(2) {
        assert_eq!(pair[1][0], pair[0][0] + 1.0);
        assert!((pair[1][2] - pair[0][2]).hypot(pair[1][3] - pair[0][3]) < 6.0);
    }
    assert!(overlay.join("track_0009.png").exists());
}

#[test]
fn encode_then_decode_gives_the_reconstruction_and_the_documented_summary() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_owned();
    let input = sample("tree_qcif.y4m");
    let v = json_stdout(
        mocomp()
            .args(["encode", input.to_str().unwrap(), "-o", &p("a.mcv"), "--qp", "30"])
            .args([
                "--predictor",
                "block",
                "--me",
                "tss",
                "--range",
                "8",
                "--subpel",
                "half",
                "--gop",
                "4",
            ])
            .args([
                "--frames",
                "6",
                "--recon",
                &p("rec.y4m"),
                "--stats",
                &p("s.csv"),
                "--json",
            ]),
    );
    for key in [
        "frames",
        "bytes",
        "kbps",
        "psnr_y",
        "psnr_u",
        "psnr_v",
        "ssim",
        "bits_header",
        "bits_motion",
        "bits_residual",
        "encode_ms",
    ] {
        assert!(v.get(key).is_some(), "{key} missing: {v}");
    }
    assert_eq!(v["frames"], 6);
    let bytes = std::fs::metadata(p("a.mcv")).unwrap().len();
    assert_eq!(v["bytes"], bytes);
    let bits = ["bits_header", "bits_motion", "bits_residual"].map(|k| v[k].as_u64().unwrap());
    assert_eq!(
        bits.iter().sum::<u64>(),
        8 * bytes,
        "the bit categories add up to the stream"
    );
    assert!(v["psnr_y"].as_f64().unwrap() > 30.0, "{v}");
    // Per-frame CSV: a header and six rows, I frames at 0 and 4.
    let csv = std::fs::read_to_string(p("s.csv")).unwrap();
    let types: Vec<&str> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap())
        .collect();
    assert_eq!(types, ["I", "P", "P", "P", "I", "P"]);

    // Decoding to a file and to standard output both give the
    // reconstruction the encoder wrote.
    mocomp()
        .args(["decode", &p("a.mcv"), "-o", &p("dec.y4m")])
        .assert()
        .success();
    let stdout = mocomp()
        .args(["decode", &p("a.mcv"), "-o", "-"])
        .output()
        .unwrap()
        .stdout;
    let frames = |bytes: &[u8]| {
        mocomp::io::y4m::Y4mReader::new(bytes)
            .unwrap()
            .read_all()
            .unwrap()
    };
    let rec = frames(&std::fs::read(p("rec.y4m")).unwrap());
    assert_eq!(rec.len(), 6);
    assert_eq!(frames(&std::fs::read(p("dec.y4m")).unwrap()), rec);
    assert_eq!(frames(&stdout), rec);

    // The text summary says where the bits went.
    let text = mocomp()
        .args([
            "encode",
            input.to_str().unwrap(),
            "-o",
            &p("b.mcv"),
            "--frames",
            "2",
            "--predictor",
            "dense-lk",
        ])
        .output()
        .unwrap();
    let text = String::from_utf8(text.stdout).unwrap();
    assert!(
        text.contains("kbit/s") && text.contains("motion") && text.contains("residual"),
        "{text}"
    );
}

#[test]
fn encode_and_decode_errors_are_one_line_and_leave_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_owned();
    std::fs::write(p("empty.y4m"), b"").unwrap();
    std::fs::write(p("noframes.y4m"), b"YUV4MPEG2 W16 H16 F25:1\n").unwrap();
    std::fs::write(p("c444.y4m"), b"YUV4MPEG2 W4 H4 F30:1 C444\nFRAME\n").unwrap();
    std::fs::write(p("junk.mcv"), b"MOCO\x01 this is not a stream").unwrap();
    for bad in ["empty.y4m", "noframes.y4m", "c444.y4m"] {
        let err = fails_cleanly(&["encode", &p(bad), "-o", &p("out.mcv")]);
        assert!(err.contains(bad), "{err}");
        assert!(!Path::new(&p("out.mcv")).exists(), "{bad} left an output file");
    }
    let mut cut = std::fs::read(sample("tree_qcif.y4m")).unwrap();
    cut.truncate(cut.len() - 100);
    std::fs::write(p("cut.y4m"), cut).unwrap();
    let err = fails_cleanly(&["encode", &p("cut.y4m"), "-o", &p("out.mcv")]);
    assert!(err.contains("truncated"), "{err}");
    assert!(!Path::new(&p("out.mcv")).exists());

    let err = fails_cleanly(&["decode", &p("junk.mcv"), "-o", &p("out.y4m")]);
    assert!(err.contains("junk.mcv"), "{err}");
    assert!(!Path::new(&p("out.y4m")).exists());
    let tree = sample("tree_qcif.y4m");
    let err = fails_cleanly(&["decode", tree.to_str().unwrap(), "-o", &p("out.y4m")]);
    assert!(err.contains("not a mocomp stream"), "{err}");

    let tree = tree.to_str().unwrap();
    assert!(
        fails_cleanly(&["encode", tree, "-o", &p("o.mcv"), "--predictor", "nope"])
            .contains("unknown predictor")
    );
    assert!(fails_cleanly(&["encode", tree, "-o", &p("o.mcv"), "--qp", "52"]).contains("QP 52"));
    assert!(fails_cleanly(&[
        "encode",
        tree,
        "-o",
        &p("o.mcv"),
        "--predictor",
        "zero",
        "--me",
        "esa"
    ])
    .contains("does not apply"));
}

/// Frames 0 and 1 of a synthetic scene panned by (dx, dy), and its exact
/// flow, written into `dir` as a.png, b.png and gt.flo; returns their paths.
fn panned_pair(dir: &Path, (w, h): (usize, usize), seed: u64, (dx, dy): (f64, f64)) -> [String; 3] {
    use mocomp::synth::{Motion, SceneSpec, Synth};
    let s = Synth::new(
        SceneSpec::new("pan", w, h, 2)
            .seed(seed)
            .camera(Motion::translation(dx, dy)),
    )
    .unwrap();
    let path = |n: &str| dir.join(n);
    mocomp::io::image::write_plane(&path("a.png"), s.frame(0).y()).unwrap();
    mocomp::io::image::write_plane(&path("b.png"), s.frame(1).y()).unwrap();
    mocomp::io::flo::write_flo(&path("gt.flo"), &s.forward_flow(0)).unwrap();
    ["a.png", "b.png", "gt.flo"].map(|n| path(n).to_str().unwrap().to_owned())
}

#[test]
fn match_writes_csv_overlay_and_accuracy() {
    let dir = tempfile::tempdir().unwrap();
    let [a, b, gt] = panned_pair(dir.path(), (240, 180), 11, (41.0, -17.0));
    let path = |n: &str| dir.path().join(n);
    let p = |n: &str| path(n).to_str().unwrap().to_owned();
    let v = json_stdout(mocomp().args([
        "match",
        &a,
        &b,
        "--out",
        &p("m.csv"),
        "--overlay",
        &p("o.png"),
        "--gt",
        &gt,
        "--json",
    ]));
    let n = v["matches"].as_u64().unwrap() as usize;
    assert!(n >= 20, "{v}");
    assert!(v["within_3px"].as_f64().unwrap() >= 90.0, "{v}");
    let csv = std::fs::read_to_string(path("m.csv")).unwrap();
    assert_eq!(csv.lines().next(), Some("x1,y1,x2,y2,distance"));
    assert_eq!(csv.lines().count(), n + 1);
    // Each row moves by about the translation.
    let row: Vec<f32> = csv
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    assert!(
        (row[2] - row[0] - 41.0).abs() < 3.0 && (row[3] - row[1] + 17.0).abs() < 3.0,
        "{row:?}"
    );
    let overlay = mocomp::io::image::read_luma(&path("o.png")).unwrap();
    assert_eq!((overlay.width(), overlay.height()), (480, 180));
    let err = fails_cleanly(&["match", &a, &gt]);
    assert!(err.contains("not a picture"), "{err}");
}

#[test]
fn flow_writes_the_occlusion_mask_of_the_forward_backward_check() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (200usize, 150usize);
    // Each method with a pan it follows (LK's pyramid is shallower).
    for (method, dx) in [("dis", 24usize), ("tvl1", 24), ("lk", 8), ("hs", 8)] {
        let [a, b, _] = panned_pair(dir.path(), (w, h), 12, (dx as f64, 0.0));
        let path = |n: &str| dir.path().join(n);
        let p = |n: &str| path(n).to_str().unwrap().to_owned();
        let v = json_stdout(mocomp().args([
            "flow",
            &a,
            &b,
            "--method",
            method,
            "--occlusion",
            &p("mask.png"),
            "--json",
        ]));
        let mask = mocomp::io::image::read_luma(&path("mask.png")).unwrap();
        assert_eq!((mask.width(), mask.height()), (w, h));
        // The pixels that leave the picture (the last dx columns) are
        // flagged; the rest, which both frames see, is not.
        let share = |xs: std::ops::Range<usize>| {
            let n = xs.len() * h;
            let flagged: usize = mask
                .rows()
                .map(|r| r[xs.clone()].iter().filter(|&&m| m == 255).count())
                .sum();
            flagged as f64 / n as f64
        };
        assert!(
            share(w - dx + 2..w) > 0.9,
            "{method}: leaving {}",
            share(w - dx + 2..w)
        );
        assert!(
            share(4..w - dx - 4) < 0.05,
            "{method}: inside {}",
            share(4..w - dx - 4)
        );
        let reported = v["inconsistent_percent"].as_f64().unwrap();
        let expected = 100.0 * dx as f64 / w as f64;
        assert!((reported - expected).abs() < 5.0, "{method}: {v}");
    }
}

#[test]
fn flow_with_matches_reaches_a_pan_beyond_the_pyramid() {
    let dir = tempfile::tempdir().unwrap();
    let [a, b, gt] = panned_pair(dir.path(), (384, 288), 6, (120.0, -9.5));
    let run = |extra: &[&str]| {
        let v = json_stdout(
            mocomp()
                .args(["flow", &a, &b, "--method", "dis", "--preset", "fast"])
                .args(["--gt", &gt, "--json"])
                .args(extra),
        );
        v["epe"].as_f64().unwrap()
    };
    let (plain, seeded) = (run(&[]), run(&["--matches"]));
    assert!(
        plain > 10.0 && seeded < 0.5,
        "plain {plain}, with matches {seeded}"
    );
}

/// tree_qcif's first two frames, then synth_qcif's first two: a cut.
fn qcif_cut() -> Vec<u8> {
    const FRAME: usize = 6 + 176 * 144 * 3 / 2;
    let frames = |name: &str| {
        let bytes = std::fs::read(sample(name)).unwrap();
        let header = bytes.iter().position(|&b| b == b'\n').unwrap() + 1;
        let frames = bytes[header..header + 2 * FRAME].to_vec();
        assert!(frames.starts_with(b"FRAME\n") && frames[FRAME..].starts_with(b"FRAME\n"));
        (bytes[..header].to_vec(), frames)
    };
    let (header, mut out) = frames("tree_qcif.y4m");
    out.extend(frames("synth_qcif.y4m").1);
    [header, out].concat()
}

#[test]
fn presets_differ_options_override_them_and_every_stream_decodes() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_owned();
    let input = sample("tree_qcif.y4m");
    let encode = |name: &str, extra: &[&str]| -> Vec<u8> {
        mocomp()
            .args([
                "encode",
                input.to_str().unwrap(),
                "-o",
                &p(name),
                "--frames",
                "4",
                "--quiet",
            ])
            .args(extra)
            .assert()
            .success();
        mocomp()
            .args(["decode", &p(name), "-o", &p("out.y4m")])
            .assert()
            .success();
        std::fs::read(p(name)).unwrap()
    };
    let streams: Vec<Vec<u8>> = ["ultrafast", "fast", "medium", "slow"]
        .iter()
        .map(|preset| encode(&format!("{preset}.mcv"), &["--preset", preset]))
        .collect();
    // The default is medium; ultrafast, fast and medium code differently.
    assert_eq!(encode("default.mcv", &[]), streams[2]);
    assert_ne!(streams[0], streams[1]);
    assert_ne!(streams[1], streams[2]);
    // Options given override the preset: superfast without the 8x8
    // transform and with I frames in 16x16 alone is ultrafast.
    let as_ultrafast = ["--no-8x8dct", "--i-partitions", "none"];
    assert_eq!(
        encode("o.mcv", &[&["--preset", "superfast"][..], &as_ultrafast].concat()),
        streams[0]
    );
    // x264's partition names: medium is all of them but 4x4 intra (P
    // frames' from slow); they are P frames' (over a cut, where P frames
    // code intra, fewer differ; I frames try every intra block alike); as
    // x264's i8x8, 8x8 intra needs the 8x8 transform.
    assert_eq!(encode("medium.mcv", &["--partitions", "p8x8,i8x8"]), streams[2]);
    let cut = dir.path().join("cut.y4m");
    std::fs::write(&cut, qcif_cut()).unwrap();
    let at_cut = |extra: &[&str]| {
        let out = p("cut.mcv");
        mocomp()
            .args(["encode", cut.to_str().unwrap(), "-o", &out, "--quiet"])
            .args(extra)
            .assert()
            .success();
        std::fs::read(out).unwrap()
    };
    let all = at_cut(&["--partitions", "all"]);
    for fewer in ["p8x8", "p8x8,i4x4", "p8x8,i8x8"] {
        assert_ne!(at_cut(&["--partitions", fewer]), all, "{fewer}");
    }
    let only_i_frames = ["--frames", "1"];
    assert_eq!(
        at_cut(&only_i_frames),
        at_cut(&[&only_i_frames[..], &["--partitions", "none"]].concat())
    );
    assert_eq!(
        encode("no8.mcv", &["--no-8x8dct"]),
        encode("no8i.mcv", &["--no-8x8dct", "--partitions", "p8x8"])
    );
    // I frames' intra blocks apart (x264's analyse.intra): with none of
    // them the I frame is 16x16 intra only and differs; naming every one
    // is the default; an inter partition is no intra block.
    let i_frame = |extra: &[&str]| at_cut(&[&only_i_frames[..], extra].concat());
    assert_eq!(i_frame(&["--i-partitions", "i8x8,i4x4"]), i_frame(&[]));
    assert_eq!(i_frame(&["--i-partitions", "all"]), i_frame(&[]));
    assert_ne!(i_frame(&["--i-partitions", "none"]), i_frame(&[]));
    assert_ne!(
        i_frame(&["--i-partitions", "i8x8"]),
        i_frame(&["--i-partitions", "i4x4"])
    );
    // A bad value is an error that names it.
    let rejects = |option: &str, value: &str, message: &str| {
        mocomp()
            .args([
                "encode",
                input.to_str().unwrap(),
                "-o",
                &p("bad.mcv"),
                option,
                value,
            ])
            .assert()
            .failure()
            .stderr(predicates::str::contains(message));
    };
    rejects("--partitions", "p4x4", "unknown partition 'p4x4'");
    rejects(
        "--i-partitions",
        "p8x8",
        "--i-partitions: p8x8 is an inter partition",
    );
    // Sub-pel RD is slow's: off there, or on in medium, the stream changes;
    // only on and off are values.
    assert_ne!(
        encode("so.mcv", &["--preset", "slow", "--subpel-rd", "off"]),
        streams[3]
    );
    assert_ne!(encode("mo.mcv", &["--subpel-rd", "on"]), streams[2]);
    rejects("--subpel-rd", "yes", "expected on or off");
    // The splits' margin is slower's: on in slow or medium, the stream
    // changes.
    assert_ne!(
        encode("sm.mcv", &["--preset", "slow", "--split-margin", "on"]),
        streams[3]
    );
    assert_ne!(encode("mm.mcv", &["--split-margin", "on"]), streams[2]);
    // The splits' search margin is slow's: off there, or on in medium,
    // the stream changes.
    assert_ne!(
        encode("ss.mcv", &["--preset", "slow", "--split-search-margin", "off"]),
        streams[3]
    );
    assert_ne!(encode("ms.mcv", &["--split-search-margin", "on"]), streams[2]);
    rejects("--split-search-margin", "maybe", "expected on or off");
    // Chroma motion estimation is no preset's (its effect on a sample
    // with colour: tests/encode.rs).
    assert_eq!(encode("co.mcv", &["--chroma-me", "off"]), streams[2]);
    rejects("--chroma-me", "1", "expected on or off");
    // Prices adapt from medium: off there, the stream changes; on in
    // fast too (ultrafast estimates its residuals' bits from their levels
    // instead of pricing them).
    assert_ne!(encode("ap.mcv", &["--adaptive-pricing", "off"]), streams[2]);
    assert_ne!(
        encode("apf.mcv", &["--preset", "fast", "--adaptive-pricing", "on"]),
        streams[1]
    );
    // Fast P-skip is every preset's: without it the stream changes
    // (ultrafast at QP 36, where some macroblock skips early on this
    // sample; medium's full decision skips early less).
    let ultrafast_qp36 = ["--preset", "ultrafast", "--qp", "36"];
    assert_ne!(
        encode("fq.mcv", &ultrafast_qp36),
        encode("nf.mcv", &[&ultrafast_qp36[..], &["--no-fast-pskip"]].concat())
    );
    // Partitions are medium's: turned off there they change the stream,
    // and fast with them is not fast.
    assert_ne!(encode("np.mcv", &["--partitions", "none"]), streams[2]);
    assert_ne!(
        encode("fp.mcv", &["--preset", "fast", "--partitions", "all"]),
        streams[1]
    );
    // `mocomp rd` codes as `mocomp encode` does with the same preset,
    // search settings included (ultrafast's half-pel).
    mocomp()
        .args([
            "rd",
            input.to_str().unwrap(),
            "--predictors",
            "block",
            "--qp",
            "28",
            "--frames",
            "4",
        ])
        .args([
            "--preset",
            "ultrafast",
            "--anchor",
            "block",
            "--quiet",
            "-o",
            &p("rd.csv"),
        ])
        .assert()
        .success();
    let (header, rows) = read_csv(Path::new(&p("rd.csv")));
    let bytes = header.iter().position(|c| c == "bytes").unwrap();
    let rd_bytes: usize = rows[0][bytes].parse().unwrap();
    assert_eq!(rd_bytes, streams[0].len());
    // An unknown preset is a usage error (exit 2) that names it.
    let out = mocomp()
        .args([
            "encode",
            input.to_str().unwrap(),
            "-o",
            &p("x.mcv"),
            "--preset",
            "placebo",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("placebo"));
}

/// A CSV's rows without what differs between runs of a job: the timing
/// columns (encode_ms, me_ms, decode_ms) and the shard that ran it.
fn rows_without_timing(path: &Path) -> Vec<Vec<String>> {
    let (header, rows) = read_csv(path);
    let timing: Vec<usize> = ["encode_ms", "me_ms", "decode_ms", "shard"]
        .iter()
        .map(|c| header.iter().position(|h| h == c).unwrap())
        .collect();
    rows.into_iter()
        .map(|r| {
            r.into_iter()
                .enumerate()
                .filter(|(i, _)| !timing.contains(i))
                .map(|(_, c)| c)
                .collect()
        })
        .collect()
}

#[test]
fn shards_merge_into_the_unsharded_rows_and_a_killed_shard_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_owned();
    let input = sample("tree_qcif.y4m");
    let sweep = |out: &str, extra: &[&str]| {
        let mut c = mocomp();
        c.args([
            "rd",
            input.to_str().unwrap(),
            "--predictors",
            "zero,block:tss",
            "--frames",
            "3",
        ])
        .args(["--threads", "1", "-o", &p(out)])
        .args(extra);
        c
    };
    sweep("whole.csv", &["--quiet"]).assert().success();
    for i in 1..=3 {
        sweep(&format!("part{i}.csv"), &["--shard", &format!("{i}/3")])
            .assert()
            .success()
            .stdout(predicate::str::contains(format!("shard {i}/3")));
    }
    // The shares differ and cover the study.
    let sizes: Vec<usize> = (1..=3)
        .map(|i| read_csv(Path::new(&p(&format!("part{i}.csv")))).1.len())
        .collect();
    assert_eq!(sizes, [3, 3, 2]);
    mocomp()
        .args([
            "rd",
            "merge",
            &p("part1.csv"),
            &p("part2.csv"),
            &p("part3.csv"),
            "-o",
            &p("merged.csv"),
        ])
        .args(["--plot", &p("m.svg")])
        .assert()
        .success()
        .stdout(predicate::str::contains("| block:tss |"));
    let whole = rows_without_timing(Path::new(&p("whole.csv")));
    assert_eq!(whole.len(), 8);
    assert_eq!(rows_without_timing(Path::new(&p("merged.csv"))), whole);
    assert!(Path::new(&p("m.svg")).exists());

    // A part missing: its jobs are named. Parts of another study: refused.
    let err = fails_cleanly(&["rd", "merge", &p("part1.csv"), &p("part3.csv"), "-o", &p("x.csv")]);
    assert!(
        err.contains("3 of the study's 8 jobs are in no part: 1, 4, 7"),
        "{err}"
    );
    sweep("other.csv", &["--qp", "20,25,30,35", "--shard", "2/3"])
        .assert()
        .success();
    let err = fails_cleanly(&["rd", "merge", &p("part1.csv"), &p("other.csv"), "-o", &p("x.csv")]);
    assert!(err.contains("parts of different studies"), "{err}");
    // ... and a CSV of another study is not resumed into.
    let out = sweep("part1.csv", &["--qp", "20,25,30,35", "--shard", "1/3"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("holds rows of study"));

    // A shard killed as it wrote its third row (the line cut short) runs
    // only that job again, with no duplicate row.
    let text = std::fs::read_to_string(p("part2.csv")).unwrap();
    let cut = text.len() - text.lines().last().unwrap().len() / 2 - 1;
    std::fs::write(p("killed.csv"), &text[..cut]).unwrap();
    sweep("killed.csv", &["--shard", "2/3"])
        .assert()
        .success()
        .stderr(predicate::str::contains(
            "2 of the 3 jobs of shard 2/3 are there already; running the other 1",
        ));
    assert_eq!(
        rows_without_timing(Path::new(&p("killed.csv"))),
        rows_without_timing(Path::new(&p("part2.csv")))
    );
    // A real kill, whenever it lands: the rerun completes the shard
    // without duplicates.
    let mut child = std::process::Command::new(assert_cmd::cargo::cargo_bin!("mocomp"))
        .args([
            "rd",
            input.to_str().unwrap(),
            "--predictors",
            "zero,block:tss",
            "--frames",
            "3",
        ])
        .args([
            "--threads",
            "1",
            "-o",
            &p("real.csv"),
            "--shard",
            "1/3",
            "--quiet",
        ])
        .spawn()
        .unwrap();
    while std::fs::read_to_string(p("real.csv")).map_or(0, |t| t.lines().count()) < 2 {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::yield_now();
    }
    let _ = child.kill();
    let _ = child.wait();
    sweep("real.csv", &["--shard", "1/3", "--quiet"])
        .assert()
        .success();
    assert_eq!(
        rows_without_timing(Path::new(&p("real.csv"))),
        rows_without_timing(Path::new(&p("part1.csv")))
    );
    // A shard out of range is a usage error.
    sweep("x.csv", &["--shard", "4/3"]).assert().code(2);
}

#[test]
fn a_part_is_resumed_only_by_its_shard_and_parts_that_disagree_are_not_merged() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_owned();
    let input = sample("tree_qcif.y4m");
    let sweep = |out: &str, shard: &str| {
        let mut c = mocomp();
        c.args([
            "rd",
            input.to_str().unwrap(),
            "--predictors",
            "zero,block:tss",
            "--frames",
            "2",
        ])
        .args([
            "--qp",
            "27,37",
            "--threads",
            "1",
            "--quiet",
            "-o",
            &p(out),
            "--shard",
            shard,
        ]);
        c
    };
    for i in 1..=3 {
        sweep(&format!("part{i}.csv"), &format!("{i}/3"))
            .assert()
            .success();
    }
    // The rows say which shard wrote them.
    let (header, rows) = read_csv(Path::new(&p("part2.csv")));
    let shard = header.iter().position(|h| h == "shard").unwrap();
    assert!(rows.iter().all(|r| r[shard] == "2/3"), "{rows:?}");
    // Resuming part 2 as another shard (as a rerun whose shard count was
    // read from a one-task array: 1/1) is refused, naming both shards.
    for other in ["1/1", "1/3", "2/4"] {
        let err = sweep("part2.csv", other)
            .assert()
            .failure()
            .get_output()
            .stderr
            .clone();
        let err = String::from_utf8_lossy(&err);
        assert!(
            err.contains("holds rows of shard 2/3") && err.contains(&format!("not of shard {other}")),
            "{err}"
        );
    }
    // A task run again gives the same rows: merging both copies is fine.
    std::fs::copy(p("part2.csv"), p("again.csv")).unwrap();
    let merge = |parts: &[&str]| {
        let mut c = mocomp();
        c.args(["rd", "merge"])
            .args(parts.iter().map(|n| p(n)))
            .args(["-o", &p("merged.csv"), "--quiet"]);
        c
    };
    merge(&["part1.csv", "part2.csv", "again.csv", "part3.csv"])
        .assert()
        .success();
    // Two parts with one job's results differing: refused, naming the job
    // and the column.
    let text = std::fs::read_to_string(p("part2.csv")).unwrap();
    let bytes = header.iter().position(|h| h == "bytes").unwrap();
    let job = header.iter().position(|h| h == "job").unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[1].split(',').map(String::from).collect();
    cells[bytes] = "1".into();
    let job_no = cells[job].split('/').next().unwrap().to_string();
    lines[1] = cells.join(",");
    std::fs::write(p("bad.csv"), lines.join("\n") + "\n").unwrap();
    let out = merge(&["part1.csv", "part2.csv", "bad.csv", "part3.csv"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains(&format!("job {job_no} is in")) && err.contains("column bytes"),
        "{err}"
    );
}

#[test]
fn aspect_ratio_siting_and_range_survive_encode_and_decode() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_owned();
    let header_of = |path: &str| -> String {
        let bytes = std::fs::read(path).unwrap();
        let end = bytes.iter().position(|&b| b == b'\n').unwrap();
        String::from_utf8(bytes[..end].to_vec()).unwrap()
    };
    // The bundled sample's frames under a header with the tags.
    let src = std::fs::read(sample("tree_qcif.y4m")).unwrap();
    let end = src.iter().position(|&b| b == b'\n').unwrap();
    for (tags, expected) in [
        (
            "A1:1 C420jpeg XCOLORRANGE=LIMITED",
            ["A1:1", "C420jpeg", "XCOLORRANGE=LIMITED"],
        ),
        (
            "A16:11 C420mpeg2 XCOLORRANGE=FULL",
            ["A16:11", "C420mpeg2", "XCOLORRANGE=FULL"],
        ),
        ("A0:0 C420paldv", ["A0:0", "C420paldv", "C420paldv"]),
    ] {
        let mut input = format!("YUV4MPEG2 W176 H144 F25:1 Ip {tags}").into_bytes();
        input.extend_from_slice(&src[end..]);
        std::fs::write(p("in.y4m"), input).unwrap();
        mocomp()
            .args([
                "encode",
                &p("in.y4m"),
                "-o",
                &p("a.mcv"),
                "--frames",
                "2",
                "--quiet",
            ])
            .args(["--recon", &p("rec.y4m")])
            .assert()
            .success();
        mocomp()
            .args(["decode", &p("a.mcv"), "-o", &p("dec.y4m")])
            .assert()
            .success();
        let decoded = header_of(&p("dec.y4m"));
        assert_eq!(decoded, header_of(&p("rec.y4m")), "{tags}");
        for tag in expected {
            assert!(
                decoded.split(' ').any(|t| t == tag),
                "{tag} missing from '{decoded}'"
            );
        }
        assert_eq!(
            std::fs::read(p("dec.y4m")).unwrap(),
            std::fs::read(p("rec.y4m")).unwrap()
        );
    }
}

#[test]
fn globalmotion_finds_the_bundled_scenes_camera_from_each_source() {
    // The bundled scene's exact forward flows (objects and occlusions
    // included) give the camera model each pair should have; every source's
    // fit from the pictures alone lands within half a pixel of it at the
    // corners (matches, about 50 keypoints at whole pixels on QCIF, within
    // 1.5), and the CSV holds one row per pair.
    use mocomp::global::{estimate, sources, GlobalParams, Model, Transform};
    let dir = tempfile::tempdir().unwrap();
    let input = sample("synth_qcif.y4m");
    for (source, bound) in [("auto", 0.5), ("flow", 0.5), ("blocks", 0.5), ("matches", 1.5)] {
        let csv = dir.path().join(format!("{source}.csv"));
        mocomp()
            .args([
                "globalmotion",
                input.to_str().unwrap(),
                "--source",
                source,
                "--model",
                "affine",
            ])
            .arg("--csv")
            .arg(&csv)
            .assert()
            .success()
            .stdout(predicate::str::contains("9 frame pairs"));
        let text = std::fs::read_to_string(&csv).unwrap();
        let rows: Vec<&str> = text.lines().skip(1).collect();
        assert_eq!(rows.len(), 9, "{source}");
        for (k, row) in rows.iter().enumerate() {
            let f: Vec<&str> = row.split(',').collect();
            assert_eq!(
                (f[0], f[1]),
                (format!("{}", k + 1).as_str(), "affine"),
                "{source}"
            );
            // What the points came from: auto's blocks fit this scene.
            let from = if source == "auto" { "blocks" } else { source };
            assert_eq!(f.last(), Some(&from), "{source}");
            let m: Vec<f64> = f[2..11].iter().map(|v| v.parse().unwrap()).collect();
            let found = Transform(m.try_into().unwrap());
            let gt =
                mocomp::io::flo::read_flo(&sample("synth_qcif").join(format!("forward_{k:04}.flo"))).unwrap();
            let truth = estimate(&sources::from_flow(&gt, 4), &GlobalParams::new(Model::Affine)).unwrap();
            let e = [(0.0, 0.0), (176.0, 0.0), (0.0, 144.0), (176.0, 144.0)]
                .iter()
                .map(|&(x, y)| {
                    let (p, q) = (found.apply(x, y).unwrap(), truth.transform.apply(x, y).unwrap());
                    (p.0 - q.0).hypot(p.1 - q.1)
                })
                .fold(0.0, f64::max);
            assert!(
                e < bound,
                "{source} pair {}: corners {e:.3} px from the truth's model",
                k + 1
            );
        }
    }
    let json = json_stdout(mocomp().args([
        "globalmotion",
        input.to_str().unwrap(),
        "--model",
        "homography",
        "--json",
    ]));
    assert_eq!(json["pairs"].as_array().unwrap().len(), 9);
    assert_eq!(json["pairs"][0]["fit"]["model"], "homography");
    fails_cleanly(&["globalmotion", input.to_str().unwrap(), "--threshold", "0"]);
}

#[test]
fn shake_then_stabilize_then_score() {
    // A known shake on the bundled scene; the stabilised output keeps the
    // size and frame count, and its residual jitter is a fraction of the
    // shake's (the scene's own camera pans, so not zero).
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let input = sample("synth_cif.y4m");
    mocomp()
        .args([
            "shake",
            input.to_str().unwrap(),
            "-o",
            &p("shaken.y4m"),
            "--translation",
            "8",
        ])
        .args(["--rotation", "1", "--seed", "3", "--truth", &p("truth.csv")])
        .assert()
        .success()
        .stdout(predicate::str::contains("shaken into"));
    let truth = std::fs::read_to_string(p("truth.csv")).unwrap();
    assert_eq!(truth.lines().count(), 1 + 10);
    mocomp()
        .args([
            "stabilize",
            &p("shaken.y4m"),
            "-o",
            &p("out.y4m"),
            "--path",
            &p("path.csv"),
        ])
        .args(["--report", "--shake", &p("truth.csv")])
        .assert()
        .success()
        .stdout(predicate::str::contains("residual jitter"));
    let (a, b) = (
        mocomp::io::y4m::Y4mReader::open(std::path::Path::new(&p("shaken.y4m")))
            .unwrap()
            .read_all()
            .unwrap(),
        mocomp::io::y4m::Y4mReader::open(std::path::Path::new(&p("out.y4m")))
            .unwrap()
            .read_all()
            .unwrap(),
    );
    assert_eq!(
        (a.len(), a[0].width(), a[0].height()),
        (b.len(), b[0].width(), b[0].height())
    );
    assert_eq!(
        std::fs::read_to_string(p("path.csv")).unwrap().lines().count(),
        1 + 10
    );
    let score = json_stdout(mocomp().args([
        "stabscore",
        &p("shaken.y4m"),
        &p("out.y4m"),
        "--shake",
        &p("truth.csv"),
        "--json",
    ]));
    let (jitter, shake) = (
        score["jitter"].as_f64().unwrap(),
        score["input_jitter"].as_f64().unwrap(),
    );
    assert!(jitter < 0.5 * shake, "{score}");
    assert!(
        score["distortion"].as_f64().unwrap() > 0.95 && score["cropping"].as_f64().unwrap() > 0.8,
        "{score}"
    );
    fails_cleanly(&[
        "stabilize",
        &p("shaken.y4m"),
        "-o",
        &p("bad.y4m"),
        "--zoom",
        "0.5",
    ]);
    fails_cleanly(&[
        "stabilize",
        &p("shaken.y4m"),
        "-o",
        &p("bad.y4m"),
        "--model",
        "affine",
    ]);
    assert!(!dir.path().join("bad.y4m").exists());
}

#[test]
fn interpolate_doubles_the_rate_and_evaluates_rebuilt_frames() {
    // Input frame k is output frame 2k; --evaluate rebuilds frames 1, 3 ...
    // of the bundled scene from their neighbours, far better than their
    // average (the scene pans and objects move).
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let input = sample("synth_qcif.y4m");
    mocomp()
        .args(["interpolate", input.to_str().unwrap(), "-o", &p("double.y4m")])
        .assert()
        .success()
        .stdout(predicate::str::contains("9 frames made"));
    let read = |path: &str| mocomp::io::y4m::Y4mReader::open(std::path::Path::new(path)).unwrap();
    let (orig, double) = (read(input.to_str().unwrap()), read(&p("double.y4m")));
    assert_eq!(
        double.info().fps.0 * orig.info().fps.1,
        2 * orig.info().fps.0 * double.info().fps.1
    );
    let (orig, double) = (orig.read_all().unwrap(), double.read_all().unwrap());
    assert_eq!(double.len(), 2 * orig.len() - 1);
    for (k, f) in orig.iter().enumerate() {
        assert!(double[2 * k] == *f, "output frame {} is input frame {k}", 2 * k);
    }
    let v = json_stdout(mocomp().args([
        "interpolate",
        input.to_str().unwrap(),
        "--evaluate",
        "--json",
        "-o",
        &p("rebuilt.y4m"),
    ]));
    assert_eq!(v["frames"], 4);
    assert!(v["mean_psnr_y"].as_f64().unwrap() > 30.0, "{v}");
    // --evaluate rebuilds what interpolating the kept frames (0, 2, 4 ...)
    // makes: the same pairs, their paths bent by the same neighbours.
    {
        let file = std::fs::File::create(p("kept.y4m")).unwrap();
        let mut writer = mocomp::io::y4m::Y4mWriter::new(file, read(input.to_str().unwrap()).info()).unwrap();
        for f in orig.iter().step_by(2) {
            writer.write_frame(f).unwrap();
        }
    }
    mocomp()
        .args(["interpolate", &p("kept.y4m"), "-o", &p("kept2.y4m")])
        .assert()
        .success();
    let (rebuilt, kept2) = (
        read(&p("rebuilt.y4m")).read_all().unwrap(),
        read(&p("kept2.y4m")).read_all().unwrap(),
    );
    assert_eq!(kept2.len(), 9);
    for k in (1..9).step_by(2) {
        assert!(rebuilt[k] == kept2[k], "frame {k}");
    }
    fails_cleanly(&[
        "interpolate",
        input.to_str().unwrap(),
        "-o",
        &p("bad.y4m"),
        "--factor",
        "1",
    ]);
    fails_cleanly(&["interpolate", input.to_str().unwrap()]);
}

#[test]
fn segment_writes_a_mask_per_frame_and_an_overlay() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let input = sample("synth_qcif.y4m");
    mocomp()
        .args([
            "segment",
            input.to_str().unwrap(),
            "--masks",
            &p("masks"),
            "--overlay",
            &p("ov.y4m"),
        ])
        .assert()
        .success()
        .stdout(predicate::str::contains("10 frames segmented"));
    for t in 0..10 {
        let mask =
            mocomp::io::image::read_luma(&dir.path().join("masks").join(format!("{t:05}.png"))).unwrap();
        assert_eq!((mask.width(), mask.height()), (176, 144));
        assert!(mask.rows().all(|r| r.iter().all(|&v| v == 0 || v == 255)));
    }
    let ov = mocomp::io::y4m::Y4mReader::open(std::path::Path::new(&p("ov.y4m")))
        .unwrap()
        .read_all()
        .unwrap();
    assert_eq!(ov.len(), 10);
    // Its own masks as the truth: IoU 1 in every frame.
    let v = json_stdout(mocomp().args([
        "segment",
        input.to_str().unwrap(),
        "--truth",
        &p("masks"),
        "--json",
    ]));
    assert_eq!(v["mean_iou"].as_f64().unwrap(), 1.0, "{v}");
    fails_cleanly(&["segment", input.to_str().unwrap(), "--tolerance", "0"]);
}

#[cfg(target_os = "linux")]
#[test]
fn the_command_line_runs_without_transparent_huge_pages() {
    // Seen from outside while it encodes: the kernel's own flag
    // (`THP_enabled` in /proc/PID/status, Linux 5.0 and later).
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/synth_cif.y4m");
    let dir = tempfile::tempdir().unwrap();
    let mut child = std::process::Command::new(assert_cmd::cargo::cargo_bin!("mocomp"))
        .args([
            "encode",
            input.to_str().unwrap(),
            "--preset",
            "slower",
            "--quiet",
            "-o",
        ])
        .arg(dir.path().join("out.mcv"))
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let status = format!("/proc/{}/status", child.id());
    let mut seen = None;
    while child.try_wait().unwrap().is_none() {
        let flag = std::fs::read_to_string(&status).ok().and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("THP_enabled:").map(|v| v.trim().to_string()))
        });
        if flag.is_some() {
            seen = flag;
        }
        if seen.as_deref() == Some("0") {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let _ = child.kill();
    let _ = child.wait();
    match seen {
        Some(flag) => assert_eq!(flag, "0", "transparent huge pages still on"),
        None => eprintln!("this kernel does not say (no THP_enabled): not checked"),
    }
}
