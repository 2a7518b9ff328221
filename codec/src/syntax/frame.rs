//! The frame layer (FORMAT.md sections 3 and 4): frame types and tools,
//! the frame header, a frame's syntax, the entropy state carried between
//! frames, writing a frame (whole or a macroblock at a time) and a
//! stream, and reading a frame's payload.

use super::error::{invalid, SyntaxError};
use super::macroblock::{check_kind, check_vector, mb_mode, mb_vectors, CodedMb, MbKind, PartitionReader};
use super::sequence::SequenceHeader;
use crate::bits::{BitReader, BitWriter};
use crate::consts::{FRAME_START, SEQUENCE_HEADER_LEN, STREAM_END};
use crate::deblock::DeblockOffsets;
use crate::entropy::{RangeDecoder, RangeEncoder};
use crate::interp::LumaFilter;
use crate::modes::{ModeCoder, VectorSyntax, MAX_REFS};
use crate::mv::Mv;
use crate::mvpred::predict_in_grid;
use crate::partition::MbVectors;
use crate::residual::ResidualCoder;
use crate::transform::MAX_QP;
use crate::warp::{MotionGrid, SPACINGS};
use crate::weight::Weights;

/// Intra (I) or predicted (P).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameType {
    /// Every macroblock intra; needs no reference.
    Intra,
    /// Macroblocks skip, inter or intra, from the previous frame.
    Inter,
}

/// How a P frame's inter macroblocks are predicted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionTool {
    /// One vector per macroblock, plain block motion compensation.
    Block,
    /// One vector per macroblock, overlapped block motion compensation.
    Obmc,
    /// A dense motion grid with this spacing (4, 8 or 16), warped.
    Grid(usize),
}

/// The frame header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameHeader {
    /// I or P.
    pub frame_type: FrameType,
    /// Quantisation parameter, 0..=51.
    pub qp: u8,
    /// Motion tool (always `Block` in I frames).
    pub tool: MotionTool,
    /// How many references the frame predicts from, 1..=[`MAX_REFS`]
    /// (1 in I frames, OBMC and grid frames; FORMAT.md section 4).
    pub refs: u8,
    /// The in-loop deblocking filter runs on the frame.
    pub deblock: bool,
    /// Its thresholds' offsets (zero where it does not run).
    pub deblock_offsets: DeblockOffsets,
    /// How the reference's planes are weighted before prediction (P
    /// frames; none in I frames).
    pub weights: Weights,
    /// The luma interpolation filter of block P frames (sharp in the
    /// others).
    pub luma_filter: LumaFilter,
}

/// Everything one coded frame says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FrameSyntax {
    /// The header.
    pub header: FrameHeader,
    /// The motion grid, for grid frames.
    pub grid: Option<MotionGrid>,
    /// Macroblocks in raster order.
    pub mbs: Vec<CodedMb>,
}

/// Bits written per category, for rate statistics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BitCounts {
    /// Framing, frame header, macroblock types, skip runs, intra modes.
    pub header: u64,
    /// Vector differences and grid vectors.
    pub motion: u64,
    /// Coded block patterns, flags and levels.
    pub residual: u64,
}

impl BitCounts {
    /// All bits.
    pub fn total(&self) -> u64 {
        self.header + self.motion + self.residual
    }
}

/// The predicted vector of grid node (col, row) from the nodes before it.
fn grid_prediction(grid: &MotionGrid, col: usize, row: usize) -> Mv {
    predict_in_grid(grid.cols(), col, row, |c, r| Some(grid.get(c, r)))
}

/// Which vectors a frame with this header codes.
pub fn vector_syntax(h: &FrameHeader) -> VectorSyntax {
    match (h.frame_type, h.tool) {
        (FrameType::Intra, _) | (_, MotionTool::Grid(_)) => VectorSyntax::None,
        (_, MotionTool::Obmc) => VectorSyntax::PerMacroblock,
        (_, MotionTool::Block) => VectorSyntax::PerPartition { refs: h.refs },
    }
}

/// What a stream's entropy coding carries from one frame to the next: P
/// frames start from the contexts the previous frame ended with, I frames
/// from the initial ones (FORMAT.md section 3.4). A writer and a reader
/// each keep one, fed every frame in order.
#[derive(Debug, Clone, Default)]
pub struct EntropyState {
    last: Option<(ModeCoder, ResidualCoder)>,
}

impl EntropyState {
    /// The state at the start of a stream.
    pub fn new() -> EntropyState {
        EntropyState::default()
    }

    /// The coders a frame of `frame_type` starts with.
    pub fn coders(&self, seq: &SequenceHeader, frame_type: FrameType) -> (ModeCoder, ResidualCoder) {
        match (&self.last, frame_type) {
            (Some((modes, residual)), FrameType::Inter) => (modes.next_frame(), residual.next_frame()),
            _ => (
                ModeCoder::new(seq.mb_cols(), seq.mb_rows()),
                ResidualCoder::new(seq.mb_cols(), seq.mb_rows()),
            ),
        }
    }
}

/// Splits `total` bits over categories in proportion to their estimated
/// costs, the remainder to the last, so they add up exactly.
fn split_bits(total: u64, estimates: [u64; 3]) -> [u64; 3] {
    let sum: u64 = estimates.iter().sum();
    if sum == 0 {
        return [total, 0, 0];
    }
    let a = (u128::from(total) * u128::from(estimates[0]) / u128::from(sum)) as u64;
    let b = (u128::from(total) * u128::from(estimates[1]) / u128::from(sum)) as u64;
    [a, b, total - a - b]
}

/// Writes a frame (start code, length, header, payload) after `seq`'s
/// sequence header. Panics if the syntax does not fit the sequence
/// (encoder bug): wrong macroblock count, a P frame tool in an I frame,
/// vectors out of range.
///
/// The bit counts: the frame header and framing are exact; the range-coded
/// partition's bits are split over header (flags, intra modes), motion
/// and residual in proportion to the cost of their bins as coded.
/// `state` is the stream's entropy state, updated for the next frame.
pub fn write_frame(
    seq: &SequenceHeader,
    frame: &FrameSyntax,
    state: &mut EntropyState,
) -> (Vec<u8>, BitCounts) {
    assert_eq!(frame.mbs.len(), seq.mb_cols() * seq.mb_rows(), "macroblock count");
    let mut w = FrameWriter::new(seq, &frame.header, frame.grid.as_ref(), state);
    for mb in &frame.mbs {
        w.push(mb);
    }
    w.finish(state)
}

/// [`write_frame`] for an encoder that has each macroblock's `vectors`
/// already ([`mb_vectors`] of its macroblock, found when it was decided):
/// a skipped macroblock's is a vector prediction, not made again. Wrong
/// vectors make a stream the decoder reads otherwise.
pub fn write_decided_frame(
    seq: &SequenceHeader,
    frame: &FrameSyntax,
    vectors: &[MbVectors],
    state: &mut EntropyState,
) -> (Vec<u8>, BitCounts) {
    assert_eq!(frame.mbs.len(), seq.mb_cols() * seq.mb_rows(), "macroblock count");
    assert_eq!(vectors.len(), frame.mbs.len(), "a macroblock's vectors each");
    let mut w = FrameWriter::new(seq, &frame.header, frame.grid.as_ref(), state);
    for (mb, &v) in frame.mbs.iter().zip(vectors) {
        w.push_decided(mb, v);
    }
    w.finish(state)
}

/// The frame header's bits (FORMAT.md, "Frame header"), aligned: the
/// writer twin of [`read_frame_header`]. Panics on a header the syntax
/// cannot carry (the encoder's bug, not input).
fn write_frame_header(h: &FrameHeader) -> Vec<u8> {
    assert!(h.qp <= MAX_QP);
    let mut w = BitWriter::new();
    w.put(u64::from(h.frame_type == FrameType::Inter), 1);
    w.put(u64::from(h.qp), 6);
    let tool_code = match h.tool {
        MotionTool::Block => 0,
        MotionTool::Obmc => 1,
        MotionTool::Grid(_) => 2,
    };
    assert!(
        h.frame_type == FrameType::Inter || tool_code == 0,
        "I frames use the block tool"
    );
    w.put(tool_code, 2);
    if let MotionTool::Grid(spacing) = h.tool {
        let code = SPACINGS.iter().position(|&s| s == spacing);
        assert!(code.is_some(), "grid spacing {spacing} is not 4, 8 or 16");
        w.put(code.unwrap_or_default() as u64, 2);
    }
    let block_p = h.frame_type == FrameType::Inter && h.tool == MotionTool::Block;
    assert!(
        (1..=MAX_REFS).contains(&h.refs) && (block_p || h.refs == 1),
        "{} references in a frame that can have {}",
        h.refs,
        if block_p { "1 to 8" } else { "only 1" }
    );
    if block_p {
        w.put(u64::from(h.refs - 1), 3);
    }
    assert!(
        h.frame_type == FrameType::Inter || !h.weights.any(),
        "I frames have no weights"
    );
    if h.frame_type == FrameType::Inter {
        h.weights.write(&mut w);
    }
    assert!(
        block_p || h.luma_filter == LumaFilter::Sharp,
        "only block P frames choose the luma filter"
    );
    if block_p {
        w.put(h.luma_filter.code(), 1);
    }
    w.put(u64::from(h.deblock), 1);
    assert!(
        h.deblock_offsets.in_range() && (h.deblock || h.deblock_offsets == DeblockOffsets::ZERO),
        "deblocking offsets {:?} out of range or without the filter",
        h.deblock_offsets
    );
    if h.deblock {
        w.put_se(i32::from(h.deblock_offsets.alpha));
        w.put_se(i32::from(h.deblock_offsets.beta));
    }
    w.align();
    w.into_bytes()
}

/// [`write_frame`] a macroblock at a time, so that an encoder can write
/// each macroblock as it decides it, pricing the next ones from the same
/// coders ([`FrameWriter::modes`], [`FrameWriter::residual`]) that writing
/// adapts, instead of adapting a copy and writing the frame again later.
///
/// ```
/// use mocomp_codec::intra::IntraMode;
/// use mocomp_codec::intra4x4::LumaIntra;
/// use mocomp_codec::syntax::*;
/// let seq = SequenceHeader { width: 32, height: 16, fps_num: 25, fps_den: 1, frame_count: 1, vui: Vui::default(), max_refs: 1 };
/// let header = FrameHeader {
///     frame_type: FrameType::Intra,
///     qp: 30,
///     tool: MotionTool::Block,
///     refs: 1,
///     deblock: true,
///     deblock_offsets: mocomp_codec::deblock::DeblockOffsets::ZERO,
///     weights: mocomp_codec::weight::Weights::NONE,
///     luma_filter: mocomp_codec::interp::LumaFilter::Sharp,
/// };
/// let kind = MbKind::Intra { luma: LumaIntra::Whole(IntraMode::Dc), chroma: IntraMode::Dc };
/// let frame = FrameSyntax { header, grid: None, mbs: vec![CodedMb::without_residual(kind); 2] };
/// let mut state = EntropyState::new();
/// let mut w = FrameWriter::new(&seq, &frame.header, None, &state);
/// for mb in &frame.mbs {
///     w.push(mb);
/// }
/// let (bytes, _) = w.finish(&mut state);
/// assert_eq!(bytes, write_frame(&seq, &frame, &mut EntropyState::new()).0);
/// ```
pub struct FrameWriter {
    cols: usize,
    count: usize,
    header: Vec<u8>,
    enc: RangeEncoder,
    modes: ModeCoder,
    residual: ResidualCoder,
    /// Estimated costs (1/256 bit) of header, motion and residual bins.
    estimates: [u64; 3],
    vectors: Vec<MbVectors>,
    inter_frame: bool,
    syntax: VectorSyntax,
}

impl FrameWriter {
    /// Starts frame `header` (with its motion `grid` in grid frames) of a
    /// stream whose entropy state is `state`: the frame header and the
    /// grid are written.
    pub fn new(
        seq: &SequenceHeader,
        h: &FrameHeader,
        grid: Option<&MotionGrid>,
        state: &EntropyState,
    ) -> FrameWriter {
        let (cols, rows) = (seq.mb_cols(), seq.mb_rows());
        let header = write_frame_header(h);
        assert!(
            matches!(h.tool, MotionTool::Grid(_)) == grid.is_some(),
            "grid frames, and only they, carry a grid"
        );
        let mut enc = RangeEncoder::new();
        let (mut modes, residual) = state.coders(seq, h.frame_type);
        let mut estimates = [0u64; 3];
        if let (MotionTool::Grid(spacing), Some(grid)) = (h.tool, grid) {
            assert_eq!(grid.spacing(), spacing, "grid spacing differs from the header's");
            for row in 0..grid.rows() {
                for col in 0..grid.cols() {
                    let mv = grid.get(col, row);
                    assert!(mv.in_range(), "grid vector {mv:?} out of range");
                    let d = mv - grid_prediction(grid, col, row);
                    estimates[1] += u64::from(modes.write_grid(&mut enc, grid.cols(), col, row, d));
                }
            }
        }
        FrameWriter {
            cols,
            count: cols * rows,
            header,
            enc,
            modes,
            residual,
            estimates,
            vectors: Vec::with_capacity(cols * rows),
            inter_frame: h.frame_type == FrameType::Inter,
            syntax: vector_syntax(h),
        }
    }

    /// The mode coder as the macroblocks written so far left it.
    pub fn modes(&self) -> &ModeCoder {
        &self.modes
    }

    /// The residual coder as the macroblocks written so far left it.
    pub fn residual(&self) -> &ResidualCoder {
        &self.residual
    }

    /// The cost of the bins written so far, header (flags, types, intra
    /// modes), motion and residual, in 1/256 bit: what `finish` splits the
    /// coded bits by, and what analysis attributes to each macroblock.
    pub fn estimates(&self) -> [u64; 3] {
        self.estimates
    }

    /// The vectors of the macroblocks written so far (raster order; `None`
    /// for intra), as vector prediction reads them.
    pub fn vectors(&self) -> &[MbVectors] {
        &self.vectors
    }

    /// Writes the next macroblock (raster order).
    pub fn push(&mut self, mb: &CodedMb) {
        let i = self.vectors.len();
        let vectors = mb_vectors(&mb.kind, &self.vectors, i % self.cols, i / self.cols, self.cols);
        self.push_decided(mb, vectors);
    }

    /// [`FrameWriter::push`] of a macroblock whose `vectors` the caller
    /// has ([`write_decided_frame`]).
    pub fn push_decided(&mut self, mb: &CodedMb, vectors: MbVectors) {
        let i = self.vectors.len();
        assert!(i < self.count, "more macroblocks than the frame holds");
        let (mb_x, mb_y) = (i % self.cols, i / self.cols);
        assert!(
            self.inter_frame || matches!(mb.kind, MbKind::Intra { .. }),
            "I frames hold only intra macroblocks"
        );
        check_kind(&mb.kind, self.syntax);
        let at = (mb_x, mb_y, self.cols);
        let mode = mb_mode(&mb.kind, &self.vectors, at, self.syntax);
        let (motion, rest) =
            self.modes
                .write(&mut self.enc, mb_x, mb_y, self.inter_frame, self.syntax, &mode);
        self.estimates[0] += u64::from(rest);
        self.estimates[1] += u64::from(motion);
        debug_assert_eq!(
            vectors,
            mb_vectors(&mb.kind, &self.vectors, mb_x, mb_y, self.cols)
        );
        self.vectors.push(vectors);
        if mb.kind == MbKind::Skip {
            assert!(mb.residual.is_none(), "skipped macroblocks have no residual");
            return;
        }
        let syntax = mb.kind.residual_syntax();
        self.estimates[2] += u64::from(
            self.residual
                .write(&mut self.enc, mb_x, mb_y, syntax, mb.residual()),
        );
    }

    /// The frame's bytes (start code to end) and bits per category, every
    /// macroblock having been pushed; `state` (the one the writer was made
    /// from) is updated for the next frame.
    pub fn finish(self, state: &mut EntropyState) -> (Vec<u8>, BitCounts) {
        assert_eq!(self.vectors.len(), self.count, "macroblock count");
        state.last = Some((self.modes.carried(), self.residual.carried()));
        let header = self.header;
        let coded = self.enc.finish();
        let [hb, mb, rb] = split_bits(8 * coded.len() as u64, self.estimates);
        let counts = BitCounts {
            // Start code and length, the frame header, and the flags' share.
            header: 40 + 8 * header.len() as u64 + hb,
            motion: mb,
            residual: rb,
        };
        let mut out = Vec::with_capacity(5 + header.len() + coded.len());
        out.push(FRAME_START);
        out.extend_from_slice(&((header.len() + coded.len()) as u32).to_be_bytes());
        out.extend_from_slice(&header);
        out.extend_from_slice(&coded);
        (out, counts)
    }
}

/// A whole stream: the sequence header, every frame, the end marker.
/// Returns the bytes and the bits per category summed over the frames (the
/// sequence header and end marker count as header bits).
pub fn write_stream(seq: &SequenceHeader, frames: &[FrameSyntax]) -> (Vec<u8>, BitCounts) {
    let mut out = seq.to_bytes();
    let mut state = EntropyState::new();
    let mut total = BitCounts {
        header: 8 * (SEQUENCE_HEADER_LEN as u64 + 1),
        ..BitCounts::default()
    };
    for f in frames {
        let (bytes, counts) = write_frame(seq, f, &mut state);
        out.extend_from_slice(&bytes);
        total.header += counts.header;
        total.motion += counts.motion;
        total.residual += counts.residual;
    }
    out.push(STREAM_END);
    (out, total)
}

/// Reads the frame header (FORMAT.md, "Frame header") and its alignment
/// bits: the reader twin of [`write_frame_header`]. Returns the header
/// and the byte at which the range-coded partition starts.
fn read_frame_header(payload: &[u8]) -> Result<(FrameHeader, usize), SyntaxError> {
    let mut r = BitReader::new(payload);
    let frame_type = if r.get(1)? == 1 {
        FrameType::Inter
    } else {
        FrameType::Intra
    };
    let pos = r.position();
    let qp = r.get(6)? as u8;
    if qp > MAX_QP {
        return Err(invalid(format!("qp {qp} above {MAX_QP}"), pos));
    }
    let pos = r.position();
    let tool = match r.get(2)? {
        0 => MotionTool::Block,
        1 => MotionTool::Obmc,
        2 => {
            let pos = r.position();
            let code = r.get(2)? as usize;
            MotionTool::Grid(
                *SPACINGS
                    .get(code)
                    .ok_or_else(|| invalid(format!("grid spacing code {code}"), pos))?,
            )
        }
        code => return Err(invalid(format!("motion tool {code}"), pos)),
    };
    if frame_type == FrameType::Intra && tool != MotionTool::Block {
        return Err(invalid("an I frame with a motion tool".into(), pos));
    }
    let refs = if frame_type == FrameType::Inter && tool == MotionTool::Block {
        r.get(3)? as u8 + 1
    } else {
        1
    };
    let pos = r.position();
    let weights = match frame_type {
        FrameType::Inter => Weights::read(&mut r)?.map_err(|what| invalid(what, pos))?,
        FrameType::Intra => Weights::NONE,
    };
    let luma_filter = if frame_type == FrameType::Inter && tool == MotionTool::Block {
        LumaFilter::from_code(r.get(1)?)
    } else {
        LumaFilter::Sharp
    };
    let deblock = r.get(1)? == 1;
    let pos = r.position();
    let deblock_offsets = if deblock {
        let mut offset = || -> Result<i8, SyntaxError> {
            let v = r.get_se()?;
            if v.abs() > i32::from(DeblockOffsets::MAX) {
                return Err(invalid(format!("deblocking offset {v} outside -12..=12"), pos));
            }
            Ok(v as i8)
        };
        DeblockOffsets {
            alpha: offset()?,
            beta: offset()?,
        }
    } else {
        DeblockOffsets::ZERO
    };
    let pos = r.position();
    let pad = (8 - pos % 8) % 8;
    if r.get(pad as u32)? != 0 {
        return Err(invalid("non-zero bits after the frame header".into(), pos));
    }
    Ok((
        FrameHeader {
            frame_type,
            qp,
            tool,
            refs,
            deblock,
            deblock_offsets,
            weights,
            luma_filter,
        },
        r.position() / 8,
    ))
}

/// The motion grid of a grid frame.
fn read_grid(
    part: &mut PartitionReader<'_>,
    seq: &SequenceHeader,
    spacing: usize,
) -> Result<MotionGrid, SyntaxError> {
    let mut grid = MotionGrid::new(seq.coded_width(), seq.coded_height(), spacing)
        .map_err(|e| invalid(e.to_string(), 8 * part.start))?;
    for row in 0..grid.rows() {
        for col in 0..grid.cols() {
            let d = part.modes.read_grid(&mut part.dec, grid.cols(), col, row);
            let p = grid_prediction(&grid, col, row);
            let mv = check_vector(d.and_then(|d| p.checked_add(d)), part.at())?;
            grid.set(col, row, mv);
        }
    }
    Ok(grid)
}

/// Reads a frame's payload (the bytes after its length field): the frame
/// header, then the range-coded partition, which must be used to its end.
/// `state` is the stream's entropy state, updated when the frame is valid.
pub fn read_frame(
    seq: &SequenceHeader,
    payload: &[u8],
    state: &mut EntropyState,
) -> Result<FrameSyntax, SyntaxError> {
    let (cols, rows) = (seq.mb_cols(), seq.mb_rows());
    let (header, start) = read_frame_header(payload)?;
    let coded = &payload[start..];
    let (modes, residual) = state.coders(seq, header.frame_type);
    let mut part = PartitionReader {
        dec: RangeDecoder::new(coded),
        modes,
        residual,
        start,
        len: coded.len(),
    };
    let grid = match header.tool {
        MotionTool::Grid(spacing) => Some(read_grid(&mut part, seq, spacing)?),
        _ => None,
    };
    let total = cols * rows;
    let layer = (vector_syntax(&header), header.frame_type == FrameType::Inter);
    let mut mbs = Vec::with_capacity(total);
    let mut vectors: Vec<MbVectors> = Vec::with_capacity(total);
    for i in 0..total {
        let (mb_x, mb_y) = (i % cols, i / cols);
        let mb = part.macroblock(layer, &vectors, (mb_x, mb_y, cols))?;
        vectors.push(mb_vectors(&mb.kind, &vectors, mb_x, mb_y, cols));
        mbs.push(mb);
    }
    if !part.dec.consumed_all() {
        return Err(invalid(
            format!(
                "the range-coded partition ({} bytes) does not end where its last macroblock does",
                coded.len()
            ),
            8 * start,
        ));
    }
    state.last = Some((part.modes.carried(), part.residual.carried()));
    Ok(FrameSyntax { header, grid, mbs })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::weight::PlaneWeight;

    fn headers() -> Vec<FrameHeader> {
        let intra = FrameHeader {
            frame_type: FrameType::Intra,
            qp: 0,
            tool: MotionTool::Block,
            refs: 1,
            deblock: false,
            deblock_offsets: DeblockOffsets::ZERO,
            weights: Weights::NONE,
            luma_filter: LumaFilter::Sharp,
        };
        let inter = FrameHeader {
            frame_type: FrameType::Inter,
            ..intra
        };
        let weighted = Weights([
            Some(PlaneWeight {
                scale: 70,
                offset: -12,
            }),
            None,
            Some(PlaneWeight { scale: 64, offset: 3 }),
        ]);
        let mut out = vec![
            intra,
            FrameHeader {
                qp: 51,
                deblock: true,
                deblock_offsets: DeblockOffsets::ZERO,
                ..intra
            },
        ];
        for refs in [1, 2, 8] {
            out.push(FrameHeader {
                refs,
                qp: 27,
                ..inter
            });
        }
        for tool in [
            MotionTool::Obmc,
            MotionTool::Grid(4),
            MotionTool::Grid(8),
            MotionTool::Grid(16),
        ] {
            out.push(FrameHeader {
                tool,
                deblock: true,
                deblock_offsets: DeblockOffsets::ZERO,
                ..inter
            });
        }
        out.push(FrameHeader {
            weights: weighted,
            refs: 3,
            ..inter
        });
        out.push(FrameHeader {
            luma_filter: LumaFilter::Smooth,
            deblock: true,
            deblock_offsets: DeblockOffsets::ZERO,
            ..inter
        });
        for (alpha, beta) in [(12, -12), (-1, 5)] {
            out.push(FrameHeader {
                deblock: true,
                deblock_offsets: DeblockOffsets { alpha, beta },
                ..inter
            });
        }
        out
    }

    #[test]
    fn every_frame_header_reads_back_whole_bytes() {
        for h in headers() {
            let bytes = write_frame_header(&h);
            let (back, used) = read_frame_header(&bytes).unwrap();
            assert_eq!((back, used), (h, bytes.len()), "{h:?}");
        }
    }

    #[test]
    fn bad_frame_headers_are_located_errors() {
        // QP 63 (6 bits of ones after the type bit), a fourth tool code.
        let e = read_frame_header(&[0b0111_1110]).unwrap_err();
        assert!(e.what.contains("qp 63") && e.bit == 1, "{e:?}");
        let e = read_frame_header(&[0b1000_0001, 0b1000_0000]).unwrap_err();
        assert!(e.what.contains("motion tool 3"), "{e:?}");
        // An I frame with OBMC.
        let e = read_frame_header(&[0b0000_0000, 0b1000_0000]).unwrap_err();
        assert!(e.what.contains("I frame with a motion tool"), "{e:?}");
        // Padding bits must be zero.
        let mut bytes = write_frame_header(&headers()[0]);
        *bytes.last_mut().unwrap() |= 1;
        assert!(read_frame_header(&bytes)
            .unwrap_err()
            .what
            .contains("non-zero bits"));
        assert!(read_frame_header(&[]).is_err());
        // A deblocking offset of 13: the bits of an I frame at QP 0,
        // deblocked, then se(13) = ue(25) = 0000 11010.
        let e = read_frame_header(&[0b0000_0000, 0b0100_0011, 0b0100_0000]).unwrap_err();
        assert!(e.what.contains("deblocking offset 13") && e.bit == 10, "{e:?}");
    }

    #[test]
    fn vector_syntax_follows_the_frame_type_and_tool() {
        let h = headers();
        assert_eq!(vector_syntax(&h[0]), VectorSyntax::None);
        assert_eq!(vector_syntax(&h[3]), VectorSyntax::PerPartition { refs: 2 });
        assert_eq!(vector_syntax(&h[5]), VectorSyntax::PerMacroblock);
        assert_eq!(vector_syntax(&h[6]), VectorSyntax::None);
    }

    #[test]
    fn bits_are_split_in_proportion_and_add_up() {
        for (total, estimates) in [(1000, [1, 1, 2]), (7, [3, 0, 0]), (0, [5, 5, 5]), (99, [0, 0, 0])] {
            let split = split_bits(total, estimates);
            assert_eq!(split.iter().sum::<u64>(), total, "{estimates:?}");
        }
        assert_eq!(split_bits(1000, [1, 1, 2]), [250, 250, 500]);
    }
}
