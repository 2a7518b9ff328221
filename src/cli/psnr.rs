//! `mocomp psnr REF.y4m TEST.y4m`: per-frame PSNR and SSIM, then the means.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde_json::json;

use crate::codec::Frame;
use crate::io::{y4m::Y4mReader, OutputFile};
use crate::metrics::{FrameQuality, QualityAccumulator, SequenceQuality};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The reference (source) Y4M.
    pub reference: PathBuf,
    /// The Y4M to measure (`-` for standard input).
    pub test: PathBuf,
    /// Print one JSON object (means and per-frame values) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also write the per-frame values as CSV.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
}

pub fn run(args: &Args) -> Result<()> {
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
    let mut a = Frame::new(ri.width, ri.height)?;
    let mut b = Frame::new(ri.width, ri.height)?;
    let mut acc = QualityAccumulator::default();
    let mut rows = Vec::new();
    if !args.json {
        outln!(
            "{:>6} {:>8} {:>8} {:>8} {:>8} {:>8}",
            "frame",
            "psnr_y",
            "psnr_u",
            "psnr_v",
            "psnr_yuv",
            "ssim"
        )?;
    }
    loop {
        let more_a = reference
            .read_frame_into(&mut a)
            .with_context(|| args.reference.display().to_string())?;
        let more_b = test
            .read_frame_into(&mut b)
            .with_context(|| args.test.display().to_string())?;
        if !(more_a && more_b) {
            if more_a || more_b {
                let (longer, shorter) = if more_a {
                    (&args.reference, &args.test)
                } else {
                    (&args.test, &args.reference)
                };
                eprintln!(
                    "mocomp: note: {} has more frames than {}; compared the first {}",
                    longer.display(),
                    shorter.display(),
                    acc.frames()
                );
            }
            break;
        }
        let q = FrameQuality::measure(&a, &b);
        if !args.json {
            outln!(
                "{:>6} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>8.6}",
                acc.frames(),
                q.psnr.y,
                q.psnr.u,
                q.psnr.v,
                q.psnr.yuv(),
                q.ssim
            )?;
        }
        rows.push(q);
        acc.push(&q);
    }
    let Some(s) = acc.summary() else {
        bail!("no frames to compare");
    };
    if let Some(path) = &args.csv {
        write_csv(path, &rows)?;
    }
    report(args.json, &rows, &s)
}

/// One row per frame: the PSNRs, SSIM and MSEs.
fn write_csv(path: &Path, rows: &[FrameQuality]) -> Result<()> {
    let mut out = OutputFile::create(path).with_context(|| path.display().to_string())?;
    writeln!(out, "frame,psnr_y,psnr_u,psnr_v,psnr_yuv,ssim,mse_y,mse_u,mse_v")?;
    for (i, q) in rows.iter().enumerate() {
        writeln!(
            out,
            "{i},{:.6},{:.6},{:.6},{:.6},{:.8},{:.6},{:.6},{:.6}",
            q.psnr.y,
            q.psnr.u,
            q.psnr.v,
            q.psnr.yuv(),
            q.ssim,
            q.psnr.mse[0],
            q.psnr.mse[1],
            q.psnr.mse[2]
        )?;
    }
    out.commit().with_context(|| path.display().to_string())
}

/// The means (after the per-frame table) or, with `json`, everything as JSON.
fn report(json: bool, rows: &[FrameQuality], s: &SequenceQuality) -> Result<()> {
    if json {
        let per_frame: Vec<_> = rows
            .iter()
            .map(|q| json!({"psnr_y": q.psnr.y, "psnr_u": q.psnr.u, "psnr_v": q.psnr.v, "psnr_yuv": q.psnr.yuv(), "ssim": q.ssim}))
            .collect();
        let mut obj = serde_json::to_value(s)?;
        obj["per_frame"] = serde_json::Value::Array(per_frame);
        outln!("{obj}")?;
    } else {
        outln!(
            "{:>6} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>8.6}",
            "mean",
            s.psnr_y,
            s.psnr_u,
            s.psnr_v,
            s.psnr_yuv,
            s.ssim
        )?;
        outln!(
            "{} frames; PSNR of the mean MSE: y {:.4}  u {:.4}  v {:.4} dB",
            s.frames,
            s.psnr_y_mse,
            s.psnr_u_mse,
            s.psnr_v_mse
        )?;
    }
    Ok(())
}
