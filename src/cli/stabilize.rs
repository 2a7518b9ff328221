//! `mocomp stabilize IN.y4m -o OUT.y4m`: the camera path smoothed and each
//! frame warped onto it; `mocomp shake` adds a known shake to a
//! still-camera clip; `mocomp stabscore` scores any stabiliser's output.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde_json::json;

use crate::codec::Frame;
use crate::flow::Preset;
use crate::global::sources::Source;
use crate::global::Model;
use crate::io::y4m::{Y4mReader, Y4mWriter};
use crate::io::OutputFile;
use crate::stabilize::path::Pose;
use crate::stabilize::quality::{QualityMeter, QualityReport};
use crate::stabilize::shake::{offsets, output_size, shaken, ShakeParams};
use crate::stabilize::{plan, FrameWarper, MotionTrack, Plan, Smoothing, StabilizeParams, Zoom};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input Y4M (a file: it is read twice).
    pub input: PathBuf,
    /// Output Y4M.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Gaussian smoothing: frames either side (vid.stab's `smoothing`).
    #[arg(long, default_value_t = 10)]
    pub smoothing: usize,
    /// The L1-optimal path (Grundmann et al. 2011) instead of Gaussian
    /// smoothing: still where possible, then constant velocity.
    #[arg(long)]
    pub l1: bool,
    /// `auto` (the least fixed zoom hiding the border), `adaptive`
    /// (per frame, smooth) or a fixed zoom (1: none).
    #[arg(long, default_value = "auto")]
    pub zoom: String,
    /// The largest zoom `auto` and `adaptive` may use.
    #[arg(long, default_value_t = 1.5)]
    pub max_zoom: f64,
    /// With `--zoom auto`: the share of frames whose border the zoom
    /// hides (about what vid.stab's optzoom=1 hides); elsewhere the output
    /// frame before fills it. 1: no border in any frame.
    #[arg(long, default_value_t = 0.75)]
    pub coverage: f64,
    /// Camera model: translation or similarity.
    #[arg(long, default_value = "similarity")]
    pub model: Model,
    /// Motion from auto (block vectors, flow where they fit no motion),
    /// blocks, flow (DIS) or matches.
    #[arg(long, default_value = "auto")]
    pub source: Source,
    /// Flow preset (with --source flow, and auto's).
    #[arg(long, default_value = "ultrafast")]
    pub preset: Preset,
    /// Print the quality figures (cropping, distortion, stability) of the
    /// output.
    #[arg(long)]
    pub report: bool,
    /// With --report: the shake's truth (from `mocomp shake --truth`) for
    /// the residual jitter.
    #[arg(long, value_name = "CSV")]
    pub shake: Option<PathBuf>,
    /// Write the camera path and the smoothed one, one row per frame.
    #[arg(long, value_name = "CSV")]
    pub path: Option<PathBuf>,
    /// Plot the camera's horizontal and vertical path and the smoothed
    /// ones (PNG for a .png name, SVG otherwise).
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
}

fn params(args: &Args) -> Result<StabilizeParams> {
    let zoom = match args.zoom.as_str() {
        "auto" => Zoom::Auto,
        "adaptive" => Zoom::Adaptive,
        z => Zoom::Fixed(
            z.parse()
                .with_context(|| format!("--zoom {z}: auto, adaptive or a number"))?,
        ),
    };
    Ok(StabilizeParams {
        model: args.model,
        smoothing: if args.l1 {
            Smoothing::L1
        } else {
            Smoothing::Gaussian(args.smoothing)
        },
        zoom,
        max_zoom: args.max_zoom,
        coverage: args.coverage,
        source: args.source,
        preset: args.preset,
        ..StabilizeParams::default()
    })
}

pub fn run(args: &Args) -> Result<()> {
    let params = params(args)?;
    let name = args.input.display().to_string();
    let start = Instant::now();
    let mut track = MotionTrack::new(&params)?;
    let mut reader = Y4mReader::open(&args.input).with_context(|| name.clone())?;
    let info = reader.info().clone();
    let mut frame = Frame::new(info.width, info.height)?;
    while reader.read_frame_into(&mut frame).with_context(|| name.clone())? {
        track.push(frame.y())?;
    }
    if track.motions().is_empty() && reader.frames_read() == 0 {
        bail!("{name} has no frames");
    }
    let plan = plan(track.motions(), info.width, info.height, &params)?;
    let motion_s = start.elapsed().as_secs_f64();
    write_output(args, &info, &plan)?;
    let total_s = start.elapsed().as_secs_f64();
    if let Some(path) = &args.path {
        write_path(path, &plan)?;
    }
    if let Some(file) = &args.plot {
        plot_path(file, &plan, &name)?;
    }
    outln!(
        "{name}: {} frames, zoom {:.3}{}, motion {:.1} ms/frame, total {:.1} ms/frame",
        plan.warps.len(),
        plan.zoom.iter().copied().fold(1.0, f64::max),
        if matches!(params.zoom, Zoom::Adaptive) {
            " (largest)"
        } else {
            ""
        },
        motion_s * 1000.0 / plan.warps.len() as f64,
        total_s * 1000.0 / plan.warps.len() as f64
    )?;
    if args.report {
        let truth = args.shake.as_deref().map(read_truth).transpose()?;
        let report = score(&args.input, &args.output, truth.as_deref())?;
        print_report(&report, false)?;
    }
    Ok(())
}

/// The second pass: every frame read again and warped.
fn write_output(args: &Args, info: &crate::io::y4m::Y4mInfo, plan: &Plan) -> Result<()> {
    let name = args.input.display().to_string();
    let mut reader = Y4mReader::open(&args.input).with_context(|| name.clone())?;
    let out_name = args.output.display().to_string();
    let mut out = OutputFile::create(&args.output).with_context(|| out_name.clone())?;
    {
        let mut writer = Y4mWriter::new(&mut out, info)?;
        let mut frame = Frame::new(info.width, info.height)?;
        let mut warper = FrameWarper::default();
        for warp in &plan.warps {
            if !reader.read_frame_into(&mut frame).with_context(|| name.clone())? {
                bail!("{name} changed while it was read");
            }
            writer.write_frame(warper.warp(&frame, warp))?;
        }
    }
    out.commit().with_context(|| out_name)
}

fn write_path(path: &Path, plan: &Plan) -> Result<()> {
    let mut out = OutputFile::create(path).with_context(|| path.display().to_string())?;
    writeln!(
        out,
        "frame,x,y,angle_deg,scale,smooth_x,smooth_y,smooth_angle_deg,smooth_scale,zoom"
    )?;
    for (t, ((c, s), z)) in plan.camera.iter().zip(&plan.smoothed).zip(&plan.zoom).enumerate() {
        writeln!(
            out,
            "{t},{:.4},{:.4},{:.5},{:.6},{:.4},{:.4},{:.5},{:.6},{z:.5}",
            c.x,
            c.y,
            c.angle.to_degrees(),
            c.log_scale.exp(),
            s.x,
            s.y,
            s.angle.to_degrees(),
            s.log_scale.exp()
        )?;
    }
    out.commit().with_context(|| path.display().to_string())
}

/// The camera path's x and y and the smoothed ones against the frame.
fn plot_path(file: &Path, plan: &Plan, name: &str) -> Result<()> {
    let line = |f: &dyn Fn(&Pose) -> f64, poses: &[Pose]| -> Vec<(f64, f64)> {
        poses.iter().enumerate().map(|(t, p)| (t as f64, f(p))).collect()
    };
    let series = vec![
        ("camera x".to_string(), line(&|p| p.x, &plan.camera)),
        ("smoothed x".to_string(), line(&|p| p.x, &plan.smoothed)),
        ("camera y".to_string(), line(&|p| p.y, &plan.camera)),
        ("smoothed y".to_string(), line(&|p| p.y, &plan.smoothed)),
    ];
    let short = Path::new(name)
        .file_name()
        .map_or(name.into(), |n| n.to_string_lossy());
    let title = format!("{short}: camera path and the smoothed one");
    crate::rd::plot::plot_lines(file, &title, ("frame", "pixels"), &series)
        .with_context(|| file.display().to_string())
}

/// The quality figures of `output` as a stabilisation of `input`.
fn score(input: &Path, output: &Path, truth: Option<&[Pose]>) -> Result<QualityReport> {
    let (a, b) = (input.display().to_string(), output.display().to_string());
    let mut ra = Y4mReader::open(input).with_context(|| a.clone())?;
    let mut rb = Y4mReader::open(output).with_context(|| b.clone())?;
    let (w, h) = (ra.info().width, ra.info().height);
    if (rb.info().width, rb.info().height) != (w, h) {
        bail!(
            "{a} is {w}x{h} but {b} is {}x{}",
            rb.info().width,
            rb.info().height
        );
    }
    let (mut fa, mut fb) = (Frame::new(w, h)?, Frame::new(w, h)?);
    let mut meter = QualityMeter::new();
    while ra.read_frame_into(&mut fa).with_context(|| a.clone())? {
        if !rb.read_frame_into(&mut fb).with_context(|| b.clone())? {
            break;
        }
        meter.push(fa.y(), fb.y())?;
    }
    if ra.frames_read() == 0 {
        bail!("{a} has no frames to score");
    }
    Ok(meter.finish(w, h, truth))
}

fn print_report(r: &QualityReport, as_json: bool) -> Result<()> {
    if as_json {
        outln!("{}", json!(r))?;
        return Ok(());
    }
    if r.fitted == 0 {
        outln!("no frame of the output could be matched to its input: no cropping or distortion")?;
    }
    outln!(
        "cropping {:.4}  distortion {:.4}  stability {:.4} (shift {:.4}, rotation {:.4}) over {} frames",
        r.cropping,
        r.distortion,
        r.stability,
        r.stability_translation,
        r.stability_rotation,
        r.frames
    )?;
    if let (Some(j), Some(i)) = (r.jitter, r.input_jitter) {
        outln!("residual jitter {j:.3} px/frame (the shake itself: {i:.3})")?;
    }
    Ok(())
}

/// `mocomp stabscore INPUT.y4m OUTPUT.y4m`.
#[derive(Debug, clap::Args)]
pub struct ScoreArgs {
    /// The video before stabilisation.
    pub input: PathBuf,
    /// The stabilised video (the same size and frame count).
    pub output: PathBuf,
    /// The shake's truth (from `mocomp shake --truth`) for the jitter.
    #[arg(long, value_name = "CSV")]
    pub shake: Option<PathBuf>,
    /// One JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run_score(args: &ScoreArgs) -> Result<()> {
    let truth = args.shake.as_deref().map(read_truth).transpose()?;
    let report = score(&args.input, &args.output, truth.as_deref())?;
    print_report(&report, args.json)
}

/// `mocomp shake IN.y4m -o OUT.y4m`.
#[derive(Debug, clap::Args)]
pub struct ShakeArgs {
    /// A still-camera clip.
    pub input: PathBuf,
    /// The shaken clip (smaller: the margin the shake needs is cut).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Largest shift of a frame, pixels (each axis).
    #[arg(long, default_value_t = 12.0)]
    pub translation: f64,
    /// Largest rotation, degrees.
    #[arg(long, default_value_t = 1.5)]
    pub rotation: f64,
    /// Seed of the random offsets.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write each frame's offset: frame,dx,dy,angle_deg.
    #[arg(long, value_name = "CSV")]
    pub truth: Option<PathBuf>,
}

pub fn run_shake(args: &ShakeArgs) -> Result<()> {
    let p = ShakeParams {
        translation: args.translation,
        rotation: args.rotation,
        seed: args.seed,
    };
    if !(p.translation.is_finite()
        && p.translation >= 0.0
        && p.rotation.is_finite()
        && p.rotation.abs() <= 30.0)
    {
        bail!("--translation must be >= 0 and --rotation within 30 degrees");
    }
    let name = args.input.display().to_string();
    let frames = Y4mReader::open(&args.input)
        .with_context(|| name.clone())?
        .read_all()?;
    let Some(first) = frames.first() else {
        bail!("{name} has no frames");
    };
    let (w, h) = output_size(first.width(), first.height(), &p);
    let poses = offsets(frames.len(), &p);
    let info = crate::io::y4m::Y4mInfo::new(w, h, Y4mReader::open(&args.input)?.info().fps);
    let out_name = args.output.display().to_string();
    let mut out = OutputFile::create(&args.output).with_context(|| out_name.clone())?;
    {
        let mut writer = Y4mWriter::new(&mut out, &info)?;
        for (f, pose) in frames.iter().zip(&poses) {
            writer.write_frame(&shaken(f, pose, w, h))?;
        }
    }
    out.commit().with_context(|| out_name)?;
    if let Some(path) = &args.truth {
        write_truth(path, &poses)?;
    }
    outln!("{name}: {} frames shaken into {w}x{h}", frames.len())?;
    Ok(())
}

fn write_truth(path: &Path, poses: &[Pose]) -> Result<()> {
    let mut out = OutputFile::create(path).with_context(|| path.display().to_string())?;
    writeln!(out, "frame,dx,dy,angle_deg")?;
    for (t, p) in poses.iter().enumerate() {
        writeln!(out, "{t},{:.6},{:.6},{:.8}", p.x, p.y, p.angle.to_degrees())?;
    }
    out.commit().with_context(|| path.display().to_string())
}

fn read_truth(path: &Path) -> Result<Vec<Pose>> {
    let name = path.display().to_string();
    let mut reader = csv::Reader::from_path(path).with_context(|| name.clone())?;
    let mut poses = Vec::new();
    for row in reader.records() {
        let row = row.with_context(|| name.clone())?;
        let field = |i: usize| -> Result<f64> {
            row.get(i).and_then(|v| v.trim().parse().ok()).with_context(|| {
                format!(
                    "{name}: row {}: column {} is not a number",
                    poses.len() + 1,
                    i + 1
                )
            })
        };
        poses.push(Pose {
            x: field(1)?,
            y: field(2)?,
            angle: field(3)?.to_radians(),
            log_scale: 0.0,
        });
    }
    Ok(poses)
}
