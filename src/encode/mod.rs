//! The encoder: IPPP coding at a fixed QP (I frames at the ipratio's
//! lower QP), P frames predicting from up to eight references (the
//! reconstructions since the last I frame, the latest weighted), the
//! per-macroblock rate-distortion mode decision over skip, inter (whole or
//! in partitions) and intra (16x16, 8x8 or 4x4 blocks), the transform size,
//! and a choice of P-frame predictors ([`Predictor`]).
//!
//! Laid out as x264's encoder is: [`encoder`](Encoder) the frame loop,
//! `slice.rs` one frame's macroblocks, `analyse.rs` every decision,
//! `macroblock.rs` coding a decided macroblock, `rdo.rs` the RD pricing,
//! `motion.rs` the predictors' motion analysis, [`dsp`] the coder's
//! kernels; [`EncoderConfig::from_preset`] and [`EncoderConfig::set`] the
//! options by name, [`encode_sequence`] the one encode loop.
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
//!     recon.extend(coded.recon);
//! }
//! stream.extend_from_slice(&Encoder::trailer());
//! let (_, decoded) = decoder::decode(&stream).unwrap();
//! assert_eq!(decoded.len(), 3);
//! assert_eq!(decoded, recon); // bit-exact
//! ```

mod analyse;
mod camera;
mod config;
mod deblock_choice;
pub mod dsp;
mod encoder;
mod filter;
mod frame_thread;
mod intra4x4;
mod intra8x8;
mod macroblock;
mod motion;
mod params;
mod partition;
mod progress;
pub mod rate;
mod rdo;
mod reference;
mod refs_choice;
mod slice;
mod stats;
mod transform8x8;
mod wavefront;
mod weights;

use std::io::Write;

pub use config::{
    EncoderConfig, EncoderPreset, FilterChoice, FlowMethod, ModeDecision, Partitions, Predictor,
    SearchSettings, DEFAULT_GRID, DEFAULT_IPRATIO, DEFAULT_REFINE,
};
pub use encoder::Encoder;
pub use params::OPTIONS;
pub use stats::{FrameStats, Summary, SummaryBuilder};
/// The weighted prediction a P frame's encoder chooses, from the source
/// and its reference (both coded size; exposed for its bench).
pub use weights::estimate as estimate_weights;

use crate::codec::syntax::Vui;
use crate::codec::{Frame, PictureError};

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
    /// What the decoder will output for it (visible size); `None` where
    /// [`EncoderConfig::reconstruction`] is off.
    pub recon: Option<Frame>,
    /// Rate, quality and time.
    pub stats: FrameStats,
}

/// Where an encode's frames come from (a Y4M reader, frames in memory,
/// arrays from Python): the one encode loop, [`encode_sequence`], reads
/// them through this.
pub trait FrameSource: Send {
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
    let wanted = |coded: usize| max_frames.is_none_or(|n| coded < n);
    let mut frame = Frame::new(info.width, info.height)?;
    let mut next = Frame::new(info.width, info.height)?;
    let mut have = wanted(0) && source.next_frame(&mut frame)?;
    let mut pushed = 0;
    let mut take = |coded: EncodedFrame, encoder: &mut Encoder| -> Result<(), EncodeError> {
        out.write_all(&coded.bytes)?;
        summary.push(&coded.stats);
        on_frame(&coded)?;
        if let Some(recon) = coded.recon {
            encoder.recycle(recon);
        }
        Ok(())
    };
    while have {
        // The next frame is read while this one is coded, on another
        // thread where the pool has one: the copies of reading are work
        // the encoder's threads would otherwise wait for. Frames come
        // back up to two pushes late (two on their threads on two).
        pushed += 1;
        let read_next = wanted(pushed);
        let (earlier, read) = rayon::join(
            || encoder.push_taking(&mut frame),
            || {
                if read_next {
                    source.next_frame(&mut next)
                } else {
                    Ok(false)
                }
            },
        );
        if let Some(coded) = earlier? {
            take(coded, &mut encoder)?;
        }
        // A read error comes after the frames before it are out.
        have = match read {
            Ok(more) => more,
            Err(e) => {
                while let Some(coded) = encoder.flush()? {
                    take(coded, &mut encoder)?;
                }
                return Err(e);
            }
        };
        std::mem::swap(&mut frame, &mut next);
    }
    while let Some(coded) = encoder.flush()? {
        take(coded, &mut encoder)?;
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
