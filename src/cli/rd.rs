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
use crate::rd::bdrate::{bd_psnr, bd_rate, Fit};
use crate::rd::{compare, markdown, plot::plot, read_csv, sweep, write_csv, PsnrKind, RdPoint, Sequence};

/// Every predictor, as `mocomp rd` runs them by default.
pub const ALL_PREDICTORS: &str =
    "zero,block:esa,block:tss,flow-block:lk,flow-block:hs,dense-lk,dense-hs,obmc";

#[derive(Debug, clap::Args)]
pub struct Args {
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
    /// The CSV to write.
    #[arg(short, long, default_value = "rd.csv")]
    pub output: PathBuf,
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
    /// Parallel jobs (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Only errors on the terminal: no progress bar, no table (the CSV,
    /// JSON and plots are still written).
    #[arg(long)]
    pub quiet: bool,
    /// Which luma PSNR the tables compare: the mean over frames of each
    /// frame's (psnr_y) or that of the mean MSE (psnr_y_mse).
    #[arg(long, default_value = "mean")]
    pub psnr: PsnrKind,
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
    /// The preset and tools every job's configuration goes through.
    pub tools: &'a (dyn Fn(EncoderConfig) -> EncoderConfig + Sync),
    pub output: &'a Path,
    pub json_path: Option<&'a Path>,
    pub plot_path: Option<&'a Path>,
    /// The anchor predictor; `None`: `block:esa` when it is among the
    /// predictors, else the first (said on standard error).
    pub anchor: Option<&'a str>,
    pub anchor_csv: Option<&'a str>,
    pub threads: Option<usize>,
    pub quiet: bool,
    /// The PSNR the tables compare.
    pub psnr: PsnrKind,
}

/// Fails when `points` (from `what`) lack the PSNR `psnr` asks for.
fn check_psnr(points: &[RdPoint], psnr: PsnrKind, what: &str) -> Result<()> {
    if points.iter().any(|p| psnr.of(p).is_nan()) {
        bail!("{what} has no psnr_y_mse column (peer CSVs hold the mean of frames only): use --psnr mean");
    }
    Ok(())
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

/// Runs a sweep and writes its CSV, JSON and plots.
pub fn run_sweep(request: &SweepRequest<'_>) -> Result<SweepReport> {
    let SweepRequest {
        inputs,
        qps,
        predictors,
        frames,
        tools,
        output,
        json_path,
        plot_path,
        anchor,
        anchor_csv,
        threads,
        quiet,
        psnr,
    } = *request;
    let predictors: Vec<Predictor> = predictors
        .iter()
        .map(|s| s.parse::<Predictor>().map_err(anyhow::Error::msg))
        .collect::<Result<_>>()?;
    if qps.is_empty() || predictors.is_empty() {
        bail!("nothing to sweep: give at least one QP and one predictor");
    }
    if let Some(q) = qps.iter().find(|&&q| q > crate::codec::transform::MAX_QP) {
        bail!("QP {q} is not in 0..=51");
    }
    let labels: Vec<String> = predictors.iter().map(Predictor::label).collect();
    let (anchor_points, anchor_name) = match anchor_csv {
        Some(spec) => {
            let (p, l) = load_curve(spec)?;
            (Some(p), l)
        }
        None => (None, anchor_label(anchor, &labels, quiet)?),
    };
    let sequences = load(inputs, frames)?;
    let jobs = sequences.len() * qps.len() * predictors.len();
    let bar = if quiet || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        let b = ProgressBar::new(jobs as u64);
        b.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} encodes  {elapsed}<{eta}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    };
    let pool = super::thread_pool(threads)?;
    let points = pool.install(|| sweep(&sequences, qps, &predictors, tools, || bar.inc(1)))?;
    bar.finish_and_clear();

    let mut out = OutputFile::create(output).with_context(|| output.display().to_string())?;
    write_csv(&points, &mut out).with_context(|| output.display().to_string())?;
    out.commit().with_context(|| output.display().to_string())?;

    let anchor_points = anchor_points.unwrap_or_else(|| points.clone());
    check_psnr(&anchor_points, psnr, "the anchor")?;
    let rows = compare(&points, &anchor_points, &anchor_name, psnr);
    let table = markdown(&rows, &anchor_name);
    if let Some(path) = json_path {
        let mut f = OutputFile::create(path).with_context(|| path.display().to_string())?;
        let v = json!({ "anchor": anchor_name, "points": points, "comparison": rows });
        writeln!(f, "{}", serde_json::to_string_pretty(&v)?)?;
        f.commit().with_context(|| path.display().to_string())?;
    }
    let plots = match plot_path {
        Some(path) => {
            let names: Vec<&str> = sequences.iter().map(|s| s.name.as_str()).collect();
            Some(plot(&points, path, &names.join(", ")).context("plotting")?)
        }
        None => None,
    };
    Ok(SweepReport { points, table, plots })
}

pub fn run(args: &Args) -> Result<()> {
    let report = run_sweep(&SweepRequest {
        inputs: &args.inputs,
        qps: &args.qp,
        predictors: &args.predictors,
        frames: args.frames,
        tools: &|c| args.tools.apply(c),
        output: &args.output,
        json_path: args.json.as_deref(),
        plot_path: args.plot.as_deref(),
        anchor: args.anchor.as_deref(),
        anchor_csv: args.anchor_csv.as_deref(),
        threads: args.threads,
        quiet: args.quiet,
        psnr: args.psnr,
    })?;
    if args.quiet {
        return Ok(());
    }
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "{}", report.table.trim_start())?;
    writeln!(stdout, "\nwrote {}", args.output.display())?;
    if let Some(p) = &report.plots {
        for f in p.rd.iter().chain(&p.bits) {
            writeln!(stdout, "wrote {}", f.display())?;
        }
    }
    Ok(())
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
}

/// `bd_rate` or `bd_psnr`.
type BdFn = fn(&[(f64, f64)], &[(f64, f64)], Fit) -> Result<f64, crate::rd::bdrate::BdError>;

pub fn run_bdrate(args: &BdArgs) -> Result<()> {
    let (a, an) = load_curve(&args.anchor)?;
    let (t, tn) = load_curve(&args.test)?;
    check_psnr(&a, args.psnr, &an)?;
    check_psnr(&t, args.psnr, &tn)?;
    let xy = |p: &[RdPoint]| p.iter().map(|p| (p.kbps, args.psnr.of(p))).collect::<Vec<_>>();
    let (a, t) = (xy(&a), xy(&t));
    let fig = |f: BdFn, fit| f(&a, &t, fit).map_err(|e| anyhow::anyhow!("{tn} against {an}: {e}"));
    let (rc, rp) = (fig(bd_rate, Fit::Cubic)?, fig(bd_rate, Fit::Pchip)?);
    let (pc, pp) = (fig(bd_psnr, Fit::Cubic)?, fig(bd_psnr, Fit::Pchip)?);
    let mut stdout = std::io::stdout().lock();
    if args.json {
        let v = json!({
            "anchor": an, "test": tn,
            "bd_rate_cubic": rc, "bd_rate_pchip": rp,
            "bd_psnr_cubic": pc, "bd_psnr_pchip": pp,
        });
        writeln!(stdout, "{v}")?;
    } else {
        writeln!(stdout, "{tn} against {an}:")?;
        writeln!(stdout, "  BD-rate  cubic {rc:+.3} %   pchip {rp:+.3} %")?;
        writeln!(stdout, "  BD-PSNR  cubic {pc:+.4} dB  pchip {pp:+.4} dB")?;
    }
    Ok(())
}
