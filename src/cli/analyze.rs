//! `mocomp analyze IN.mcv`: what a stream holds, per frame (a summary
//! line) and per macroblock (CSV, JSON), and pictures of it (PNGs or a
//! Y4M of the decoded frames with modes and vectors drawn over them).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::json;

use crate::analyze::{csv_row, Analyzer, FrameAnalysis, CSV_HEADER};
use crate::io::y4m::{Y4mInfo, Y4mWriter};
use crate::io::{image, OutputFile};
use crate::viz::draw_stream_overlay;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The stream (`-` for standard input).
    pub input: PathBuf,
    /// Write one row per macroblock as CSV.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Print every frame and macroblock as one JSON object instead of the
    /// per-frame table.
    #[arg(long)]
    pub json: bool,
    /// Draw modes and vectors over the decoded frames: a directory of PNGs
    /// (`frame_0000.png`, ...) or, for a name ending in `.y4m`, one Y4M.
    #[arg(long, value_name = "DIR|OUT.y4m")]
    pub overlay: Option<PathBuf>,
}

pub fn run(args: &Args) -> Result<()> {
    let name = args.input.display().to_string();
    let reader: Box<dyn std::io::Read> = if args.input.as_os_str() == "-" {
        Box::new(std::io::stdin().lock())
    } else {
        Box::new(std::io::BufReader::new(
            std::fs::File::open(&args.input).with_context(|| name.clone())?,
        ))
    };
    let mut analyzer = Analyzer::new(reader).with_context(|| name.clone())?;
    let seq = *analyzer.sequence();
    let mut overlay = Overlay::open(args.overlay.as_deref(), &Y4mInfo::for_sequence(&seq))?;
    let mut csv = match &args.csv {
        Some(p) => {
            let mut f = OutputFile::create(p).with_context(|| p.display().to_string())?;
            writeln!(f, "{CSV_HEADER}")?;
            Some(f)
        }
        None => None,
    };
    let mut frames_json = Vec::new();
    if !args.json {
        outln!("{}", table_header())?;
    }
    for frame in analyzer.by_ref() {
        let frame = frame.with_context(|| name.clone())?;
        if let Some(f) = csv.as_mut() {
            for m in &frame.mbs {
                writeln!(f, "{}", csv_row(&frame, m))?;
            }
        }
        overlay.push(&frame)?;
        if args.json {
            frames_json.push(frame_json(&frame));
        } else {
            outln!("{}", table_row(&frame))?;
        }
    }
    if let (Some(f), Some(p)) = (csv, &args.csv) {
        f.commit().with_context(|| p.display().to_string())?;
    }
    overlay.finish()?;
    if args.json {
        let v = json!({
            "width": seq.width, "height": seq.height,
            "fps": [seq.fps_num, seq.fps_den],
            "frames": frames_json,
        });
        outln!("{v}")?;
    }
    Ok(())
}

fn table_header() -> String {
    format!(
        "{:>5} {:>4} {:>3} {:>7} {:>8} {:>8} {:>8} {:>5} {:>5} {:>5} {:>5} {:>5} {:>5}",
        "frame",
        "type",
        "qp",
        "bytes",
        "hdr_bits",
        "mv_bits",
        "res_bits",
        "skip",
        "inter",
        "intra",
        "split",
        "i8x8",
        "i4x4"
    )
}

fn table_row(f: &FrameAnalysis) -> String {
    let [skip, inter, intra] = f.kinds();
    let split = f
        .mbs
        .iter()
        .filter(|m| m.kind == "inter" && m.partition != "16x16")
        .count();
    let intra_in = |size: &str| {
        f.mbs
            .iter()
            .filter(|m| m.kind == "intra" && m.partition == size)
            .count()
    };
    format!(
        "{:>5} {:>4} {:>3} {:>7} {:>8} {:>8} {:>8} {:>5} {:>5} {:>5} {:>5} {:>5} {:>5}",
        f.index,
        f.frame_type,
        f.qp,
        f.bytes,
        f.bits.header,
        f.bits.motion,
        f.bits.residual,
        skip,
        inter,
        intra,
        split,
        intra_in("8x8"),
        intra_in("4x4")
    )
}

fn frame_json(f: &FrameAnalysis) -> serde_json::Value {
    let [skip, inter, intra] = f.kinds();
    json!({
        "frame": f.index, "type": f.frame_type.to_string(), "qp": f.qp, "tool": f.tool,
        "deblock": f.deblock, "deblock_offsets": [f.deblock_offsets.0, f.deblock_offsets.1],
        "luma_filter": f.luma_filter, "bytes": f.bytes,
        "bits_header": f.bits.header, "bits_motion": f.bits.motion, "bits_residual": f.bits.residual,
        "skip_mbs": skip, "inter_mbs": inter, "intra_mbs": intra,
        "grid": f.grid.as_ref().map(|g| json!({
            "spacing": g.spacing(), "cols": g.cols(), "rows": g.rows(),
            "vectors": g.vectors().iter().map(|v| [v.x, v.y]).collect::<Vec<_>>(),
        })),
        "mbs": f.mbs,
    })
}

/// Where the overlay pictures go.
enum Overlay {
    None,
    Pngs(PathBuf),
    Y4m(Box<Y4mWriter<OutputFile>>, PathBuf),
}

impl Overlay {
    fn open(path: Option<&Path>, info: &Y4mInfo) -> Result<Overlay> {
        let Some(path) = path else {
            return Ok(Overlay::None);
        };
        if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("y4m")) {
            let f = OutputFile::create(path).with_context(|| path.display().to_string())?;
            return Ok(Overlay::Y4m(
                Box::new(Y4mWriter::new(f, info)?),
                path.to_path_buf(),
            ));
        }
        std::fs::create_dir_all(path).with_context(|| path.display().to_string())?;
        Ok(Overlay::Pngs(path.to_path_buf()))
    }

    fn push(&mut self, frame: &FrameAnalysis) -> Result<()> {
        if matches!(self, Overlay::None) {
            return Ok(());
        }
        let img = draw_stream_overlay(frame);
        match self {
            Overlay::None => {}
            Overlay::Pngs(dir) => {
                let path = dir.join(format!("frame_{:04}.png", frame.index));
                image::write_rgb(&path, img.width, img.height, &img.data)
                    .with_context(|| path.display().to_string())?;
            }
            Overlay::Y4m(w, _) => {
                let yuv = image::frame_from_rgb(img.width, img.height, &img.data)?;
                w.write_frame(&yuv)?;
            }
        }
        Ok(())
    }

    fn finish(self) -> Result<()> {
        if let Overlay::Y4m(w, path) = self {
            w.into_inner()
                .commit()
                .with_context(|| path.display().to_string())?;
        }
        Ok(())
    }
}
