//! `mocomp track IN.y4m`: sparse corners followed through a sequence.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use ndarray::Array2;
use serde_json::json;

use crate::codec::Frame;

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

/// A point's move from one frame to the next: from, to.
type Step = ((f32, f32), (f32, f32));

/// The points being followed and what the run adds up.
#[derive(Default)]
struct Tracker {
    points: Vec<Point>,
    next_id: usize,
    frames: usize,
    track_ms: f64,
    followed: usize,
    lost: usize,
    /// Lengths of the tracks that ended.
    finished_ages: Vec<usize>,
}

impl Tracker {
    /// Follows the points from `prev` to `img`; returns each followed
    /// point's step, for the overlay.
    fn follow(&mut self, prev: &Array2<f32>, img: &Array2<f32>, params: &TrackParams) -> Vec<Step> {
        let start = Instant::now();
        let from: Vec<(f32, f32)> = self.points.iter().map(|p| (p.x, p.y)).collect();
        let tracks = track(prev, img, &from, params);
        self.track_ms += start.elapsed().as_secs_f64() * 1000.0;
        let mut steps = Vec::new();
        let mut kept = Vec::with_capacity(self.points.len());
        for (p, t) in std::mem::take(&mut self.points).into_iter().zip(tracks) {
            if t.found {
                steps.push(((p.x, p.y), (t.x, t.y)));
                kept.push(Point {
                    x: t.x,
                    y: t.y,
                    age: p.age + 1,
                    error: t.error,
                    ..p
                });
                self.followed += 1;
            } else {
                self.finished_ages.push(p.age);
                self.lost += 1;
            }
        }
        self.points = kept;
        steps
    }

    /// Tops up to `max` points with new corners away from the points still followed.
    fn detect(&mut self, img: &Array2<f32>, max: usize) {
        for (x, y) in good_features(img, max, 0.01, 8.0) {
            if self.points.len() >= max {
                break;
            }
            if self.points.iter().all(|p| (p.x - x).hypot(p.y - y) >= 8.0) {
                self.points.push(Point {
                    id: self.next_id,
                    x,
                    y,
                    age: 0,
                    error: 0.0,
                });
                self.next_id += 1;
            }
        }
    }
}

/// The frame with each step in red and each point in green, as a PNG in `dir`.
fn write_overlay(dir: &Path, frame: &Frame, tracker: &Tracker, steps: &[Step]) -> Result<()> {
    let mut rgb = Rgb::from_luma(frame.y());
    for &((x0, y0), (x1, y1)) in steps {
        rgb.line(
            (x0.round() as i64, y0.round() as i64),
            (x1.round() as i64, y1.round() as i64),
            [255, 40, 40],
        );
    }
    for p in &tracker.points {
        rgb.put(p.x.round() as i64, p.y.round() as i64, [40, 255, 40]);
    }
    let path = dir.join(format!("track_{:04}.png", tracker.frames));
    write_rgb(&path, rgb.width, rgb.height, &rgb.data).with_context(|| path.display().to_string())
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
    let mut tracker = Tracker::default();
    let mut prev: Option<Array2<f32>> = None;
    let mut frame = Frame::new(reader.info().width, reader.info().height)?;
    while reader.read_frame_into(&mut frame).with_context(|| name.clone())? {
        let img = plane_to_array(frame.y());
        let steps = match &prev {
            Some(prev_img) => tracker.follow(prev_img, &img, &params),
            None => Vec::new(),
        };
        if tracker.points.len() < args.max / 2 || prev.is_none() {
            tracker.detect(&img, args.max);
        }
        if let Some(out) = csv.as_mut() {
            for p in &tracker.points {
                writeln!(
                    out,
                    "{},{},{:.3},{:.3},{:.3}",
                    tracker.frames, p.id, p.x, p.y, p.error
                )?;
            }
        }
        if let Some(dir) = &args.overlay {
            write_overlay(dir, &frame, &tracker, &steps)?;
        }
        prev = Some(img);
        tracker.frames += 1;
    }
    if tracker.frames == 0 {
        bail!("{name} has no frames");
    }
    if let Some(out) = csv {
        out.commit().context("writing --out")?;
    }
    report(args, &name, tracker)
}

/// The summary, as text or JSON.
fn report(args: &Args, name: &str, mut tracker: Tracker) -> Result<()> {
    let Tracker {
        frames,
        next_id,
        followed,
        lost,
        track_ms,
        ..
    } = tracker;
    tracker.finished_ages.extend(tracker.points.iter().map(|p| p.age));
    let ages = &tracker.finished_ages;
    let pairs = frames.saturating_sub(1).max(1) as f64;
    let mean_length = ages.iter().sum::<usize>() as f64 / ages.len().max(1) as f64;
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
