//! The stream syntax: sequence header, frame framing and header, and the
//! macroblock layer. `FORMAT.md` is the specification; this is its code.
//!
//! A [`FrameSyntax`] is everything one coded frame says. The encoder fills
//! one and writes it with [`write_frame`]; the decoder gets it back from
//! [`read_frame`]; both reconstruct it with [`crate::recon`], so their
//! pictures are equal by construction.

use crate::bits::{BitError, BitReader, BitWriter};
use crate::entropy::{RangeDecoder, RangeEncoder};
use crate::intra::IntraMode;
use crate::intra4x4::{self, LumaIntra};
use crate::intra8x8;
use crate::modes::{MbMode, ModeCoder, VectorSyntax, MAX_REFS};
use crate::mv::{Mv, MV_LIMIT};
use crate::mvpred::{mv_prediction, mv_prediction_into, predict_in_grid, walk_partitions};
use crate::partition::{MbVectors, RefMv, Split};
use crate::picture::{check_size, MAX_DIMENSION};
use crate::residual::{MbResidual, ResidualCoder, ResidualError, ResidualSyntax};
use crate::transform::MAX_QP;
use crate::warp::{MotionGrid, SPACINGS};
use crate::weight::Weights;

pub use crate::consts::{FRAME_START, MAGIC, MB, SEQUENCE_HEADER_LEN, STREAM_END, VERSION};

/// What the sequence header says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SequenceHeader {
    /// Picture width in luma samples, 1..=16384.
    pub width: usize,
    /// Picture height in luma samples, 1..=16384.
    pub height: usize,
    /// Frame rate numerator (non-zero).
    pub fps_num: u32,
    /// Frame rate denominator (non-zero).
    pub fps_den: u32,
    /// Number of frames, or 0 when not known in advance.
    pub frame_count: u32,
    /// What the samples mean, for whoever shows the pictures; decoding
    /// does not use it.
    pub vui: Vui,
    /// The most references a P frame of the stream predicts from,
    /// 1..=[`MAX_REFS`]: how many decoded frames a decoder keeps.
    pub max_refs: u8,
}

/// Video usability information (as a codec's VUI): carried from the
/// source to the decoder's output, not used in decoding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Vui {
    /// Sample (pixel) aspect ratio, width:height; 0:0 when unknown.
    pub sar: (u16, u16),
    /// The samples' range.
    pub range: ColourRange,
    /// Where chroma samples sit against luma.
    pub siting: ChromaSiting,
}

/// The range of the samples' values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ColourRange {
    /// Not said.
    #[default]
    Unknown = 0,
    /// Limited ("TV"): luma 16-235, chroma 16-240.
    Limited = 1,
    /// Full ("PC"): 0-255.
    Full = 2,
}

/// Where 4:2:0 chroma samples sit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ChromaSiting {
    /// Not said.
    #[default]
    Unknown = 0,
    /// Centred between the four luma samples (JPEG, MPEG-1).
    Centred = 1,
    /// Co-sited with the left luma samples, centred vertically (MPEG-2,
    /// H.264).
    Left = 2,
    /// PAL DV's siting.
    PalDv = 3,
}

/// Why a sequence header is refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HeaderError {
    /// Fewer bytes than a header.
    #[error("stream of {0} bytes is shorter than the {SEQUENCE_HEADER_LEN}-byte sequence header")]
    Short(usize),
    /// Not `MOCO`.
    #[error("not a mocomp stream: it starts with {0:02x?}, not \"MOCO\"")]
    Magic([u8; 4]),
    /// Another version.
    #[error("stream version {0} is not supported (this decoder reads version {VERSION})")]
    Version(u8),
    /// A field out of range.
    #[error("sequence header: {what} = {value} is out of range")]
    Field {
        /// The field.
        what: &'static str,
        /// Its value.
        value: u64,
    },
}

impl SequenceHeader {
    /// Macroblock columns.
    pub fn mb_cols(&self) -> usize {
        self.width.div_ceil(MB)
    }

    /// Macroblock rows.
    pub fn mb_rows(&self) -> usize {
        self.height.div_ceil(MB)
    }

    /// Width of the coded (macroblock-aligned) picture.
    pub fn coded_width(&self) -> usize {
        self.mb_cols() * MB
    }

    /// Height of the coded (macroblock-aligned) picture.
    pub fn coded_height(&self) -> usize {
        self.mb_rows() * MB
    }

    /// The largest `frame_length` a frame of this size may declare: six
    /// times the raw coded picture (no valid frame comes near) plus 1 KiB.
    /// A decoder never buffers more than this per frame.
    pub fn max_frame_bytes(&self) -> u64 {
        let samples = (self.coded_width() * self.coded_height() * 3 / 2) as u64;
        6 * samples + 1024
    }

    /// Writes the header's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut w = BitWriter::new();
        w.put_bytes(&MAGIC);
        w.put(u64::from(VERSION), 8);
        w.put(self.width as u64 - 1, 16);
        w.put(self.height as u64 - 1, 16);
        w.put(1, 8); // chroma format: 4:2:0
        w.put(8, 8); // bit depth
        w.put(u64::from(self.fps_num), 32);
        w.put(u64::from(self.fps_den), 32);
        w.put(u64::from(self.frame_count), 32);
        w.put(u64::from(self.vui.sar.0), 16);
        w.put(u64::from(self.vui.sar.1), 16);
        w.put(self.vui.range as u64, 8);
        w.put(self.vui.siting as u64, 8);
        w.put(u64::from(self.max_refs), 8);
        w.into_bytes()
    }

    /// Parses and checks the first bytes of a stream.
    pub fn parse(bytes: &[u8]) -> Result<SequenceHeader, HeaderError> {
        if bytes.len() < SEQUENCE_HEADER_LEN {
            if bytes.len() >= 4 && bytes[..4] != MAGIC {
                return Err(HeaderError::Magic([bytes[0], bytes[1], bytes[2], bytes[3]]));
            }
            return Err(HeaderError::Short(bytes.len()));
        }
        let mut r = BitReader::new(&bytes[..SEQUENCE_HEADER_LEN]);
        let field = |r: &mut BitReader<'_>, n| r.get(n).map_err(|_| HeaderError::Short(bytes.len()));
        let magic = [bytes[0], bytes[1], bytes[2], bytes[3]];
        if magic != MAGIC {
            return Err(HeaderError::Magic(magic));
        }
        field(&mut r, 32)?;
        let version = field(&mut r, 8)? as u8;
        if version != VERSION {
            return Err(HeaderError::Version(version));
        }
        let width = field(&mut r, 16)? as usize + 1;
        let height = field(&mut r, 16)? as usize + 1;
        let check = |what: &'static str, value: u64, ok: bool| {
            if ok {
                Ok(())
            } else {
                Err(HeaderError::Field { what, value })
            }
        };
        check("width", width as u64, width <= MAX_DIMENSION)?;
        check("height", height as u64, height <= MAX_DIMENSION)?;
        let chroma = field(&mut r, 8)?;
        check("chroma_format", chroma, chroma == 1)?;
        let depth = field(&mut r, 8)?;
        check("bit_depth", depth, depth == 8)?;
        let fps_num = field(&mut r, 32)? as u32;
        check("fps_num", u64::from(fps_num), fps_num != 0)?;
        let fps_den = field(&mut r, 32)? as u32;
        check("fps_den", u64::from(fps_den), fps_den != 0)?;
        let frame_count = field(&mut r, 32)? as u32;
        let sar = (field(&mut r, 16)? as u16, field(&mut r, 16)? as u16);
        check("sar", u64::from(sar.0), (sar.0 == 0) == (sar.1 == 0))?;
        let range = match field(&mut r, 8)? {
            0 => ColourRange::Unknown,
            1 => ColourRange::Limited,
            2 => ColourRange::Full,
            v => {
                return Err(HeaderError::Field {
                    what: "colour_range",
                    value: v,
                })
            }
        };
        let siting = match field(&mut r, 8)? {
            0 => ChromaSiting::Unknown,
            1 => ChromaSiting::Centred,
            2 => ChromaSiting::Left,
            3 => ChromaSiting::PalDv,
            v => {
                return Err(HeaderError::Field {
                    what: "chroma_siting",
                    value: v,
                })
            }
        };
        let max_refs = field(&mut r, 8)? as u8;
        check(
            "max_refs",
            u64::from(max_refs),
            (1..=MAX_REFS).contains(&max_refs),
        )?;
        debug_assert!(check_size(width, height).is_ok());
        Ok(SequenceHeader {
            width,
            height,
            fps_num,
            fps_den,
            frame_count,
            vui: Vui { sar, range, siting },
            max_refs,
        })
    }
}

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
    /// How the reference's planes are weighted before prediction (P
    /// frames; none in I frames).
    pub weights: Weights,
}

/// How one macroblock is coded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MbKind {
    /// The prediction alone: the predicted vector (block, OBMC) or the warp
    /// (grid); no residual.
    Skip,
    /// Motion-compensated prediction plus residual. `mv` is the vector
    /// and its reference (block, OBMC); ignored (zero) with a grid.
    Inter {
        /// The macroblock's motion.
        mv: RefMv,
    },
    /// Motion-compensated prediction of each partition plus residual
    /// (block frames).
    Split {
        /// How the macroblock is split.
        split: Split,
        /// Each partition's motion in coding order; entries past the
        /// split's partitions are zero.
        mvs: [RefMv; 4],
    },
    /// Intra prediction plus residual.
    Intra {
        /// Luma mode(s): one 16x16 mode or sixteen 4x4 ones.
        luma: LumaIntra,
        /// Chroma 8x8 mode.
        chroma: IntraMode,
    },
}

impl MbKind {
    /// The syntax of its residual (section 3.3).
    pub fn residual_syntax(&self) -> ResidualSyntax {
        match self {
            MbKind::Intra {
                luma: LumaIntra::Blocks8(_),
                ..
            } => ResidualSyntax::Intra8x8,
            MbKind::Intra { .. } => ResidualSyntax::Intra,
            _ => ResidualSyntax::Inter,
        }
    }

    /// Whether the luma of a macroblock of this kind with these levels is
    /// in the 8x8 transform (section 10.2): always for 8x8 intra, for inter
    /// when it says so.
    pub fn luma_transform_8x8(&self, residual: &MbResidual) -> bool {
        self.residual_syntax() == ResidualSyntax::Intra8x8 || residual.transform_8x8()
    }
}

/// One coded macroblock.
///
/// Levels are stored only when some are non-zero, so a frame of many
/// skipped macroblocks (which a few bytes can declare) stays small.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CodedMb {
    /// How it is predicted.
    pub kind: MbKind,
    residual: Option<Box<MbResidual>>,
}

/// All-zero levels.
static NO_RESIDUAL: MbResidual = MbResidual {
    luma: [[[0; 4]; 4]; 16],
    chroma: [[[[0; 4]; 4]; 4]; 2],
    luma8: None,
};

impl CodedMb {
    /// A macroblock of `kind` with these levels.
    pub fn new(kind: MbKind, residual: MbResidual) -> CodedMb {
        CodedMb {
            kind,
            residual: (!residual.is_empty()).then(|| Box::new(residual)),
        }
    }

    /// [`CodedMb::new`] with levels already on the heap (kept there, not
    /// copied).
    pub fn with_levels(kind: MbKind, residual: Box<MbResidual>) -> CodedMb {
        CodedMb {
            kind,
            residual: (!residual.is_empty()).then_some(residual),
        }
    }

    /// A macroblock of `kind` without residual.
    pub fn without_residual(kind: MbKind) -> CodedMb {
        CodedMb { kind, residual: None }
    }

    /// Its levels (all zero when none were coded).
    pub fn residual(&self) -> &MbResidual {
        self.residual.as_deref().unwrap_or(&NO_RESIDUAL)
    }
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

/// The vectors a macroblock's 8x8 blocks use: its own for inter, the
/// prediction for skip, none for intra (which counts as unavailable to its
/// neighbours). `done` holds the vectors of the macroblocks before it in
/// raster order.
pub fn mb_vectors(kind: &MbKind, done: &[MbVectors], mb_x: usize, mb_y: usize, mb_cols: usize) -> MbVectors {
    match kind {
        MbKind::Skip => [Some(RefMv::previous(mv_prediction(done, mb_x, mb_y, mb_cols))); 4],
        MbKind::Inter { mv } => [Some(*mv); 4],
        MbKind::Split { split, mvs } => split.block_vectors(mvs).map(Some),
        MbKind::Intra { .. } => [None; 4],
    }
}

/// The predicted vector of grid node (col, row) from the nodes before it.
fn grid_prediction(grid: &MotionGrid, col: usize, row: usize) -> Mv {
    predict_in_grid(grid.cols(), col, row, |c, r| Some(grid.get(c, r)))
}

/// The mode layer's view of macroblock (mb_x, mb_y): its vectors as
/// differences from their predictions (zero when the frame codes none).
/// `done` holds the vectors of the macroblocks before it.
pub fn mb_mode(
    kind: &MbKind,
    done: &[MbVectors],
    (mb_x, mb_y, mb_cols): (usize, usize, usize),
    vectors: VectorSyntax,
) -> MbMode {
    match *kind {
        MbKind::Skip => MbMode::Skip,
        MbKind::Inter { mv } => MbMode::Inter {
            mvd: if vectors.any() {
                mv.mv - mv_prediction_into(done, (mb_x, mb_y, mb_cols), mv.ref_idx)
            } else {
                Mv::ZERO
            },
            ref_idx: mv.ref_idx,
        },
        MbKind::Split { split, mvs } => {
            let mut mvds = [Mv::ZERO; 4];
            walk_partitions(split, done, (mb_x, mb_y, mb_cols), |k, predict| {
                mvds[k] = mvs[k].mv - predict(mvs[k].ref_idx);
                Some(mvs[k])
            });
            MbMode::Split {
                split,
                mvds,
                refs: mvs.map(|m| m.ref_idx),
            }
        }
        MbKind::Intra { luma, chroma } => MbMode::Intra { luma, chroma },
    }
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
    w.put(u64::from(h.deblock), 1);
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
///     weights: mocomp_codec::weight::Weights::NONE,
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
        self.vectors
            .push(mb_vectors(&mb.kind, &self.vectors, mb_x, mb_y, self.cols));
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
        state.last = Some((self.modes, self.residual));
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

/// Panics unless a frame coding `syntax` can hold `kind` (an encoder bug).
fn check_kind(kind: &MbKind, syntax: VectorSyntax) {
    match *kind {
        MbKind::Inter { mv } => {
            assert!(
                syntax.any() || mv == RefMv::default(),
                "inter macroblocks of grid frames have no vector"
            );
            assert!(mv.mv.in_range(), "vector {mv:?} out of range");
            assert!(
                mv.ref_idx < syntax.refs(),
                "reference {} of {}",
                mv.ref_idx,
                syntax.refs()
            );
        }
        MbKind::Split { split, mvs } => {
            assert!(syntax.per_partition(), "only block frames split macroblocks");
            let n = split.parts().len();
            assert!(
                mvs[..n]
                    .iter()
                    .all(|m| m.mv.in_range() && m.ref_idx < syntax.refs()),
                "vectors {mvs:?} out of range"
            );
            assert!(
                mvs[n..].iter().all(|&mv| mv == RefMv::default()),
                "unused partition vectors"
            );
        }
        _ => {}
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

/// Why a frame's payload is invalid; `bit` counts from the first bit after
/// the frame's length field.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{what} at bit {bit} of the frame")]
pub struct SyntaxError {
    /// What is wrong.
    pub what: String,
    /// Where.
    pub bit: usize,
}

impl From<BitError> for SyntaxError {
    fn from(e: BitError) -> SyntaxError {
        let bit = match e {
            BitError::EndOfData { pos, .. }
            | BitError::ExpGolombTooLong { pos }
            | BitError::ExpGolombRange { pos } => pos,
        };
        SyntaxError {
            what: e.to_string(),
            bit,
        }
    }
}

fn invalid(what: String, bit: usize) -> SyntaxError {
    SyntaxError { what, bit }
}

/// Whether intra `mode` has its neighbours at macroblock (mb_x, mb_y):
/// the row above exists below the top row, the column to the left right of
/// the first column, the corner with both.
pub fn intra_mode_allowed(mode: IntraMode, mb_x: usize, mb_y: usize) -> bool {
    match mode {
        IntraMode::Vertical => mb_y > 0,
        IntraMode::Horizontal => mb_x > 0,
        IntraMode::Dc => true,
        IntraMode::Plane => mb_x > 0 && mb_y > 0,
    }
}

/// Whether macroblock (mb_x, mb_y) of a picture `mb_cols` macroblocks
/// wide has the neighbours of its luma intra modes: the 16x16 mode's, or
/// each 4x4 block's (inside the macroblock, its blocks above and to the
/// left).
pub fn luma_intra_allowed(luma: &LumaIntra, mb_x: usize, mb_y: usize, mb_cols: usize) -> bool {
    match luma {
        LumaIntra::Whole(mode) => intra_mode_allowed(*mode, mb_x, mb_y),
        LumaIntra::Blocks(modes) => modes.iter().enumerate().all(|(k, m)| {
            let (above, left, _) = intra4x4::neighbours(k, mb_x, mb_y, mb_cols);
            m.is_available(above, left)
        }),
        LumaIntra::Blocks8(modes) => modes.iter().enumerate().all(|(q, m)| {
            let (above, left, _) = intra8x8::neighbours(q, mb_x, mb_y, mb_cols);
            m.is_available(above, left)
        }),
    }
}

fn check_vector(mv: Option<Mv>, bit: usize) -> Result<Mv, SyntaxError> {
    match mv {
        Some(mv) if mv.in_range() => Ok(mv),
        Some(mv) => Err(invalid(
            format!("vector ({}, {}) beyond +-{MV_LIMIT}", mv.x, mv.y),
            bit,
        )),
        None => Err(invalid(
            "a vector difference beyond the syntax's range".into(),
            bit,
        )),
    }
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
    let deblock = r.get(1)? == 1;
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
            weights,
        },
        r.position() / 8,
    ))
}

/// The range-coded partition of one frame as it is read: the decoder, the
/// coders, and where errors are located.
struct PartitionReader<'a> {
    dec: RangeDecoder<'a>,
    modes: ModeCoder,
    residual: ResidualCoder,
    /// The partition's first byte in the payload.
    start: usize,
    len: usize,
}

impl PartitionReader<'_> {
    /// The bit position of the byte being read, for errors.
    fn at(&self) -> usize {
        8 * (self.start + self.dec.position().min(self.len))
    }

    /// The motion grid of a grid frame.
    fn grid(&mut self, seq: &SequenceHeader, spacing: usize) -> Result<MotionGrid, SyntaxError> {
        let mut grid = MotionGrid::new(seq.coded_width(), seq.coded_height(), spacing)
            .map_err(|e| invalid(e.to_string(), 8 * self.start))?;
        for row in 0..grid.rows() {
            for col in 0..grid.cols() {
                let d = self.modes.read_grid(&mut self.dec, grid.cols(), col, row);
                let p = grid_prediction(&grid, col, row);
                let mv = check_vector(d.and_then(|d| p.checked_add(d)), self.at())?;
                grid.set(col, row, mv);
            }
        }
        Ok(grid)
    }

    /// Macroblock (mb_x, mb_y): its mode, then its residual; `vectors`
    /// holds the vectors of the macroblocks before it.
    fn macroblock(
        &mut self,
        h: &FrameHeader,
        vectors: &[MbVectors],
        (mb_x, mb_y, cols): (usize, usize, usize),
    ) -> Result<CodedMb, SyntaxError> {
        let syntax = vector_syntax(h);
        let inter_frame = h.frame_type == FrameType::Inter;
        let kind = match self.modes.read(&mut self.dec, mb_x, mb_y, inter_frame, syntax) {
            None => {
                return Err(invalid(
                    "a vector difference beyond the syntax's range".into(),
                    self.at(),
                ))
            }
            Some(MbMode::Skip) => return Ok(CodedMb::without_residual(MbKind::Skip)),
            Some(MbMode::Inter { mvd, ref_idx }) => {
                let mv = if syntax.any() {
                    let predicted = mv_prediction_into(vectors, (mb_x, mb_y, cols), ref_idx);
                    check_vector(predicted.checked_add(mvd), self.at())?
                } else {
                    Mv::ZERO
                };
                MbKind::Inter {
                    mv: RefMv::new(mv, ref_idx),
                }
            }
            Some(MbMode::Split { split, mvds, refs }) => {
                let mut mvs = [RefMv::default(); 4];
                let mut error = None;
                walk_partitions(
                    split,
                    vectors,
                    (mb_x, mb_y, cols),
                    |k, predict| match check_vector(predict(refs[k]).checked_add(mvds[k]), self.at()) {
                        Ok(mv) => {
                            mvs[k] = RefMv::new(mv, refs[k]);
                            Some(mvs[k])
                        }
                        Err(e) => {
                            error = Some(e);
                            None
                        }
                    },
                );
                if let Some(e) = error {
                    return Err(e);
                }
                MbKind::Split { split, mvs }
            }
            Some(MbMode::Intra { luma, chroma }) => {
                if !luma_intra_allowed(&luma, mb_x, mb_y, cols) {
                    let what = match luma {
                        LumaIntra::Whole(mode) => format!("luma intra mode {mode:?} needs"),
                        LumaIntra::Blocks(modes) => format!("luma 4x4 intra modes {modes:?} need"),
                        LumaIntra::Blocks8(modes) => format!("luma 8x8 intra modes {modes:?} need"),
                    };
                    return Err(invalid(
                        format!("{what} neighbours outside the picture"),
                        self.at(),
                    ));
                }
                if !intra_mode_allowed(chroma, mb_x, mb_y) {
                    return Err(invalid(
                        format!("chroma intra mode {chroma:?} needs neighbours outside the picture"),
                        self.at(),
                    ));
                }
                MbKind::Intra { luma, chroma }
            }
        };
        let levels = self
            .residual
            .read(&mut self.dec, mb_x, mb_y, kind.residual_syntax());
        let levels = levels.map_err(|e| match e {
            ResidualError::Range { what, value, .. } => {
                invalid(format!("{what} = {value} out of range"), self.at())
            }
        })?;
        Ok(CodedMb::new(kind, levels))
    }
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
        MotionTool::Grid(spacing) => Some(part.grid(seq, spacing)?),
        _ => None,
    };
    let total = cols * rows;
    let mut mbs = Vec::with_capacity(total);
    let mut vectors: Vec<MbVectors> = Vec::with_capacity(total);
    for i in 0..total {
        let (mb_x, mb_y) = (i % cols, i / cols);
        let mb = part.macroblock(&header, &vectors, (mb_x, mb_y, cols))?;
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
    state.last = Some((part.modes, part.residual));
    Ok(FrameSyntax { header, grid, mbs })
}
