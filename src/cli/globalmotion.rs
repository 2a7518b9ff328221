//! `mocomp globalmotion IN.y4m`: the camera's motion between each frame and
//! the next, one model per pair, fitted robustly to flow, block vectors or
//! feature matches.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde_json::json;

use crate::codec::Frame;
use crate::flow::Preset;
use crate::global::sources::{PairCorrespondences, Source};
use crate::global::{estimate, GlobalMotion, GlobalParams, Model};
use crate::io::{y4m::Y4mReader, OutputFile};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input Y4M (`-` for standard input).
    pub input: PathBuf,
    /// Camera model: translation, similarity, affine, homography.
    #[arg(long, default_value = "affine")]
    pub model: Model,
    /// What the model is fitted to: flow (DIS at --preset, every 8
    /// pixels), blocks (16x16 EPZS vectors, quarter-pel, the worst tenth
    /// left out) or matches (feature matches).
    #[arg(long, default_value = "flow")]
    pub source: Source,
    /// Flow preset (with --source flow).
    #[arg(long, default_value = "fast")]
    pub preset: Preset,
    /// A correspondence within this many pixels of the model is an inlier.
    #[arg(long, default_value_t = 1.0)]
    pub threshold: f64,
    /// Write one row per frame pair: frame,model,h11..h33,inliers,points,rms.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Print one JSON object (every pair's model) instead of text.
    #[arg(long)]
    pub json: bool,
}

/// What one pair gave: the frame it ends on, the fit, the points it had.
struct Pair {
    frame: usize,
    fit: Option<GlobalMotion>,
    points: usize,
}

pub fn run(args: &Args) -> Result<()> {
    let params = GlobalParams {
        threshold: args.threshold,
        ..GlobalParams::new(args.model)
    };
    if !(args.threshold > 0.0 && args.threshold.is_finite()) {
        bail!("--threshold must be a positive number of pixels");
    }
    let name = args.input.display().to_string();
    let mut reader = Y4mReader::open(&args.input).with_context(|| name.clone())?;
    let mut source = PairCorrespondences::new(args.source, args.preset).weighted_by_texture();
    let (w, h) = (reader.info().width, reader.info().height);
    let (mut prev, mut cur) = (Frame::new(w, h)?, Frame::new(w, h)?);
    if !reader.read_frame_into(&mut prev).with_context(|| name.clone())? {
        bail!("{name} has no frames");
    }
    let (mut pairs, start) = (Vec::new(), Instant::now());
    while reader.read_frame_into(&mut cur).with_context(|| name.clone())? {
        let points = source.between(prev.y(), cur.y())?;
        pairs.push(Pair {
            frame: pairs.len() + 1,
            fit: estimate(&points, &params).ok(),
            points: points.len(),
        });
        std::mem::swap(&mut prev, &mut cur);
    }
    let ms = start.elapsed().as_secs_f64() * 1000.0 / pairs.len().max(1) as f64;
    if let Some(path) = &args.csv {
        write_csv(path, &pairs)?;
    }
    report(args, &name, &pairs, ms)
}

fn write_csv(path: &Path, pairs: &[Pair]) -> Result<()> {
    let mut out = OutputFile::create(path).with_context(|| path.display().to_string())?;
    writeln!(
        out,
        "frame,model,h11,h12,h13,h21,h22,h23,h31,h32,h33,inliers,points,rms"
    )?;
    for p in pairs {
        match &p.fit {
            Some(f) => {
                let m = f.transform.0.map(|v| format!("{v:.9}")).join(",");
                writeln!(
                    out,
                    "{},{},{m},{},{},{:.4}",
                    p.frame, f.model, f.inlier_count, p.points, f.rms
                )?;
            }
            None => writeln!(out, "{},,,,,,,,,,,0,{},", p.frame, p.points)?,
        }
    }
    out.commit().with_context(|| path.display().to_string())
}

/// Each pair's shift and rotation, as text; or everything as JSON.
fn report(args: &Args, name: &str, pairs: &[Pair], ms: f64) -> Result<()> {
    if args.json {
        let rows: Vec<_> = pairs
            .iter()
            .map(|p| json!({"frame": p.frame, "points": p.points, "fit": p.fit}))
            .collect();
        outln!(
            "{}",
            json!({"model": args.model, "ms_per_pair": ms, "pairs": rows})
        )?;
        return Ok(());
    }
    outln!(
        "{name}: {} frame pairs, {} model from {:?}, {ms:.1} ms a pair",
        pairs.len(),
        args.model,
        args.source
    )?;
    outln!("frame     dx       dy   rotation   scale  inliers")?;
    for p in pairs {
        let Some(f) = &p.fit else {
            outln!("{:5}  no model ({} correspondences)", p.frame, p.points)?;
            continue;
        };
        let m = &f.transform.0;
        outln!(
            "{:5} {:7.2}  {:7.2}  {:7.3}°  {:6.4}  {}/{}",
            p.frame,
            m[2],
            m[5],
            m[3].atan2(m[0]).to_degrees(),
            (m[0] * m[4] - m[1] * m[3]).abs().sqrt(),
            f.inlier_count,
            p.points
        )?;
    }
    Ok(())
}
