//! `mocomp me IN.y4m`: block motion of each frame against the previous one.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde_json::json;

use crate::codec::Frame;
use crate::flow::Flow;
use crate::io::{flo, image::write_rgb, y4m::Y4mReader, OutputFile};
use crate::me::{estimate_with_prior, lambda_for_qp, MeConfig, Method, Metric, MotionField, Subpel};
use crate::synth::{backward_flow_name, forward_flow_name};
use crate::viz::draw_field;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input Y4M (`-` for standard input).
    pub input: PathBuf,
    /// Search method: esa, tss, ntss, tdls, fss, ds, hexbs, epzs.
    #[arg(long, default_value = "epzs")]
    pub method: Method,
    /// Search range in pixels, 1..=64.
    #[arg(long, default_value_t = 16)]
    pub range: i32,
    /// Block size: 4, 8, 16 or 32.
    #[arg(long, default_value_t = 16)]
    pub block: usize,
    /// Sub-pel refinement: none, half, quarter.
    #[arg(long, default_value = "none")]
    pub subpel: Subpel,
    /// Cost: sad, ssd, satd.
    #[arg(long, default_value = "sad")]
    pub metric: Metric,
    /// Add the rate term of the codec's vector code at this QP (H.264's lambda).
    #[arg(long)]
    pub qp: Option<u8>,
    /// Frames A:B (inclusive, from 0): frames A+1..=B are searched against their predecessors.
    #[arg(long, value_name = "A:B")]
    pub frames: Option<String>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Write the vectors as CSV: frame,x,y,w,h,dx,dy,cost.
    #[arg(long, value_name = "FILE")]
    pub mvs: Option<PathBuf>,
    /// Write a PNG per frame with the vectors drawn over it.
    #[arg(long, value_name = "DIR")]
    pub overlay: Option<PathBuf>,
    /// Folder of ground-truth flows as `mocomp samples` writes them.
    #[arg(long, value_name = "DIR")]
    pub gt: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Parses `A:B` into an inclusive range of frame indices.
pub(crate) fn parse_frames(spec: Option<&str>) -> Result<(usize, usize)> {
    let Some(spec) = spec else {
        return Ok((0, usize::MAX));
    };
    let (a, b) = spec
        .split_once(':')
        .with_context(|| format!("--frames '{spec}' is not A:B"))?;
    let a: usize = a
        .parse()
        .with_context(|| format!("--frames '{spec}': bad start"))?;
    let b: usize = b.parse().with_context(|| format!("--frames '{spec}': bad end"))?;
    if b <= a {
        bail!("--frames '{spec}': the end must come after the start");
    }
    Ok((a, b))
}

/// The ground truth for the search of frame `t` against `t - 1`: the
/// backward flow of frame `t` if present, else minus the forward flow of
/// frame `t - 1` (exact for translations, approximate otherwise).
fn ground_truth(dir: &Path, t: usize) -> Result<Option<(Flow, bool)>> {
    let backward = dir.join(backward_flow_name(t));
    if backward.exists() {
        return Ok(Some((
            flo::read_flo(&backward).with_context(|| backward.display().to_string())?,
            true,
        )));
    }
    let forward = dir.join(forward_flow_name(t - 1));
    if forward.exists() {
        let f = flo::read_flo(&forward).with_context(|| forward.display().to_string())?;
        let (u, v, valid) = f.into_parts();
        return Ok(Some((Flow::from_parts(-u, -v, valid), false)));
    }
    Ok(None)
}

/// Sum over blocks of |vector - mean true flow over the block's valid
/// pixels|, and the number of blocks with a valid pixel.
fn block_epe(field: &MotionField, gt: &Flow) -> (f64, usize) {
    let (mut sum, mut n) = (0.0, 0);
    let b = field.block();
    for r in 0..field.rows() {
        for c in 0..field.cols() {
            let (mut su, mut sv, mut k) = (0.0f64, 0.0f64, 0usize);
            for y in r * b..((r + 1) * b).min(gt.height()) {
                for x in c * b..((c + 1) * b).min(gt.width()) {
                    if gt.is_valid(x, y) {
                        let (u, v) = gt.get(x, y);
                        su += f64::from(u);
                        sv += f64::from(v);
                        k += 1;
                    }
                }
            }
            if k > 0 {
                let mv = field.vector(c, r);
                let (ex, ey) = (
                    f64::from(mv.x) / 4.0 - su / k as f64,
                    f64::from(mv.y) / 4.0 - sv / k as f64,
                );
                sum += ex.hypot(ey);
                n += 1;
            }
        }
    }
    (sum, n)
}

pub fn run(args: &Args) -> Result<()> {
    let mut cfg = MeConfig::new(args.method, args.block, args.range);
    cfg.subpel = args.subpel;
    cfg.metric = args.metric;
    if let Some(qp) = args.qp {
        if qp > 51 {
            bail!("--qp {qp} is above 51");
        }
        cfg.lambda = lambda_for_qp(args.metric, qp);
    }
    let (first, last) = parse_frames(args.frames.as_deref())?;
    let pool = super::thread_pool(args.threads)?;
    let name = args.input.display().to_string();
    let mut reader = Y4mReader::open(&args.input).with_context(|| name.clone())?;
    let (w, h) = (reader.info().width, reader.info().height);
    let mut prev = Frame::new(w, h)?;
    let mut cur = Frame::new(w, h)?;
    let mut csv = match &args.mvs {
        Some(p) => {
            let mut out = OutputFile::create(p).with_context(|| p.display().to_string())?;
            writeln!(out, "frame,x,y,w,h,dx,dy,cost")?;
            Some(out)
        }
        None => None,
    };
    if let Some(dir) = &args.overlay {
        std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
    }
    let (mut frames, mut search_ms, mut cost_sum, mut pixels) = (0usize, 0.0f64, 0u64, 0u64);
    let (mut epe_sum, mut epe_blocks, mut approximate_gt) = (0.0f64, 0usize, false);
    let mut prior: Option<MotionField> = None;
    let mut t = 0usize;
    let mut have_prev = false;
    while t <= last && reader.read_frame_into(&mut cur).with_context(|| name.clone())? {
        if t > first && have_prev {
            let start = Instant::now();
            let field = pool.install(|| estimate_with_prior(cur.y(), prev.y(), &cfg, prior.as_ref()))?;
            search_ms += start.elapsed().as_secs_f64() * 1000.0;
            frames += 1;
            cost_sum += field.costs().iter().map(|&c| u64::from(c)).sum::<u64>();
            pixels += (field.cols() * field.rows() * field.block() * field.block()) as u64;
            if let Some(out) = csv.as_mut() {
                for r in 0..field.rows() {
                    for c in 0..field.cols() {
                        let (x, y) = (c * field.block(), r * field.block());
                        let (bw, bh) = (field.block().min(w - x), field.block().min(h - y));
                        let v = field.vector(c, r);
                        writeln!(
                            out,
                            "{t},{x},{y},{bw},{bh},{},{},{}",
                            f64::from(v.x) / 4.0,
                            f64::from(v.y) / 4.0,
                            field.cost(c, r)
                        )?;
                    }
                }
            }
            if let Some(dir) = &args.overlay {
                let img = draw_field(cur.y(), &field);
                let path = dir.join(format!("me_{t:04}.png"));
                write_rgb(&path, img.width, img.height, &img.data)
                    .with_context(|| path.display().to_string())?;
            }
            if let Some(dir) = &args.gt {
                if let Some((gt, exact)) = ground_truth(dir, t)? {
                    if (gt.width(), gt.height()) != (w, h) {
                        bail!(
                            "ground truth for frame {t} is {}x{}, the video {w}x{h}",
                            gt.width(),
                            gt.height()
                        );
                    }
                    let (s, n) = block_epe(&field, &gt);
                    epe_sum += s;
                    epe_blocks += n;
                    approximate_gt |= !exact;
                }
            }
            prior = Some(field);
        }
        std::mem::swap(&mut prev, &mut cur);
        have_prev = true;
        t += 1;
    }
    if frames == 0 {
        bail!("no frame pairs to search in {name} (it needs at least two frames in the --frames range)");
    }
    if let Some(out) = csv {
        out.commit().context("writing --mvs")?;
    }
    if args.gt.is_some() && epe_blocks == 0 {
        bail!("--gt: no ground-truth flow files for these frames");
    }
    let ms_per_frame = search_ms / frames as f64;
    let mean_cost = cost_sum as f64 / pixels as f64;
    let epe = (epe_blocks > 0).then(|| epe_sum / epe_blocks as f64);
    if args.json {
        let mut obj = json!({
            "frames": frames,
            "ms_per_frame": ms_per_frame,
            "mean_cost": mean_cost,
            "method": args.method.name(),
            "range": args.range,
            "block": args.block,
            "metric": args.metric.name(),
            "threads": pool.current_num_threads(),
        });
        if let Some(e) = epe {
            obj["epe"] = json!(e);
            obj["epe_from_forward_flow"] = json!(approximate_gt);
        }
        outln!("{obj}")?;
    } else {
        outln!(
            "{name}: {} {}x{} blocks, range {}, {} threads",
            args.method,
            args.block,
            args.block,
            args.range,
            pool.current_num_threads()
        )?;
        outln!("frames searched      {frames}")?;
        outln!("ME time per frame    {ms_per_frame:.3} ms")?;
        outln!("mean cost per pixel  {mean_cost:.4} ({})", args.metric)?;
        if let Some(e) = epe {
            let note = if approximate_gt {
                " (against minus the forward flow: approximate)"
            } else {
                ""
            };
            outln!("block EPE            {e:.4} px{note}")?;
        }
    }
    Ok(())
}
