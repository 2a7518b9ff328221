//! `mocomp rd`: sweeps of sequences x QPs x predictors, with a CSV in the
//! peers' format, BD tables against an anchor, and plots. `mocomp bdrate`:
//! BD figures between two curves from CSV files.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use super::encode::ToolArgs;
use crate::encode::{EncoderConfig, Predictor};
use crate::io::y4m::Y4mReader;
use crate::io::OutputFile;
use crate::metrics::Metric;
use crate::rd::bdrate::{bd_psnr, bd_rate, Fit};
use crate::rd::part::{merge, PartFile};
use crate::rd::{
    compare, markdown, plot::plot, read_csv, write_csv, PsnrKind, QualityAxis, RdPoint, Sequence, Study,
};

/// Every predictor, as `mocomp rd` runs them by default.
pub const ALL_PREDICTORS: &str =
    "zero,block:esa,block:tss,flow-block:lk,flow-block:hs,dense-lk,dense-hs,obmc";

#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct Args {
    #[command(subcommand)]
    pub command: Option<RdCommand>,
    /// Source Y4M files.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// QPs, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "22,27,32,37")]
    pub qp: Vec<u8>,
    /// Predictors, comma-separated (see `mocomp encode --help`).
    #[arg(long, value_delimiter = ',', default_value = ALL_PREDICTORS)]
    pub predictors: Vec<String>,
    /// Code at most this many frames of each sequence.
    #[arg(long)]
    pub frames: Option<usize>,
    /// The CSV to write, a row as each encode ends; a CSV of the same
    /// study already there is resumed (its jobs are not run again).
    #[arg(short, long, default_value = "rd.csv")]
    pub output: PathBuf,
    #[command(flatten)]
    pub report: ReportArgs,
    /// Parallel jobs (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Only errors on the terminal: no progress bar, no table (the CSV,
    /// JSON and plots are still written).
    #[arg(long)]
    pub quiet: bool,
    /// Run only the I-th of N shares of the jobs (the same split on every
    /// machine; merge the CSVs with `mocomp rd merge`).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<Shard>,
    #[command(flatten)]
    pub tools: ToolArgs,
}

/// Reads `FILE.csv[:LABEL]`: the curve's points and its label.
pub fn load_curve(spec: &str) -> Result<(Vec<RdPoint>, String)> {
    // Labels may hold ':' (block:esa): the path is the first prefix before
    // a ':' that names a file.
    let (path, label) = if Path::new(spec).exists() {
        (spec, None)
    } else {
        spec.match_indices(':')
            .map(|(i, _)| (&spec[..i], &spec[i + 1..]))
            .find(|(p, _)| Path::new(p).is_file())
            .map_or((spec, None), |(p, l)| (p, Some(l.to_string())))
    };
    let file = std::fs::File::open(path).with_context(|| path.to_string())?;
    let points = read_csv(std::io::BufReader::new(file)).with_context(|| path.to_string())?;
    let mut codecs: Vec<&str> = points.iter().map(|p| p.codec.as_str()).collect();
    codecs.sort_unstable();
    codecs.dedup();
    let label = match label {
        Some(l) if codecs.contains(&l.as_str()) => l,
        Some(l) => bail!("{path} has no codec '{l}' (it has {})", codecs.join(", ")),
        None if codecs.len() == 1 => codecs[0].to_string(),
        None => bail!(
            "{path} holds several codecs ({}): name one as {path}:CODEC",
            codecs.join(", ")
        ),
    };
    let points = points.into_iter().filter(|p| p.codec == label).collect();
    Ok((points, label))
}

/// Loads the sequences.
fn load(inputs: &[PathBuf], frames: Option<usize>) -> Result<Vec<Sequence>> {
    let mut out = Vec::new();
    for path in inputs {
        let name = path
            .file_stem()
            .map_or("input".into(), |s| s.to_string_lossy().into_owned());
        let mut r = Y4mReader::open(path).with_context(|| path.display().to_string())?;
        let info = r.info().clone();
        let mut list = Vec::new();
        while frames.is_none_or(|n| list.len() < n) {
            match r.read_frame().with_context(|| path.display().to_string())? {
                Some(f) => list.push(f),
                None => break,
            }
        }
        if list.is_empty() {
            bail!("{}: no frames", path.display());
        }
        let fps = (
            u32::try_from(info.fps.0).context("frame rate")?,
            u32::try_from(info.fps.1).context("frame rate")?,
        );
        out.push(Sequence {
            name,
            frames: list,
            fps,
        });
    }
    Ok(out)
}

/// What a sweep made.
pub struct SweepReport {
    pub points: Vec<RdPoint>,
    pub table: String,
    pub plots: Option<crate::rd::plot::PlotFiles>,
}

/// What to sweep and where the results go.
pub struct SweepRequest<'a> {
    pub inputs: &'a [PathBuf],
    pub qps: &'a [u8],
    pub predictors: &'a [String],
    pub frames: Option<usize>,
    /// Every job's configuration but its QP and predictor (a preset and
    /// options).
    pub base: EncoderConfig,
    pub output: &'a Path,
    pub json_path: Option<&'a Path>,
    pub plot_path: Option<&'a Path>,
    /// The anchor predictor; `None`: `block:esa` when it is among the
    /// predictors, else the first (said on standard error).
    pub anchor: Option<&'a str>,
    pub anchor_csv: Option<&'a str>,
    pub threads: Option<usize>,
    pub quiet: bool,
    /// The quality the tables and plots compare.
    pub axis: QualityAxis,
    /// This run's shard and the number of shards (1-based; `(1, 1)`: the
    /// whole sweep).
    pub shard: (usize, usize),
}

/// Fails when `points` (from `what`) lack the quality `axis` asks for.
fn check_axis(points: &[RdPoint], axis: QualityAxis, what: &str) -> Result<()> {
    if !points.iter().any(|p| axis.of(p).is_nan()) {
        return Ok(());
    }
    if axis.metric == Metric::Psnr {
        bail!("{what} has no psnr_y_mse column (peer CSVs hold the mean of frames only): use --psnr mean");
    }
    bail!(
        "{what} has no {} values: sweep with --metrics {} (peer CSVs: measure them with mocomp quality)",
        axis.metric.column(),
        axis.metric.name()
    )
}

/// The anchor among `labels`: `given`, or `block:esa` when it is there,
/// else the first (said on standard error unless `quiet`).
fn anchor_label(given: Option<&str>, labels: &[String], quiet: bool) -> Result<String> {
    let label = match given {
        Some(a) => a.parse::<Predictor>().map_err(anyhow::Error::msg)?.label(),
        None => {
            let esa = "block:esa".to_string();
            let label = if labels.contains(&esa) {
                esa
            } else {
                labels[0].clone()
            };
            if !quiet && label != "block:esa" {
                eprintln!("mocomp: anchor {label} (block:esa is not among the predictors; --anchor chooses)");
            }
            label
        }
    };
    if !labels.contains(&label) {
        bail!(
            "the anchor {label} is not among the predictors ({})",
            labels.join(", ")
        );
    }
    Ok(label)
}

/// Runs a sweep (or the request's shard of it), its rows appended to the
/// output CSV as they come, jobs already there skipped; then, for a whole
/// sweep, the tables, JSON and plots. A shard's report is `None`.
pub fn run_sweep(request: &SweepRequest<'_>) -> Result<Option<SweepReport>> {
    let r = request;
    let predictors: Vec<Predictor> = r
        .predictors
        .iter()
        .map(|s| s.parse::<Predictor>().map_err(anyhow::Error::msg))
        .collect::<Result<_>>()?;
    if r.qps.is_empty() || predictors.is_empty() {
        bail!("nothing to sweep: give at least one QP and one predictor");
    }
    if let Some(q) = r.qps.iter().find(|&&q| q > crate::codec::transform::MAX_QP) {
        bail!("QP {q} is not in 0..=51");
    }
    let labels: Vec<String> = predictors.iter().map(Predictor::label).collect();
    // The anchor is checked before any encode (a shard makes no table).
    let whole = r.shard.1 == 1;
    let anchor = match (r.anchor_csv, whole) {
        (_, false) => None,
        (Some(spec), true) => Some(Anchor::Curve(load_curve(spec)?)),
        (None, true) => Some(Anchor::Predictor(anchor_label(r.anchor, &labels, r.quiet)?)),
    };
    let sequences = load(r.inputs, r.frames)?;
    let study = Study {
        sequences: &sequences,
        qps: r.qps,
        predictors: &predictors,
        base: r.base,
    };
    let points = run_jobs(&study, r)?;
    let Some(anchor) = anchor else {
        return Ok(None);
    };
    // Every job is in: the CSV again in job order, atomically.
    let mut out = OutputFile::create(r.output).with_context(|| r.output.display().to_string())?;
    write_csv(&points, &mut out).with_context(|| r.output.display().to_string())?;
    out.commit().with_context(|| r.output.display().to_string())?;
    report(points, &anchor, r).map(Some)
}

/// The anchor of a sweep's tables.
enum Anchor {
    /// One of the sweep's predictors, by label.
    Predictor(String),
    /// A curve from a CSV: its points and label.
    Curve((Vec<RdPoint>, String)),
}

/// Runs the request's shard of `study` into the output CSV, skipping the
/// jobs already there; returns every row the CSV then holds, in job order.
fn run_jobs(study: &Study<'_>, r: &SweepRequest<'_>) -> Result<Vec<RdPoint>> {
    let (shard, shards) = r.shard;
    let id = study.id();
    let (part, mut points) = PartFile::open(r.output, &id, (shard, shards))?;
    let done: std::collections::HashSet<usize> = points.iter().filter_map(|p| p.job.map(|j| j.0)).collect();
    let mine: Vec<usize> = (0..study.len()).filter(|j| j % shards == shard - 1).collect();
    let todo: Vec<usize> = mine.iter().copied().filter(|j| !done.contains(j)).collect();
    if !r.quiet && todo.len() < mine.len() {
        eprintln!(
            "mocomp: {}: {} of the {} jobs{} are there already; running the other {}",
            r.output.display(),
            mine.len() - todo.len(),
            mine.len(),
            if shards > 1 {
                format!(" of shard {shard}/{shards}")
            } else {
                String::new()
            },
            todo.len()
        );
    }
    let bar = if r.quiet || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        let b = ProgressBar::new(todo.len() as u64);
        b.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} encodes  {elapsed}<{eta}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    };
    let new = std::sync::Mutex::new(Vec::with_capacity(todo.len()));
    let pool = super::thread_pool(r.threads)?;
    pool.install(|| {
        study.run(&id, &todo, |mut p| -> Result<()> {
            p.shard = Some((shard, shards));
            part.append(&p)?;
            new.lock().unwrap_or_else(|e| e.into_inner()).push(p);
            bar.inc(1);
            Ok(())
        })
    })?;
    bar.finish_and_clear();
    points.extend(new.into_inner().unwrap_or_else(|e| e.into_inner()));
    points.sort_by_key(|p| p.job);
    if !r.quiet && shards > 1 {
        println!(
            "shard {shard}/{shards}: {} jobs run, {} rows in {}",
            todo.len(),
            points.len(),
            r.output.display()
        );
    }
    Ok(points)
}

/// The tables, JSON and plots of a whole sweep's `points`.
fn report(points: Vec<RdPoint>, anchor: &Anchor, r: &SweepRequest<'_>) -> Result<SweepReport> {
    let (anchor_points, anchor_name) = match anchor {
        Anchor::Curve((p, l)) => (p.clone(), l.clone()),
        Anchor::Predictor(l) => (points.clone(), l.clone()),
    };
    check_axis(&anchor_points, r.axis, "the anchor")?;
    check_axis(&points, r.axis, "the sweep")?;
    let rows = compare(&points, &anchor_points, &anchor_name, r.axis);
    let table = markdown(&rows, &anchor_name);
    if let Some(path) = r.json_path {
        let mut f = OutputFile::create(path).with_context(|| path.display().to_string())?;
        let v = json!({ "anchor": anchor_name, "points": points, "comparison": rows });
        writeln!(f, "{}", serde_json::to_string_pretty(&v)?)?;
        f.commit().with_context(|| path.display().to_string())?;
    }
    let plots = match r.plot_path {
        Some(path) => {
            let mut names: Vec<&str> = Vec::new();
            for p in &points {
                if !names.contains(&p.sequence.as_str()) {
                    names.push(&p.sequence);
                }
            }
            Some(plot(&points, path, &names.join(", "), r.axis).context("plotting")?)
        }
        None => None,
    };
    Ok(SweepReport { points, table, plots })
}

pub fn run(args: &Args) -> Result<()> {
    if let Some(RdCommand::Merge(m)) = &args.command {
        return run_merge(m);
    }
    // A BD table on a metric measures it (x264's --ssim is implied by
    // --tune ssim in the same way).
    let metric = args.report.bd_metric;
    let mut base = args.tools.configure(&[])?;
    base.metrics = base.metrics.with(metric, true);
    if metric == Metric::Vmaf && crate::metrics::vmaf::ffmpeg_with_libvmaf().is_none() {
        bail!(crate::metrics::vmaf::VmafError::NoLibvmaf);
    }
    let report = run_sweep(&SweepRequest {
        inputs: &args.inputs,
        qps: &args.qp,
        predictors: &args.predictors,
        frames: args.frames,
        base,
        output: &args.output,
        json_path: args.report.json.as_deref(),
        plot_path: args.report.plot.as_deref(),
        anchor: args.report.anchor.as_deref(),
        anchor_csv: args.report.anchor_csv.as_deref(),
        threads: args.threads,
        quiet: args.quiet,
        axis: args.report.axis(),
        shard: args.shard.map_or((1, 1), |s| (s.index, s.count)),
    })?;
    match report {
        Some(report) if !args.quiet => print_report(&report, &args.output),
        _ => Ok(()),
    }
}

/// The table and the files written.
fn print_report(report: &SweepReport, csv: &Path) -> Result<()> {
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "{}", report.table.trim_start())?;
    writeln!(stdout, "\nwrote {}", csv.display())?;
    if let Some(p) = &report.plots {
        for f in p.rd.iter().chain(&p.bits) {
            writeln!(stdout, "wrote {}", f.display())?;
        }
    }
    Ok(())
}

/// `I/N`: the I-th (1-based) of N shares of a sweep's jobs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Shard, String> {
        let bad = || format!("'{s}' is not a shard: I/N with 1 <= I <= N");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (i.parse().map_err(|_| bad())?, n.parse().map_err(|_| bad())?);
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

#[derive(Debug, clap::Subcommand)]
pub enum RdCommand {
    /// Merge the CSVs that the shards of one study wrote into one, with
    /// the tables and plots of an unsharded run.
    Merge(MergeArgs),
}

#[derive(Debug, clap::Args)]
pub struct MergeArgs {
    /// The shards' CSVs.
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// The merged CSV.
    #[arg(short, long, default_value = "rd.csv")]
    pub output: PathBuf,
    #[command(flatten)]
    pub report: ReportArgs,
    /// Only errors on the terminal.
    #[arg(long)]
    pub quiet: bool,
}

/// The tables' and reports' options, of `rd` and `rd merge` alike.
#[derive(Debug, clap::Args)]
pub struct ReportArgs {
    /// Also write the points and the comparison as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Plot the RD curves to this SVG (a PNG beside it, and `_bits` plots
    /// of the bit split).
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// The predictor the others are compared with [default: block:esa
    /// when it is among the predictors, else the first].
    #[arg(long, conflicts_with = "anchor_csv")]
    pub anchor: Option<String>,
    /// A CSV in the peer format (e.g. from rd_ffmpeg.sh) as the anchor:
    /// `FILE.csv:CODEC`, or `FILE.csv` when it holds one codec.
    #[arg(long, value_name = "FILE.csv[:CODEC]")]
    pub anchor_csv: Option<String>,
    /// Which luma PSNR the tables compare: the mean over frames of each
    /// frame's (psnr_y) or that of the mean MSE (psnr_y_mse).
    #[arg(long, default_value = "mean")]
    pub psnr: PsnrKind,
    /// The quality metric of the BD tables and plots: psnr, ssim, ms-ssim,
    /// psnr-hvs, ciede2000, vmaf (SSIM and MS-SSIM in dB,
    /// -10 log10(1 - x), as AWCY); the sweep measures it (no need to add
    /// it to --metrics).
    #[arg(long, default_value = "psnr", value_name = "METRIC")]
    pub bd_metric: Metric,
}

impl ReportArgs {
    fn axis(&self) -> QualityAxis {
        QualityAxis {
            metric: self.bd_metric,
            psnr: self.psnr,
        }
    }
}

/// `mocomp rd merge`.
fn run_merge(m: &MergeArgs) -> Result<()> {
    let points = merge(&m.parts)?;
    let mut labels: Vec<String> = Vec::new();
    for p in &points {
        if !labels.contains(&p.codec) {
            labels.push(p.codec.clone());
        }
    }
    let anchor = match &m.report.anchor_csv {
        Some(spec) => Anchor::Curve(load_curve(spec)?),
        None => Anchor::Predictor(anchor_label(m.report.anchor.as_deref(), &labels, m.quiet)?),
    };
    let mut out = OutputFile::create(&m.output).with_context(|| m.output.display().to_string())?;
    write_csv(&points, &mut out).with_context(|| m.output.display().to_string())?;
    out.commit().with_context(|| m.output.display().to_string())?;
    let request = SweepRequest {
        inputs: &[],
        qps: &[],
        predictors: &[],
        frames: None,
        base: EncoderConfig::new(),
        output: &m.output,
        json_path: m.report.json.as_deref(),
        plot_path: m.report.plot.as_deref(),
        anchor: None,
        anchor_csv: None,
        threads: None,
        quiet: m.quiet,
        axis: m.report.axis(),
        shard: (1, 1),
    };
    let report = report(points, &anchor, &request)?;
    if m.quiet {
        return Ok(());
    }
    print_report(&report, &m.output)
}

#[derive(Debug, clap::Args)]
pub struct BdArgs {
    /// The anchor curve: `FILE.csv[:CODEC]` (peer format).
    pub anchor: String,
    /// The test curve: `FILE.csv[:CODEC]`.
    pub test: String,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Which luma PSNR: the mean over frames (psnr_y) or that of the mean
    /// MSE (psnr_y_mse).
    #[arg(long, default_value = "mean")]
    pub psnr: PsnrKind,
    /// The quality metric: psnr, ssim, ms-ssim, psnr-hvs, ciede2000, vmaf
    /// (similarities in dB, -10 log10(1 - x)).
    #[arg(long, default_value = "psnr", value_name = "METRIC")]
    pub metric: Metric,
}

/// `bd_rate` or `bd_psnr`.
type BdFn = fn(&[(f64, f64)], &[(f64, f64)], Fit) -> Result<f64, crate::rd::bdrate::BdError>;

pub fn run_bdrate(args: &BdArgs) -> Result<()> {
    let (a, an) = load_curve(&args.anchor)?;
    let (t, tn) = load_curve(&args.test)?;
    let axis = QualityAxis {
        metric: args.metric,
        psnr: args.psnr,
    };
    check_axis(&a, axis, &an)?;
    check_axis(&t, axis, &tn)?;
    let xy = |p: &[RdPoint]| p.iter().map(|p| (p.kbps, axis.of(p))).collect::<Vec<_>>();
    let (a, t) = (xy(&a), xy(&t));
    let fig = |f: BdFn, fit| f(&a, &t, fit).map_err(|e| anyhow::anyhow!("{tn} against {an}: {e}"));
    let (rc, rp) = (fig(bd_rate, Fit::Cubic)?, fig(bd_rate, Fit::Pchip)?);
    let (pc, pp) = (fig(bd_psnr, Fit::Cubic)?, fig(bd_psnr, Fit::Pchip)?);
    let mut stdout = std::io::stdout().lock();
    if args.json {
        // bd_psnr_*: the BD-quality on the chosen metric (the key keeps
        // its name so that scripts reading PSNR figures go on working).
        let v = json!({
            "anchor": an, "test": tn, "metric": axis.metric.name(),
            "bd_rate_cubic": rc, "bd_rate_pchip": rp,
            "bd_psnr_cubic": pc, "bd_psnr_pchip": pp,
        });
        writeln!(stdout, "{v}")?;
    } else {
        let (bd, unit) = (axis.bd_name(), axis.metric.unit());
        writeln!(stdout, "{tn} against {an} ({}):", axis.label())?;
        writeln!(stdout, "  BD-rate  cubic {rc:+.3} %   pchip {rp:+.3} %")?;
        writeln!(stdout, "  {bd}  cubic {pc:+.4}{unit}  pchip {pp:+.4}{unit}")?;
    }
    Ok(())
}
