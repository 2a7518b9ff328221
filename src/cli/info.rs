//! `mocomp info FILE`: what a Y4M, `.flo` or image file holds.

use std::io::Read;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use serde_json::json;

use crate::io::{flo, y4m::Y4mReader};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// A Y4M (`-` for standard input), Middlebury .flo or image file.
    pub file: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

enum Kind {
    Y4m,
    Flo,
    Image,
}

fn sniff(args: &Args) -> Result<Kind> {
    if args.file.as_os_str() == "-" {
        return Ok(Kind::Y4m);
    }
    let mut head = [0u8; 10];
    let mut file = std::fs::File::open(&args.file)?;
    let n = file.read(&mut head)?;
    Ok(if head[..n].starts_with(b"YUV4MPEG2") {
        Kind::Y4m
    } else if head[..n].starts_with(&flo::MAGIC) {
        Kind::Flo
    } else {
        Kind::Image
    })
}

pub fn run(args: &Args) -> Result<()> {
    let name = args.file.display().to_string();
    let report = match sniff(args).with_context(|| name.clone())? {
        Kind::Y4m => y4m_info(args).with_context(|| name.clone())?,
        Kind::Flo => flo_info(args).with_context(|| name.clone())?,
        Kind::Image => image_info(args).with_context(|| name.clone())?,
    };
    if args.json {
        outln!("{}", serde_json::to_string(&report)?)?;
    } else {
        outln!("{name}")?;
        if let Some(map) = report.as_object() {
            for (k, v) in map {
                let text = match v {
                    serde_json::Value::String(s) => s.clone(),
                    other => other.to_string(),
                };
                outln!("  {k:<12} {text}")?;
            }
        }
    }
    Ok(())
}

fn y4m_info(args: &Args) -> Result<serde_json::Value> {
    let mut reader = Y4mReader::open(&args.file)?;
    let info = reader.info().clone();
    let mut frame = crate::codec::Frame::new(info.width, info.height)?;
    while reader.read_frame_into(&mut frame)? {}
    let frames = reader.frames_read();
    Ok(json!({
        "format": "Y4M, 8-bit 4:2:0",
        "chroma": info.siting.tag(),
        "width": info.width,
        "height": info.height,
        "fps": format!("{}:{} ({:.3})", info.fps.0, info.fps.1, info.fps_f64()),
        "aspect": format!("{}:{}", info.aspect.0, info.aspect.1),
        "extensions": info.extensions.iter().map(|x| format!("X{x}")).collect::<Vec<_>>().join(" "),
        "frames": frames,
        "duration_s": (frames as f64 / info.fps_f64() * 1000.0).round() / 1000.0,
    }))
}

fn flo_info(args: &Args) -> Result<serde_json::Value> {
    let flow = flo::read_flo(&args.file)?;
    let n = flow.width() * flow.height();
    let range = |a: &ndarray::Array2<f32>| {
        let vals = a
            .iter()
            .zip(flow.valid().iter())
            .filter(|(_, &ok)| ok)
            .map(|(&v, _)| v);
        let (lo, hi) = vals.fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), v| {
            (l.min(v), h.max(v))
        });
        if lo <= hi {
            format!("{lo:.3} .. {hi:.3}")
        } else {
            "none valid".to_owned()
        }
    };
    Ok(json!({
        "format": "Middlebury .flo",
        "width": flow.width(),
        "height": flow.height(),
        "valid": format!("{} of {} pixels ({:.1} %)", flow.valid_count(), n, 100.0 * flow.valid_count() as f64 / n as f64),
        "u": range(flow.u()),
        "v": range(flow.v()),
        "mean_abs": (flow.mean_magnitude() * 1000.0).round() / 1000.0,
        "max_abs": (flow.max_magnitude() as f64 * 1000.0).round() / 1000.0,
    }))
}

fn image_info(args: &Args) -> Result<serde_json::Value> {
    let reader = image::ImageReader::open(&args.file)?.with_guessed_format()?;
    let Some(format) = reader.format() else {
        bail!("not a Y4M, .flo or image file mocomp can read");
    };
    let (w, h) = reader.into_dimensions()?;
    Ok(json!({
        "format": format!("{format:?} image"),
        "width": w,
        "height": h,
    }))
}
