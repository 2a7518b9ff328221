//! `mocomp segment IN.y4m --masks DIR`: what moves against the camera,
//! one 8-bit PNG mask per frame (255 moving, 0 still), named by frame
//! number; an overlay video on request; IoU against known masks.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde_json::json;

use crate::codec::{Frame, Plane};
use crate::flow::Preset;
use crate::io::image::{read_luma, write_plane};
use crate::io::y4m::{Y4mReader, Y4mWriter};
use crate::io::OutputFile;
use crate::segment::{iou_against_truth, SegmentParams, Segmenter};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input Y4M.
    pub input: PathBuf,
    /// Directory for the masks: 00000.png, 00001.png ... (made if missing).
    #[arg(long, value_name = "DIR")]
    pub masks: Option<PathBuf>,
    /// Write the video with the moving pixels tinted red.
    #[arg(long, value_name = "OUT.y4m")]
    pub overlay: Option<PathBuf>,
    /// DIS preset of the flows.
    #[arg(long, default_value = "fast")]
    pub preset: Preset,
    /// Residual, pixels, at which a pixel counts as moving (plus 10 % of
    /// its motion).
    #[arg(long, default_value_t = 1.0)]
    pub tolerance: f32,
    /// Known masks (00000.png, 00001.png, ...) to score against: IoU per
    /// frame. In CDnet 2014's labels: 255 moving, 0 and 50 (shadow)
    /// static, 85 (outside the region of interest) and 170 (unknown) not
    /// scored; other values moving from 128.
    #[arg(long, value_name = "DIR")]
    pub truth: Option<PathBuf>,
    /// One JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &Args) -> Result<()> {
    let params = SegmentParams {
        preset: args.preset,
        tolerance: args.tolerance,
        ..SegmentParams::default()
    };
    let mut seg = Segmenter::new(&params)?;
    let name = args.input.display().to_string();
    let mut reader = Y4mReader::open(&args.input).with_context(|| name.clone())?;
    let info = reader.info().clone();
    let frames: Vec<Frame> = std::iter::from_fn(|| reader.read_frame().transpose())
        .collect::<Result<_, _>>()
        .with_context(|| name.clone())?;
    if frames.len() < 2 {
        bail!(
            "{name}: segmentation needs at least 2 frames, it has {}",
            frames.len()
        );
    }
    if let Some(dir) = &args.masks {
        std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
    }
    let mut overlay = match &args.overlay {
        Some(p) => Some(OutputFile::create(p).with_context(|| p.display().to_string())?),
        None => None,
    };
    let mut writer = match overlay.as_mut() {
        Some(out) => Some(Y4mWriter::new(out, &info)?),
        None => None,
    };
    let (start, mut scores) = (Instant::now(), Vec::new());
    seg.masks(&frames, |t, mask| -> Result<()> {
        if let Some(dir) = &args.masks {
            let path = dir.join(format!("{t:05}.png"));
            write_plane(&path, &mask).with_context(|| path.display().to_string())?;
        }
        if let Some(w) = writer.as_mut() {
            w.write_frame(&tinted(&frames[t], &mask))?;
        }
        if let Some(dir) = &args.truth {
            scores.push((t, iou_against_truth(&mask, &read_truth(dir, t)?)));
        }
        Ok(())
    })?;
    drop(writer);
    if let (Some(out), Some(p)) = (overlay, &args.overlay) {
        out.commit().with_context(|| p.display().to_string())?;
    }
    report(args, &name, frames.len(), start.elapsed().as_secs_f64(), &scores)
}

fn read_truth(dir: &Path, t: usize) -> Result<Plane> {
    let path = dir.join(format!("{t:05}.png"));
    read_luma(&path).with_context(|| path.display().to_string())
}

fn report(args: &Args, name: &str, frames: usize, seconds: f64, scores: &[(usize, f64)]) -> Result<()> {
    let ms = seconds * 1000.0 / frames as f64;
    let mean = (!scores.is_empty()).then(|| scores.iter().map(|s| s.1).sum::<f64>() / scores.len() as f64);
    if args.json {
        let per: Vec<_> = scores
            .iter()
            .map(|(t, v)| json!({"frame": t, "iou": v}))
            .collect();
        outln!(
            "{}",
            json!({"frames": frames, "ms_per_frame": ms, "mean_iou": mean, "iou": per})
        )?;
        return Ok(());
    }
    outln!("{name}: {frames} frames segmented, {ms:.1} ms each")?;
    if let Some(m) = mean {
        outln!("mean IoU against the truth: {m:.4}")?;
    }
    Ok(())
}

/// `frame` with the masked pixels' chroma pushed towards red.
fn tinted(frame: &Frame, mask: &Plane) -> Frame {
    let mut out = frame.clone();
    let (cw, ch) = (out.u().width(), out.u().height());
    for y in 0..ch {
        for x in 0..cw {
            let (mx, my) = ((2 * x).min(mask.width() - 1), (2 * y).min(mask.height() - 1));
            if mask.get(mx, my) > 0 {
                let u = out.u().get(x, y);
                out.plane_mut(1).set(x, y, u / 2 + 32);
                out.plane_mut(2).set(x, y, 230);
            }
        }
    }
    out
}
