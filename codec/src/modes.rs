//! Coding of the macroblock layer (normative syntax, FORMAT.md section 3.2):
//! skip and intra flags, vector differences, intra modes and grid vectors,
//! in the frame's range-coded partition beside the residual.
//!
//! Binarised as H.264's CABAC does: the skip and intra flags in contexts
//! counting the neighbours (left, above) that were skipped or intra; each
//! vector-difference component as a zero flag in a context chosen by the
//! neighbours' difference magnitudes, `|d| - 1` in unary (up to 8, contexts
//! by bin) then third-order Exp-Golomb in bypass bins, and a bypass sign;
//! intra modes as two bins each. [`ModeCoder`] holds the contexts and the
//! neighbours' state; one binarisation writes, reads, adapts and prices.

use crate::entropy::{
    get_exp_golomb, put_exp_golomb, Adapter, Bins, Context, RangeDecoder, RangeEncoder, Writer,
};
use crate::intra::IntraMode;
use crate::intra4x4::{most_probable, neighbour_modes, Intra4x4Mode, LumaIntra, CODING_ORDER};
use crate::intra8x8::neighbour_modes8;
use crate::mv::Mv;
use crate::partition::{Part, Split, WHOLE};

// Context layout.
const SKIP: usize = 0; // 3: skipped neighbours
const INTRA: usize = SKIP + 3; // 3: intra neighbours
/// Per component: zero flag (3, by the neighbours' magnitudes), then the
/// unary bins of |d| - 1 (4: bins 0, 1, 2, 3 and beyond).
const VECTOR_CONTEXTS: usize = 7;
const MVD: usize = INTRA + 3; // 2 components
const GRID: usize = MVD + 2 * VECTOR_CONTEXTS; // 2 components
const LUMA_MODE: usize = GRID + 2 * VECTOR_CONTEXTS; // 3
const CHROMA_MODE: usize = LUMA_MODE + 3; // 3
/// Split flag (3: split neighbours), then quad (1) and vertical (1).
const SPLIT: usize = CHROMA_MODE + 3;
/// Luma coded in 4x4 blocks (3: such neighbours), then the 4x4 modes'
/// most-probable flag (1) and the bins of the others (1).
const BLOCKS4: usize = SPLIT + 5;
const MOST_PROBABLE: usize = BLOCKS4 + 3;
const REMAINING: usize = MOST_PROBABLE + 1;
/// Reference index: the first bin (3: neighbours with an index above 0),
/// the second (1), the rest (1).
const REF: usize = REMAINING + 1;
/// Luma coded in 8x8 rather than 4x4 blocks (3: such neighbours).
const BLOCKS8: usize = REF + 5;
const CONTEXTS: usize = BLOCKS8 + 3;

pub use crate::consts::MAX_REFS;

/// Unary bins of |d| - 1 before the Exp-Golomb suffix.
const UNARY_MAX: u32 = 8;
/// Order of the suffix.
const SUFFIX_ORDER: u32 = 3;
/// Longest suffix prefix a reader accepts (values far past any vector).
const MAX_SUFFIX_ONES: u32 = 24;

/// How a macroblock is coded, as the mode layer codes it (the vector as
/// its difference from the prediction).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MbMode {
    /// Skipped (P frames).
    Skip,
    /// Inter with this vector difference (zero, and not coded, in grid
    /// frames) into reference `ref_idx` (0 unless the frame has several).
    Inter {
        /// Vector minus predicted vector, quarter-pel.
        mvd: Mv,
        /// Index in the frame's reference list.
        ref_idx: u8,
    },
    /// Inter, split into partitions, with their reference indices and
    /// vector differences in coding order (entries past the split's
    /// partitions are zero).
    Split {
        /// How it is split.
        split: Split,
        /// Vector minus predicted vector per partition, quarter-pel.
        mvds: [Mv; 4],
        /// Reference index per partition.
        refs: [u8; 4],
    },
    /// Intra with these modes.
    Intra {
        /// Luma mode(s).
        luma: LumaIntra,
        /// Chroma mode.
        chroma: IntraMode,
    },
}

/// What the neighbours of a macroblock say about it.
#[derive(Debug, Clone, Copy, Default)]
struct MbState {
    /// Inside the picture (a macroblock coded already).
    inside: bool,
    skip: bool,
    intra: bool,
    split: bool,
    /// Per 8x8 block (raster order), |mvd| per component (0 unless inter).
    mvd_abs: [[u32; 2]; 4],
    /// Per 8x8 block, the reference index (0 unless inter).
    refs: [u8; 4],
    /// The 4x4 intra modes, when coded in 4x4 or 8x8 blocks (an 8x8
    /// block's mode on each of its 4x4 blocks).
    modes4: Option<[Intra4x4Mode; 16]>,
    /// Coded in 8x8 intra blocks.
    blocks8: bool,
}

impl MbState {
    /// Records partition `p`'s difference and reference on its blocks.
    fn set_partition(&mut self, p: &Part, d: Mv, ref_idx: u8) {
        for k in p.blocks() {
            self.mvd_abs[k] = [d.x.unsigned_abs(), d.y.unsigned_abs()];
            self.refs[k] = ref_idx;
        }
    }

    /// The 4x4 modes a block of the next macroblocks sees here: none
    /// outside the picture, DC unless coded in 4x4 or 8x8 blocks.
    fn modes4_seen(&self) -> Option<[Intra4x4Mode; 16]> {
        self.inside.then(|| self.modes4.unwrap_or([Intra4x4Mode::Dc; 16]))
    }
}

/// Which vectors a frame's macroblocks code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VectorSyntax {
    /// None (I frames, grid frames).
    None,
    /// One per inter macroblock (OBMC frames).
    PerMacroblock,
    /// One per partition, the split coded, each partition's vector into
    /// one of `refs` references (block frames).
    PerPartition {
        /// References the frame predicts from, 1..=[`MAX_REFS`].
        refs: u8,
    },
}

impl VectorSyntax {
    /// [`VectorSyntax::PerPartition`] with one reference.
    pub const ONE_REFERENCE: VectorSyntax = VectorSyntax::PerPartition { refs: 1 };

    /// Whether any vector is coded.
    pub fn any(self) -> bool {
        self != VectorSyntax::None
    }

    /// Whether vectors are coded per partition (the split coded).
    pub fn per_partition(self) -> bool {
        matches!(self, VectorSyntax::PerPartition { .. })
    }

    /// How many references the frame's vectors can point into.
    pub fn refs(self) -> u8 {
        match self {
            VectorSyntax::PerPartition { refs } => refs,
            _ => 1,
        }
    }
}

/// A reference index in truncated unary over `refs - 1` bins (none with
/// one reference): the first bin's context by how many of the blocks left
/// of and above the partition use a reference above 0.
fn code_ref<B: Bins>(b: &mut B, neighbours_above_0: usize, ref_idx: u8, refs: u8) {
    for i in 0..refs.saturating_sub(1) {
        let ctx = match i {
            0 => REF + neighbours_above_0,
            1 => REF + 3,
            _ => REF + 4,
        };
        b.bin(ctx, ref_idx > i);
        if ref_idx == i {
            return;
        }
    }
}

/// Reads what [`code_ref`] writes.
fn read_ref(dec: &mut RangeDecoder<'_>, c: &mut [Context], neighbours_above_0: usize, refs: u8) -> u8 {
    let mut r = 0;
    while r + 1 < refs {
        let ctx = match r {
            0 => REF + neighbours_above_0,
            1 => REF + 3,
            _ => REF + 4,
        };
        if !dec.decode(&mut c[ctx]) {
            break;
        }
        r += 1;
    }
    r
}

/// Context increment of a vector difference's zero flag from the sum of
/// the neighbours' magnitudes of that component (H.264's thresholds).
fn zero_ctx(sum: u32) -> usize {
    match sum {
        0..=2 => 0,
        3..=32 => 1,
        _ => 2,
    }
}

fn code_component<B: Bins>(b: &mut B, base: usize, neighbours: u32, d: i32) {
    b.bin(base + zero_ctx(neighbours), d != 0);
    if d == 0 {
        return;
    }
    let a = d.unsigned_abs() - 1;
    for k in 0..a.min(UNARY_MAX) {
        b.bin(base + 3 + (k as usize).min(3), true);
    }
    if a < UNARY_MAX {
        b.bin(base + 3 + (a as usize).min(3), false);
    } else {
        put_exp_golomb(b, a - UNARY_MAX, SUFFIX_ORDER);
    }
    b.bypass(d < 0);
}

fn read_component(
    dec: &mut RangeDecoder<'_>,
    c: &mut [Context],
    base: usize,
    neighbours: u32,
) -> Option<i32> {
    if !dec.decode(&mut c[base + zero_ctx(neighbours)]) {
        return Some(0);
    }
    let mut a = 0u32;
    while a < UNARY_MAX && dec.decode(&mut c[base + 3 + (a as usize).min(3)]) {
        a += 1;
    }
    if a == UNARY_MAX {
        a = a.checked_add(get_exp_golomb(dec, SUFFIX_ORDER, MAX_SUFFIX_ONES)?)?;
    }
    let m = i32::try_from(a.checked_add(1)?).ok()?;
    Some(if dec.decode_bypass() { -m } else { m })
}

fn code_intra_mode<B: Bins>(b: &mut B, base: usize, mode: IntraMode) {
    let m = mode as usize;
    b.bin(base, m >> 1 != 0);
    b.bin(base + 1 + (m >> 1), m & 1 != 0);
}

fn read_intra_mode(dec: &mut RangeDecoder<'_>, c: &mut [Context], base: usize) -> IntraMode {
    let hi = usize::from(dec.decode(&mut c[base]));
    let lo = usize::from(dec.decode(&mut c[base + 1 + hi]));
    match hi * 2 + lo {
        0 => IntraMode::Vertical,
        1 => IntraMode::Horizontal,
        2 => IntraMode::Dc,
        _ => IntraMode::Plane,
    }
}

/// The luma modes of an intra macroblock: whether in blocks, whether
/// those are 8x8, then either each block's mode against its most probable
/// one ([`code_block_modes`]), or the 16x16 mode.
fn code_luma_intra<B: Bins>(b: &mut B, n: &[&MbState; 2], luma: &LumaIntra) {
    let in_blocks = n.iter().filter(|s| s.modes4.is_some()).count();
    b.bin(BLOCKS4 + in_blocks, !matches!(luma, LumaIntra::Whole(_)));
    let around = [n[0].modes4_seen(), n[1].modes4_seen()];
    match luma {
        LumaIntra::Whole(mode) => code_intra_mode(b, LUMA_MODE, *mode),
        LumaIntra::Blocks(modes) => {
            b.bin(BLOCKS8 + blocks8_around(n), false);
            for k in CODING_ORDER {
                let (l, a) = neighbour_modes(k, modes, around[0].as_ref(), around[1].as_ref());
                code_block_mode(b, modes[k], most_probable(l, a));
            }
        }
        LumaIntra::Blocks8(modes) => {
            b.bin(BLOCKS8 + blocks8_around(n), true);
            for (q, &mode) in modes.iter().enumerate() {
                let (l, a) = neighbour_modes8(q, modes, around[0].as_ref(), around[1].as_ref());
                code_block_mode(b, mode, most_probable(l, a));
            }
        }
    }
}

/// How many of the neighbours are coded in 8x8 intra blocks.
fn blocks8_around(n: &[&MbState; 2]) -> usize {
    n.iter().filter(|s| s.blocks8).count()
}

/// A block's mode against its most probable one: a flag, else the 3 bits
/// of its rank among the other eight, least significant first.
fn code_block_mode<B: Bins>(b: &mut B, mode: Intra4x4Mode, predicted: Intra4x4Mode) {
    let (mode, predicted) = (mode as u32, predicted as u32);
    b.bin(MOST_PROBABLE, mode == predicted);
    if mode != predicted {
        let rank = mode - u32::from(mode > predicted);
        for bit in 0..3 {
            b.bin(REMAINING, (rank >> bit) & 1 == 1);
        }
    }
}

/// Reads what [`code_block_mode`] codes.
fn read_block_mode(dec: &mut RangeDecoder<'_>, c: &mut [Context], predicted: Intra4x4Mode) -> Intra4x4Mode {
    if dec.decode(&mut c[MOST_PROBABLE]) {
        return predicted;
    }
    let mut rank = 0;
    for bit in 0..3 {
        rank |= u32::from(dec.decode(&mut c[REMAINING])) << bit;
    }
    let code = rank + u32::from(rank >= predicted as u32);
    Intra4x4Mode::from_code(code).unwrap_or(Intra4x4Mode::Dc)
}

/// Reads what [`code_luma_intra`] codes.
fn read_luma_intra(dec: &mut RangeDecoder<'_>, c: &mut [Context], n: &[&MbState; 2]) -> LumaIntra {
    let in_blocks = n.iter().filter(|s| s.modes4.is_some()).count();
    if !dec.decode(&mut c[BLOCKS4 + in_blocks]) {
        return LumaIntra::Whole(read_intra_mode(dec, c, LUMA_MODE));
    }
    let around = [n[0].modes4_seen(), n[1].modes4_seen()];
    if dec.decode(&mut c[BLOCKS8 + blocks8_around(n)]) {
        let mut modes = [Intra4x4Mode::Dc; 4];
        for q in 0..4 {
            let (l, a) = neighbour_modes8(q, &modes, around[0].as_ref(), around[1].as_ref());
            modes[q] = read_block_mode(dec, c, most_probable(l, a));
        }
        return LumaIntra::Blocks8(modes);
    }
    let mut modes = [Intra4x4Mode::Dc; 16];
    for k in CODING_ORDER {
        let (l, a) = neighbour_modes(k, &modes, around[0].as_ref(), around[1].as_ref());
        modes[k] = read_block_mode(dec, c, most_probable(l, a));
    }
    LumaIntra::Blocks(modes)
}

/// The split (when the frame codes one) and vector differences of an inter
/// macroblock: the reader twin of [`code_flags`]' split and [`code_mvd`].
fn read_inter(
    dec: &mut RangeDecoder<'_>,
    c: &mut [Context],
    n: &[&MbState; 2],
    vectors: VectorSyntax,
) -> Option<MbMode> {
    let split = if vectors.per_partition() && dec.decode(&mut c[SPLIT + n.iter().filter(|s| s.split).count()])
    {
        Some(if dec.decode(&mut c[SPLIT + 3]) {
            Split::Quad
        } else if dec.decode(&mut c[SPLIT + 4]) {
            Split::Vertical
        } else {
            Split::Horizontal
        })
    } else {
        None
    };
    let parts = split.map_or(std::slice::from_ref(&WHOLE), Split::parts);
    let (mut mvds, mut refs) = ([Mv::ZERO; 4], [0u8; 4]);
    if vectors.any() {
        let mut own = MbState::default();
        for ((p, d), r) in parts.iter().zip(&mut mvds).zip(&mut refs) {
            *r = read_ref(dec, c, refs_above_0(n, &own, p), vectors.refs());
            let sums = neighbour_sums(n, &own, p);
            d.x = read_component(dec, c, MVD, sums[0])?;
            d.y = read_component(dec, c, MVD + VECTOR_CONTEXTS, sums[1])?;
            own.set_partition(p, *d, *r);
        }
    }
    Some(match split {
        Some(split) => MbMode::Split { split, mvds, refs },
        None => MbMode::Inter {
            mvd: mvds[0],
            ref_idx: refs[0],
        },
    })
}

/// The state of a macroblock outside the picture.
const OUTSIDE: MbState = MbState {
    inside: false,
    skip: false,
    intra: false,
    split: false,
    mvd_abs: [[0; 2]; 4],
    refs: [0; 4],
    modes4: None,
    blocks8: false,
};

/// Neighbour state of macroblock (x, y): the left and above ones
/// ([`OUTSIDE`] outside the picture). By reference: the pricing of every
/// candidate asks for them.
fn neighbours(states: &[MbState], cols: usize, x: usize, y: usize) -> [&MbState; 2] {
    let left = if x > 0 {
        &states[y * cols + x - 1]
    } else {
        &OUTSIDE
    };
    let above = if y > 0 {
        &states[(y - 1) * cols + x]
    } else {
        &OUTSIDE
    };
    [left, above]
}

/// Everything of a macroblock's mode but its vector difference.
fn code_flags<B: Bins>(
    b: &mut B,
    n: &[&MbState; 2],
    inter_frame: bool,
    mode: &MbMode,
    vectors: VectorSyntax,
) {
    if inter_frame {
        let skipped = n.iter().filter(|s| s.skip).count();
        b.bin(SKIP + skipped, *mode == MbMode::Skip);
        if *mode == MbMode::Skip {
            return;
        }
        let intra = n.iter().filter(|s| s.intra).count();
        b.bin(INTRA + intra, matches!(mode, MbMode::Intra { .. }));
    }
    match *mode {
        MbMode::Intra { luma, chroma } => {
            code_luma_intra(b, n, &luma);
            code_intra_mode(b, CHROMA_MODE, chroma);
        }
        MbMode::Inter { .. } if vectors.per_partition() => code_split(b, n, None),
        MbMode::Split { split, .. } => code_split(b, n, Some(split)),
        _ => {}
    }
}

/// The reference indices and vector differences of an inter macroblock
/// (none for the others, or when the frame codes no vectors), per
/// partition, each element's context from the 8x8 blocks left of and
/// above the partition's top-left block.
fn code_mvd<B: Bins>(b: &mut B, n: &[&MbState; 2], mode: &MbMode, vectors: VectorSyntax) {
    if !vectors.any() {
        return;
    }
    let (parts, mvds, refs) = match mode {
        MbMode::Inter { mvd, ref_idx } => (
            std::slice::from_ref(&WHOLE),
            std::slice::from_ref(mvd),
            std::slice::from_ref(ref_idx),
        ),
        MbMode::Split { split, mvds, refs } => (split.parts(), &mvds[..], &refs[..]),
        _ => return,
    };
    let mut own = MbState::default();
    for ((p, d), &r) in parts.iter().zip(mvds).zip(refs) {
        code_ref(b, refs_above_0(n, &own, p), r, vectors.refs());
        let sums = neighbour_sums(n, &own, p);
        for (c, v) in [d.x, d.y].into_iter().enumerate() {
            code_component(b, MVD + c * VECTOR_CONTEXTS, sums[c], v);
        }
        own.set_partition(p, *d, r);
    }
}

/// The 8x8 blocks left of and above partition `p`'s top-left block: in
/// the macroblock (`own`, its partitions coded so far) or in the
/// neighbours `n`, as (state, block index).
fn left_and_above<'a>(n: &[&'a MbState; 2], own: &'a MbState, p: &Part) -> [(&'a MbState, usize); 2] {
    let left = if p.x8 > 0 {
        (own, p.y8 * 2)
    } else {
        (n[0], p.y8 * 2 + 1)
    };
    let above = if p.y8 > 0 { (own, p.x8) } else { (n[1], 2 + p.x8) };
    [left, above]
}

/// Per component, |mvd| of the 8x8 block left of partition `p`'s top-left
/// block plus that of the one above it.
fn neighbour_sums(n: &[&MbState; 2], own: &MbState, p: &Part) -> [u32; 2] {
    let [(l, i), (a, j)] = left_and_above(n, own, p);
    [
        l.mvd_abs[i][0] + a.mvd_abs[j][0],
        l.mvd_abs[i][1] + a.mvd_abs[j][1],
    ]
}

/// How many of the 8x8 blocks left of and above partition `p`'s top-left
/// block use a reference above 0.
fn refs_above_0(n: &[&MbState; 2], own: &MbState, p: &Part) -> usize {
    left_and_above(n, own, p)
        .iter()
        .filter(|(s, k)| s.refs[*k] > 0)
        .count()
}

/// The split of an inter macroblock of a frame coding vectors per partition.
fn code_split<B: Bins>(b: &mut B, n: &[&MbState; 2], split: Option<Split>) {
    let ctx = SPLIT + n.iter().filter(|s| s.split).count();
    b.bin(ctx, split.is_some());
    if let Some(split) = split {
        b.bin(SPLIT + 3, split == Split::Quad);
        if split != Split::Quad {
            b.bin(SPLIT + 4, split == Split::Vertical);
        }
    }
}

fn code_mb<B: Bins>(b: &mut B, n: &[&MbState; 2], inter_frame: bool, mode: &MbMode, vectors: VectorSyntax) {
    code_flags(b, n, inter_frame, mode, vectors);
    code_mvd(b, n, mode, vectors);
}

/// `out` set to the state `mode` leaves, in place (built apart and
/// copied in, the 60-byte record was read back before its narrower
/// stores had landed: a stall a macroblock, 1.8 % of the samples of an
/// ultrafast encode of dog_1080p in one profile).
fn set_state(out: &mut MbState, mode: &MbMode) {
    *out = MbState {
        inside: true,
        ..MbState::default()
    };
    match *mode {
        MbMode::Skip => out.skip = true,
        MbMode::Inter { mvd, ref_idx } => out.set_partition(&WHOLE, mvd, ref_idx),
        MbMode::Split { split, mvds, refs } => {
            out.split = true;
            for ((p, &d), &r) in split.parts().iter().zip(&mvds).zip(&refs) {
                out.set_partition(p, d, r);
            }
        }
        MbMode::Intra { luma, .. } => {
            out.intra = true;
            out.modes4 = luma.modes4();
            out.blocks8 = matches!(luma, LumaIntra::Blocks8(_));
        }
    }
}

/// The mode coder of one frame: contexts, and the state of the macroblocks
/// (and grid nodes) coded so far.
///
/// ```
/// use mocomp_codec::entropy::{RangeDecoder, RangeEncoder};
/// use mocomp_codec::intra::IntraMode;
/// use mocomp_codec::intra4x4::LumaIntra;
/// use mocomp_codec::modes::{MbMode, ModeCoder, VectorSyntax};
/// use mocomp_codec::mv::Mv;
/// let modes = [
///     MbMode::Skip,
///     MbMode::Inter { mvd: Mv::new(-5, 130), ref_idx: 0 },
///     MbMode::Intra { luma: LumaIntra::Whole(IntraMode::Dc), chroma: IntraMode::Horizontal },
/// ];
/// let mut coder = ModeCoder::new(3, 1);
/// let mut enc = RangeEncoder::new();
/// for (x, m) in modes.iter().enumerate() {
///     coder.write(&mut enc, x, 0, true, VectorSyntax::ONE_REFERENCE, m);
/// }
/// let bytes = enc.finish();
/// let mut coder = ModeCoder::new(3, 1);
/// let mut dec = RangeDecoder::new(&bytes);
/// for (x, m) in modes.iter().enumerate() {
///     assert_eq!(coder.read(&mut dec, x, 0, true, VectorSyntax::ONE_REFERENCE), Some(*m));
/// }
/// ```
#[derive(Debug, Clone)]
pub struct ModeCoder {
    contexts: [Context; CONTEXTS],
    mb_cols: usize,
    mb_rows: usize,
    states: Vec<MbState>,
    /// |difference| per component of the grid nodes coded so far.
    grid: Vec<[u32; 2]>,
}

impl ModeCoder {
    /// A coder at the start of a frame of `mb_cols x mb_rows` macroblocks.
    pub fn new(mb_cols: usize, mb_rows: usize) -> ModeCoder {
        ModeCoder {
            contexts: [Context::new(); CONTEXTS],
            mb_cols,
            mb_rows,
            states: vec![MbState::default(); mb_cols * mb_rows],
            grid: Vec::new(),
        }
    }

    /// A coder for the next frame that starts from the contexts this one
    /// has reached (P frames carry them over, FORMAT.md section 3.4).
    pub fn next_frame(&self) -> ModeCoder {
        let mut next = ModeCoder::new(self.mb_cols, self.mb_rows);
        next.contexts = self.contexts;
        next
    }

    /// What the next frame carries over of this coder: its contexts, the
    /// macroblocks' states dropped (so that the state kept between frames
    /// is cheap to hold and to copy).
    pub fn carried(mut self) -> ModeCoder {
        self.states = Vec::new();
        self.grid = Vec::new();
        self
    }

    fn neighbours(&self, mb_x: usize, mb_y: usize) -> [&MbState; 2] {
        neighbours(&self.states, self.mb_cols, mb_x, mb_y)
    }

    /// Runs the binarisation of `mode` as macroblock (mb_x, mb_y) in the
    /// present state into `bins` (`inter_frame`: a P frame; `vectors`:
    /// which vectors the frame codes), adapting nothing: what an encoder
    /// prices its choices with ([`crate::entropy::Pricer`]).
    pub fn replay<B: Bins>(
        &self,
        bins: &mut B,
        (mb_x, mb_y): (usize, usize),
        inter_frame: bool,
        vectors: VectorSyntax,
        mode: &MbMode,
    ) {
        code_mb(bins, &self.neighbours(mb_x, mb_y), inter_frame, mode, vectors);
    }

    /// The context of macroblock (mb_x, mb_y)'s skip flag (in a P frame).
    pub fn skip_context(&self, mb_x: usize, mb_y: usize) -> usize {
        SKIP + self.skipped_neighbours(mb_x, mb_y)
    }

    /// How many of macroblock (mb_x, mb_y)'s neighbours (left, above) are
    /// intra.
    pub fn intra_neighbours(&self, mb_x: usize, mb_y: usize) -> usize {
        self.neighbours(mb_x, mb_y).iter().filter(|s| s.intra).count()
    }

    /// How many of macroblock (mb_x, mb_y)'s neighbours (left, above) were
    /// skipped.
    pub fn skipped_neighbours(&self, mb_x: usize, mb_y: usize) -> usize {
        self.neighbours(mb_x, mb_y).iter().filter(|s| s.skip).count()
    }

    /// The contexts of a 4x4 or 8x8 intra mode: the most-probable flag,
    /// and the remaining mode's three bins.
    pub const MODE4_CONTEXTS: (usize, usize) = (MOST_PROBABLE, REMAINING);

    /// The contexts in their present state.
    pub fn contexts(&self) -> &[Context] {
        &self.contexts
    }

    /// The 4x4 intra modes the blocks of macroblock (mb_x, mb_y) see in
    /// the macroblocks left of and above it (`None` outside the picture,
    /// all DC when not coded in 4x4 blocks): what an encoder needs to
    /// predict modes while choosing them.
    pub fn modes4_around(&self, mb_x: usize, mb_y: usize) -> [Option<[Intra4x4Mode; 16]>; 2] {
        self.neighbours(mb_x, mb_y).map(|s| s.modes4_seen())
    }

    /// Takes `contexts` (another coder's [`ModeCoder::contexts`]) as its
    /// own, keeping its record of the macroblocks: an encoder pricing a
    /// row from the state the row above reached (wavefront). Panics if
    /// `contexts` is not another mode coder's (a different length).
    pub fn set_contexts(&mut self, contexts: &[Context]) {
        self.contexts.copy_from_slice(contexts);
    }

    /// Records macroblock (mb_x, mb_y)'s `mode` as a neighbour without
    /// adapting anything: what another coder committed there.
    pub fn record(&mut self, mb_x: usize, mb_y: usize, mode: &MbMode) {
        set_state(&mut self.states[mb_y * self.mb_cols + mb_x], mode);
    }

    /// Adapts and records as [`ModeCoder::write`] does, without writing.
    pub fn commit(
        &mut self,
        mb_x: usize,
        mb_y: usize,
        inter_frame: bool,
        vectors: VectorSyntax,
        mode: &MbMode,
    ) {
        let n = neighbours(&self.states, self.mb_cols, mb_x, mb_y);
        code_mb(
            &mut Adapter(&mut self.contexts[..]),
            &n,
            inter_frame,
            mode,
            vectors,
        );
        set_state(&mut self.states[mb_y * self.mb_cols + mb_x], mode);
    }

    /// Writes macroblock (mb_x, mb_y)'s mode; returns the cost, in 1/256
    /// bit, of the bins as coded: `(vector difference, the rest)`.
    pub fn write(
        &mut self,
        enc: &mut RangeEncoder,
        mb_x: usize,
        mb_y: usize,
        inter_frame: bool,
        vectors: VectorSyntax,
        mode: &MbMode,
    ) -> (u32, u32) {
        let n = neighbours(&self.states, self.mb_cols, mb_x, mb_y);
        // The flags and modes first, priced apart from the vector.
        let mut w = Writer::new(enc, &mut self.contexts[..]);
        code_flags(&mut w, &n, inter_frame, mode, vectors);
        let rest = w.cost;
        w.cost = 0;
        code_mvd(&mut w, &n, mode, vectors);
        let motion = w.cost;
        set_state(&mut self.states[mb_y * self.mb_cols + mb_x], mode);
        (motion, rest)
    }

    /// Reads what [`ModeCoder::write`] writes; `None` for a vector
    /// difference beyond what the syntax can carry.
    pub fn read(
        &mut self,
        dec: &mut RangeDecoder<'_>,
        mb_x: usize,
        mb_y: usize,
        inter_frame: bool,
        vectors: VectorSyntax,
    ) -> Option<MbMode> {
        let n = neighbours(&self.states, self.mb_cols, mb_x, mb_y);
        let c = &mut self.contexts;
        let mut intra = !inter_frame;
        if inter_frame {
            let skipped = n.iter().filter(|s| s.skip).count();
            if dec.decode(&mut c[SKIP + skipped]) {
                set_state(&mut self.states[mb_y * self.mb_cols + mb_x], &MbMode::Skip);
                return Some(MbMode::Skip);
            }
            intra = dec.decode(&mut c[INTRA + n.iter().filter(|s| s.intra).count()]);
        }
        let mode = if intra {
            let luma = read_luma_intra(dec, c, &n);
            let chroma = read_intra_mode(dec, c, CHROMA_MODE);
            MbMode::Intra { luma, chroma }
        } else {
            read_inter(dec, c, &n, vectors)?
        };
        set_state(&mut self.states[mb_y * self.mb_cols + mb_x], &mode);
        Some(mode)
    }

    /// Writes the difference of grid node (col, row) of a grid `cols`
    /// wide (nodes in raster order); returns its cost in 1/256 bit.
    pub fn write_grid(&mut self, enc: &mut RangeEncoder, cols: usize, col: usize, row: usize, d: Mv) -> u32 {
        let sums = self.grid_sums(cols, col, row);
        let mut w = Writer::new(enc, &mut self.contexts[..]);
        code_component(&mut w, GRID, sums[0], d.x);
        code_component(&mut w, GRID + VECTOR_CONTEXTS, sums[1], d.y);
        self.grid.push([d.x.unsigned_abs(), d.y.unsigned_abs()]);
        w.cost
    }

    /// Reads what [`ModeCoder::write_grid`] writes.
    pub fn read_grid(
        &mut self,
        dec: &mut RangeDecoder<'_>,
        cols: usize,
        col: usize,
        row: usize,
    ) -> Option<Mv> {
        let sums = self.grid_sums(cols, col, row);
        let x = read_component(dec, &mut self.contexts, GRID, sums[0])?;
        let y = read_component(dec, &mut self.contexts, GRID + VECTOR_CONTEXTS, sums[1])?;
        self.grid.push([x.unsigned_abs(), y.unsigned_abs()]);
        Some(Mv::new(x, y))
    }

    /// Per component, the magnitudes of the left and above nodes' differences.
    fn grid_sums(&self, cols: usize, col: usize, row: usize) -> [u32; 2] {
        debug_assert_eq!(self.grid.len(), row * cols + col, "grid nodes in raster order");
        let mut s = [0u32; 2];
        let i = row * cols + col;
        for (ok, j) in [(col > 0, i.wrapping_sub(1)), (row > 0, i.wrapping_sub(cols))] {
            if let Some(d) = self.grid.get(j).filter(|_| ok) {
                s[0] = s[0].saturating_add(d[0]);
                s[1] = s[1].saturating_add(d[1]);
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::entropy::Pricer;

    /// The bits of `mode` at (x, y), priced as an encoder prices it.
    fn cost(
        c: &ModeCoder,
        x: usize,
        y: usize,
        inter_frame: bool,
        vectors: VectorSyntax,
        mode: &MbMode,
    ) -> u32 {
        let mut p = Pricer::new(c.contexts(), 0);
        c.replay(&mut p, (x, y), inter_frame, vectors, mode);
        p.cost
    }
    use proptest::prelude::*;

    fn mode_strategy() -> impl Strategy<Value = MbMode> {
        prop_oneof![
            Just(MbMode::Skip),
            (-40_000i32..=40_000, -300i32..=300, 0..MAX_REFS).prop_map(|(x, y, ref_idx)| MbMode::Inter {
                mvd: Mv::new(x, y),
                ref_idx
            }),
            (
                0usize..3,
                proptest::collection::vec((-3000i32..=3000, -40i32..=40, 0..MAX_REFS), 4)
            )
                .prop_map(|(s, d)| {
                    let split = Split::ALL[s];
                    let (mut mvds, mut refs) = ([Mv::ZERO; 4], [0; 4]);
                    for (k, &(x, y, r)) in d.iter().enumerate().take(split.parts().len()) {
                        mvds[k] = Mv::new(x, y);
                        refs[k] = r;
                    }
                    MbMode::Split { split, mvds, refs }
                }),
            (0u32..4, 0u32..4).prop_map(|(l, c)| MbMode::Intra {
                luma: LumaIntra::Whole(IntraMode::from_code(l).unwrap_or(IntraMode::Dc)),
                chroma: IntraMode::from_code(c).unwrap_or(IntraMode::Dc),
            }),
            (proptest::collection::vec(0u32..9, 16), 0u32..4).prop_map(|(l, c)| {
                let mut modes = [Intra4x4Mode::Dc; 16];
                for (m, &code) in modes.iter_mut().zip(&l) {
                    *m = Intra4x4Mode::from_code(code).unwrap_or(Intra4x4Mode::Dc);
                }
                MbMode::Intra {
                    luma: LumaIntra::Blocks(modes),
                    chroma: IntraMode::from_code(c).unwrap_or(IntraMode::Dc),
                }
            }),
            (proptest::collection::vec(0u32..9, 4), 0u32..4).prop_map(|(l, c)| {
                let mut modes = [Intra4x4Mode::Dc; 4];
                for (m, &code) in modes.iter_mut().zip(&l) {
                    *m = Intra4x4Mode::from_code(code).unwrap_or(Intra4x4Mode::Dc);
                }
                MbMode::Intra {
                    luma: LumaIntra::Blocks8(modes),
                    chroma: IntraMode::from_code(c).unwrap_or(IntraMode::Dc),
                }
            }),
        ]
    }

    proptest! {
        #[test]
        fn modes_and_grids_round_trip(
            modes in proptest::collection::vec(mode_strategy(), 12),
            grid in proptest::collection::vec((-70_000i32..=70_000, -5i32..=5), 6),
            inter_frame in any::<bool>(),
            refs in 1..=MAX_REFS,
        ) {
            // 4 x 3 macroblocks; a 3 x 2 grid first. I frames hold intra
            // only; reference indices below `refs`.
            let syntax = VectorSyntax::PerPartition { refs };
            let modes: Vec<MbMode> = modes
                .into_iter()
                .map(|m| match m {
                    MbMode::Intra { .. } => m,
                    MbMode::Inter { mvd, ref_idx } if inter_frame => MbMode::Inter { mvd, ref_idx: ref_idx % refs },
                    MbMode::Split { split, mvds, refs: r } if inter_frame => {
                        MbMode::Split { split, mvds, refs: r.map(|r| r % refs) }
                    }
                    _ if inter_frame => m,
                    _ => MbMode::Intra { luma: LumaIntra::Whole(IntraMode::Dc), chroma: IntraMode::Plane },
                })
                .collect();
            let mut w = ModeCoder::new(4, 3);
            let mut shadow = ModeCoder::new(4, 3);
            let mut enc = RangeEncoder::new();
            for (i, &(x, y)) in grid.iter().enumerate() {
                w.write_grid(&mut enc, 3, i % 3, i / 3, Mv::new(x, y));
            }
            for (i, m) in modes.iter().enumerate() {
                w.write(&mut enc, i % 4, i / 4, inter_frame, syntax, m);
                shadow.commit(i % 4, i / 4, inter_frame, syntax, m);
            }
            let bytes = enc.finish();
            let mut r = ModeCoder::new(4, 3);
            let mut dec = RangeDecoder::new(&bytes);
            for (i, &(x, y)) in grid.iter().enumerate() {
                prop_assert_eq!(r.read_grid(&mut dec, 3, i % 3, i / 3), Some(Mv::new(x, y)));
            }
            for (i, m) in modes.iter().enumerate() {
                prop_assert_eq!(r.read(&mut dec, i % 4, i / 4, inter_frame, syntax), Some(*m));
            }
            prop_assert!(dec.consumed_all());
            // Committing adapts the macroblock contexts as writing does.
            prop_assert_eq!(&shadow.contexts[..GRID], &w.contexts[..GRID]);
            prop_assert_eq!(&shadow.contexts[LUMA_MODE..], &w.contexts[LUMA_MODE..]);
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..32)) {
            let mut r = ModeCoder::new(3, 3);
            let mut dec = RangeDecoder::new(&bytes);
            for i in 0..4 {
                let _ = r.read_grid(&mut dec, 2, i % 2, i / 2);
            }
            for i in 0..9 {
                let refs = 1 + i as u8 % MAX_REFS;
                let _ = r.read(&mut dec, i % 3, i / 3, i % 2 == 0, VectorSyntax::PerPartition { refs });
            }
        }
    }

    /// The bits of a lone intra macroblock at (1, 0) of a 2 x 1 picture
    /// whose left neighbour is `left`.
    fn bits_after(left: LumaIntra, mb: LumaIntra) -> u32 {
        let mut c = ModeCoder::new(2, 1);
        let intra = |luma| MbMode::Intra {
            luma,
            chroma: IntraMode::Dc,
        };
        c.commit(0, 0, false, VectorSyntax::None, &intra(left));
        // Every bin at even odds: a bin costs one bit.
        c.contexts = [Context::new(); CONTEXTS];
        cost(&c, 1, 0, false, VectorSyntax::None, &intra(mb))
    }

    #[test]
    fn block_modes_are_predicted_across_4x4_and_8x8_macroblocks() {
        use Intra4x4Mode::*;
        // In the top row, 8x8 blocks 0 and 1 have nothing above: DC is
        // their most probable mode. Left of 8x8 block 2 lies 4x4 block 11
        // of the left macroblock (Horizontal), above it block 0 (DC): the
        // lower, Horizontal. Block 3 has block 2 left, block 1 above.
        let mut left4 = [VerticalLeft; 16];
        left4[11] = Horizontal;
        let left8 = [VerticalLeft, VerticalLeft, VerticalLeft, Horizontal];
        let probable = LumaIntra::Blocks8([Dc, Dc, Horizontal, Horizontal]);
        let one_other = LumaIntra::Blocks8([Dc, Dc, Vertical, Vertical]);
        for left in [LumaIntra::Blocks(left4), LumaIntra::Blocks8(left8)] {
            // Two flags (in blocks, 8x8), the chroma mode's two bins, a
            // flag per block; a mode other than the most probable one adds
            // its rank's three bins.
            assert_eq!(bits_after(left, probable), 8 * 256, "{left:?}");
            assert_eq!(bits_after(left, one_other), 11 * 256, "{left:?}");
        }
        // A 4x4 macroblock after an 8x8 one sees the 8x8 modes on its
        // blocks: with the top row DC and the rest Horizontal, every block
        // has its most probable mode after the 8x8 macroblock; after a
        // 16x16 one, block 4 does not (left DC, above DC).
        let blocks = std::array::from_fn(|k| if k < 4 { Dc } else { Horizontal });
        let left8 = [VerticalLeft, Horizontal, VerticalLeft, Horizontal];
        let after8 = bits_after(LumaIntra::Blocks8(left8), LumaIntra::Blocks(blocks));
        let after16 = bits_after(LumaIntra::Whole(IntraMode::Dc), LumaIntra::Blocks(blocks));
        assert_eq!((after8, after16), (20 * 256, 23 * 256));
    }

    #[test]
    fn a_run_of_skips_gets_cheap() {
        let mut c = ModeCoder::new(40, 1);
        let first = cost(&c, 0, 0, true, VectorSyntax::ONE_REFERENCE, &MbMode::Skip);
        for x in 0..39 {
            c.commit(x, 0, true, VectorSyntax::ONE_REFERENCE, &MbMode::Skip);
        }
        let later = cost(&c, 39, 0, true, VectorSyntax::ONE_REFERENCE, &MbMode::Skip);
        assert_eq!(first, 256);
        assert!(later < 64, "{later}"); // under a quarter of a bit
    }

    #[test]
    fn reference_indices_cost_nothing_with_one_reference_and_grow_with_the_index() {
        let c = ModeCoder::new(2, 1);
        let inter = |ref_idx| MbMode::Inter {
            mvd: Mv::new(4, 0),
            ref_idx,
        };
        let one = cost(&c, 0, 0, true, VectorSyntax::ONE_REFERENCE, &inter(0));
        // A first bin at even odds costs one bit.
        let three = VectorSyntax::PerPartition { refs: 3 };
        assert_eq!(cost(&c, 0, 0, true, three, &inter(0)), one + 256);
        assert_eq!(cost(&c, 0, 0, true, three, &inter(1)), one + 512);
        // The last index needs no terminating bin.
        assert_eq!(cost(&c, 0, 0, true, three, &inter(2)), one + 512);
        // A neighbour on reference 2 moves the first bin to another context.
        let mut c = ModeCoder::new(2, 1);
        for _ in 0..20 {
            c.commit(0, 0, true, three, &inter(0));
        }
        let after_zeros = cost(&c, 1, 0, true, three, &inter(0));
        c.commit(0, 0, true, three, &inter(2));
        assert!(cost(&c, 1, 0, true, three, &inter(0)) > after_zeros);
    }
}
