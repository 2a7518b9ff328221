//! `mocomp match A.png B.png`: sparse feature matches between two
//! pictures, as CSV, JSON or drawn side by side, and their accuracy
//! against a ground-truth flow.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde_json::json;

use crate::features::{match_pictures, Match, MatchParams};
use crate::flow::Flow;
use crate::io::{flo, image, OutputFile};
use crate::raster::plane_to_array;
use crate::viz::Rgb;

/// Arguments of `mocomp match`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// First picture (PNG, JPEG, PGM ...).
    pub first: PathBuf,
    /// Second picture.
    pub second: PathBuf,
    /// Write the matches as CSV (x1,y1,x2,y2,distance; `-` for stdout).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Draw the pictures side by side with a line per match (PNG).
    #[arg(long, value_name = "FILE")]
    pub overlay: Option<PathBuf>,
    /// Ground-truth flow (.flo) from the first picture to the second: say
    /// how many matches are right (within 1 and 3 px).
    #[arg(long, value_name = "FILE")]
    pub gt: Option<PathBuf>,
    /// Keypoints per picture, at most.
    #[arg(long, default_value_t = MatchParams::default().max_features)]
    pub max_features: usize,
    /// Lowe's ratio test threshold, in (0, 1].
    #[arg(long, default_value_t = MatchParams::default().ratio)]
    pub ratio: f32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// One JSON object on stdout instead of the text summary.
    #[arg(long)]
    pub json: bool,
}

/// Share of matches whose end point is within 1 and 3 px of the ground
/// truth's, over the matches where the ground truth is known.
fn accuracy(matches: &[Match], gt: &Flow) -> (usize, f64, f64) {
    let (mut known, mut r1, mut r3) = (0usize, 0usize, 0usize);
    for m in matches {
        let (x, y) = (m.x1.round() as usize, m.y1.round() as usize);
        if x >= gt.width() || y >= gt.height() {
            continue;
        }
        let (u, v) = gt.get(x, y);
        if !(u.abs() < 1e8 && v.abs() < 1e8) {
            continue;
        }
        known += 1;
        let err = (m.x1 + u - m.x2).hypot(m.y1 + v - m.y2);
        r1 += usize::from(err <= 1.0);
        r3 += usize::from(err <= 3.0);
    }
    let share = |n: usize| {
        if known == 0 {
            0.0
        } else {
            100.0 * n as f64 / known as f64
        }
    };
    (known, share(r1), share(r3))
}

/// The two pictures side by side, each match a line from its point in the
/// first to its point in the second, coloured by Hamming distance (green
/// close, red far).
fn overlay(a: &crate::codec::Plane, b: &crate::codec::Plane, matches: &[Match]) -> Rgb {
    let (wa, wb) = (a.width(), b.width());
    let (w, h) = (wa + wb, a.height().max(b.height()));
    let mut img = Rgb {
        width: w,
        height: h,
        data: vec![0; 3 * w * h],
    };
    for (plane, x0) in [(a, 0), (b, wa)] {
        for (y, row) in plane.rows().enumerate() {
            for (x, &v) in row.iter().enumerate() {
                img.put((x0 + x) as i64, y as i64, [v / 2 + 40, v / 2 + 40, v / 2 + 40]);
            }
        }
    }
    for m in matches {
        let t = (m.distance as f32 / 80.0).min(1.0);
        let colour = [(255.0 * t) as u8, (255.0 * (1.0 - t)) as u8, 40];
        let (p, q) = (
            (m.x1.round() as i64, m.y1.round() as i64),
            ((m.x2 + wa as f32).round() as i64, m.y2.round() as i64),
        );
        img.line(p, q, colour);
    }
    img
}

fn write_csv(path: &std::path::Path, matches: &[Match]) -> Result<()> {
    let mut out = OutputFile::create(path)?;
    writeln!(out, "x1,y1,x2,y2,distance")?;
    for m in matches {
        writeln!(out, "{},{},{},{},{}", m.x1, m.y1, m.x2, m.y2, m.distance)?;
    }
    out.commit()?;
    Ok(())
}

/// Runs `mocomp match`.
pub fn run(args: &Args) -> Result<()> {
    if !(args.ratio > 0.0 && args.ratio <= 1.0) {
        bail!("--ratio {} must be in (0, 1]", args.ratio);
    }
    if args.max_features == 0 {
        bail!("--max-features must be at least 1");
    }
    let read = |p: &PathBuf| {
        image::read_luma(p).with_context(|| format!("{}: not a picture mocomp reads", p.display()))
    };
    let (a, b) = (read(&args.first)?, read(&args.second)?);
    let params = MatchParams {
        max_features: args.max_features,
        ratio: args.ratio,
        ..MatchParams::default()
    };
    let pool = super::thread_pool(args.threads)?;
    let (i1, i2) = (plane_to_array(&a), plane_to_array(&b));
    let start = Instant::now();
    let matches = pool.install(|| match_pictures(&i1, &i2, &params));
    let ms = start.elapsed().as_secs_f64() * 1000.0;
    let acc = match &args.gt {
        Some(path) => Some(accuracy(
            &matches,
            &flo::read_flo(path).with_context(|| path.display().to_string())?,
        )),
        None => None,
    };
    if let Some(path) = &args.out {
        write_csv(path, &matches).with_context(|| path.display().to_string())?;
    }
    if let Some(path) = &args.overlay {
        let img = overlay(&a, &b, &matches);
        image::write_rgb(path, img.width, img.height, &img.data)
            .with_context(|| path.display().to_string())?;
    }
    let to_stdout = args.out.as_ref().is_some_and(|p| p.as_os_str() == "-");
    if to_stdout {
        return Ok(());
    }
    let mut stdout = std::io::stdout().lock();
    if args.json {
        let mut obj = json!({"matches": matches.len(), "ms": ms});
        if let Some((known, r1, r3)) = acc {
            obj["with_ground_truth"] = json!(known);
            obj["within_1px"] = json!(r1);
            obj["within_3px"] = json!(r3);
        }
        writeln!(stdout, "{obj}")?;
    } else {
        write!(stdout, "{} matches in {ms:.1} ms", matches.len())?;
        if let Some((known, r1, r3)) = acc {
            write!(
                stdout,
                "; of {known} with ground truth, {r1:.1} % within 1 px, {r3:.1} % within 3 px"
            )?;
        }
        writeln!(stdout)?;
    }
    Ok(())
}
