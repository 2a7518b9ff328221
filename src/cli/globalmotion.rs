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
use crate::global::sources::{PairCorrespondences, PairFit, Source};
use crate::global::{GlobalParams, Model};
use crate::io::{y4m::Y4mReader, OutputFile};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input Y4M (`-` for standard input).
    pub input: PathBuf,
    /// Camera model: translation, similarity (a camera that pans, turns
    /// and zooms), affine, homography.
    #[arg(long, default_value = "similarity")]
    pub model: Model,
    /// What the model is fitted to: auto (block vectors; flow where fewer
    /// than a quarter of them follow the model), flow (DIS at --preset,
    /// every 8 pixels, weighed by texture), blocks (16x16 EPZS vectors,
    /// quarter-pel, the worst tenth left out) or matches (feature matches).
    #[arg(long, default_value = "auto")]
    pub source: Source,
    /// Flow preset (with --source flow, and auto's).
    #[arg(long, default_value = "medium")]
    pub preset: Preset,
    /// A correspondence within this many pixels of the model is an inlier
    /// [default: 2 with --source matches, else 1].
    #[arg(long)]
    pub threshold: Option<f64>,
    /// Write one row per frame pair: frame,model,h11..h33,inliers,points,rms.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Print one JSON object (every pair's model) instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &Args) -> Result<()> {
    let threshold = args.threshold.unwrap_or(args.source.threshold());
    let params = GlobalParams {
        threshold,
        ..GlobalParams::new(args.model)
    };
    if !(threshold > 0.0 && threshold.is_finite()) {
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
        pairs.push(source.fit(prev.y(), cur.y(), &params)?);
        std::mem::swap(&mut prev, &mut cur);
    }
    let ms = start.elapsed().as_secs_f64() * 1000.0 / pairs.len().max(1) as f64;
    if let Some(path) = &args.csv {
        write_csv(path, &pairs)?;
    }
    report(args, &name, &pairs, ms)
}

/// One row per pair (frame t: the pair ending on it), `source` last: what
/// the correspondences came from (with auto, blocks or flow).
fn write_csv(path: &Path, pairs: &[PairFit]) -> Result<()> {
    let mut out = OutputFile::create(path).with_context(|| path.display().to_string())?;
    writeln!(
        out,
        "frame,model,h11,h12,h13,h21,h22,h23,h31,h32,h33,inliers,points,rms,source"
    )?;
    for (i, p) in pairs.iter().enumerate() {
        let (frame, source) = (i + 1, p.source.name());
        match &p.fit {
            Some(f) => {
                let m = f.transform.0.map(|v| format!("{v:.9}")).join(",");
                writeln!(
                    out,
                    "{frame},{},{m},{},{},{:.4},{source}",
                    f.model, f.inlier_count, p.points, f.rms
                )?;
            }
            None => writeln!(out, "{frame},,,,,,,,,,,0,{},,{source}", p.points)?,
        }
    }
    out.commit().with_context(|| path.display().to_string())
}

/// Each pair's shift and rotation, as text; or everything as JSON.
fn report(args: &Args, name: &str, pairs: &[PairFit], ms: f64) -> Result<()> {
    if args.json {
        let rows: Vec<_> = pairs
            .iter()
            .enumerate()
            .map(
                |(i, p)| json!({"frame": i + 1, "points": p.points, "source": p.source.name(), "fit": p.fit}),
            )
            .collect();
        outln!(
            "{}",
            json!({"model": args.model, "ms_per_pair": ms, "pairs": rows})
        )?;
        return Ok(());
    }
    outln!(
        "{name}: {} frame pairs, {} model from {}, {ms:.1} ms a pair",
        pairs.len(),
        args.model,
        args.source.name()
    )?;
    outln!("frame     dx       dy   rotation   scale  inliers  source")?;
    for (i, p) in pairs.iter().enumerate() {
        let (frame, source) = (i + 1, p.source.name());
        let Some(f) = &p.fit else {
            outln!("{frame:5}  no model ({} correspondences, {source})", p.points)?;
            continue;
        };
        let m = &f.transform.0;
        outln!(
            "{frame:5} {:7.2}  {:7.2}  {:7.3}°  {:6.4}  {}/{}  {source}",
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
