//! The `mocomp` command line. Each subcommand is a file here; `main.rs` only
//! calls [`main`].

/// `println!` that returns the write's error instead of panicking, so that
/// output into a closed pipe ends the command quietly (see [`main`]).
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*)
    }};
}

mod analyze;
mod compare;
mod decode;
mod encode;
mod flow;
mod flowbench;
mod globalmotion;
mod info;
mod interpolate;
mod matches;
mod me;
mod psnr;
mod rd;
mod samples;
mod segment;
mod stabilize;
mod track;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Motion estimation, optical flow and motion-compensated compression.
#[derive(Debug, Parser)]
#[command(name = "mocomp", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the comparison on the bundled sample (the default).
    Compare(compare::Args),
    /// BD-rate and BD-PSNR between two RD curves from CSV files.
    Bdrate(rd::BdArgs),
    /// Decode a stream to Y4M.
    Decode(decode::Args),
    /// Encode a Y4M into a stream, with rate and quality statistics.
    Encode(encode::Args),
    /// Dense optical flow between two pictures.
    Flow(flow::Args),
    /// Write the flow benchmark: photographs under exactly known motion.
    Flowbench(flowbench::Args),
    /// The camera's motion between frames: one model (translation,
    /// similarity, affine, homography) per pair, robustly fitted.
    #[command(name = "globalmotion")]
    Globalmotion(globalmotion::Args),
    /// Say what a Y4M, .flo or image file holds.
    Info(info::Args),
    /// New frames between each pair from dense flow both ways (slow
    /// motion, frame-rate conversion); --evaluate rebuilds dropped frames.
    Interpolate(interpolate::Args),
    /// Sparse feature matches between two pictures (large displacements).
    Match(matches::Args),
    /// Block motion estimation of each frame against the previous one.
    Me(me::Args),
    /// Rate-distortion sweep: sequences x QPs x predictors, BD tables, plots.
    Rd(rd::Args),
    /// Write the synthetic samples with exact ground-truth flow.
    Samples(samples::Args),
    /// What a stream holds, per frame and macroblock: modes, partitions,
    /// vectors, coded blocks, bits by category; overlays of them.
    Analyze(analyze::Args),
    /// Quality of a Y4M against a reference, per frame and overall: PSNR,
    /// SSIM, and with --metrics MS-SSIM, PSNR-HVS, CIEDE2000, VMAF.
    #[command(name = "quality", visible_alias = "psnr")]
    Psnr(psnr::Args),
    /// Follow corners through a sequence (sparse pyramidal LK).
    Track(track::Args),
    /// What moves against the camera: one PNG mask per frame, from where
    /// the flow departs from the camera's homography.
    Segment(segment::Args),
    /// Stabilise a video: the camera path smoothed (Gaussian or L1-optimal),
    /// each frame warped onto it, cropped so no border shows.
    Stabilize(stabilize::Args),
    /// Add a known camera shake to a still-camera clip (test material).
    Shake(stabilize::ShakeArgs),
    /// Score a stabilised video against its input: cropping, distortion,
    /// stability (Liu et al. 2013) and, with the shake's truth, jitter.
    Stabscore(stabilize::ScoreArgs),
}

/// Parses the command line, runs it, and reports any error on one line of
/// standard error.
pub fn main() -> ExitCode {
    let mut cli = Cli::parse();
    if cli.command.is_none() {
        // No subcommand: the main job, with the defaults clap documents.
        cli = Cli::parse_from(["mocomp", "compare"]);
    }
    let result = match cli.command {
        Some(Command::Compare(a)) => compare::run(&a),
        Some(Command::Bdrate(a)) => rd::run_bdrate(&a),
        Some(Command::Decode(a)) => decode::run(&a),
        Some(Command::Encode(a)) => encode::run(&a),
        Some(Command::Flow(a)) => flow::run(&a),
        Some(Command::Flowbench(a)) => flowbench::run(&a),
        Some(Command::Info(a)) => info::run(&a),
        Some(Command::Interpolate(a)) => interpolate::run(&a),
        Some(Command::Match(a)) => matches::run(&a),
        Some(Command::Me(a)) => me::run(&a),
        Some(Command::Rd(a)) => rd::run(&a),
        Some(Command::Samples(a)) => samples::run(&a),
        Some(Command::Psnr(a)) => psnr::run(&a),
        Some(Command::Analyze(a)) => analyze::run(&a),
        Some(Command::Track(a)) => track::run(&a),
        Some(Command::Globalmotion(a)) => globalmotion::run(&a),
        Some(Command::Segment(a)) => segment::run(&a),
        Some(Command::Stabilize(a)) => stabilize::run(&a),
        Some(Command::Shake(a)) => stabilize::run_shake(&a),
        Some(Command::Stabscore(a)) => stabilize::run_score(&a),
        None => unreachable!("set to compare above"),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("mocomp: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// A rayon pool of `threads` workers (all cores when `None`).
pub(crate) fn thread_pool(threads: Option<usize>) -> anyhow::Result<rayon::ThreadPool> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        anyhow::ensure!(n > 0, "--threads must be at least 1");
        builder = builder.num_threads(n);
    }
    Ok(builder.build()?)
}

/// A reader of our output went away (`mocomp ... | head`): not an error.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}
