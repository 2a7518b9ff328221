//! `mocomp flow A.png B.png` (or `mocomp flow IN.y4m --frames 10:11`):
//! dense optical flow, its time, and its errors against ground truth.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use ndarray::Array2;
use serde_json::json;

use crate::flow::consistency::inconsistent;
use crate::flow::warp::warp_bilinear;
use crate::flow::{Flow, FlowEstimator, FlowMethod, FlowOptions, Preset};
use crate::io::{flo, image, y4m::Y4mReader};
use crate::metrics::{flow_errors, psnr_from_mse, FlowErrors};
use crate::raster::{array_to_plane, plane_to_u8_array};
use crate::viz::{draw_flow_arrows, flow_to_rgb};

/// Speed / accuracy trade-offs, as x264 and DIS have them.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// First picture (an image), or a Y4M with --frames.
    pub first: PathBuf,
    /// Second picture (an image; not with a Y4M).
    pub second: Option<PathBuf>,
    /// Write the flow as Middlebury .flo.
    #[arg(short, long, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Method: dis (dense inverse search, the default), lk (dense
    /// pyramidal Lucas-Kanade), hs (Horn-Schunck) or tvl1 (TV-L1).
    #[arg(long)]
    pub method: Option<FlowMethod>,
    /// Settings preset.
    #[arg(long, value_enum, default_value = "medium")]
    pub preset: Preset,
    /// Pyramid levels (overrides the preset).
    #[arg(long)]
    pub levels: Option<usize>,
    /// LK: window standard deviation in pixels (overrides the preset).
    #[arg(long)]
    pub sigma: Option<f32>,
    /// Iterations per level (overrides the preset): Gauss-Newton steps for
    /// LK, the most SOR sweeps per warp for HS.
    #[arg(long)]
    pub iterations: Option<usize>,
    /// HS: smoothness weight alpha (overrides the preset).
    #[arg(long)]
    pub alpha: Option<f32>,
    /// Horn-Schunck's gradient-constancy weight (0 = off, the default):
    /// holds where the lighting changes between the pictures.
    #[arg(long)]
    pub gamma: Option<f32>,
    /// TV-L1's structure-texture split: each level minus its smoothed self,
    /// times this gain (0 = off, the default; 3 where the lighting changes).
    #[arg(long)]
    pub texture: Option<f32>,
    /// HS: warps per level (overrides the preset).
    #[arg(long)]
    pub warps: Option<usize>,
    /// Finest pyramid level computed, 0 = full size (LK and DIS; overrides
    /// the preset).
    #[arg(long)]
    pub finest: Option<usize>,
    /// DIS: also try each patch's exhaustive match at the coarsest level
    /// (reaches motions of a quarter of the picture; see the README).
    #[arg(long)]
    pub global_search: bool,
    /// DIS: also start each patch from the nearest feature match (as the
    /// accurate preset does): motions beyond the pyramid's reach, for the
    /// matching's time (`mocomp match` shows the matches).
    #[arg(long)]
    pub matches: bool,

    /// DIS: compute pictures under about 450 pixels a level finer than the
    /// preset (CIF at half size with fast, full size with medium): about
    /// half the end-point error there for 2-4 times the time, as the
    /// applications use DIS
    #[arg(long)]
    pub fine_on_small: bool,
    /// With a Y4M: the pair A:B of frame indices (from 0).
    #[arg(long, value_name = "A:B", default_value = "0:1")]
    pub frames: String,
    /// Ground-truth .flo: report EPE, AE, R1 and R3 over its valid pixels.
    #[arg(long, value_name = "FILE")]
    pub gt: Option<PathBuf>,
    /// Write the flow in the Middlebury colour coding as PNG.
    #[arg(long, value_name = "FILE")]
    pub viz: Option<PathBuf>,
    /// Write the second picture warped back by the flow as PNG.
    #[arg(long, value_name = "FILE")]
    pub warp: Option<PathBuf>,
    /// Write the first picture with flow arrows (one per 16x16 cell) as PNG.
    #[arg(long, value_name = "FILE")]
    pub arrows: Option<PathBuf>,
    /// Also compute the backward flow with the same method and write the
    /// pixels that fail the forward-backward check (occluded in the second
    /// picture, leaving it, or unreliable) as a PNG mask: 255 there, else 0.
    #[arg(long, value_name = "FILE")]
    pub occlusion: Option<PathBuf>,
    /// Worker threads (default: all cores; 1 for the one-thread comparison).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Compute the flow this many times and report the median time (as the
    /// OpenCV peer script does, median of 5).
    #[arg(long, default_value_t = 1)]
    pub runs: usize,
    /// Compute the flow this many times first, untimed (the buffers'
    /// allocations and first touches of memory; the OpenCV peer script
    /// makes one such call before it times).
    #[arg(long, default_value_t = 0)]
    pub warmup: usize,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

fn read_pair(args: &Args) -> Result<(Array2<u8>, Array2<u8>)> {
    let is_y4m = args.first.extension().is_some_and(|e| e == "y4m") || args.first.as_os_str() == "-";
    if is_y4m {
        if args.second.is_some() {
            bail!("give one Y4M with --frames A:B, or two images");
        }
        let (a, b) = super::me::parse_frames(Some(&args.frames))?;
        let name = args.first.display().to_string();
        let mut reader = Y4mReader::open(&args.first).with_context(|| name.clone())?;
        let (mut fa, mut fb) = (None, None);
        let mut t = 0;
        let mut frame = crate::codec::Frame::new(reader.info().width, reader.info().height)?;
        while reader.read_frame_into(&mut frame).with_context(|| name.clone())? {
            if t == a {
                fa = Some(plane_to_u8_array(frame.y()));
            }
            if t == b {
                fb = Some(plane_to_u8_array(frame.y()));
                break;
            }
            t += 1;
        }
        match (fa, fb) {
            (Some(x), Some(y)) => Ok((x, y)),
            _ => bail!("{name} has no frames {a} and {b} ({t} frames read)"),
        }
    } else {
        let Some(second) = &args.second else {
            bail!("give two pictures, or a Y4M with --frames A:B");
        };
        for p in [&args.first, second] {
            if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("flo")) {
                bail!(
                    "{}: a flow file; mocomp flow takes two pictures or a Y4M (mocomp info reads .flo files)",
                    p.display()
                );
            }
        }
        let read = |p: &PathBuf| image::read_luma(p).with_context(|| p.display().to_string());
        let (a, b) = (read(&args.first)?, read(second)?);
        if (a.width(), a.height()) != (b.width(), b.height()) {
            bail!(
                "the pictures differ in size: {}x{} and {}x{}",
                a.width(),
                a.height(),
                b.width(),
                b.height()
            );
        }
        Ok((plane_to_u8_array(&a), plane_to_u8_array(&b)))
    }
}

/// The flow options `args` give.
fn flow_options(args: &Args) -> FlowOptions {
    FlowOptions {
        method: args.method.unwrap_or_default(),
        preset: args.preset,
        levels: args.levels,
        sigma: args.sigma,
        iterations: args.iterations,
        alpha: args.alpha,
        gamma: args.gamma,
        texture: args.texture,
        warps: args.warps,
        finest: args.finest,
        global_search: args.global_search,
        matches: args.matches,
        fine_on_small: args.fine_on_small,
    }
}

/// The ground truth named by `--gt`, checked against the pictures' size.
fn read_ground_truth(args: &Args, (h, w): (usize, usize)) -> Result<Option<Flow>> {
    let Some(path) = &args.gt else {
        return Ok(None);
    };
    let gt = flo::read_flo(path).with_context(|| path.display().to_string())?;
    if (gt.width(), gt.height()) != (w, h) {
        bail!(
            "ground truth is {}x{}, the pictures {w}x{h}",
            gt.width(),
            gt.height()
        );
    }
    Ok(Some(gt))
}

/// What one run measured.
struct Measured {
    method: FlowMethod,
    ms: f64,
    mc_psnr: f64,
    /// Share of pixels failing the forward-backward check, percent.
    inconsistent: Option<f64>,
    errors: Option<FlowErrors>,
}

pub fn run(args: &Args) -> Result<()> {
    let (p1, p2) = read_pair(args)?;
    let gt = read_ground_truth(args, p1.dim())?;
    if args.runs == 0 {
        bail!("--runs must be at least 1");
    }
    let pool = super::thread_pool(args.threads)?;
    let mut estimator = FlowEstimator::new(&flow_options(args))?;
    // The estimator reads the 8-bit pictures as they were decoded.
    let mut times = Vec::with_capacity(args.runs);
    // One field written over run after run, as a frame loop keeps it.
    let mut flow = Flow::zeros(1, 1);
    for _ in 0..args.warmup {
        pool.install(|| estimator.compute_luma_into((&p1).into(), (&p2).into(), &mut flow));
    }
    for _ in 0..args.runs {
        let start = Instant::now();
        pool.install(|| estimator.compute_luma_into((&p1).into(), (&p2).into(), &mut flow));
        times.push(start.elapsed().as_secs_f64() * 1000.0);
    }
    let mut estimate =
        |a: &Array2<u8>, b: &Array2<u8>| pool.install(|| estimator.compute_luma(a.into(), b.into()));
    times.sort_by(f64::total_cmp);
    let occluded = args
        .occlusion
        .as_ref()
        .map(|_| inconsistent(&flow, &estimate(&p2, &p1)));
    let (i1, i2) = (p1.mapv(f32::from), p2.mapv(f32::from));
    let warped = warp_bilinear(&i2, &flow);
    let mse = i1
        .iter()
        .zip(warped.iter())
        .map(|(&a, &b)| f64::from(a - b).powi(2))
        .sum::<f64>()
        / i1.len() as f64;
    let errors = match &gt {
        Some(gt) => Some(flow_errors(&flow, gt).context("the ground truth has no valid pixel")?),
        None => None,
    };
    write_outputs(args, &flow, &i1, &warped, occluded.as_ref())?;
    let measured = Measured {
        method: estimator.method(),
        ms: times[times.len() / 2],
        mc_psnr: psnr_from_mse(mse),
        inconsistent: occluded
            .as_ref()
            .map(|mask| 100.0 * mask.iter().filter(|&&m| m).count() as f64 / mask.len() as f64),
        errors,
    };
    report(args, &flow, &measured)
}

/// The files the options ask for.
fn write_outputs(
    args: &Args,
    flow: &Flow,
    i1: &Array2<f32>,
    warped: &Array2<f32>,
    occluded: Option<&Array2<bool>>,
) -> Result<()> {
    if let Some(path) = &args.output {
        flo::write_flo(path, flow).with_context(|| path.display().to_string())?;
    }
    if let Some(path) = &args.viz {
        let img = flow_to_rgb(flow, None);
        image::write_rgb(path, img.width, img.height, &img.data)
            .with_context(|| path.display().to_string())?;
    }
    if let Some(path) = &args.arrows {
        let img = draw_flow_arrows(&array_to_plane(i1)?, flow, 16, 2.0);
        image::write_rgb(path, img.width, img.height, &img.data)
            .with_context(|| path.display().to_string())?;
    }
    if let (Some(path), Some(mask)) = (&args.occlusion, occluded) {
        let plane = array_to_plane(&mask.mapv(|m| if m { 255.0 } else { 0.0 }))?;
        image::write_plane(path, &plane).with_context(|| path.display().to_string())?;
    }
    if let Some(path) = &args.warp {
        image::write_plane(path, &array_to_plane(warped)?).with_context(|| path.display().to_string())?;
    }
    Ok(())
}

/// The summary, as text or one JSON object.
fn report(args: &Args, flow: &Flow, m: &Measured) -> Result<()> {
    let mut stdout = std::io::stdout().lock();
    let (ms, mc_psnr) = (m.ms, m.mc_psnr);
    if args.json {
        let mut obj = json!({
            "method": m.method.name(),
            "preset": format!("{:?}", args.preset).to_lowercase(),
            "width": flow.width(),
            "height": flow.height(),
            "ms": ms,
            "mc_psnr": mc_psnr,
        });
        if let Some(share) = m.inconsistent {
            obj["inconsistent_percent"] = json!(share);
        }
        if let Some(e) = &m.errors {
            obj["epe"] = json!(e.epe);
            obj["ae"] = json!(e.ae);
            obj["r1"] = json!(e.r1);
            obj["r3"] = json!(e.r3);
        }
        writeln!(stdout, "{obj}")?;
        return Ok(());
    }
    writeln!(
        stdout,
        "flow ({}x{}, {}, {:?}): {ms:.2} ms",
        flow.width(),
        flow.height(),
        m.method.name(),
        args.preset
    )?;
    writeln!(stdout, "motion-compensated PSNR  {mc_psnr:.2} dB")?;
    if let Some(share) = m.inconsistent {
        writeln!(stdout, "forward-backward inconsistent  {share:.2} %")?;
    }
    if let Some(e) = &m.errors {
        writeln!(
            stdout,
            "EPE {:.4} px  AE {:.3} deg  R1 {:.2} %  R3 {:.2} %",
            e.epe, e.ae, e.r1, e.r3
        )?;
    }
    Ok(())
}
