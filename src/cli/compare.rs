//! `mocomp compare` (and `mocomp` with no arguments): the main job on the
//! bundled sample.
//!
//! For every consecutive pair of frames with a ground-truth flow, how well
//! frame t is predicted from frame t + 1 with no motion, and with the exact
//! motion (frame t + 1 warped back by the true forward flow): the gap is what
//! motion compensation can buy on this sequence.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::flow::warp::warp_bilinear;
use crate::io::{flo, y4m::Y4mReader, OutputFile};
use crate::metrics::psnr_from_mse;
use crate::raster::plane_to_array;
use crate::synth::forward_flow_name;

/// The bundled sample with exact flow, relative to the repository root.
const DEFAULT_INPUT: &str = "samples/synth_qcif.y4m";

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input Y4M [default: samples/synth_qcif.y4m].
    pub input: Option<PathBuf>,
    /// Folder of ground-truth forward flows `forward_NNNN.flo`
    /// [default: the input's path without `.y4m`].
    #[arg(long)]
    pub gt: Option<PathBuf>,
    /// Folder for the results.
    #[arg(long, default_value = "mocomp-out")]
    pub out: PathBuf,
}

/// `path` as given if it exists, else relative to the source tree (so the
/// default works from any folder of a checkout).
fn locate(path: &Path) -> PathBuf {
    if path.exists() || path.is_absolute() {
        return path.to_path_buf();
    }
    let in_tree = Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    if in_tree.exists() {
        in_tree
    } else {
        path.to_path_buf()
    }
}

fn masked_mse(
    a: &ndarray::Array2<f32>,
    b: &ndarray::Array2<f32>,
    mask: Option<&ndarray::Array2<bool>>,
) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for ((idx, &x), &y) in a.indexed_iter().zip(b.iter()) {
        if mask.is_none_or(|m| m[idx]) {
            // Predictions are rounded to 8 bits, as a decoder's would be.
            let d = f64::from(x) - f64::from(y.round().clamp(0.0, 255.0));
            sum += d * d;
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

pub fn run(args: &Args) -> Result<()> {
    let input = locate(args.input.as_deref().unwrap_or(Path::new(DEFAULT_INPUT)));
    let gt_dir = match &args.gt {
        Some(d) => d.clone(),
        None => input.with_extension(""),
    };
    let name = input.display().to_string();
    let reader = Y4mReader::open(&input).with_context(|| name.clone())?;
    let info = reader.info().clone();
    let frames = reader.read_all().with_context(|| name.clone())?;
    println!(
        "mocomp compare: {name} ({}x{}, {} frames, ground truth in {})",
        info.width,
        info.height,
        frames.len(),
        gt_dir.display()
    );
    println!("Luma PSNR (dB) of frame t predicted from frame t+1:");
    println!(
        "{:>7} {:>12} {:>14} {:>16} {:>7}",
        "pair", "zero motion", "true motion", "true, valid px", "valid"
    );
    let mut rows = Vec::new();
    for t in 0..frames.len().saturating_sub(1) {
        let path = gt_dir.join(forward_flow_name(t));
        if !path.exists() {
            continue;
        }
        let flow = flo::read_flo(&path).with_context(|| path.display().to_string())?;
        let cur = plane_to_array(frames[t].y());
        let next = plane_to_array(frames[t + 1].y());
        if flow.width() != info.width || flow.height() != info.height {
            bail!(
                "{}: flow is {}x{}, the video {}x{}",
                path.display(),
                flow.width(),
                flow.height(),
                info.width,
                info.height
            );
        }
        let warped = warp_bilinear(&next, &flow);
        let zero = psnr_from_mse(masked_mse(&cur, &next, None));
        let exact = psnr_from_mse(masked_mse(&cur, &warped, None));
        let exact_valid = psnr_from_mse(masked_mse(&cur, &warped, Some(flow.valid())));
        let valid_share = 100.0 * flow.valid_count() as f64 / (info.width * info.height) as f64;
        println!(
            "{:>7} {zero:>12.2} {exact:>14.2} {exact_valid:>16.2} {valid_share:>6.1}%",
            format!("{t}-{}", t + 1)
        );
        rows.push((t, zero, exact, exact_valid, valid_share));
    }
    if rows.is_empty() {
        bail!(
            "no ground-truth flow files ({}) in {}",
            forward_flow_name(0),
            gt_dir.display()
        );
    }
    let n = rows.len() as f64;
    let mean = |f: fn(&(usize, f64, f64, f64, f64)) -> f64| rows.iter().map(f).sum::<f64>() / n;
    println!(
        "{:>7} {:>12.2} {:>14.2} {:>16.2} {:>6.1}%",
        "mean",
        mean(|r| r.1),
        mean(|r| r.2),
        mean(|r| r.3),
        mean(|r| r.4)
    );
    std::fs::create_dir_all(&args.out).with_context(|| args.out.display().to_string())?;
    let csv = args.out.join("compare.csv");
    let mut out = OutputFile::create(&csv).with_context(|| csv.display().to_string())?;
    writeln!(
        out,
        "pair,psnr_zero,psnr_true_motion,psnr_true_motion_valid,valid_percent"
    )?;
    for (t, zero, exact, exact_valid, share) in &rows {
        writeln!(out, "{t},{zero:.4},{exact:.4},{exact_valid:.4},{share:.2}")?;
    }
    out.commit().with_context(|| csv.display().to_string())?;
    println!("wrote {}", csv.display());
    Ok(())
}
