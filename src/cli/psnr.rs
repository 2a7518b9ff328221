//! `mocomp quality REF.y4m TEST.y4m` (also `mocomp psnr`): per-frame
//! quality figures, then the means. PSNR always; SSIM by default; MS-SSIM,
//! PSNR-HVS, CIEDE2000 and VMAF when `--metrics` asks for them.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde_json::{json, Map, Value};

use crate::codec::Frame;
use crate::io::{y4m::Y4mReader, OutputFile};
use crate::metrics::{vmaf, FrameQuality, Metric, Metrics, QualityAccumulator, SequenceQuality};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The reference (source) Y4M.
    pub reference: PathBuf,
    /// The Y4M to measure (`-` for standard input).
    pub test: PathBuf,
    /// Metrics, comma-separated: psnr, ssim, ms-ssim, psnr-hvs, ciede2000,
    /// vmaf (through an ffmpeg built with libvmaf), or all (all but vmaf).
    /// PSNR is always measured.
    #[arg(long, default_value = "psnr,ssim", value_name = "LIST")]
    pub metrics: Metrics,
    /// Print one JSON object (means and per-frame values) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also write the per-frame values as CSV.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
}

/// A column beside PSNR: its name, its per-frame value and its mean.
struct Column {
    name: &'static str,
    frame: fn(&FrameQuality) -> f64,
    mean: fn(&SequenceQuality) -> f64,
}

/// The columns of the metrics in `m`, in order.
fn extra_columns(m: Metrics) -> Vec<Column> {
    let all = [
        (
            Metric::Ssim,
            Column {
                name: "ssim",
                frame: |q| q.ssim,
                mean: |s| s.ssim,
            },
        ),
        (
            Metric::MsSsim,
            Column {
                name: "ms_ssim",
                frame: |q| q.ms_ssim,
                mean: |s| s.ms_ssim,
            },
        ),
        (
            Metric::PsnrHvs,
            Column {
                name: "psnr_hvs",
                frame: |q| q.psnr_hvs,
                mean: |s| s.psnr_hvs,
            },
        ),
        (
            Metric::PsnrHvs,
            Column {
                name: "psnr_hvs_y",
                frame: |q| q.psnr_hvs_y,
                mean: |s| s.psnr_hvs_y,
            },
        ),
        (
            Metric::Ciede2000,
            Column {
                name: "ciede2000",
                frame: |q| q.ciede2000,
                mean: |s| s.ciede2000,
            },
        ),
        (
            Metric::Vmaf,
            Column {
                name: "vmaf",
                frame: |q| q.vmaf,
                mean: |s| s.vmaf,
            },
        ),
    ];
    all.into_iter()
        .filter(|(metric, _)| m.has(*metric))
        .map(|(_, c)| c)
        .collect()
}

pub fn run(args: &Args) -> Result<()> {
    let (rows, s) = measure(args)?;
    if let Some(path) = &args.csv {
        write_csv(path, &rows, args.metrics)?;
    }
    report(args, &rows, &s)
}

/// Reads both files frame by frame and measures every pair.
fn measure(args: &Args) -> Result<(Vec<FrameQuality>, SequenceQuality)> {
    if args.metrics.is_none() {
        bail!("--metrics none measures nothing (it is for encode): quality measures PSNR at least");
    }
    if args.metrics.has(Metric::Vmaf) && vmaf::ffmpeg_with_libvmaf().is_none() {
        bail!(vmaf::VmafError::NoLibvmaf);
    }
    let open = |p: &PathBuf| Y4mReader::open(p).with_context(|| p.display().to_string());
    let mut reference = open(&args.reference)?;
    let mut test = open(&args.test)?;
    let (ri, ti) = (reference.info().clone(), test.info().clone());
    if (ri.width, ri.height) != (ti.width, ti.height) {
        bail!(
            "sizes differ: {} is {}x{}, {} is {}x{}",
            args.reference.display(),
            ri.width,
            ri.height,
            args.test.display(),
            ti.width,
            ti.height
        );
    }
    let keep = args.metrics.has(Metric::Vmaf);
    let (mut kept_a, mut kept_b) = (Vec::new(), Vec::new());
    let mut a = Frame::new(ri.width, ri.height)?;
    let mut b = Frame::new(ri.width, ri.height)?;
    let mut rows = Vec::new();
    loop {
        let more_a = reference
            .read_frame_into(&mut a)
            .with_context(|| args.reference.display().to_string())?;
        let more_b = test
            .read_frame_into(&mut b)
            .with_context(|| args.test.display().to_string())?;
        if !(more_a && more_b) {
            if more_a != more_b {
                let (longer, shorter) = if more_a {
                    (&args.reference, &args.test)
                } else {
                    (&args.test, &args.reference)
                };
                eprintln!(
                    "mocomp: note: {} has more frames than {}; compared the first {}",
                    longer.display(),
                    shorter.display(),
                    rows.len()
                );
            }
            break;
        }
        rows.push(FrameQuality::measure_with(&a, &b, args.metrics));
        if keep {
            kept_a.push(a.clone());
            kept_b.push(b.clone());
        }
    }
    if keep {
        for (q, v) in rows.iter_mut().zip(vmaf::vmaf(&kept_a, &kept_b)?) {
            q.vmaf = v;
        }
    }
    let mut acc = QualityAccumulator::default();
    rows.iter().for_each(|q| acc.push(q));
    let Some(s) = acc.summary() else {
        bail!("no frames to compare");
    };
    Ok((rows, s))
}

/// One row per frame: the PSNRs, the other metrics asked for, the MSEs.
fn write_csv(path: &Path, rows: &[FrameQuality], metrics: Metrics) -> Result<()> {
    let cols = extra_columns(metrics);
    let mut out = OutputFile::create(path).with_context(|| path.display().to_string())?;
    let names: String = cols.iter().map(|c| format!("{},", c.name)).collect();
    writeln!(
        out,
        "frame,psnr_y,psnr_u,psnr_v,psnr_yuv,{names}mse_y,mse_u,mse_v"
    )?;
    for (i, q) in rows.iter().enumerate() {
        let values: String = cols.iter().map(|c| format!("{:.8},", (c.frame)(q))).collect();
        writeln!(
            out,
            "{i},{:.6},{:.6},{:.6},{:.6},{values}{:.6},{:.6},{:.6}",
            q.psnr.y,
            q.psnr.u,
            q.psnr.v,
            q.psnr.yuv(),
            q.psnr.mse[0],
            q.psnr.mse[1],
            q.psnr.mse[2]
        )?;
    }
    out.commit().with_context(|| path.display().to_string())
}

/// The per-frame table and the means, or with `--json` everything as JSON
/// (keys for the metrics not asked for are left out).
fn report(args: &Args, rows: &[FrameQuality], s: &SequenceQuality) -> Result<()> {
    let cols = extra_columns(args.metrics);
    if args.json {
        let per_frame: Vec<Value> = rows
            .iter()
            .map(|q| {
                let mut o = Map::new();
                o.insert("psnr_y".into(), json!(q.psnr.y));
                o.insert("psnr_u".into(), json!(q.psnr.u));
                o.insert("psnr_v".into(), json!(q.psnr.v));
                o.insert("psnr_yuv".into(), json!(q.psnr.yuv()));
                for c in &cols {
                    o.insert(c.name.into(), json!((c.frame)(q)));
                }
                Value::Object(o)
            })
            .collect();
        let mut obj = serde_json::to_value(s)?;
        if let Value::Object(map) = &mut obj {
            map.retain(|_, v| !v.is_null());
        }
        obj["per_frame"] = Value::Array(per_frame);
        outln!("{obj}")?;
        return Ok(());
    }
    let header: String = cols.iter().map(|c| format!(" {:>10}", c.name)).collect();
    outln!(
        "{:>6} {:>8} {:>8} {:>8} {:>8}{header}",
        "frame",
        "psnr_y",
        "psnr_u",
        "psnr_v",
        "psnr_yuv"
    )?;
    let line = |label: String, p: [f64; 4], extra: Vec<f64>| -> Result<()> {
        let extra: String = extra.iter().map(|v| format!(" {v:>10.6}")).collect();
        outln!(
            "{label:>6} {:>8.4} {:>8.4} {:>8.4} {:>8.4}{extra}",
            p[0],
            p[1],
            p[2],
            p[3]
        )?;
        Ok(())
    };
    for (i, q) in rows.iter().enumerate() {
        let p = [q.psnr.y, q.psnr.u, q.psnr.v, q.psnr.yuv()];
        line(i.to_string(), p, cols.iter().map(|c| (c.frame)(q)).collect())?;
    }
    let means: Vec<f64> = cols.iter().map(|c| (c.mean)(s)).collect();
    line("mean".into(), [s.psnr_y, s.psnr_u, s.psnr_v, s.psnr_yuv], means)?;
    outln!(
        "{} frames; PSNR of the mean MSE: y {:.4}  u {:.4}  v {:.4} dB",
        s.frames,
        s.psnr_y_mse,
        s.psnr_u_mse,
        s.psnr_v_mse
    )?;
    Ok(())
}
