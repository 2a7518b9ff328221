//! `mocomp interpolate IN.y4m -o OUT.y4m --factor 2`: new frames between
//! each pair from dense flow both ways; `--evaluate` rebuilds every other
//! frame from its neighbours and measures it against the original.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde_json::json;

use crate::codec::Frame;
use crate::flow::Preset;
use crate::interpolate::{InterpolateParams, Interpolator, PairMotion};
use crate::io::y4m::{Y4mInfo, Y4mReader, Y4mWriter};
use crate::io::OutputFile;
use crate::metrics::{mse, psnr_from_mse};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input Y4M.
    pub input: PathBuf,
    /// Output Y4M (with --evaluate: the sequence with every other frame
    /// rebuilt; optional there).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Output frames per input frame: input frame k is output frame
    /// factor * k, and the ones after it are at times 1/factor, 2/factor ...
    /// of the way to the next.
    #[arg(long, default_value_t = 2)]
    pub factor: usize,
    /// DIS preset of the flows.
    #[arg(long, default_value = "fast")]
    pub preset: Preset,
    /// Drop every other frame (1, 3, 5 ...), rebuild each from its two
    /// neighbours, and print the rebuilt frames' PSNR against the originals.
    #[arg(long)]
    pub evaluate: bool,
    /// One JSON object instead of text (with --evaluate).
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &Args) -> Result<()> {
    if !(2..=16).contains(&args.factor) {
        bail!("--factor must be 2 to 16");
    }
    let params = InterpolateParams {
        preset: args.preset,
        ..InterpolateParams::default()
    };
    let mut interp = Interpolator::new(&params)?;
    let name = args.input.display().to_string();
    let mut reader = Y4mReader::open(&args.input).with_context(|| name.clone())?;
    let info = reader.info().clone();
    if args.evaluate {
        return evaluate(args, &mut interp, &mut reader, &info);
    }
    let Some(path) = &args.output else {
        bail!("-o OUT.y4m is needed (or --evaluate)");
    };
    let mut out_info = info.clone();
    out_info.fps = (info.fps.0 * args.factor as u64, info.fps.1);
    let out_name = path.display().to_string();
    let mut out = OutputFile::create(path).with_context(|| out_name.clone())?;
    let (start, mut made) = (Instant::now(), 0usize);
    {
        let mut writer = Y4mWriter::new(&mut out, &out_info)?;
        let mut read = || reader.read_frame().with_context(|| name.clone());
        let Some(mut f0) = read()? else {
            bail!("{name} has no frames");
        };
        // Each pair is interpolated once the next pair's motion is known,
        // which bends its paths (`accelerate`); the flows are found once.
        let mut before: Option<PairMotion> = None;
        let mut ahead = read()?.map(|f1| (interp.pair(&f0, &f1), f1));
        while let Some((mut pair, f1)) = ahead.take() {
            ahead = read()?.map(|f2| (interp.pair(&f1, &f2), f2));
            pair.accelerate(before.as_ref(), ahead.as_ref().map(|(p, _)| p));
            writer.write_frame(&f0)?;
            for j in 1..args.factor {
                writer.write_frame(&interp.at(&pair, &f0, &f1, j as f64 / args.factor as f64))?;
                made += 1;
            }
            (before, f0) = (Some(pair), f1);
        }
        writer.write_frame(&f0)?;
    }
    out.commit().with_context(|| out_name)?;
    outln!(
        "{name}: {} frames made, {:.1} ms each",
        made,
        start.elapsed().as_secs_f64() * 1000.0 / made.max(1) as f64
    )?;
    Ok(())
}

/// Frames 1, 3, 5 ... rebuilt from 0 and 2, 2 and 4 ...: their luma PSNR.
fn evaluate(
    args: &Args,
    interp: &mut Interpolator,
    reader: &mut Y4mReader<Box<dyn std::io::Read + Send>>,
    info: &Y4mInfo,
) -> Result<()> {
    let name = args.input.display().to_string();
    let frames: Vec<Frame> = std::iter::from_fn(|| reader.read_frame().transpose())
        .collect::<Result<_, _>>()
        .with_context(|| name.clone())?;
    if frames.len() < 3 {
        bail!(
            "{name}: --evaluate needs at least 3 frames, it has {}",
            frames.len()
        );
    }
    let start = Instant::now();
    let mut rows = Vec::new();
    let mut rebuilt = frames.clone();
    let odd: Vec<usize> = (1..frames.len() - 1).step_by(2).collect();
    let motion = |interp: &mut Interpolator, k: usize| interp.pair(&frames[k - 1], &frames[k + 1]);
    // The kept frames' paths bent through the kept frames either side, as
    // `run` bends them on a whole sequence; three pairs held at a time.
    let (mut before, mut current) = (None, Some(motion(interp, 1)));
    for (i, &k) in odd.iter().enumerate() {
        let Some(mut pair) = current.take() else { break };
        current = odd.get(i + 1).map(|&n| motion(interp, n));
        pair.accelerate(before.as_ref(), current.as_ref());
        let made = interp.at(&pair, &frames[k - 1], &frames[k + 1], 0.5);
        let psnr = psnr_from_mse(mse(frames[k].y(), made.y()));
        rows.push((k, psnr, pair.cut));
        rebuilt[k] = made;
        before = Some(pair);
    }
    let ms = start.elapsed().as_secs_f64() * 1000.0 / rows.len() as f64;
    let mean = rows.iter().map(|r| r.1).sum::<f64>() / rows.len() as f64;
    if let Some(path) = &args.output {
        let out_name = path.display().to_string();
        let mut out = OutputFile::create(path).with_context(|| out_name.clone())?;
        {
            let mut writer = Y4mWriter::new(&mut out, info)?;
            for f in &rebuilt {
                writer.write_frame(f)?;
            }
        }
        out.commit().with_context(|| out_name)?;
    }
    if args.json {
        let per: Vec<_> = rows
            .iter()
            .map(|(k, p, c)| json!({"frame": k, "psnr_y": p, "cut": c}))
            .collect();
        outln!(
            "{}",
            json!({"frames": rows.len(), "mean_psnr_y": mean, "ms_per_frame": ms, "rebuilt": per})
        )?;
        return Ok(());
    }
    outln!(
        "{name}: {} frames rebuilt, mean PSNR-Y {mean:.3} dB, {ms:.1} ms each",
        rows.len()
    )?;
    for (k, p, cut) in rows {
        outln!("{k:5} {p:7.3} dB{}", if cut { "  (cut: repeated)" } else { "" })?;
    }
    Ok(())
}
