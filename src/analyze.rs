//! What a stream holds, frame by frame and macroblock by macroblock: type,
//! partition, intra modes, vectors (and the motion grid), QP, coded
//! blocks, and the bits each macroblock took by category, with the decoded
//! picture beside them; what `mocomp analyze` prints and draws.
//!
//! The bits are those the encoder reports. The frame's range-coded bits are
//! split over header, motion and residual by the cost of the bins of each
//! category under the contexts as coded, and a macroblock's share is the
//! cost of its own bins (to 1/256 bit): re-pricing the decoded syntax with
//! the stream's own entropy state gives exactly what the encoder counted.

use std::io::Read;

use serde::Serialize;

use crate::codec::decoder::{DecodeError, Decoder};
use crate::codec::interp::LumaFilter;
use crate::codec::intra::IntraMode;
use crate::codec::intra4x4::{Intra4x4Mode, LumaIntra};
use crate::codec::partition::{MbVectors, Split};
use crate::codec::syntax::{
    BitCounts, CodedMb, EntropyState, FrameSyntax, FrameType, FrameWriter, MbKind, MotionTool, SequenceHeader,
};
use crate::codec::warp::MotionGrid;
use crate::codec::Frame;

/// One macroblock as the stream codes it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MbRecord {
    /// Macroblock column.
    pub mb_x: usize,
    /// Macroblock row.
    pub mb_y: usize,
    /// `skip`, `inter` or `intra`.
    pub kind: &'static str,
    /// `16x16`, `16x8`, `8x16`, `8x8` for inter and skip; `16x16` or `4x4`
    /// for intra.
    pub partition: &'static str,
    /// Intra modes: luma (one 16x16 mode, or sixteen 4x4 ones in raster
    /// order separated by `/`) then `,` and the chroma mode; empty for
    /// inter.
    pub intra_modes: String,
    /// The vectors of the four 8x8 blocks in raster order, quarter-pel (a
    /// skipped macroblock's is its predicted vector; grid frames: zero, the
    /// grid moves the samples); `None` for intra.
    pub vectors: [Option<(i32, i32)>; 4],
    /// The reference index of each 8x8 block's vector (0: the previous
    /// frame); `None` for intra.
    pub refs: [Option<u8>; 4],
    /// The frame's QP (the format has no per-macroblock QP).
    pub qp: u8,
    /// The luma's transform size, 4 or 8 (8 for intra in 8x8 blocks; 4 for
    /// inter macroblocks without luma levels).
    pub transform: u8,
    /// Luma 4x4 blocks with levels (0..=16; with the 8x8 transform, four
    /// for each 8x8 block with levels).
    pub coded_luma_blocks: u8,
    /// Chroma 4x4 blocks with levels (0..=8).
    pub coded_chroma_blocks: u8,
    /// Bits of its header bins (type, skip, intra modes), motion bins and
    /// residual bins (the cost of the bins as coded, fractional).
    pub bits_header: f64,
    /// See `bits_header`.
    pub bits_motion: f64,
    /// See `bits_header`.
    pub bits_residual: f64,
}

/// One frame: its header, its bits, its macroblocks and its picture.
#[derive(Debug, Clone)]
pub struct FrameAnalysis {
    /// Frame number, from 0.
    pub index: usize,
    /// `I` or `P`.
    pub frame_type: char,
    /// QP.
    pub qp: u8,
    /// `block`, `obmc` or `grid`.
    pub tool: &'static str,
    /// Whether the deblocking filter ran.
    pub deblock: bool,
    /// Its offsets (alpha's and tc0's, beta's; FORMAT.md section 11).
    pub deblock_offsets: (i8, i8),
    /// The luma interpolation filter, `sharp` or `smooth` (block P
    /// frames choose; the others are sharp).
    pub luma_filter: &'static str,
    /// Bytes in the stream (start code and length included).
    pub bytes: usize,
    /// Bits by category, as the encoder's statistics count them.
    pub bits: BitCounts,
    /// The motion grid of grid frames.
    pub grid: Option<MotionGrid>,
    /// The macroblocks in raster order.
    pub mbs: Vec<MbRecord>,
    /// The decoded picture.
    pub picture: Frame,
}

impl FrameAnalysis {
    /// Macroblocks of each kind: skip, inter, intra.
    pub fn kinds(&self) -> [usize; 3] {
        let count = |k: &str| self.mbs.iter().filter(|m| m.kind == k).count();
        [count("skip"), count("inter"), count("intra")]
    }
}

/// The frames of a stream with their analysis, in order.
///
/// ```
/// use mocomp::analyze::Analyzer;
/// use mocomp::codec::Frame;
/// use mocomp::encode::{encode_frames_keeping_stream, EncoderConfig};
/// let frames = vec![Frame::filled(32, 32, 90, 128, 128).unwrap(); 2];
/// let (_, stream) = encode_frames_keeping_stream(&frames, (25, 1), EncoderConfig::new()).unwrap();
/// let analysed: Vec<_> = Analyzer::new(&stream[..]).unwrap().collect::<Result<_, _>>().unwrap();
/// assert_eq!(analysed.len(), 2);
/// assert_eq!(analysed[1].mbs.len(), 4);
/// assert_eq!(analysed[1].mbs[0].kind, "skip");
/// ```
pub struct Analyzer<R: Read> {
    decoder: Decoder<R>,
    seq: SequenceHeader,
    state: EntropyState,
    index: usize,
}

impl<R: Read> Analyzer<R> {
    /// Reads the sequence header.
    pub fn new(reader: R) -> Result<Analyzer<R>, DecodeError> {
        let decoder = Decoder::new(reader)?;
        let seq = *decoder.sequence();
        Ok(Analyzer {
            decoder,
            seq,
            state: EntropyState::new(),
            index: 0,
        })
    }

    /// The stream's sequence header.
    pub fn sequence(&self) -> &SequenceHeader {
        &self.seq
    }

    fn next_frame(&mut self) -> Result<Option<FrameAnalysis>, DecodeError> {
        let Some((syntax, picture)) = self.decoder.next_frame_with_syntax()? else {
            return Ok(None);
        };
        let (mbs, bytes, bits) = price(&self.seq, &syntax, &mut self.state);
        let h = &syntax.header;
        let analysis = FrameAnalysis {
            index: self.index,
            frame_type: if h.frame_type == FrameType::Intra {
                'I'
            } else {
                'P'
            },
            qp: h.qp,
            tool: match h.tool {
                MotionTool::Block => "block",
                MotionTool::Obmc => "obmc",
                MotionTool::Grid(_) => "grid",
            },
            deblock: h.deblock,
            deblock_offsets: (h.deblock_offsets.alpha, h.deblock_offsets.beta),
            luma_filter: match h.luma_filter {
                LumaFilter::Sharp => "sharp",
                LumaFilter::Smooth => "smooth",
            },
            bytes,
            bits,
            grid: syntax.grid.clone(),
            mbs,
            picture,
        };
        self.index += 1;
        Ok(Some(analysis))
    }
}

impl<R: Read> Iterator for Analyzer<R> {
    type Item = Result<FrameAnalysis, DecodeError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_frame().transpose()
    }
}

/// Writes the frame again with the stream's entropy state, pricing each
/// macroblock: its records, the frame's bytes and its bit counts.
fn price(
    seq: &SequenceHeader,
    syntax: &FrameSyntax,
    state: &mut EntropyState,
) -> (Vec<MbRecord>, usize, BitCounts) {
    let mut w = FrameWriter::new(seq, &syntax.header, syntax.grid.as_ref(), state);
    let cols = seq.mb_cols();
    let mut records = Vec::with_capacity(syntax.mbs.len());
    for (i, mb) in syntax.mbs.iter().enumerate() {
        let before = w.estimates();
        w.push(mb);
        let after = w.estimates();
        let vectors = w.vectors()[i];
        let bits = std::array::from_fn(|c| (after[c] - before[c]) as f64 / 256.0);
        records.push(record(mb, (i % cols, i / cols), syntax.header.qp, vectors, bits));
    }
    let (bytes, bits) = w.finish(state);
    (records, bytes.len(), bits)
}

fn record(
    mb: &CodedMb,
    (mb_x, mb_y): (usize, usize),
    qp: u8,
    vectors: MbVectors,
    bits: [f64; 3],
) -> MbRecord {
    let (kind, partition, intra_modes) = match &mb.kind {
        MbKind::Skip => ("skip", "16x16", String::new()),
        MbKind::Inter { .. } => ("inter", "16x16", String::new()),
        MbKind::Split { split, .. } => (
            "inter",
            match split {
                Split::Horizontal => "16x8",
                Split::Vertical => "8x16",
                Split::Quad => "8x8",
            },
            String::new(),
        ),
        MbKind::Intra { luma, chroma } => match luma {
            LumaIntra::Whole(m) => ("intra", "16x16", format!("{m:?},{chroma:?}").to_lowercase()),
            LumaIntra::Blocks(modes) => ("intra", "4x4", block_modes(modes, *chroma)),
            LumaIntra::Blocks8(modes) => ("intra", "8x8", block_modes(modes, *chroma)),
        },
    };
    let r = mb.residual();
    let coded = |b: &&[[i32; 4]; 4]| b.as_flattened().iter().any(|&v| v != 0);
    MbRecord {
        mb_x,
        mb_y,
        kind,
        partition,
        intra_modes,
        vectors: vectors.map(|v| v.map(|v| (v.mv.x, v.mv.y))),
        refs: vectors.map(|v| v.map(|v| v.ref_idx)),
        qp,
        transform: if mb.kind.luma_transform_8x8(r) { 8 } else { 4 },
        coded_luma_blocks: r.luma_coded().iter().filter(|&&c| c).count() as u8,
        coded_chroma_blocks: r.chroma.iter().flatten().filter(coded).count() as u8,
        bits_header: bits[0],
        bits_motion: bits[1],
        bits_residual: bits[2],
    }
}

/// The CSV header of [`csv_row`].
pub const CSV_HEADER: &str = "frame,type,mb_x,mb_y,kind,partition,intra_modes,\
mv0_x,mv0_y,mv1_x,mv1_y,mv2_x,mv2_y,mv3_x,mv3_y,refs,qp,transform,coded_luma_blocks,coded_chroma_blocks,\
bits_header,bits_motion,bits_residual";

/// One macroblock as a CSV row (vectors of the 8x8 blocks in quarter-pel
/// and their reference indices separated by `/`, empty for intra).
pub fn csv_row(frame: &FrameAnalysis, m: &MbRecord) -> String {
    let vectors: String = m
        .vectors
        .iter()
        .map(|v| v.map_or(",".to_string(), |(x, y)| format!("{x},{y}")))
        .collect::<Vec<_>>()
        .join(",");
    let refs: Vec<String> = m.refs.iter().flatten().map(u8::to_string).collect();
    format!(
        "{},{},{},{},{},{},{},{vectors},{},{},{},{},{},{:.3},{:.3},{:.3}",
        frame.index,
        frame.frame_type,
        m.mb_x,
        m.mb_y,
        m.kind,
        m.partition,
        m.intra_modes.replace(',', ";"),
        refs.join("/"),
        m.qp,
        m.transform,
        m.coded_luma_blocks,
        m.coded_chroma_blocks,
        m.bits_header,
        m.bits_motion,
        m.bits_residual
    )
}

/// Block intra modes as the records list them: the luma modes in raster
/// order, joined by '/', then the chroma mode.
fn block_modes(modes: &[Intra4x4Mode], chroma: IntraMode) -> String {
    let luma: Vec<String> = modes.iter().map(|m| format!("{m:?}").to_lowercase()).collect();
    format!("{},{}", luma.join("/"), format!("{chroma:?}").to_lowercase())
}
