//! `mocomp encode IN.y4m -o OUT.mcv`: a Y4M in, a stream out, and where
//! the bits went.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};

use crate::encode::{
    encode_sequence, EncodeError, EncoderConfig, EncoderPreset, FilterChoice, FlowMethod, FrameSource,
    FrameStats, ModeDecision, Partitions, SequenceInfo, Summary, DEFAULT_IPRATIO,
};
use crate::io::y4m::{Y4mReader, Y4mWriter};
use crate::io::OutputFile;
use crate::me::{Method, Subpel};
use crate::metrics::{vmaf, Metric, Metrics};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The source Y4M (4:2:0, 8 bits; `-` for standard input).
    pub input: PathBuf,
    /// The stream to write.
    #[arg(short, long, value_name = "OUT.mcv")]
    pub output: PathBuf,
    /// Quantisation parameter, 0..=51.
    #[arg(long, default_value_t = 28)]
    pub qp: u8,
    /// P-frame predictor: zero, block, flow-block, dense-lk, dense-hs,
    /// dense-dis, obmc (a `:METHOD` or `:lk|hs|dis` suffix also works).
    #[arg(long, default_value = "block")]
    pub predictor: String,
    /// Block search of `block` and `obmc`: esa, tss, ntss, tdls, fss, ds,
    /// hexbs, epzs.
    #[arg(long, value_name = "METHOD")]
    pub me: Option<Method>,
    /// Full-pel search range of `block` and `obmc`.
    #[arg(long)]
    pub range: Option<i32>,
    /// Sub-pel refinement of `block` and `obmc`: none, half, quarter.
    #[arg(long)]
    pub subpel: Option<Subpel>,
    /// Flow of `flow-block` and `dense-*`: lk, hs or dis.
    #[arg(long)]
    pub flow: Option<FlowMethod>,
    /// `flow-block`: full-pel search radius around the flow's vector (0 =
    /// the flow's vector as it is).
    #[arg(long)]
    pub refine: Option<i32>,
    /// `dense-lk`, `dense-hs`: motion grid spacing, 4, 8 or 16.
    #[arg(long)]
    pub grid: Option<usize>,
    /// I-frame period (0 = only the first frame is intra).
    #[arg(long, default_value_t = 0)]
    pub gop: usize,
    /// Code at most this many frames.
    #[arg(long)]
    pub frames: Option<usize>,
    #[command(flatten)]
    pub tools: ToolArgs,
    /// Also write the reconstruction (what the decoder outputs) as Y4M.
    #[arg(long, value_name = "REC.y4m")]
    pub recon: Option<PathBuf>,
    /// Write per-frame statistics as CSV.
    #[arg(long, value_name = "FILE.csv")]
    pub stats: Option<PathBuf>,
    /// Print the summary as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Only errors on the terminal (and what --json asks for): no
    /// progress bar, no summary.
    #[arg(long)]
    pub quiet: bool,
    /// Worker threads (default: all cores). Two run two frames at once
    /// (frame threads); more decide each frame's rows on a wavefront. The
    /// stream is the same for any number.
    #[arg(long)]
    pub threads: Option<usize>,
}

/// The coding tools' options, the same for every predictor (`mocomp
/// encode` and `mocomp rd` share them).
#[derive(Debug, Clone, clap::Args)]
pub struct ToolArgs {
    /// Speed against compression, as x264's: ultrafast, superfast,
    /// veryfast, faster, fast, medium, slow, slower, each the one before
    /// with tools added (the options below override it).
    #[arg(long, default_value = "medium")]
    pub preset: EncoderPreset,
    /// Multiply the mode-decision lambda `0.85 * 2^((QP - 12) / 3)`
    /// [default: the preset's: 1.4, from fast 1.0].
    #[arg(long)]
    pub lambda_scale: Option<f64>,
    /// No rate-distortion optimised quantisation.
    #[arg(long)]
    pub no_rdoq: bool,
    /// Inter mode decision: fast (the vector with the lower SATD is the
    /// one coded) or full (both coded and compared by SSD + lambda * bits)
    /// [default: the preset's].
    #[arg(long)]
    pub decision: Option<ModeDecision>,
    /// Quantiser step of P frames over I frames (x264's --ipratio): I
    /// frames at QP - 6 log2(ratio).
    #[arg(long, default_value_t = DEFAULT_IPRATIO)]
    pub ipratio: f64,
    /// No in-loop deblocking filter.
    #[arg(long, conflicts_with = "deblock")]
    pub no_deblock: bool,
    /// The deblocking filter's offsets, as x264's `--deblock A:B`: A moves
    /// alpha and tc0 (how large a step is taken for blocking, how far
    /// samples move), B beta (how flat either side must be), each -6..=6;
    /// positive filters more [default: 0:0].
    #[arg(long, value_name = "A:B", allow_hyphen_values = true)]
    pub deblock: Option<String>,
    /// Block P frames deblocked only where the filter lowered the error
    /// of the frames before, on or off (off: every frame deblocked, as
    /// x264 does) [default: on].
    #[arg(long, value_name = "on|off", value_parser = on_off)]
    pub deblock_choice: Option<bool>,
    /// No weighted prediction (P frames scaling and offsetting the
    /// reference where the light changed).
    #[arg(long)]
    pub no_weightp: bool,
    /// References P frames may predict from, 1 to 8, as x264's --ref
    /// (`block` only) [default: the preset's].
    #[arg(long, value_name = "N")]
    pub refs: Option<u8>,
    /// Older references searched only while they saved enough in the
    /// frames before (the medium preset's), on or off (off: every
    /// reference in every frame) [default: the preset's].
    #[arg(long, value_name = "on|off", value_parser = on_off)]
    pub refs_choice: Option<bool>,
    /// Sub-pel RD refinement on or off, as x264's --subme 8 (`block`
    /// only; the slow preset has it on) [default: the preset's].
    #[arg(long, value_name = "on|off", value_parser = on_off)]
    pub subpel_rd: Option<bool>,
    /// Splits (16x8, 8x16, 8x8) searched and coded where their estimate is
    /// within 5/4 of the whole macroblock's, on or off (off: only below
    /// it; the slower preset has it on) [default: the preset's].
    #[arg(long, value_name = "on|off", value_parser = on_off)]
    pub split_margin: Option<bool>,
    /// Splits searched where their candidates alone come within 1.1 of the
    /// whole macroblock's estimate, on or off (off: only below it; from
    /// the slow preset on; where --split-margin is on, its 5/4 stands
    /// instead) [default: the preset's].
    #[arg(long, value_name = "on|off", value_parser = on_off)]
    pub split_search_margin: Option<bool>,
    /// Chroma priced beside luma in the search's sub-pel steps, on or off,
    /// as x264's chroma motion estimation (`block` only) [default: the
    /// preset's].
    #[arg(long, value_name = "on|off", value_parser = on_off)]
    pub chroma_me: Option<bool>,
    /// The mode decision's residual prices adapting through each P frame,
    /// on or off (off: priced with the contexts the frame starts from;
    /// `block` only) [default: the preset's: on from medium].
    #[arg(long, value_name = "on|off", value_parser = on_off)]
    pub adaptive_pricing: Option<bool>,
    /// No fast P-skip (x264's --no-fast-pskip): every P-frame macroblock
    /// tries its other modes even where skipping it would code no level.
    #[arg(long)]
    pub no_fast_pskip: bool,
    /// Fast P-skip probed before the motion search too beside a skipped left
    /// or upper neighbour, saving the search (x264's rule below --subme 3;
    /// beside one, only a skip that leaves little error) [default: the
    /// preset's].
    #[arg(long, value_name = "on|off", value_parser = on_off)]
    pub early_pskip: Option<bool>,
    /// No 8x8 transform (x264's --no-8x8dct): luma in 4x4 transforms only
    /// (no 8x8 intra either).
    #[arg(long = "no-8x8dct")]
    pub no_8x8dct: bool,
    /// Luma interpolation of `block` P frames: auto (per frame, from how
    /// the two filters predicted the frames before), sharp (HEVC's 8-tap)
    /// or smooth (H.264's 6-tap shape) [default: auto].
    #[arg(long, value_name = "auto|sharp|smooth")]
    pub luma_filter: Option<FilterChoice>,
    /// P frames' macroblock partitions, as x264's --partitions: all, none,
    /// or a list of p8x8 (16x8, 8x16 and 8x8 inter partitions), i8x8
    /// (intra luma in 8x8 blocks, with the 8x8 transform on) and i4x4
    /// (intra luma in 4x4 blocks) [default: the preset's]. As in x264, I
    /// frames' intra blocks are set apart (`--i-partitions`).
    #[arg(long, value_name = "all|none|p8x8,i8x8,i4x4")]
    pub partitions: Option<Partitions>,
    /// I frames' intra blocks: all, none (16x16 intra only, as x264's
    /// ultrafast), or a list of i8x8 (with the 8x8 transform on) and i4x4
    /// [default: the preset's].
    #[arg(long, value_name = "all|none|i8x8,i4x4")]
    pub i_partitions: Option<Partitions>,
    /// Quality metrics to measure, comma-separated: psnr, ssim, ms-ssim,
    /// psnr-hvs, ciede2000, vmaf (through an ffmpeg built with libvmaf), or
    /// all (all but vmaf); none for no measurement at all (as x264 without
    /// --psnr: the encode's time alone). PSNR is measured unless none.
    #[arg(long, default_value = "psnr,ssim", value_name = "LIST")]
    pub metrics: Metrics,
}

impl ToolArgs {
    /// The options given, by the names [`EncoderConfig::set`] takes, in
    /// the order they apply (after the preset).
    fn options(&self) -> Vec<(&'static str, String)> {
        let on = |b: bool| if b { "on" } else { "off" }.to_string();
        let mut o = vec![
            ("ipratio", self.ipratio.to_string()),
            ("metrics", self.metrics.to_string()),
        ];
        o.extend(self.lambda_scale.map(|l| ("lambda-scale", l.to_string())));
        o.extend(self.decision.map(|d| ("decision", d.name().to_string())));
        o.extend(self.no_rdoq.then(|| ("rdoq", on(false))));
        o.extend(self.no_deblock.then(|| ("deblock", on(false))));
        o.extend(self.deblock.clone().map(|d| ("deblock", d)));
        o.extend(self.deblock_choice.map(|b| ("deblock-choice", on(b))));
        o.extend(self.no_weightp.then(|| ("weightp", on(false))));
        o.extend(self.no_8x8dct.then(|| ("8x8dct", on(false))));
        o.extend(self.no_fast_pskip.then(|| ("fast-pskip", on(false))));
        o.extend(self.early_pskip.map(|b| ("early-pskip", on(b))));
        o.extend(self.partitions.map(|p| ("partitions", p.to_string())));
        o.extend(self.i_partitions.map(|p| ("i-partitions", p.to_string())));
        o.extend(self.refs.map(|n| ("refs", n.to_string())));
        o.extend(self.refs_choice.map(|b| ("refs-choice", on(b))));
        o.extend(self.subpel_rd.map(|b| ("subpel-rd", on(b))));
        o.extend(self.split_margin.map(|b| ("split-margin", on(b))));
        o.extend(self.split_search_margin.map(|b| ("split-search-margin", on(b))));
        o.extend(self.chroma_me.map(|b| ("chroma-me", on(b))));
        o.extend(self.adaptive_pricing.map(|b| ("adaptive-pricing", on(b))));
        o.extend(self.luma_filter.map(|f| ("luma-filter", f.name().to_string())));
        o
    }

    /// The preset, then `first` (options by name), then these tools, as
    /// x264's `param_default_preset` and `param_parse` (what Python does
    /// with its keyword arguments).
    pub fn configure(&self, first: &[(&str, String)]) -> Result<EncoderConfig> {
        let mut config = EncoderConfig::from_preset(self.preset.name()).map_err(anyhow::Error::msg)?;
        for (name, value) in first.iter().cloned().chain(self.options()) {
            // The option's name once: the setter's message may start with it.
            config.set(name, &value).map_err(|e| {
                let prefix = format!("{name}: ");
                anyhow::anyhow!("--{name}: {}", e.strip_prefix(&prefix).unwrap_or(&e))
            })?;
        }
        Ok(config)
    }
}

/// `on` or `off`.
fn on_off(s: &str) -> Result<bool, String> {
    match s {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("'{s}': expected on or off")),
    }
}

/// The configuration the options describe.
pub fn config(args: &Args) -> Result<EncoderConfig> {
    // The predictor first: the options of its search and flow follow it.
    let mut first = vec![
        ("qp", args.qp.to_string()),
        ("gop", args.gop.to_string()),
        ("predictor", args.predictor.clone()),
    ];
    first.extend(args.me.map(|m| ("me", m.name().to_string())));
    first.extend(args.range.map(|r| ("range", r.to_string())));
    first.extend(args.subpel.map(|s| ("subpel", s.name().to_string())));
    first.extend(args.flow.map(|f| ("flow", f.name().to_string())));
    first.extend(args.refine.map(|r| ("refine", r.to_string())));
    first.extend(args.grid.map(|g| ("grid", g.to_string())));
    args.tools.configure(&first)
}

/// A Y4M reader as the encoder's frame source.
struct Y4mSource<'a, R: std::io::Read>(&'a mut Y4mReader<R>);

impl<R: std::io::Read + Send> FrameSource for Y4mSource<'_, R> {
    fn next_frame(&mut self, frame: &mut crate::codec::Frame) -> Result<bool, EncodeError> {
        // The encoder pads the frame to its coded size, borders and all.
        self.0
            .read_pictures_into(frame)
            .map_err(|e| EncodeError::Input(Box::new(e)))
    }
}

/// A frame rate's numerator or denominator as the stream stores it.
fn fps_part(v: u64) -> Result<u32, EncodeError> {
    u32::try_from(v).map_err(|_| EncodeError::Config(format!("frame rate term {v} is too large")))
}

pub fn run(args: &Args) -> Result<()> {
    let mut config = config(args)?;
    // The reconstruction is copied out of the encoder only for what reads
    // it here: the --recon file and VMAF.
    config.reconstruction = args.recon.is_some() || config.metrics.has(Metric::Vmaf);
    let pool = super::thread_pool(args.threads)?;
    let input = args.input.display().to_string();
    let mut reader = Y4mReader::open(&args.input).with_context(|| input.clone())?;
    let info = reader.info().clone();
    let mut out = OutputFile::create(&args.output).with_context(|| args.output.display().to_string())?;
    let mut recon_file = match &args.recon {
        Some(p) => Some(OutputFile::create(p).with_context(|| p.display().to_string())?),
        None => None,
    };
    // The reconstruction's header is the one the decoder will write.
    let mut recon = match recon_file.as_mut() {
        Some(f) => Some(Y4mWriter::new(f, &info.as_decoded())?),
        None => None,
    };
    let with_vmaf = config.metrics.has(Metric::Vmaf);
    if with_vmaf {
        check_vmaf(args)?;
    }
    let mut frame_stats: Vec<FrameStats> = Vec::new();
    let mut recons = Vec::new();
    let bar = progress_bar(args);
    let summary = pool.install(|| {
        let sequence = SequenceInfo {
            width: info.width,
            height: info.height,
            fps: (fps_part(info.fps.0)?, fps_part(info.fps.1)?),
            vui: info.vui(),
        };
        encode_sequence(
            &mut Y4mSource(&mut reader),
            sequence,
            config,
            args.frames,
            &mut out,
            |coded| {
                if let (Some(w), Some(frame)) = (recon.as_mut(), &coded.recon) {
                    w.write_frame(frame)
                        .map_err(|e| EncodeError::Output(std::io::Error::other(e)))?;
                }
                frame_stats.push(coded.stats);
                if with_vmaf {
                    recons.extend(coded.recon.clone());
                }
                bar.inc(1);
                bar.set_message(format!(
                    "{:.2} dB  {} B",
                    coded.stats.quality.psnr.y, coded.stats.bytes
                ));
                Ok(())
            },
        )
    });
    bar.finish_and_clear();
    let mut summary = summary.with_context(|| input.clone())?;
    if with_vmaf {
        add_vmaf(args, &recons, &mut frame_stats, &mut summary)?;
    }
    out.commit().with_context(|| args.output.display().to_string())?;
    drop(recon);
    if let (Some(f), Some(path)) = (recon_file, &args.recon) {
        f.commit().with_context(|| path.display().to_string())?;
    }
    if let Some(path) = &args.stats {
        write_stats(path, &frame_stats).with_context(|| path.display().to_string())?;
    }
    print_summary(args, &config, &summary)
}

/// Refuses VMAF where it cannot be measured: the source read from
/// standard input (it is read again after the encode), or no ffmpeg with
/// libvmaf.
fn check_vmaf(args: &Args) -> Result<()> {
    if args.input.as_os_str() == "-" {
        anyhow::bail!("--metrics vmaf needs the source as a file (it is read again after the encode)");
    }
    if vmaf::ffmpeg_with_libvmaf().is_none() {
        anyhow::bail!(vmaf::VmafError::NoLibvmaf);
    }
    Ok(())
}

/// The encode's progress on a terminal, hidden when quiet, for JSON, or
/// when standard error is not a terminal.
fn progress_bar(args: &Args) -> ProgressBar {
    if args.quiet || args.json || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(args.frames.map_or(0, |n| n as u64));
    bar.set_style(
        ProgressStyle::with_template("{spinner} {pos} frames  {per_sec}  {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar
}

/// Each frame's VMAF (the source read again, the reconstructions kept)
/// into its statistics, and their mean into the summary's.
fn add_vmaf(
    args: &Args,
    recons: &[crate::codec::Frame],
    frame_stats: &mut [FrameStats],
    summary: &mut Summary,
) -> Result<()> {
    let input = args.input.display().to_string();
    let sources: Vec<_> = Y4mReader::open(&args.input)
        .with_context(|| input.clone())?
        .read_all()
        .with_context(|| input.clone())?;
    let scores = vmaf::vmaf(&sources[..recons.len()], recons)?;
    for (f, v) in frame_stats.iter_mut().zip(&scores) {
        f.quality.vmaf = *v;
    }
    summary.quality.vmaf = scores.iter().sum::<f64>() / scores.len().max(1) as f64;
    Ok(())
}

/// The per-frame statistics as CSV, written whole or not at all.
fn write_stats(path: &std::path::Path, frame_stats: &[FrameStats]) -> Result<()> {
    let mut f = OutputFile::create(path)?;
    writeln!(f, "{}", FrameStats::CSV_HEADER)?;
    for s in frame_stats {
        writeln!(f, "{}", s.csv_row())?;
    }
    f.commit()?;
    Ok(())
}

fn print_summary(args: &Args, config: &EncoderConfig, s: &Summary) -> Result<()> {
    let mut stdout = std::io::stdout().lock();
    if args.json {
        let mut v = serde_json::to_value(s)?;
        if let Some(o) = v.as_object_mut() {
            o.insert("predictor".into(), config.predictor.label().into());
            o.insert("qp".into(), config.qp.into());
        }
        writeln!(stdout, "{v}")?;
        return Ok(());
    }
    if args.quiet {
        return Ok(());
    }
    let total = (s.bits_header + s.bits_motion + s.bits_residual).max(1) as f64;
    let share = |b: u64| 100.0 * b as f64 / total;
    writeln!(
        stdout,
        "{}: {} frames, QP {}, {}",
        args.output.display(),
        s.quality.frames,
        config.qp,
        config.predictor.describe()
    )?;
    writeln!(stdout, "  {} bytes, {:.2} kbit/s", s.bytes, s.kbps)?;
    if s.quality.psnr_y.is_nan() {
        write!(stdout, "  quality not measured (--metrics none)")?;
    } else {
        write!(
            stdout,
            "  PSNR Y {:.3} U {:.3} V {:.3} dB",
            s.quality.psnr_y, s.quality.psnr_u, s.quality.psnr_v
        )?;
    }
    let q = &s.quality;
    for (name, v, unit) in [
        ("SSIM", q.ssim, ""),
        ("MS-SSIM", q.ms_ssim, ""),
        ("PSNR-HVS", q.psnr_hvs, " dB"),
        ("CIEDE2000", q.ciede2000, " dB"),
        ("VMAF", q.vmaf, ""),
    ] {
        if !v.is_nan() {
            write!(stdout, ", {name} {v:.5}{unit}")?;
        }
    }
    writeln!(stdout)?;
    writeln!(
        stdout,
        "  bits: header {} ({:.1} %), motion {} ({:.1} %), residual {} ({:.1} %)",
        s.bits_header,
        share(s.bits_header),
        s.bits_motion,
        share(s.bits_motion),
        s.bits_residual,
        share(s.bits_residual)
    )?;
    writeln!(
        stdout,
        "  {:.1} ms ({:.1} fps), of which motion {:.1} ms",
        s.encode_ms, s.fps, s.me_ms
    )?;
    Ok(())
}
