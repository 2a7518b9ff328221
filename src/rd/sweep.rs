//! Sweeps: every (sequence, QP, predictor) encode, in parallel; the CSV
//! they make (peer format first); BD tables against an anchor.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::{Read, Write};

use rayon::prelude::*;
use serde::Serialize;

use super::bdrate::{bd_psnr, bd_rate, Fit};
use crate::codec::Frame;
use crate::encode::{encode_frames_keeping_stream, EncodeError, EncoderConfig, Predictor};
use crate::metrics::{vmaf, Metric, SequenceQuality};

/// One point of a rate-distortion curve.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RdPoint {
    /// The predictor's label (or a peer codec's name).
    pub codec: String,
    /// QP (or the peer's quantiser).
    pub q: f64,
    /// Stream bytes.
    pub bytes: u64,
    /// kbit/s at the sequence's frame rate.
    pub kbps: f64,
    /// The sequence's quality (frames, PSNR means and of the mean MSE,
    /// SSIM, the other metrics: the encoder's record; in peer CSVs what
    /// their columns hold, NaN where they have none).
    #[serde(flatten)]
    pub quality: SequenceQuality,
    /// The sequence's name (empty in peer CSVs).
    pub sequence: String,
    /// Header bits.
    pub bits_header: u64,
    /// Motion bits.
    pub bits_motion: u64,
    /// Residual bits.
    pub bits_residual: u64,
    /// Encode time, ms.
    pub encode_ms: f64,
    /// Of which motion estimation or flow, ms.
    pub me_ms: f64,
    /// The [`Study::id`] of the sweep that made the point (empty in peer
    /// CSVs).
    pub study: String,
    /// Its job's number in the study and the study's number of jobs.
    pub job: Option<(usize, usize)>,
    /// The shard `I/N` of the study that ran the job (`None` in peer CSVs
    /// and sweeps run whole in one process).
    pub shard: Option<(usize, usize)>,
    /// Decode time, ms (NaN when a CSV lacks it).
    pub decode_ms: f64,
}

impl RdPoint {
    /// The sequence figure of `m` (mean luma PSNR for [`Metric::Psnr`]).
    pub fn metric(&self, m: Metric) -> f64 {
        self.quality.value(m)
    }
}

/// Which luma PSNR a curve uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum PsnrKind {
    /// The mean over frames of each frame's PSNR (`psnr_y`; ffmpeg's
    /// per-frame stats, HM, AWCY). The default.
    #[default]
    Mean,
    /// The PSNR of the mean MSE (`psnr_y_mse`; ffmpeg's summary, x264's
    /// "Global"): not lifted by frames coded exactly.
    Mse,
}

impl PsnrKind {
    /// That PSNR of `p`.
    pub fn of(self, p: &RdPoint) -> f64 {
        match self {
            PsnrKind::Mean => p.quality.psnr_y,
            PsnrKind::Mse => p.quality.psnr_y_mse,
        }
    }
}

/// The quality axis of curves and BD figures: a metric (and for PSNR,
/// which PSNR). Similarities (SSIM, MS-SSIM) are taken in dB,
/// `-10 log10(1 - x)`, as AWCY takes them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QualityAxis {
    /// The metric.
    pub metric: Metric,
    /// Which PSNR, when the metric is PSNR.
    pub psnr: PsnrKind,
}

impl From<PsnrKind> for QualityAxis {
    fn from(psnr: PsnrKind) -> QualityAxis {
        QualityAxis {
            metric: Metric::Psnr,
            psnr,
        }
    }
}

impl From<Metric> for QualityAxis {
    fn from(metric: Metric) -> QualityAxis {
        QualityAxis {
            metric,
            psnr: PsnrKind::Mean,
        }
    }
}

impl QualityAxis {
    /// The curve's quality value of `p` (NaN when `p` lacks the metric).
    pub fn of(self, p: &RdPoint) -> f64 {
        match self.metric {
            Metric::Psnr => self.psnr.of(p),
            m => m.curve_value(p.metric(m)),
        }
    }

    /// Its name in tables and plots, with the unit.
    pub fn label(self) -> String {
        match (self.metric, self.psnr) {
            (Metric::Psnr, PsnrKind::Mean) => "PSNR-Y (dB)".into(),
            (Metric::Psnr, PsnrKind::Mse) => "PSNR-Y of the mean MSE (dB)".into(),
            (Metric::Ssim, _) => "SSIM (dB)".into(),
            (Metric::MsSsim, _) => "MS-SSIM (dB)".into(),
            (Metric::PsnrHvs, _) => "PSNR-HVS (dB)".into(),
            (Metric::Ciede2000, _) => "CIEDE2000 (dB)".into(),
            (Metric::Vmaf, _) => "VMAF".into(),
        }
    }

    /// The short name of the BD-quality figure ("BD-PSNR", "BD-MS-SSIM").
    pub fn bd_name(self) -> String {
        match self.metric {
            Metric::Psnr => "BD-PSNR".into(),
            m => format!("BD-{}", m.name().to_uppercase()),
        }
    }
}

/// The CSV columns: `../shared/peers/rd_ffmpeg.sh`'s, then ours.
pub const CSV_COLUMNS: [&str; 24] = [
    "codec",
    "q",
    "bytes",
    "frames",
    "kbps",
    "psnr_y",
    "sequence",
    "psnr_u",
    "psnr_v",
    "ssim",
    "bits_header",
    "bits_motion",
    "bits_residual",
    "encode_ms",
    "me_ms",
    "psnr_y_mse",
    "study",
    "job",
    "decode_ms",
    "ms_ssim",
    "psnr_hvs",
    "ciede2000",
    "vmaf",
    "shard",
];

/// A sequence to sweep.
#[derive(Debug, Clone)]
pub struct Sequence {
    /// Its name in tables (the file stem).
    pub name: String,
    /// Its frames.
    pub frames: Vec<Frame>,
    /// Frame rate, numerator and denominator.
    pub fps: (u32, u32),
}

/// A sweep: every sequence at every QP with every predictor, each job's
/// configuration the study's `base` (a preset and options) with its QP
/// and predictor ([`EncoderConfig::with_predictor`]: a search predictor
/// keeps the preset's search settings). Jobs are numbered in (sequence,
/// predictor, QP) order, the same on every machine, so that a study can be
/// split into shards and its rows merged back.
pub struct Study<'a> {
    /// The sequences, in order.
    pub sequences: &'a [Sequence],
    /// The QPs, in order.
    pub qps: &'a [u8],
    /// The predictors, in order.
    pub predictors: &'a [Predictor],
    /// Every job's configuration but its QP and predictor.
    pub base: EncoderConfig,
}

impl Study<'_> {
    /// How many jobs.
    pub fn len(&self) -> usize {
        self.sequences.len() * self.predictors.len() * self.qps.len()
    }

    /// Whether there is no job.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Job `index`: its sequence, predictor and QP.
    fn job(&self, index: usize) -> (&Sequence, Predictor, u8) {
        let (q, p) = (self.qps.len(), self.predictors.len());
        (
            &self.sequences[index / (q * p)],
            self.predictors[index / q % p],
            self.qps[index % q],
        )
    }

    /// What identifies the study: a hash (16 hex digits) of the sequences
    /// (names, frame counts, sizes, rates, and a checksum of their
    /// samples), the QPs and every job's full configuration. Paths are
    /// left out: the same study reads its files from different places on
    /// different machines.
    pub fn id(&self) -> String {
        let mut text = String::new();
        for s in self.sequences {
            let first = s.frames.first();
            let _ = write!(
                text,
                "{}:{}:{:?}:{:?}:{:016x};",
                s.name,
                s.frames.len(),
                first.map(|f| (f.width(), f.height())),
                s.fps,
                s.frames
                    .iter()
                    .fold(0xcbf2_9ce4_8422_2325u64, |h, f| fnv1a(h, f.y().data()))
            );
        }
        let _ = write!(text, "{:?};", self.qps);
        for p in self.predictors {
            let _ = write!(
                text,
                "{:?};",
                EncoderConfig {
                    qp: EncoderConfig::new().qp,
                    ..self.base.with_predictor(*p)
                }
            );
        }
        format!("{:016x}", fnv1a(0xcbf2_9ce4_8422_2325, text.as_bytes()))
    }

    /// Runs the jobs `indices` in parallel on the current rayon pool,
    /// giving each point, tagged with `id` (the caller's [`Study::id`],
    /// computed once since it reads every frame), to `done` as it is made
    /// (from the worker threads, in no set order); the first error of
    /// either stops it.
    pub fn run<E: From<EncodeError> + Send>(
        &self,
        id: &str,
        indices: &[usize],
        done: impl Fn(RdPoint) -> Result<(), E> + Sync,
    ) -> Result<(), E> {
        let total = self.len();
        indices.par_iter().try_for_each(|&index| {
            let (seq, predictor, qp) = self.job(index);
            let config = self.base.with_predictor(predictor).qp(qp);
            let (s, stream) = encode_frames_keeping_stream(&seq.frames, seq.fps, config)?;
            let decoded = DecodedJob::of(&stream, &seq.frames, config.metrics.has(Metric::Vmaf))?;
            done(RdPoint {
                codec: predictor.label(),
                q: f64::from(qp),
                bytes: s.bytes,
                kbps: s.kbps,
                quality: SequenceQuality {
                    vmaf: decoded.vmaf,
                    ..s.quality
                },
                sequence: seq.name.clone(),
                bits_header: s.bits_header,
                bits_motion: s.bits_motion,
                bits_residual: s.bits_residual,
                encode_ms: s.encode_ms,
                me_ms: s.me_ms,
                study: id.to_string(),
                job: Some((index, total)),
                shard: None,
                decode_ms: decoded.ms,
            })
        })
    }
}

/// What decoding a sweep job's stream gives: the time, and VMAF of the
/// decoded frames when asked for.
struct DecodedJob {
    ms: f64,
    vmaf: f64,
}

impl DecodedJob {
    fn of(stream: &[u8], source: &[Frame], with_vmaf: bool) -> Result<DecodedJob, EncodeError> {
        let start = std::time::Instant::now();
        let (_, frames) = crate::codec::decoder::decode(stream)
            .map_err(|e| EncodeError::Config(format!("the encoder's own stream does not decode: {e}")))?;
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let vmaf = if with_vmaf {
            let v = vmaf::vmaf(source, &frames).map_err(|e| EncodeError::Config(e.to_string()))?;
            v.iter().sum::<f64>() / v.len().max(1) as f64
        } else {
            f64::NAN
        };
        Ok(DecodedJob { ms, vmaf })
    }
}

/// 64-bit FNV-1a of `bytes`, continuing from `hash`.
fn fnv1a(hash: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(hash, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Encodes every sequence at every QP with every predictor (a whole
/// [`Study`]), jobs in parallel on the current rayon pool; `done` is
/// called after each job. Points come back in (sequence, predictor, QP)
/// order.
pub fn sweep(
    sequences: &[Sequence],
    qps: &[u8],
    predictors: &[Predictor],
    base: EncoderConfig,
    done: impl Fn() + Sync,
) -> Result<Vec<RdPoint>, EncodeError> {
    let study = Study {
        sequences,
        qps,
        predictors,
        base,
    };
    let all: Vec<usize> = (0..study.len()).collect();
    let points = std::sync::Mutex::new(Vec::with_capacity(all.len()));
    study.run(&study.id(), &all, |p| -> Result<(), EncodeError> {
        points.lock().unwrap_or_else(|e| e.into_inner()).push(p);
        done();
        Ok(())
    })?;
    let mut points = points.into_inner().unwrap_or_else(|e| e.into_inner());
    points.sort_by_key(|p| p.job);
    Ok(points)
}

/// `v` with `decimals` decimals, or an empty cell for NaN (not measured).
fn cell(v: f64, decimals: usize) -> String {
    if v.is_nan() {
        String::new()
    } else {
        format!("{v:.decimals$}")
    }
}

/// The CSV cells of `p`, in [`CSV_COLUMNS`] order.
pub fn csv_record(p: &RdPoint) -> [String; 24] {
    [
        p.codec.clone(),
        format!("{}", p.q),
        p.bytes.to_string(),
        p.quality.frames.to_string(),
        format!("{:.3}", p.kbps),
        format!("{:.4}", p.quality.psnr_y),
        p.sequence.clone(),
        format!("{:.4}", p.quality.psnr_u),
        format!("{:.4}", p.quality.psnr_v),
        format!("{:.6}", p.quality.ssim),
        p.bits_header.to_string(),
        p.bits_motion.to_string(),
        p.bits_residual.to_string(),
        format!("{:.1}", p.encode_ms),
        format!("{:.1}", p.me_ms),
        format!("{:.4}", p.quality.psnr_y_mse),
        p.study.clone(),
        p.job.map_or(String::new(), |(i, n)| format!("{i}/{n}")),
        cell(p.decode_ms, 1),
        cell(p.quality.ms_ssim, 6),
        cell(p.quality.psnr_hvs, 4),
        cell(p.quality.ciede2000, 4),
        cell(p.quality.vmaf, 4),
        p.shard.map_or(String::new(), |(i, n)| format!("{i}/{n}")),
    ]
}

/// Writes points as CSV with [`CSV_COLUMNS`].
pub fn write_csv(points: &[RdPoint], out: impl Write) -> csv::Result<()> {
    let mut w = csv::Writer::from_writer(out);
    w.write_record(CSV_COLUMNS)?;
    for p in points {
        w.write_record(csv_record(p))?;
    }
    w.flush()?;
    Ok(())
}

/// Why an RD CSV could not be read.
#[derive(Debug, thiserror::Error)]
pub enum CsvError {
    /// Not readable as CSV (or not readable at all).
    #[error(transparent)]
    Csv(#[from] csv::Error),
    /// One of the six leading columns of the peer format is missing.
    #[error("no '{0}' column (the peer format starts codec,q,bytes,frames,kbps,psnr_y)")]
    MissingColumn(&'static str),
    /// A value that should be a number is not.
    #[error("row {row}: '{column}' is '{text}', not a number")]
    NotANumber {
        /// The row, counting the header as row 1.
        row: usize,
        /// The column's name.
        column: &'static str,
        /// What the cell holds.
        text: String,
    },
}

/// Reads a CSV in the peer format (`codec,q,bytes,frames,kbps,psnr_y`,
/// more columns optional, in any order). Missing optional values are 0 or
/// empty.
pub fn read_csv(input: impl Read) -> Result<Vec<RdPoint>, CsvError> {
    let mut r = csv::Reader::from_reader(input);
    let headers = r.headers()?.clone();
    if let Some(missing) = CSV_COLUMNS[..6]
        .iter()
        .find(|c| !headers.iter().any(|h| h.trim() == **c))
    {
        return Err(CsvError::MissingColumn(missing));
    }
    let mut out = Vec::new();
    for (line, record) in r.records().enumerate() {
        let record = record?;
        let row = CsvRow {
            headers: &headers,
            record: &record,
            number: line + 2,
        };
        out.push(row.point()?);
    }
    Ok(out)
}

/// One record of a peer-format CSV, its fields read by column name.
struct CsvRow<'r> {
    headers: &'r csv::StringRecord,
    record: &'r csv::StringRecord,
    /// Its row in the file (the header is row 1).
    number: usize,
}

impl CsvRow<'_> {
    /// The field of column `name`, trimmed; empty where the column or the
    /// field is missing.
    fn text(&self, name: &str) -> String {
        self.headers
            .iter()
            .position(|h| h.trim() == name)
            .and_then(|i| self.record.get(i))
            .unwrap_or("")
            .trim()
            .to_string()
    }

    fn not_a_number(&self, column: &'static str, text: String) -> CsvError {
        CsvError::NotANumber {
            row: self.number,
            column,
            text,
        }
    }

    /// A number; 0 where an optional column is missing or empty.
    fn num(&self, name: &'static str) -> Result<f64, CsvError> {
        let t = self.text(name);
        if t.is_empty() && !CSV_COLUMNS[..6].contains(&name) {
            return Ok(0.0);
        }
        t.parse::<f64>().map_err(|_| self.not_a_number(name, t))
    }

    /// A number of a column that may be absent or empty: NaN, not 0.
    fn optional(&self, name: &'static str) -> Result<f64, CsvError> {
        match self.text(name).is_empty() {
            true => Ok(f64::NAN),
            false => self.num(name),
        }
    }

    /// A field read by `parse`; `None` where empty.
    fn parsed<T>(&self, name: &'static str, parse: fn(&str) -> Option<T>) -> Result<Option<T>, CsvError> {
        match self.text(name) {
            t if t.is_empty() => Ok(None),
            t => parse(&t).map(Some).ok_or_else(|| self.not_a_number(name, t)),
        }
    }

    fn point(&self) -> Result<RdPoint, CsvError> {
        Ok(RdPoint {
            codec: self.text("codec"),
            q: self.num("q")?,
            bytes: self.num("bytes")? as u64,
            kbps: self.num("kbps")?,
            quality: SequenceQuality {
                psnr_y: self.num("psnr_y")?,
                psnr_u: self.num("psnr_u")?,
                psnr_v: self.num("psnr_v")?,
                ssim: self.num("ssim")?,
                psnr_y_mse: self.optional("psnr_y_mse")?,
                ms_ssim: self.optional("ms_ssim")?,
                psnr_hvs: self.optional("psnr_hvs")?,
                ciede2000: self.optional("ciede2000")?,
                vmaf: self.optional("vmaf")?,
                ..SequenceQuality::unknown(self.num("frames")? as usize)
            },
            sequence: self.text("sequence"),
            bits_header: self.num("bits_header")? as u64,
            bits_motion: self.num("bits_motion")? as u64,
            bits_residual: self.num("bits_residual")? as u64,
            encode_ms: self.num("encode_ms")?,
            me_ms: self.num("me_ms")?,
            decode_ms: self.optional("decode_ms")?,
            study: self.text("study"),
            job: self.parsed("job", parse_job)?,
            shard: self.parsed("shard", parse_shard)?,
        })
    }
}

/// `I/N` with 1 <= I <= N.
fn parse_shard(t: &str) -> Option<(usize, usize)> {
    let (i, n) = t.split_once('/')?;
    let (i, n) = (i.parse().ok()?, n.parse().ok()?);
    (1..=n).contains(&i).then_some((i, n))
}

/// `I/N` with I < N.
fn parse_job(t: &str) -> Option<(usize, usize)> {
    let (i, n) = t.split_once('/')?;
    let (i, n) = (i.parse().ok()?, n.parse().ok()?);
    (i < n).then_some((i, n))
}

/// The (kbps, quality) points of one codec (and sequence, when given).
pub fn curve(
    points: &[RdPoint],
    codec: &str,
    sequence: Option<&str>,
    axis: impl Into<QualityAxis>,
) -> Vec<(f64, f64)> {
    let axis = axis.into();
    points
        .iter()
        .filter(|p| p.codec == codec && sequence.is_none_or(|s| p.sequence.is_empty() || p.sequence == s))
        .map(|p| (p.kbps, axis.of(p)))
        .collect()
}

/// One row of a comparison table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Comparison {
    /// Sequence.
    pub sequence: String,
    /// Predictor or codec.
    pub codec: String,
    /// BD-rate against the anchor, percent, cubic and pchip (None when the
    /// curves do not overlap).
    pub bd_rate_cubic: Option<f64>,
    /// See `bd_rate_cubic`.
    pub bd_rate_pchip: Option<f64>,
    /// BD-quality against the anchor in the axis' unit (BD-PSNR, dB, by
    /// default).
    pub bd_psnr_cubic: Option<f64>,
    /// See `bd_psnr_cubic`.
    pub bd_psnr_pchip: Option<f64>,
    /// Motion bits over all bits, percent, over the QPs.
    pub motion_share: f64,
    /// Mean encode time per frame, ms.
    pub ms_per_frame: f64,
    /// Mean decode time per frame, ms (NaN when not known).
    pub decode_ms_per_frame: f64,
    /// The quality axis' BD name ("BD-PSNR", "BD-MS-SSIM").
    pub quality: String,
}

/// Compares every codec of `points` with the anchor curve, per sequence,
/// on the quality `axis` (a [`PsnrKind`] or a [`Metric`]). `anchor` is a
/// codec in `points`, or given as its own points (a peer CSV);
/// `anchor_name` labels it.
pub fn compare(
    points: &[RdPoint],
    anchor: &[RdPoint],
    anchor_name: &str,
    axis: impl Into<QualityAxis>,
) -> Vec<Comparison> {
    let axis = axis.into();
    let mut sequences: Vec<&str> = Vec::new();
    let mut codecs: Vec<&str> = Vec::new();
    for p in points {
        if !sequences.contains(&p.sequence.as_str()) {
            sequences.push(&p.sequence);
        }
        if !codecs.contains(&p.codec.as_str()) {
            codecs.push(&p.codec);
        }
    }
    let mut out = Vec::new();
    for &seq in &sequences {
        let a = curve(anchor, anchor_name, Some(seq), axis);
        for &codec in &codecs {
            let mine: Vec<&RdPoint> = points
                .iter()
                .filter(|p| p.codec == codec && p.sequence == seq)
                .collect();
            let t: Vec<(f64, f64)> = mine.iter().map(|p| (p.kbps, axis.of(p))).collect();
            let bits: u64 = mine
                .iter()
                .map(|p| p.bits_header + p.bits_motion + p.bits_residual)
                .sum();
            let frames: usize = mine.iter().map(|p| p.quality.frames).sum();
            out.push(Comparison {
                sequence: seq.to_string(),
                codec: codec.to_string(),
                bd_rate_cubic: bd_rate(&a, &t, Fit::Cubic).ok(),
                bd_rate_pchip: bd_rate(&a, &t, Fit::Pchip).ok(),
                bd_psnr_cubic: bd_psnr(&a, &t, Fit::Cubic).ok(),
                bd_psnr_pchip: bd_psnr(&a, &t, Fit::Pchip).ok(),
                motion_share: 100.0 * mine.iter().map(|p| p.bits_motion).sum::<u64>() as f64
                    / bits.max(1) as f64,
                ms_per_frame: mine.iter().map(|p| p.encode_ms).sum::<f64>() / frames.max(1) as f64,
                decode_ms_per_frame: mine.iter().map(|p| p.decode_ms).sum::<f64>() / frames.max(1) as f64,
                quality: axis.bd_name(),
            });
        }
    }
    out
}

/// Markdown tables: one per sequence, then the mean over sequences.
pub fn markdown(rows: &[Comparison], anchor_name: &str) -> String {
    let fmt = |v: Option<f64>, unit: &str| v.map_or("n/a".to_string(), |v| format!("{v:+.2}{unit}"));
    let bd = rows.first().map_or("BD-PSNR", |r| r.quality.as_str());
    let unit = if bd == "BD-VMAF" { "" } else { " dB" };
    let header = format!(
        "| predictor | BD-rate cubic | BD-rate pchip | {bd} cubic | {bd} pchip | motion bits | ms/frame | decode ms/frame |\n\
         |---|---:|---:|---:|---:|---:|---:|---:|\n"
    );
    let mut s = String::new();
    let mut by_seq: BTreeMap<&str, Vec<&Comparison>> = BTreeMap::new();
    for r in rows {
        by_seq.entry(&r.sequence).or_default().push(r);
    }
    let mut table = |title: &str, rows: &[Comparison]| {
        let _ = writeln!(s, "\n### {title} (anchor: {anchor_name})\n");
        s.push_str(&header);
        for r in rows {
            let decode = if r.decode_ms_per_frame.is_nan() {
                "n/a".to_string()
            } else {
                format!("{:.1}", r.decode_ms_per_frame)
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {:.1} % | {:.1} | {decode} |",
                r.codec,
                fmt(r.bd_rate_cubic, " %"),
                fmt(r.bd_rate_pchip, " %"),
                fmt(r.bd_psnr_cubic, unit),
                fmt(r.bd_psnr_pchip, unit),
                r.motion_share,
                r.ms_per_frame
            );
        }
    };
    for (seq, rows) in &by_seq {
        let rows: Vec<Comparison> = rows.iter().map(|&r| r.clone()).collect();
        table(seq, &rows);
    }
    if by_seq.len() > 1 {
        let mut codecs: Vec<&str> = Vec::new();
        for r in rows {
            if !codecs.contains(&r.codec.as_str()) {
                codecs.push(&r.codec);
            }
        }
        let mean = |v: Vec<Option<f64>>| -> Option<f64> {
            let n = v.len() as f64;
            v.into_iter().sum::<Option<f64>>().map(|s| s / n)
        };
        let avg: Vec<Comparison> = codecs
            .iter()
            .map(|&c| {
                let of: Vec<&Comparison> = rows.iter().filter(|r| r.codec == c).collect();
                let n = of.len() as f64;
                Comparison {
                    sequence: "mean".into(),
                    codec: c.to_string(),
                    bd_rate_cubic: mean(of.iter().map(|r| r.bd_rate_cubic).collect()),
                    bd_rate_pchip: mean(of.iter().map(|r| r.bd_rate_pchip).collect()),
                    bd_psnr_cubic: mean(of.iter().map(|r| r.bd_psnr_cubic).collect()),
                    bd_psnr_pchip: mean(of.iter().map(|r| r.bd_psnr_pchip).collect()),
                    motion_share: of.iter().map(|r| r.motion_share).sum::<f64>() / n,
                    ms_per_frame: of.iter().map(|r| r.ms_per_frame).sum::<f64>() / n,
                    decode_ms_per_frame: of.iter().map(|r| r.decode_ms_per_frame).sum::<f64>() / n,
                    quality: of[0].quality.clone(),
                }
            })
            .collect();
        table(&format!("mean over {} sequences", by_seq.len()), &avg);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_peer_csv_reads_by_name_in_any_order_with_optional_columns_empty_or_absent() {
        let text = "psnr_y,codec,kbps,q,frames,bytes,ms_ssim,job\n\
                    38.5, x264 ,120.5,27,30,4500,,2/3\n\
                    41.0,x264,240,22,30,9000,0.99,\n";
        let points = read_csv(text.as_bytes()).expect("a valid CSV");
        assert_eq!(points.len(), 2);
        let p = &points[0];
        assert_eq!(
            (p.codec.as_str(), p.q, p.bytes, p.kbps),
            ("x264", 27.0, 4500, 120.5)
        );
        assert_eq!((p.quality.psnr_y, p.quality.frames), (38.5, 30));
        // Absent optional columns: 0 where a number, NaN where a metric.
        assert_eq!((p.quality.psnr_u, p.encode_ms, p.bits_motion), (0.0, 0.0, 0));
        assert!(p.quality.vmaf.is_nan() && p.quality.ms_ssim.is_nan() && p.decode_ms.is_nan());
        assert_eq!((p.job, p.shard), (Some((2, 3)), None));
        assert_eq!(points[1].quality.ms_ssim, 0.99);
        assert_eq!(points[1].job, None);
    }

    #[test]
    fn a_bad_field_names_its_row_and_column_and_a_missing_leading_column_is_named() {
        let header = "codec,q,bytes,frames,kbps,psnr_y,shard\n";
        let bad_number = format!("{header}x264,27,4500,30,120,38.5,\nx264,22,many,30,240,41,\n");
        match read_csv(bad_number.as_bytes()) {
            Err(CsvError::NotANumber { row, column, text }) => {
                assert_eq!((row, column, text.as_str()), (3, "bytes", "many"))
            }
            other => panic!("expected a bad number, got {other:?}"),
        }
        let bad_shard = format!("{header}x264,27,4500,30,120,38.5,4/3\n");
        match read_csv(bad_shard.as_bytes()) {
            Err(CsvError::NotANumber { row, column, .. }) => assert_eq!((row, column), (2, "shard")),
            other => panic!("expected a bad shard, got {other:?}"),
        }
        let no_psnr = "codec,q,bytes,frames,kbps\nx264,27,4500,30,120\n";
        assert!(matches!(
            read_csv(no_psnr.as_bytes()),
            Err(CsvError::MissingColumn("psnr_y"))
        ));
    }
}
