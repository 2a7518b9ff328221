//! `mocomp compare` (and `mocomp` with no arguments): the main job. Every
//! predictor at four QPs on the bundled sample: the BD table against
//! `block:esa`, the CSV and the plots in `./mocomp-out/`.

use crate::encode::EncoderConfig;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::rd::{run_sweep, SweepRequest, ALL_PREDICTORS};

/// The bundled sample, relative to the repository root.
const DEFAULT_INPUT: &str = "samples/synth_qcif.y4m";

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input Y4M [default: samples/synth_qcif.y4m].
    pub input: Option<PathBuf>,
    /// Folder for the results.
    #[arg(long, default_value = "mocomp-out")]
    pub out: PathBuf,
    /// QPs, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "22,27,32,37")]
    pub qp: Vec<u8>,
    /// Parallel jobs (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

/// `path` as given if it exists, else relative to the source tree (so the
/// default works from any folder of a checkout).
fn locate(path: &Path) -> PathBuf {
    if path.exists() || path.is_absolute() {
        return path.to_path_buf();
    }
    let in_tree = Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    if in_tree.exists() {
        in_tree
    } else {
        path.to_path_buf()
    }
}

pub fn run(args: &Args) -> Result<()> {
    let input = locate(args.input.as_deref().unwrap_or(Path::new(DEFAULT_INPUT)));
    std::fs::create_dir_all(&args.out).with_context(|| args.out.display().to_string())?;
    let csv = args.out.join("rd.csv");
    let predictors: Vec<String> = ALL_PREDICTORS.split(',').map(String::from).collect();
    let start = std::time::Instant::now();
    let report = run_sweep(&SweepRequest {
        inputs: std::slice::from_ref(&input),
        qps: &args.qp,
        predictors: &predictors,
        frames: None,
        base: EncoderConfig::new(),
        output: &csv,
        json_path: None,
        plot_path: Some(&args.out.join("rd.svg")),
        anchor: Some("block:esa"),
        anchor_csv: None,
        threads: args.threads,
        quiet: false,
        axis: crate::rd::PsnrKind::Mean.into(),
        shard: (1, 1),
    })?
    .context("a whole sweep reports")?;
    let mut stdout = std::io::stdout().lock();
    writeln!(
        stdout,
        "Every predictor at QP {} on {} ({} encodes, {:.1} s).",
        args.qp
            .iter()
            .map(|q| q.to_string())
            .collect::<Vec<_>>()
            .join(", "),
        input.display(),
        report.points.len(),
        start.elapsed().as_secs_f64()
    )?;
    writeln!(stdout, "{}", report.table)?;
    writeln!(
        stdout,
        "Negative BD-rate: fewer bits than block:esa for the same PSNR."
    )?;
    writeln!(stdout, "wrote {}", csv.display())?;
    if let Some(p) = &report.plots {
        for f in p.rd.iter().chain(&p.bits) {
            writeln!(stdout, "wrote {}", f.display())?;
        }
    }
    Ok(())
}
