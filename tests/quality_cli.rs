//! The quality metrics from the command line: `mocomp quality --metrics`,
//! `mocomp encode --metrics`, `mocomp rd --metrics --bd-metric` and
//! `mocomp bdrate --metric`, each agreeing with the library and with the
//! other commands.

use std::path::{Path, PathBuf};

use assert_cmd::Command;
use mocomp::io::y4m::Y4mReader;
use mocomp::metrics::{ciede2000, ms_ssim, psnr_hvs};

fn mocomp() -> Command {
    Command::new(assert_cmd::cargo::cargo_bin!("mocomp"))
}

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("samples").join(name)
}

fn json_stdout(cmd: &mut Command) -> serde_json::Value {
    let out = cmd.assert().success().get_output().stdout.clone();
    serde_json::from_slice(&out).expect("one JSON value")
}

/// Header and rows of a CSV file.
fn csv_rows(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text
        .lines()
        .map(|l| l.split(',').map(str::to_string).collect::<Vec<_>>());
    let header = lines.next().unwrap();
    (header, lines.collect())
}

fn column(header: &[String], rows: &[Vec<String>], name: &str) -> Vec<String> {
    let i = header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no {name}"));
    rows.iter().map(|r| r[i].clone()).collect()
}

fn stderr_of(args: &[&str]) -> String {
    let out = mocomp().args(args).output().unwrap();
    assert_eq!(out.status.code(), Some(1), "{args:?}");
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(
        err.starts_with("mocomp: error: ") && !err.contains("panicked"),
        "{err}"
    );
    err
}

#[test]
fn quality_reports_the_metrics_asked_for_and_no_others() {
    let (r, t) = (sample("tree_176.y4m"), sample("tree_176_mpeg4.y4m"));
    let v = json_stdout(mocomp().args([
        "quality",
        r.to_str().unwrap(),
        t.to_str().unwrap(),
        "--metrics",
        "ms-ssim,psnr-hvs,ciede2000",
        "--json",
    ]));
    let read = |p: &Path| Y4mReader::open(p).unwrap().read_all().unwrap();
    let (a, b) = (read(&r), read(&t));
    let frames = v["per_frame"].as_array().unwrap();
    assert_eq!(frames.len(), 3);
    for (i, f) in frames.iter().enumerate() {
        let close = |key: &str, want: f64| {
            let got = f[key].as_f64().unwrap();
            assert!((got - want).abs() < 1e-12, "{key}: {got} {want}");
        };
        close("ms_ssim", ms_ssim(a[i].y(), b[i].y()));
        close("psnr_hvs", psnr_hvs(&a[i], &b[i]).total);
        close("ciede2000", ciede2000(&a[i], &b[i]));
        assert!(f.get("ssim").is_none() && f.get("vmaf").is_none(), "{f}");
    }
    let mean = frames
        .iter()
        .map(|f| f["ciede2000"].as_f64().unwrap())
        .sum::<f64>()
        / 3.0;
    assert!((v["ciede2000"].as_f64().unwrap() - mean).abs() < 1e-9);
    assert!(v.get("ssim").is_none() && v.get("vmaf").is_none(), "{v}");
    // `psnr` is the same command.
    let old = json_stdout(mocomp().args(["psnr", r.to_str().unwrap(), t.to_str().unwrap(), "--json"]));
    assert!(old["ssim"].as_f64().unwrap() > 0.8 && old.get("ms_ssim").is_none());
    // An unknown name is a usage error (exit 2, as clap's) that lists the known ones.
    let out = mocomp()
        .args([
            "quality",
            r.to_str().unwrap(),
            t.to_str().unwrap(),
            "--metrics",
            "butteraugli",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        err.contains("unknown metric 'butteraugli'") && err.contains("ms-ssim"),
        "{err}"
    );
}

#[test]
fn encode_measures_the_reconstruction_as_quality_does() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let src = sample("tree_176.y4m");
    let summary = json_stdout(mocomp().args([
        "encode",
        src.to_str().unwrap(),
        "-o",
        &p("t.mcv"),
        "--recon",
        &p("rec.y4m"),
        "--stats",
        &p("stats.csv"),
        "--metrics",
        "all",
        "--json",
    ]));
    let q = json_stdout(mocomp().args([
        "quality",
        src.to_str().unwrap(),
        &p("rec.y4m"),
        "--metrics",
        "all",
        "--json",
    ]));
    let (header, rows) = csv_rows(Path::new(&p("stats.csv")));
    for (key, col) in [
        ("ms_ssim", "ms_ssim"),
        ("psnr_hvs", "psnr_hvs"),
        ("ciede2000", "ciede2000"),
    ] {
        let per_frame: Vec<f64> = column(&header, &rows, col)
            .iter()
            .map(|c| c.parse().unwrap())
            .collect();
        let theirs: Vec<f64> = q["per_frame"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f[key].as_f64().unwrap())
            .collect();
        for (a, b) in per_frame.iter().zip(&theirs) {
            assert!((a - b).abs() < 1e-4, "{col}: {a} against {b}");
        }
        assert!(
            (summary[key].as_f64().unwrap() - q[key].as_f64().unwrap()).abs() < 1e-9,
            "{key}"
        );
    }
    // Not asked for: an empty cell, and null in JSON.
    assert!(column(&header, &rows, "vmaf").iter().all(String::is_empty));
    assert!(summary["vmaf"].is_null());
}

#[test]
fn rd_compares_on_any_metric_and_bdrate_reads_it_back() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let src = sample("synth_qcif.y4m");
    let run = |extra: &[&str]| {
        let mut c = mocomp();
        c.args([
            "rd",
            src.to_str().unwrap(),
            "--qp",
            "26,32,38,44",
            "--frames",
            "4",
        ])
        .args([
            "--predictors",
            "zero,block:tss",
            "--threads",
            "1",
            "-o",
            &p("rd.csv"),
        ])
        .args(extra);
        c.output().unwrap()
    };
    // A BD table on a metric measures it, without --metrics naming it.
    let out = run(&["--bd-metric", "ms-ssim"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.contains("BD-MS-SSIM cubic"), "{table}");
    let (header, rows) = csv_rows(Path::new(&p("rd.csv")));
    let ms_ssim = column(&header, &rows, "ms_ssim");
    assert!(
        ms_ssim
            .iter()
            .all(|c| c.parse::<f64>().is_ok_and(|v| v > 0.5 && v < 1.0)),
        "{ms_ssim:?}"
    );
    std::fs::remove_file(p("rd.csv")).unwrap();
    let out = run(&["--metrics", "ms-ssim,psnr-hvs", "--bd-metric", "ms-ssim"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(
        table.contains("BD-MS-SSIM cubic") && table.contains("decode ms/frame"),
        "{table}"
    );
    let (header, rows) = csv_rows(Path::new(&p("rd.csv")));
    for col in ["ms_ssim", "psnr_hvs", "decode_ms"] {
        assert!(
            column(&header, &rows, col)
                .iter()
                .all(|c| c.parse::<f64>().unwrap() > 0.0),
            "{col}"
        );
    }
    assert!(column(&header, &rows, "ciede2000").iter().all(String::is_empty));
    let bd = |metric: &str| {
        json_stdout(mocomp().args([
            "bdrate",
            &format!("{}:zero", p("rd.csv")),
            &format!("{}:block:tss", p("rd.csv")),
            "--metric",
            metric,
            "--json",
        ]))
    };
    let (on_ms, on_psnr) = (bd("ms-ssim"), bd("psnr"));
    assert_eq!(on_ms["metric"], "ms-ssim");
    let r = on_ms["bd_rate_pchip"].as_f64().unwrap();
    assert!(
        r < -10.0 && r != on_psnr["bd_rate_pchip"].as_f64().unwrap(),
        "{on_ms}"
    );
    assert!(
        table.contains(&format!("{r:+.2} %")),
        "the table's figure is bdrate's: {r}\n{table}"
    );
}

#[test]
fn similarities_are_compared_in_decibels() {
    // MS-SSIM = 1 - 10^(-PSNR/10): its dB are the PSNR, so BD-rate on it
    // must be BD-rate on PSNR exactly.
    let dir = tempfile::tempdir().unwrap();
    let mut csv = String::from("codec,q,bytes,frames,kbps,psnr_y,ms_ssim\n");
    for (codec, rates, psnrs) in [
        ("a", [100.0, 200.0, 400.0, 800.0], [30.0, 33.0, 36.0, 39.0]),
        ("b", [90.0, 170.0, 380.0, 700.0], [30.2, 33.1, 36.4, 39.1]),
    ] {
        for (r, q) in rates.iter().zip(psnrs) {
            let ms = 1.0 - 10f64.powf(-q / 10.0);
            csv += &format!("{codec},0,0,1,{r},{q},{ms:.12}\n");
        }
    }
    let path = dir.path().join("c.csv");
    std::fs::write(&path, csv).unwrap();
    let bd = |metric: &str| {
        json_stdout(mocomp().args([
            "bdrate",
            &format!("{}:a", path.display()),
            &format!("{}:b", path.display()),
            "--metric",
            metric,
            "--json",
        ]))
    };
    let (on_ms, on_psnr) = (bd("ms-ssim"), bd("psnr"));
    for key in ["bd_rate_cubic", "bd_rate_pchip", "bd_psnr_cubic", "bd_psnr_pchip"] {
        let (a, b) = (on_ms[key].as_f64().unwrap(), on_psnr[key].as_f64().unwrap());
        assert!((a - b).abs() < 1e-6, "{key}: {a} {b}");
    }
    // A CSV without the column: a clear error.
    let err = stderr_of(&[
        "bdrate",
        &format!("{}:a", path.display()),
        &format!("{}:b", path.display()),
        "--metric",
        "ciede2000",
    ]);
    assert!(err.contains("no ciede2000 values"), "{err}");
}

#[test]
fn encode_with_no_metrics_measures_nothing_and_codes_the_same_stream() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let src = sample("tree_176.y4m");
    let encode = |out: &str, metrics: &str| {
        json_stdout(mocomp().args([
            "encode",
            src.to_str().unwrap(),
            "-o",
            &p(out),
            "--preset",
            "ultrafast",
            "--metrics",
            metrics,
            "--json",
            "--quiet",
        ]))
    };
    let (measured, bare) = (encode("a.mcv", "psnr"), encode("b.mcv", "none"));
    assert_eq!(
        std::fs::read(p("a.mcv")).unwrap(),
        std::fs::read(p("b.mcv")).unwrap()
    );
    assert_eq!(measured["bytes"], bare["bytes"]);
    assert!(measured["psnr_y"].as_f64().unwrap() > 25.0, "{measured}");
    for key in ["psnr_y", "psnr_u", "psnr_v", "psnr_y_mse", "ssim"] {
        assert!(bare[key].is_null(), "{key}: {bare}");
    }
    // The text summary says so rather than printing NaN.
    let out = mocomp()
        .args([
            "encode",
            src.to_str().unwrap(),
            "-o",
            &p("c.mcv"),
            "--metrics",
            "none",
        ])
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    let text = String::from_utf8(out).unwrap();
    assert!(
        text.contains("quality not measured") && !text.contains("NaN"),
        "{text}"
    );
    // `quality` exists to measure: none is refused there, with a reason.
    let err = stderr_of(&[
        "quality",
        src.to_str().unwrap(),
        src.to_str().unwrap(),
        "--metrics",
        "none",
    ]);
    assert!(err.contains("measures nothing"), "{err}");
}
