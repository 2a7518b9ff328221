//! The encoder: IPPP coding at a fixed QP, one reference (the previous
//! reconstruction), per-macroblock rate-distortion mode decision over skip,
//! inter and intra, and a choice of P-frame predictors ([`Predictor`]).
//!
//! Everything here is encoder choice; what a frame decodes to is fixed by
//! the codec crate, whose functions do all reconstruction, so the
//! encoder's reconstruction is the decoder's output byte for byte.
//!
//! ```
//! use mocomp::codec::{decoder, Frame};
//! use mocomp::encode::{Encoder, EncoderConfig};
//!
//! let config = EncoderConfig::new().qp(30).predictor("block:esa".parse().unwrap());
//! let mut encoder = Encoder::new(40, 24, (30, 1), config).unwrap();
//! let mut stream = encoder.header();
//! let mut recon = Vec::new();
//! for t in 0..3 {
//!     let frame = Frame::filled(40, 24, 60 + 20 * t as u8, 128, 128).unwrap();
//!     let coded = encoder.encode(&frame).unwrap();
//!     stream.extend_from_slice(&coded.bytes);
//!     recon.push(coded.recon);
//! }
//! stream.extend_from_slice(&Encoder::trailer());
//! let (_, decoded) = decoder::decode(&stream).unwrap();
//! assert_eq!(decoded.len(), 3);
//! assert_eq!(decoded, recon); // bit-exact
//! ```

mod config;
pub mod dsp;
mod frame;
mod intra4x4;
mod intra8x8;
mod macroblock;
mod motion;
mod params;
mod partition;
mod stats;
mod transform8x8;
mod weights;

use std::io::Write;
use std::time::Instant;

pub use config::{
    EncoderConfig, EncoderPreset, FlowMethod, ModeDecision, Partitions, Predictor, SearchSettings,
    DEFAULT_GRID, DEFAULT_IPRATIO, DEFAULT_REFINE,
};
pub use params::OPTIONS;
pub use stats::{FrameStats, Summary, SummaryBuilder};

use crate::codec::recon::crop_reusing;
use crate::codec::syntax::{EntropyState, FrameType, MotionTool, SequenceHeader, Vui, STREAM_END};
use crate::codec::weight::Weights;
use crate::codec::{Frame, PictureError};
use crate::metrics::{psnr_from_mse, FrameQuality};
use macroblock::MbCoder;
use motion::MotionAnalyser;

/// Why encoding stops.
#[derive(Debug, thiserror::Error)]
pub enum EncodeError {
    /// A setting out of range.
    #[error("{0}")]
    Config(String),
    /// A picture of the wrong size, or one too large.
    #[error(transparent)]
    Picture(#[from] PictureError),
    /// A frame of another size than the sequence.
    #[error("frame is {got_w}x{got_h}, the sequence is {width}x{height}")]
    FrameSize {
        /// Frame width.
        got_w: usize,
        /// Frame height.
        got_h: usize,
        /// Sequence width.
        width: usize,
        /// Sequence height.
        height: usize,
    },
    /// Reading the input (the source's own error, as it says it).
    #[error("{0}")]
    Input(Box<dyn std::error::Error + Send + Sync>),
    /// Writing the stream.
    #[error("writing the stream: {0}")]
    Output(#[from] std::io::Error),
}

/// One coded frame.
#[derive(Debug, Clone)]
pub struct EncodedFrame {
    /// The frame's bytes in the stream (start code to end).
    pub bytes: Vec<u8>,
    /// What the decoder will output for it (visible size).
    pub recon: Frame,
    /// Rate, quality and time.
    pub stats: FrameStats,
}

/// Encodes a sequence frame by frame. See the [module](self) example.
pub struct Encoder {
    seq: SequenceHeader,
    config: EncoderConfig,
    /// P frames' quantiser and lambda.
    coder: MbCoder,
    /// I frames' (at [`EncoderConfig::intra_qp`]).
    intra_coder: MbCoder,
    analyser: MotionAnalyser,
    /// The reconstructions since the last I frame, the latest first, at
    /// most the configuration's references (coded size, borders extended).
    references: Vec<Frame>,
    /// The previous source, coded size (flow predictors read it).
    prev_source: Option<Frame>,
    /// Coded-size frames to reuse (the reference and source before the
    /// previous ones): fresh ones cost page faults every frame.
    spare_recon: Option<Frame>,
    /// A returned reconstruction given back ([`Encoder::recycle`]).
    spare_output: Option<Frame>,
    spare_source: Option<Frame>,
    /// Contexts carried from frame to frame, as the decoder carries them.
    entropy: EntropyState,
    index: usize,
}

impl Encoder {
    /// An encoder for `width x height` pictures at `fps` (numerator,
    /// denominator).
    pub fn new(
        width: usize,
        height: usize,
        fps: (u32, u32),
        config: EncoderConfig,
    ) -> Result<Encoder, EncodeError> {
        config.check().map_err(EncodeError::Config)?;
        crate::codec::picture::check_size(width, height)?;
        if fps.0 == 0 || fps.1 == 0 {
            return Err(EncodeError::Config(format!(
                "frame rate {}/{} is not positive",
                fps.0, fps.1
            )));
        }
        let seq = SequenceHeader {
            width,
            height,
            fps_num: fps.0,
            fps_den: fps.1,
            frame_count: 0,
            vui: Vui::default(),
            max_refs: config.effective_refs(),
        };
        Ok(Encoder {
            seq,
            config,
            coder: MbCoder::new(config.qp, config.lambda_scale, config.rdoq)
                .intra4x4(config.partitions.i4x4)
                .intra8x8(config.intra8x8())
                .transform_8x8(config.transform_8x8),
            intra_coder: MbCoder::new(config.intra_qp(), config.lambda_scale, config.rdoq)
                .intra4x4(config.partitions.i4x4)
                .intra8x8(config.intra8x8()),
            analyser: MotionAnalyser::new(config.predictor, config.qp, config.partitions.p8x8),
            references: Vec::new(),
            prev_source: None,
            spare_recon: None,
            spare_output: None,
            spare_source: None,
            entropy: EntropyState::new(),
            index: 0,
        })
    }

    /// Sets what the sequence header says about the samples (aspect ratio,
    /// range, chroma siting) for the decoder's output; call it before
    /// [`Encoder::header`].
    pub fn set_vui(&mut self, vui: Vui) {
        self.seq.vui = vui;
    }

    /// The sequence header that starts the stream (frame count 0: not
    /// known in advance).
    pub fn header(&self) -> Vec<u8> {
        self.seq.to_bytes()
    }

    /// The byte that ends the stream.
    pub fn trailer() -> [u8; 1] {
        [STREAM_END]
    }

    /// The sequence header.
    pub fn sequence(&self) -> &SequenceHeader {
        &self.seq
    }

    /// Gives back a reconstruction [`Encoder::encode`] returned, once the
    /// caller is done with it: the next one is written into it instead of
    /// a fresh frame (optional; it saves an allocation a frame).
    pub fn recycle(&mut self, recon: Frame) {
        self.spare_output = Some(recon);
    }

    /// Codes the next frame.
    pub fn encode(&mut self, source: &Frame) -> Result<EncodedFrame, EncodeError> {
        if (source.width(), source.height()) != (self.seq.width, self.seq.height) {
            return Err(EncodeError::FrameSize {
                got_w: source.width(),
                got_h: source.height(),
                width: self.seq.width,
                height: self.seq.height,
            });
        }
        let start = Instant::now();
        let (cw, ch) = (self.seq.coded_width(), self.seq.coded_height());
        let src = pad_to_coded(source, self.spare_source.take(), cw, ch)?;
        let recon = match self.spare_recon.take() {
            Some(f) => f,
            None => Frame::new(cw, ch)?,
        };
        let intra = self.config.gop > 0 && self.index % self.config.gop == 0;
        let mut me_ms = 0.0;
        let coded = match (self.references.first(), &self.prev_source, intra) {
            (Some(unweighted), Some(prev), false) => {
                let weights = if self.config.weightp {
                    weights::estimate(&src, unweighted)
                } else {
                    Weights::NONE
                };
                let weighted = weights.any().then(|| {
                    let mut out = unweighted.clone();
                    weights.apply_into(unweighted, &mut out);
                    out
                });
                let reference = weighted.as_ref().unwrap_or(unweighted);
                let t = Instant::now();
                // Older references: `block` only (the list holds one
                // frame for the other predictors).
                let motion = self
                    .analyser
                    .analyse(&src, prev, reference, &self.references[1..]);
                me_ms = t.elapsed().as_secs_f64() * 1e3;
                let tool = match self.config.predictor {
                    Predictor::Obmc(_) => MotionTool::Obmc,
                    Predictor::Dense { grid, .. } => MotionTool::Grid(grid),
                    _ => MotionTool::Block,
                };
                // Weights apply to reference 0 alone (FORMAT.md section 12).
                let mut references = vec![reference];
                references.extend(&self.references[1..]);
                let inputs = frame::InterInputs {
                    references,
                    motion,
                    tool,
                    decision: self.config.decision,
                    deblock: self.config.deblock,
                    weights,
                    partitions: self.config.partitions.p8x8,
                    subpel_rd: self.config.subpel_rd,
                };
                frame::code_inter(&self.seq, &self.coder, &src, inputs, &mut self.entropy, recon)?
            }
            _ => frame::code_intra(
                &self.seq,
                &self.intra_coder,
                &src,
                self.config.deblock,
                &mut self.entropy,
                recon,
            )?,
        };
        let (bytes, bits) = (coded.bytes, coded.bits);
        let recon = crop_reusing(
            &coded.recon,
            self.seq.width,
            self.seq.height,
            self.spare_output.take(),
        )?;
        // The quality measurements are not coding time: some cost more than
        // the coding.
        let coding_ms = start.elapsed().as_secs_f64() * 1e3;
        let quality = FrameQuality::measure_as(source, &recon, &self.config.quality());
        let stats = FrameStats {
            index: self.index,
            frame_type: if coded.syntax.header.frame_type == FrameType::Intra {
                'I'
            } else {
                'P'
            },
            qp: coded.syntax.header.qp,
            bytes: bytes.len(),
            bits_header: bits.header,
            bits_motion: bits.motion,
            bits_residual: bits.residual,
            quality,
            prediction_psnr_y: psnr_from_mse(
                coded.prediction_sse as f64 / (self.seq.width * self.seq.height) as f64,
            ),
            skip_mbs: coded.kinds[0],
            inter_mbs: coded.kinds[1],
            intra_mbs: coded.kinds[2],
            me_ms,
            total_ms: coding_ms,
        };
        if intra {
            self.references.clear();
        }
        if self.references.len() == usize::from(self.seq.max_refs) {
            self.spare_recon = self.references.pop();
        }
        self.references.insert(0, coded.recon);
        self.spare_source = self.prev_source.replace(src);
        self.index += 1;
        Ok(EncodedFrame { bytes, recon, stats })
    }
}

/// `frame` at the coded size: the right column and bottom row repeated
/// into the macroblocks' padding (which costs few bits and no distortion
/// that anyone sees), borders extended; written into `reuse` when given.
fn pad_to_coded(
    frame: &Frame,
    reuse: Option<Frame>,
    width: usize,
    height: usize,
) -> Result<Frame, PictureError> {
    let mut out = match reuse {
        Some(f) => f,
        None => Frame::new(width, height)?,
    };
    for p in 0..3 {
        let src = frame.plane(p);
        let dst = out.plane_mut(p);
        let (sw, sh) = (src.width(), src.height());
        for y in 0..dst.height() {
            let row = src.row(y.min(sh - 1));
            let d = dst.row_mut(y);
            d[..sw].copy_from_slice(row);
            let last = row[sw - 1];
            d[sw..].fill(last);
        }
    }
    out.extend_borders();
    Ok(out)
}

/// Where an encode's frames come from (a Y4M reader, frames in memory,
/// arrays from Python): the one encode loop, [`encode_sequence`], reads
/// them through this.
pub trait FrameSource {
    /// The next frame into `frame` (the sequence's size); `false` at the
    /// end.
    fn next_frame(&mut self, frame: &mut Frame) -> Result<bool, EncodeError>;
}

impl FrameSource for std::slice::Iter<'_, Frame> {
    fn next_frame(&mut self, frame: &mut Frame) -> Result<bool, EncodeError> {
        let Some(f) = self.next() else {
            return Ok(false);
        };
        if (f.width(), f.height()) != (frame.width(), frame.height()) {
            return Err(EncodeError::FrameSize {
                got_w: f.width(),
                got_h: f.height(),
                width: frame.width(),
                height: frame.height(),
            });
        }
        frame.clone_from(f);
        Ok(true)
    }
}

/// What a sequence is: its size, frame rate and how its samples are to be
/// shown.
#[derive(Debug, Clone, Copy)]
pub struct SequenceInfo {
    /// Width, luma samples.
    pub width: usize,
    /// Height, luma samples.
    pub height: usize,
    /// Frame rate, numerator and denominator.
    pub fps: (u32, u32),
    /// Aspect ratio, range, chroma siting.
    pub vui: Vui,
}

/// The one encode loop (the command line, RD sweeps and Python run it):
/// at most `max_frames` frames of `source` coded into `out` (sequence
/// header, frames, end marker), `on_frame` called after each. Returns the
/// summary; a source with no frame is an error.
pub fn encode_sequence<W: Write>(
    source: &mut dyn FrameSource,
    info: SequenceInfo,
    config: EncoderConfig,
    max_frames: Option<usize>,
    mut out: W,
    mut on_frame: impl FnMut(&EncodedFrame) -> Result<(), EncodeError>,
) -> Result<Summary, EncodeError> {
    let mut encoder = Encoder::new(info.width, info.height, info.fps, config)?;
    encoder.set_vui(info.vui);
    let header = encoder.header();
    out.write_all(&header)?;
    let rate = f64::from(info.fps.0) / f64::from(info.fps.1);
    let mut summary = SummaryBuilder::new(rate, header.len() + 1);
    let mut frame = Frame::new(info.width, info.height)?;
    while max_frames.is_none_or(|n| summary.frames() < n) && source.next_frame(&mut frame)? {
        let coded = encoder.encode(&frame)?;
        out.write_all(&coded.bytes)?;
        summary.push(&coded.stats);
        on_frame(&coded)?;
        encoder.recycle(coded.recon);
    }
    out.write_all(&Encoder::trailer())?;
    out.flush()?;
    if summary.frames() == 0 {
        return Err(EncodeError::Config("the input holds no frames".into()));
    }
    Ok(summary.finish())
}

/// Encodes frames held in memory, keeping only the statistics (the stream
/// is measured, not kept).
pub fn encode_frames(
    frames: &[Frame],
    fps: (u32, u32),
    config: EncoderConfig,
) -> Result<Summary, EncodeError> {
    encode_frames_keeping_stream(frames, fps, config).map(|(summary, _)| summary)
}

/// Encodes frames held in memory: the statistics and the whole stream
/// (what rate-distortion sweeps need, to time its decoding).
pub fn encode_frames_keeping_stream(
    frames: &[Frame],
    fps: (u32, u32),
    config: EncoderConfig,
) -> Result<(Summary, Vec<u8>), EncodeError> {
    let first = frames
        .first()
        .ok_or_else(|| EncodeError::Config("no frames to encode".into()))?;
    let info = SequenceInfo {
        width: first.width(),
        height: first.height(),
        fps,
        vui: Vui::default(),
    };
    let mut stream = Vec::new();
    let summary = encode_sequence(&mut frames.iter(), info, config, None, &mut stream, |_| Ok(()))?;
    Ok((summary, stream))
}
