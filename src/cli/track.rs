//! `mocomp track IN.y4m`: sparse corners followed through a sequence.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde_json::json;

use crate::flow::track::{good_features, track, TrackParams};
use crate::io::{image::write_rgb, y4m::Y4mReader, OutputFile};
use crate::raster::plane_to_array;
use crate::viz::Rgb;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input Y4M (`-` for standard input).
    pub input: PathBuf,
    /// Write the tracks as CSV: frame,id,x,y,error.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Write a PNG per frame with the points and their last step drawn.
    #[arg(long, value_name = "DIR")]
    pub overlay: Option<PathBuf>,
    /// Most points tracked at once.
    #[arg(long, default_value_t = 300)]
    pub max: usize,
    /// Forward-backward threshold in pixels (0 turns the check off).
    #[arg(long, default_value_t = 0.5)]
    pub fb: f32,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

struct Point {
    id: usize,
    x: f32,
    y: f32,
    age: usize,
    /// Patch difference of the last step (0 when just detected).
    error: f32,
}

pub fn run(args: &Args) -> Result<()> {
    if args.max == 0 {
        bail!("--max must be at least 1");
    }
    let params = TrackParams {
        fb_threshold: (args.fb > 0.0).then_some(args.fb),
        ..TrackParams::default()
    };
    let name = args.input.display().to_string();
    let mut reader = Y4mReader::open(&args.input).with_context(|| name.clone())?;
    let mut csv = match &args.out {
        Some(p) => {
            let mut out = OutputFile::create(p).with_context(|| p.display().to_string())?;
            writeln!(out, "frame,id,x,y,error")?;
            Some(out)
        }
        None => None,
    };
    if let Some(dir) = &args.overlay {
        std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
    }
    let (mut points, mut next_id): (Vec<Point>, usize) = (Vec::new(), 0);
    let mut prev: Option<ndarray::Array2<f32>> = None;
    let (mut frames, mut track_ms, mut followed, mut lost, mut finished_ages) =
        (0usize, 0.0f64, 0usize, 0usize, Vec::new());
    let mut frame = crate::codec::Frame::new(reader.info().width, reader.info().height)?;
    while reader.read_frame_into(&mut frame).with_context(|| name.clone())? {
        let img = plane_to_array(frame.y());
        let mut steps: Vec<((f32, f32), (f32, f32))> = Vec::new();
        if let Some(prev_img) = &prev {
            let start = Instant::now();
            let from: Vec<(f32, f32)> = points.iter().map(|p| (p.x, p.y)).collect();
            let tracks = track(prev_img, &img, &from, &params);
            track_ms += start.elapsed().as_secs_f64() * 1000.0;
            let mut kept = Vec::with_capacity(points.len());
            for (p, t) in points.into_iter().zip(tracks) {
                if t.found {
                    steps.push(((p.x, p.y), (t.x, t.y)));
                    kept.push(Point {
                        x: t.x,
                        y: t.y,
                        age: p.age + 1,
                        error: t.error,
                        ..p
                    });
                    followed += 1;
                } else {
                    finished_ages.push(p.age);
                    lost += 1;
                }
            }
            points = kept;
        }
        // Top up with new corners away from the points still followed.
        if points.len() < args.max / 2 || prev.is_none() {
            for (x, y) in good_features(&img, args.max, 0.01, 8.0) {
                if points.len() >= args.max {
                    break;
                }
                if points.iter().all(|p| (p.x - x).hypot(p.y - y) >= 8.0) {
                    points.push(Point {
                        id: next_id,
                        x,
                        y,
                        age: 0,
                        error: 0.0,
                    });
                    next_id += 1;
                }
            }
        }
        if let Some(out) = csv.as_mut() {
            for p in &points {
                writeln!(out, "{frames},{},{:.3},{:.3},{:.3}", p.id, p.x, p.y, p.error)?;
            }
        }
        if let Some(dir) = &args.overlay {
            let mut rgb = Rgb::from_luma(frame.y());
            for &((x0, y0), (x1, y1)) in &steps {
                rgb.line(
                    (x0.round() as i64, y0.round() as i64),
                    (x1.round() as i64, y1.round() as i64),
                    [255, 40, 40],
                );
            }
            for p in &points {
                rgb.put(p.x.round() as i64, p.y.round() as i64, [40, 255, 40]);
            }
            let path = dir.join(format!("track_{frames:04}.png"));
            write_rgb(&path, rgb.width, rgb.height, &rgb.data).with_context(|| path.display().to_string())?;
        }
        prev = Some(img);
        frames += 1;
    }
    if frames == 0 {
        bail!("{name} has no frames");
    }
    if let Some(out) = csv {
        out.commit().context("writing --out")?;
    }
    finished_ages.extend(points.iter().map(|p| p.age));
    let pairs = frames.saturating_sub(1).max(1) as f64;
    let mean_length = finished_ages.iter().sum::<usize>() as f64 / finished_ages.len().max(1) as f64;
    if args.json {
        outln!(
            "{}",
            json!({
                "frames": frames,
                "points": next_id,
                "followed_per_frame": followed as f64 / pairs,
                "lost": lost,
                "mean_track_length": mean_length,
                "ms_per_frame": track_ms / pairs,
            })
        )?;
    } else {
        outln!("{name}: {frames} frames, {next_id} points detected")?;
        outln!("points followed per frame  {:.1}", followed as f64 / pairs)?;
        outln!("points lost                {lost}")?;
        outln!("mean track length          {mean_length:.2} frames")?;
        outln!("tracking time per frame    {:.3} ms", track_ms / pairs)?;
    }
    Ok(())
}
