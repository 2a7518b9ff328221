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
    /// Evaluate every position of an exhaustive window, one at a time,
    /// instead of skipping those successive elimination rules out or taking
    /// a row's SADs at once (the same vectors, slower: for comparison).
    #[arg(long)]
    pub no_elimination: bool,
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

/// The search `args` ask for.
fn search_config(args: &Args) -> Result<MeConfig> {
    let mut cfg = MeConfig::new(args.method, args.block, args.range);
    cfg.subpel = args.subpel;
    cfg.metric = args.metric;
    cfg.successive_elimination = !args.no_elimination;
    if let Some(qp) = args.qp {
        if qp > 51 {
            bail!("--qp {qp} is above 51");
        }
        cfg.lambda = lambda_for_qp(args.metric, qp);
    }
    Ok(cfg)
}

/// What the run adds up over the frames.
#[derive(Default)]
struct Totals {
    frames: usize,
    search_ms: f64,
    cost_sum: u64,
    pixels: u64,
    epe_sum: f64,
    epe_blocks: usize,
    /// Some ground truth was minus the forward flow.
    approximate_gt: bool,
}

impl Totals {
    fn add_field(&mut self, field: &MotionField, ms: f64) {
        self.search_ms += ms;
        self.frames += 1;
        self.cost_sum += field.costs().iter().map(|&c| u64::from(c)).sum::<u64>();
        self.pixels += (field.cols() * field.rows() * field.block() * field.block()) as u64;
    }

    /// Adds the field's block EPE against frame `t`'s ground truth in `dir`, if there is one.
    fn add_ground_truth(
        &mut self,
        dir: &Path,
        t: usize,
        field: &MotionField,
        (w, h): (usize, usize),
    ) -> Result<()> {
        let Some((gt, exact)) = ground_truth(dir, t)? else {
            return Ok(());
        };
        if (gt.width(), gt.height()) != (w, h) {
            bail!(
                "ground truth for frame {t} is {}x{}, the video {w}x{h}",
                gt.width(),
                gt.height()
            );
        }
        let (s, n) = block_epe(field, &gt);
        self.epe_sum += s;
        self.epe_blocks += n;
        self.approximate_gt |= !exact;
        Ok(())
    }
}

/// One CSV row per block of frame `t`'s field (blocks cut at the picture's edge).
fn write_field_rows(
    out: &mut impl Write,
    t: usize,
    field: &MotionField,
    (w, h): (usize, usize),
) -> Result<()> {
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
    Ok(())
}

pub fn run(args: &Args) -> Result<()> {
    let cfg = search_config(args)?;
    let (first, last) = parse_frames(args.frames.as_deref())?;
    let pool = super::thread_pool(args.threads)?;
    let name = args.input.display().to_string();
    let mut reader = Y4mReader::open(&args.input).with_context(|| name.clone())?;
    let size = (reader.info().width, reader.info().height);
    let mut prev = Frame::new(size.0, size.1)?;
    let mut cur = Frame::new(size.0, size.1)?;
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
    let mut totals = Totals::default();
    let mut prior: Option<MotionField> = None;
    let mut t = 0usize;
    while t <= last && reader.read_frame_into(&mut cur).with_context(|| name.clone())? {
        if t > first {
            let start = Instant::now();
            let field = pool.install(|| estimate_with_prior(cur.y(), prev.y(), &cfg, prior.as_ref()))?;
            totals.add_field(&field, start.elapsed().as_secs_f64() * 1000.0);
            if let Some(out) = csv.as_mut() {
                write_field_rows(out, t, &field, size)?;
            }
            if let Some(dir) = &args.overlay {
                let img = draw_field(cur.y(), &field);
                let path = dir.join(format!("me_{t:04}.png"));
                write_rgb(&path, img.width, img.height, &img.data)
                    .with_context(|| path.display().to_string())?;
            }
            if let Some(dir) = &args.gt {
                totals.add_ground_truth(dir, t, &field, size)?;
            }
            prior = Some(field);
        }
        std::mem::swap(&mut prev, &mut cur);
        t += 1;
    }
    if totals.frames == 0 {
        bail!("no frame pairs to search in {name} (it needs at least two frames in the --frames range)");
    }
    if let Some(out) = csv {
        out.commit().context("writing --mvs")?;
    }
    if args.gt.is_some() && totals.epe_blocks == 0 {
        bail!("--gt: no ground-truth flow files for these frames");
    }
    report(args, &name, &totals, pool.current_num_threads())
}

/// The summary, as text or JSON.
fn report(args: &Args, name: &str, totals: &Totals, threads: usize) -> Result<()> {
    let frames = totals.frames;
    let ms_per_frame = totals.search_ms / frames as f64;
    let mean_cost = totals.cost_sum as f64 / totals.pixels as f64;
    let epe = (totals.epe_blocks > 0).then(|| totals.epe_sum / totals.epe_blocks as f64);
    if args.json {
        let mut obj = json!({
            "frames": frames,
            "ms_per_frame": ms_per_frame,
            "mean_cost": mean_cost,
            "method": args.method.name(),
            "range": args.range,
            "block": args.block,
            "metric": args.metric.name(),
            "threads": threads,
        });
        if let Some(e) = epe {
            obj["epe"] = json!(e);
            obj["epe_from_forward_flow"] = json!(totals.approximate_gt);
        }
        outln!("{obj}")?;
        return Ok(());
    }
    outln!(
        "{name}: {} {}x{} blocks, range {}, {threads} threads",
        args.method,
        args.block,
        args.block,
        args.range
    )?;
    outln!("frames searched      {frames}")?;
    outln!("ME time per frame    {ms_per_frame:.3} ms")?;
    outln!("mean cost per pixel  {mean_cost:.4} ({})", args.metric)?;
    if let Some(e) = epe {
        let note = if totals.approximate_gt {
            " (against minus the forward flow: approximate)"
        } else {
            ""
        };
        outln!("block EPE            {e:.4} px{note}")?;
    }
    Ok(())
}
