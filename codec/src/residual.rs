//! Coding of quantised transform coefficients (normative syntax, FORMAT.md
//! section 3.3).
//!
//! A macroblock's residual is 16 luma and 2 x 4 chroma 4x4 blocks of levels,
//! coded in the frame's range-coded partition with the adaptive binary range
//! coder of [`crate::entropy`], binarised as H.264's CABAC does:
//!
//! * the coded block pattern, one bin per luma 8x8 quadrant and one per
//!   chroma plane, each in a context chosen by whether the neighbouring
//!   quadrant (or the neighbouring macroblocks' plane) left and above had
//!   levels;
//! * per 4x4 block of a flagged quadrant or plane, a coded-block flag whose
//!   context counts the coded blocks left and above (the fourth flag of a
//!   group whose first three are 0 is implied);
//! * per flagged chroma plane, first its DC levels as H.264 codes them:
//!   the 2x2 Hadamard transform of its four blocks' DC coefficients
//!   ([`crate::transform::quantize_chroma_dc`]), held in the blocks'
//!   position 0, a flag then one 4-position block in contexts of their
//!   own; its blocks' flags and scans then cover their AC levels
//!   (positions 1 to 15; the fourth flag implied only without DC levels);
//! * in an intra 16x16 macroblock, likewise its luma DC levels: the 4x4
//!   Hadamard transform of its sixteen blocks' DC coefficients
//!   ([`crate::transform::quantize_luma_dc`], held in
//!   [`MbResidual::luma_dc`]), a flag then one 16-position block in
//!   contexts of their own, right after the coded block pattern; its
//!   quadrants' pattern bits, blocks' flags and scans then cover the
//!   blocks' AC levels (the fourth flag of a quadrant implied as ever);
//! * per coded block, the significance map in zig-zag order (a
//!   `significant` bin per position, each followed when set by a `last`
//!   bin, both with a context per position), then the levels from the last
//!   to the first: `|level| > 1` in a context counting the levels of 1 and
//!   above 1 seen so far, `|level| - 2` in unary (contexts by the levels
//!   above 1 seen) up to 14 and Exp-Golomb (k = 0) in bypass bins beyond,
//!   and a bypass sign bin.
//!
//! Each of the four block classes (luma or chroma, of intra or inter
//! macroblocks) has its own contexts. [`ResidualCoder`] holds the contexts
//! and the neighbours' coded flags of one frame; the same binarisation
//! writes ([`ResidualCoder::write`]), reads ([`ResidualCoder::read`]),
//! adapts without writing ([`ResidualCoder::commit`]) and prices
//! ([`ResidualCoder::cost`]), so the encoder's rate term follows the coder
//! exactly as it adapts.

use crate::entropy::{
    exp_golomb_bins, get_exp_golomb, put_exp_golomb, Adapter, Bins, Context, RangeDecoder, RangeEncoder,
    Writer,
};
use crate::transform::Block4;
use crate::transform8x8::{Block8, ZIGZAG8};

/// H.264's 4x4 frame zig-zag scan: `ZIGZAG[k]` is the raster index
/// (`row * 4 + col`) of the k-th coefficient.
pub const ZIGZAG: [usize; 16] = [0, 1, 4, 8, 5, 2, 3, 6, 9, 12, 13, 10, 7, 11, 14, 15];

pub use crate::consts::MAX_LEVEL;

/// Levels up to `2 + UNARY_MAX - 1` above 1 are coded in unary; beyond,
/// an Exp-Golomb suffix follows.
const UNARY_MAX: u32 = 14;

/// Longest Exp-Golomb prefix a reader accepts (enough for [`MAX_LEVEL`]).
const MAX_EG_PREFIX: u32 = 16;

/// Why coefficient data is invalid.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ResidualError {
    /// A value outside its range.
    #[error("{what} is {value}, out of range, at byte {pos} of the range-coded partition")]
    Range {
        /// The syntax element.
        what: &'static str,
        /// Its value.
        value: u64,
        /// Byte of the range-coded partition being read.
        pos: usize,
    },
}

/// The levels of one macroblock: 16 luma blocks in raster order of 4x4
/// blocks within the macroblock (or four 8x8 blocks), then 4 Cb and 4 Cr
/// blocks.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct MbResidual {
    /// Luma 4x4 blocks, index `by * 4 + bx` (all zero when `luma8` holds
    /// the luma).
    pub luma: [Block4; 16],
    /// Chroma 4x4 blocks, `[plane][by * 2 + bx]`, plane 0 = Cb: their AC
    /// levels, and in position 0 of block k the plane's DC level k (of the
    /// 2x2 Hadamard transform of the blocks' DC coefficients).
    pub chroma: [[Block4; 4]; 2],
    /// The luma in the 8x8 transform's blocks (quadrant `qy * 2 + qx`),
    /// when the macroblock uses it. An inter macroblock says so only when
    /// it has luma levels: `Some` must hold at least one.
    pub luma8: Option<Box<[Block8; 4]>>,
    /// An intra 16x16 macroblock's luma DC levels (of the 4x4 Hadamard
    /// transform of its sixteen blocks' DC coefficients, raster order of
    /// the blocks), its luma blocks then holding their AC levels alone
    /// (position 0 zero). Zero in every other macroblock.
    pub luma_dc: [i32; 16],
}

// (An OR of every level rather than a search for the first non-zero one:
// it vectorises, and most blocks asked about are all zero.)
fn is_zero(b: &Block4) -> bool {
    b.as_flattened().iter().fold(0, |acc, &v| acc | v) == 0
}

fn is_zero8(b: &Block8) -> bool {
    b.as_flattened().iter().fold(0, |acc, &v| acc | v) == 0
}

/// Luma 4x4 block indices of 8x8 quadrant `q`.
fn quadrant_blocks(q: usize) -> [usize; 4] {
    let (qx, qy) = (q % 2, q / 2);
    let first = qy * 8 + qx * 2;
    [first, first + 1, first + 4, first + 5]
}

impl MbResidual {
    /// Whether every level is zero.
    pub fn is_empty(&self) -> bool {
        self.luma.iter().all(is_zero)
            && self.luma_dc == [0; 16]
            && self.chroma.iter().flatten().all(is_zero)
            && self.luma8.as_deref().is_none_or(|b| b.iter().all(is_zero8))
    }

    /// The coded block pattern of these levels: bit q for luma quadrant q,
    /// bit 4 for Cb, bit 5 for Cr.
    pub fn cbp(&self) -> u32 {
        cbp_of(
            &self.luma_coded(),
            &[coded_flags(&self.chroma[0]), coded_flags(&self.chroma[1])],
        )
    }

    /// Whether each luma 4x4 block (raster, `by * 4 + bx`) has levels; with
    /// the 8x8 transform, the four of an 8x8 block with levels all do.
    pub fn luma_coded(&self) -> [bool; 16] {
        match &self.luma8 {
            None => coded_flags(&self.luma),
            Some(b8) => {
                let coded = [0, 1, 2, 3].map(|q| !is_zero8(&b8[q]));
                std::array::from_fn(|k| coded[(k / 8) * 2 + (k % 4) / 2])
            }
        }
    }

    /// Whether the luma uses the 8x8 transform.
    pub fn transform_8x8(&self) -> bool {
        self.luma8.is_some()
    }
}

// Context layout: four block classes, then the coded-block-pattern
// contexts of intra and of inter macroblocks.
const CBF: usize = 0; // 3: coded neighbours left + above
const SIG: usize = 3; // 15: scan position
const LAST: usize = SIG + 15; // 15: scan position
const GT1: usize = LAST + 15; // 5
const ABS: usize = GT1 + 5; // 5
/// Contexts of one 4x4 block class.
pub const CLASS_CONTEXTS: usize = ABS + 5;
const CBP: usize = 4 * CLASS_CONTEXTS;
/// Per kind: 4 luma (left + 2 above), 3 Cb (left + above), 6 Cr (left +
/// above + 3 Cb).
const CBP_CONTEXTS: usize = 13;
// The 8x8 blocks' classes (luma of intra and of inter macroblocks): no
// coded flag (the pattern bit says), significance and last by the
// position's anti-diagonal (15, and 8 in pairs of diagonals).
const SIG8: usize = 0;
const LAST8: usize = SIG8 + 15;
const GT1_8: usize = LAST8 + 8;
const ABS8: usize = GT1_8 + 5;
/// Contexts of one 8x8 block class.
pub const CLASS8_CONTEXTS: usize = ABS8 + 5;
const CLASS8: usize = CBP + 2 * CBP_CONTEXTS;
/// The transform-size flag of inter macroblocks: neighbours left and
/// above that use the 8x8 transform.
const T8_FLAG: usize = CLASS8 + 2 * CLASS8_CONTEXTS;
// The chroma DC blocks' classes (of intra and of inter macroblocks): a
// coded flag per plane, then a 4-position scan.
const DC_CBF: usize = 0; // 2: Cb, Cr
const DC_SIG: usize = 2; // 3
const DC_LAST: usize = DC_SIG + 3; // 3
const DC_GT1: usize = DC_LAST + 3; // 5
const DC_ABS: usize = DC_GT1 + 5; // 5
/// Contexts of one chroma DC class.
pub const CHROMA_DC_CONTEXTS: usize = DC_ABS + 5;
const CHROMA_DC: usize = T8_FLAG + 3;
// Intra 16x16 luma DC: its coded flag and one 16-position block.
const DC16_CBF: usize = 0; // 1
const DC16_SIG: usize = 1; // 15: scan position
const DC16_LAST: usize = DC16_SIG + 15; // 15: scan position
const DC16_GT1: usize = DC16_LAST + 15; // 5
const DC16_ABS: usize = DC16_GT1 + 5; // 5
/// Contexts of the intra 16x16 luma DC levels.
pub const LUMA_DC_CONTEXTS: usize = DC16_ABS + 5;
const LUMA_DC: usize = CHROMA_DC + 2 * CHROMA_DC_CONTEXTS;
// Intra 16x16 luma AC: a block class of its own.
const LUMA_AC16: usize = LUMA_DC + LUMA_DC_CONTEXTS;
const CONTEXTS: usize = LUMA_AC16 + CLASS_CONTEXTS;

/// The anti-diagonal of each scan position of an 8x8 block: its
/// significance context (its last context is half of it).
const DIAGONAL8: [usize; 64] = {
    let mut d = [0usize; 64];
    let mut k = 0;
    while k < 64 {
        d[k] = ZIGZAG8[k] / 8 + ZIGZAG8[k] % 8;
        k += 1;
    }
    d
};

/// Where the bins of an `N`-coefficient block take their contexts, as
/// offsets from its class's first context: the significance and last
/// flags of each scan position (the last position has neither: a level
/// there is implied), then the first of the levels' "> 1" contexts and of
/// their magnitudes' ([`level_contexts`] picks among them). The writer
/// and the reader code by it; an encoder prices a block from it a position
/// at a time instead of replaying the bins (x264's `rdo.c` sizes CABAC
/// blocks from its own tables in the same way).
#[derive(Debug)]
pub struct ScanContexts<const N: usize> {
    /// Significance context of each scan position (entry `N - 1` unused).
    pub sig: [usize; N],
    /// Last-flag context of each scan position (entry `N - 1` unused).
    pub last: [usize; N],
    /// The first "> 1" context.
    pub gt1: usize,
    /// The first magnitude context.
    pub abs: usize,
}

/// `first + i` for scan position `i` but the last.
const fn consecutive<const N: usize>(first: usize) -> [usize; N] {
    let mut c = [0; N];
    let mut i = 0;
    while i < N - 1 {
        c[i] = first + i;
        i += 1;
    }
    c
}

/// `first` plus an 8x8 scan position's anti-diagonal over `per`, for
/// every position but the last.
const fn by_diagonal(first: usize, per: usize) -> [usize; 64] {
    let mut c = [0; 64];
    let mut i = 0;
    while i < 63 {
        c[i] = first + DIAGONAL8[i] / per;
        i += 1;
    }
    c
}

/// The 4x4 blocks' contexts: one significance and one last context per
/// position.
pub const SCAN4: ScanContexts<16> = ScanContexts {
    sig: consecutive(SIG),
    last: consecutive(LAST),
    gt1: GT1,
    abs: ABS,
};

/// The chroma blocks' AC levels (scan positions 1 to 15: position 0 holds
/// one of the plane's DC levels, coded apart): the 4x4 blocks' contexts
/// of those positions.
pub const SCAN4_AC: ScanContexts<15> = ScanContexts {
    sig: consecutive(SIG + 1),
    last: consecutive(LAST + 1),
    gt1: GT1,
    abs: ABS,
};

/// The zig-zag scan's positions 1 to 15: a chroma block's AC levels.
pub const ZIGZAG_AC: [usize; 15] = {
    let mut z = [0usize; 15];
    let mut i = 0;
    while i < 15 {
        z[i] = ZIGZAG[i + 1];
        i += 1;
    }
    z
};

/// A chroma plane's DC levels in block order, as one 4-position scan.
pub const SCAN_DC: ScanContexts<4> = ScanContexts {
    sig: consecutive(DC_SIG),
    last: consecutive(DC_LAST),
    gt1: DC_GT1,
    abs: DC_ABS,
};

/// The DC scan's order: the blocks' (0 to 3).
const BLOCK_ORDER: [usize; 4] = [0, 1, 2, 3];

/// An intra 16x16 macroblock's luma DC levels, scanned as a 4x4 block
/// ([`ZIGZAG`] over the blocks' raster order), relative to
/// [`LUMA_DC_BASE`].
pub const SCAN_LUMA_DC: ScanContexts<16> = ScanContexts {
    sig: consecutive(DC16_SIG),
    last: consecutive(DC16_LAST),
    gt1: DC16_GT1,
    abs: DC16_ABS,
};

/// The first context of the intra 16x16 luma DC levels.
pub const LUMA_DC_BASE: usize = LUMA_DC;

/// The context of the intra 16x16 luma DC coded flag.
pub const LUMA_DC_FLAG_CONTEXT: usize = LUMA_DC + DC16_CBF;

/// The first context of the chroma DC blocks of intra (`true`) or inter
/// macroblocks.
pub fn chroma_dc_base(intra: bool) -> usize {
    CHROMA_DC + usize::from(intra) * CHROMA_DC_CONTEXTS
}

/// The context of plane `p`'s (0 Cb, 1 Cr) DC coded flag in intra
/// (`true`) or inter macroblocks.
pub fn chroma_dc_flag_context(intra: bool, p: usize) -> usize {
    chroma_dc_base(intra) + DC_CBF + p
}

/// A chroma plane's DC levels (each block's position 0), in block order.
#[inline]
pub fn chroma_dc_levels(blocks: &[Block4; 4]) -> [i32; 4] {
    [blocks[0][0][0], blocks[1][0][0], blocks[2][0][0], blocks[3][0][0]]
}

/// Whether a chroma block has AC levels (any beside position 0).
#[inline]
fn has_ac(b: &Block4) -> bool {
    b.as_flattened()[1..].iter().any(|&v| v != 0)
}

/// The 8x8 blocks' contexts: significance by the position's anti-diagonal,
/// last by pairs of anti-diagonals.
pub const SCAN8: ScanContexts<64> = ScanContexts {
    sig: by_diagonal(SIG8, 1),
    last: by_diagonal(LAST8, 2),
    gt1: GT1_8,
    abs: ABS8,
};

/// The offsets of a level's "> 1" context and of its magnitude's from
/// the class's first of each, after `eq1` levels equal to 1 and `gt1`
/// greater (in reverse scan order).
#[inline]
pub fn level_contexts(eq1: usize, gt1: usize) -> (usize, usize) {
    let first = if gt1 > 0 { 0 } else { (1 + eq1).min(4) };
    (first, gt1.min(4))
}

/// The bins of magnitude `m` (a level's absolute value less 2): ones in
/// its context, whether a terminating zero follows, and the bypass bins
/// of the Exp-Golomb suffix past the unary part.
#[inline]
pub fn magnitude_bins(m: u32) -> (u32, bool, u32) {
    if m < UNARY_MAX {
        (m, true, 0)
    } else {
        (UNARY_MAX, false, exp_golomb_bins(m - UNARY_MAX, 0))
    }
}

/// One of the four block classes whose contexts are kept apart: luma or
/// chroma blocks, of intra or inter macroblocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockClass {
    chroma: bool,
    intra: bool,
    /// An intra 16x16 macroblock's luma blocks, whose DC levels are coded
    /// apart (their own contexts, as H.264's Intra16x16ACLevel).
    dc_apart: bool,
}

impl BlockClass {
    /// The context of the class's coded flag with `coded` (0..=2) coded
    /// neighbours.
    pub fn coded_flag_context(self, coded: usize) -> usize {
        self.first_context() + CBF + coded.min(2)
    }

    /// Luma blocks of an intra (`true`) or inter macroblock.
    pub fn luma(intra: bool) -> BlockClass {
        BlockClass {
            chroma: false,
            intra,
            dc_apart: false,
        }
    }

    /// The luma blocks of an intra 16x16 macroblock (their AC levels).
    pub fn luma_ac16() -> BlockClass {
        BlockClass {
            chroma: false,
            intra: true,
            dc_apart: true,
        }
    }

    /// Chroma blocks of an intra (`true`) or inter macroblock.
    pub fn chroma(intra: bool) -> BlockClass {
        BlockClass {
            chroma: true,
            intra,
            dc_apart: false,
        }
    }

    /// The class's first context (of [`CLASS_CONTEXTS`], in the coder's
    /// [`ResidualCoder::contexts`]).
    pub fn first_context(self) -> usize {
        if self.dc_apart {
            return LUMA_AC16;
        }
        (usize::from(self.chroma) * 2 + usize::from(self.intra)) * CLASS_CONTEXTS
    }
}

/// What a macroblock's kind says of its residual's syntax (FORMAT.md
/// section 3.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResidualSyntax {
    /// Inter: luma in 4x4 transforms, or in 8x8 ones by a flag.
    Inter,
    /// Intra in 4x4 blocks: luma in 4x4 transforms.
    Intra,
    /// Intra 16x16: luma DC levels apart, then the 4x4 blocks' AC levels.
    Intra16x16,
    /// Intra in 8x8 blocks: luma in 8x8 transforms, no flag.
    Intra8x8,
}

impl ResidualSyntax {
    /// Intra (`true`) or inter, as the block classes' contexts are chosen.
    pub fn intra(self) -> bool {
        self != ResidualSyntax::Inter
    }

    /// [`ResidualSyntax::Intra`] or [`ResidualSyntax::Inter`].
    pub fn of_4x4(intra: bool) -> ResidualSyntax {
        if intra {
            ResidualSyntax::Intra
        } else {
            ResidualSyntax::Inter
        }
    }
}

/// Coded flags of the 4x4 blocks across a macroblock's left and top edges
/// (false outside the picture and for macroblocks without residual).
#[derive(Debug, Clone, Copy, Default)]
struct Edges {
    /// Luma blocks left of rows 0..4, above columns 0..4.
    luma_left: [bool; 4],
    luma_above: [bool; 4],
    /// Per chroma plane, blocks left of rows 0..2, above columns 0..2.
    chroma_left: [[bool; 2]; 2],
    chroma_above: [[bool; 2]; 2],
    /// The same blocks' AC coded flags.
    ac_left: [[bool; 2]; 2],
    ac_above: [[bool; 2]; 2],
    /// The macroblocks left and above use the 8x8 transform.
    t8_left: bool,
    t8_above: bool,
}

/// Context increment of a block's coded flag: coded blocks left and above,
/// inside the macroblock from `coded` (the blocks' coded flags, raster,
/// `width` blocks a row), across its edges from `left` / `above`.
#[inline]
fn cbf_ctx(coded: &[bool], width: usize, k: usize, left: &[bool], above: &[bool]) -> usize {
    let (x, y) = (k % width, k / width);
    let l = if x > 0 { coded[k - 1] } else { left[y] };
    let a = if y > 0 { coded[k - width] } else { above[x] };
    usize::from(l) + usize::from(a)
}

/// The coded flags of `blocks` (whether each has a level).
#[inline]
fn coded_flags<const N: usize>(blocks: &[Block4; N]) -> [bool; N] {
    let mut flags = [false; N];
    for (f, b) in flags.iter_mut().zip(blocks) {
        *f = !is_zero(b);
    }
    flags
}

/// The coded block pattern from the blocks' coded flags.
#[inline]
fn cbp_of(luma: &[bool; 16], chroma: &[[bool; 4]; 2]) -> u32 {
    let mut cbp = 0;
    for q in 0..4 {
        if quadrant_blocks(q).iter().any(|&b| luma[b]) {
            cbp |= 1 << q;
        }
    }
    for (p, c) in chroma.iter().enumerate() {
        if c.iter().any(|&f| f) {
            cbp |= 1 << (4 + p);
        }
    }
    cbp
}

/// Context increment of luma quadrant `q`'s pattern bin: the quadrant left
/// (its pattern bit inside the macroblock, the two adjacent 4x4 blocks
/// across the edge) plus twice the one above.
fn luma_cbp_ctx(e: &Edges, cbp: u32, q: usize) -> usize {
    let (qx, qy) = (q % 2, q / 2);
    let left = if qx == 1 {
        cbp & (1 << (q - 1)) != 0
    } else {
        e.luma_left[2 * qy] || e.luma_left[2 * qy + 1]
    };
    let above = if qy == 1 {
        cbp & (1 << (q - 2)) != 0
    } else {
        e.luma_above[2 * qx] || e.luma_above[2 * qx + 1]
    };
    usize::from(left) + 2 * usize::from(above)
}

/// Context increment of chroma plane `p`'s pattern bin (`cb_coded`: the
/// Cb bin, for Cr).
fn chroma_cbp_ctx(e: &Edges, p: usize, cb_coded: bool) -> usize {
    let left = e.chroma_left[p][0] || e.chroma_left[p][1];
    let above = e.chroma_above[p][0] || e.chroma_above[p][1];
    let n = usize::from(left) + usize::from(above);
    if p == 0 {
        n
    } else {
        3 + n + 3 * usize::from(cb_coded)
    }
}

fn cbp_base(intra: bool) -> usize {
    CBP + usize::from(intra) * CBP_CONTEXTS
}

/// Where a group of four blocks sits: its blocks' indices, the width of
/// the rows they are counted in, the coded flags across the macroblock's
/// left and top edges.
struct Group<'a> {
    blocks: [usize; 4],
    width: usize,
    left: &'a [bool],
    above: &'a [bool],
}

/// A group of four blocks (quadrant or chroma plane) whose pattern bit is
/// set: flags (the last implied when the others are 0 and `implied`) and
/// blocks, each coded by `code`.
fn code_group<B: Bins>(
    b: &mut B,
    cls: usize,
    (blocks, flags): (&[Block4], &[bool]),
    g: &Group<'_>,
    implied: bool,
    code: fn(&mut B, usize, &Block4),
) {
    let mut any = !implied;
    for (i, &k) in g.blocks.iter().enumerate() {
        let coded = flags[k];
        if i < 3 || any {
            b.bin(cls + CBF + cbf_ctx(flags, g.width, k, g.left, g.above), coded);
        }
        any |= coded;
        if coded {
            code(b, cls, &blocks[k]);
        }
    }
}

/// A chroma plane whose pattern bit is set: its DC levels (a coded flag,
/// then one 4-position block), then its blocks' AC levels as a group (the
/// last flag implied only when no DC level was coded).
fn code_chroma_plane<B: Bins>(b: &mut B, e: &Edges, intra: bool, p: usize, blocks: &[Block4; 4]) {
    let dc = chroma_dc_levels(blocks);
    let dc_coded = dc.iter().any(|&v| v != 0);
    code_chroma_dc(b, intra, p, &dc);
    let flags = blocks.each_ref().map(has_ac);
    let group = Group {
        blocks: [0, 1, 2, 3],
        width: 2,
        left: &e.ac_left[p],
        above: &e.ac_above[p],
    };
    let cls = BlockClass::chroma(intra).first_context();
    code_group(b, cls, (blocks, &flags), &group, !dc_coded, code_block_ac);
}

/// The class of a macroblock's luma 4x4 blocks under `syntax`.
fn luma_class(syntax: ResidualSyntax) -> BlockClass {
    if syntax == ResidualSyntax::Intra16x16 {
        BlockClass::luma_ac16()
    } else {
        BlockClass::luma(syntax.intra())
    }
}

fn t8_ctx(e: &Edges) -> usize {
    T8_FLAG + usize::from(e.t8_left) + usize::from(e.t8_above)
}

/// The first context of the 8x8 luma blocks of intra (`true`) or inter
/// macroblocks.
pub fn class8_base(intra: bool) -> usize {
    CLASS8 + usize::from(intra) * CLASS8_CONTEXTS
}

fn code_mb<B: Bins>(b: &mut B, e: &Edges, syntax: ResidualSyntax, res: &MbResidual) {
    let intra = syntax.intra();
    let luma_flags = res.luma_coded();
    let chroma_flags = [coded_flags(&res.chroma[0]), coded_flags(&res.chroma[1])];
    let cbp = cbp_of(&luma_flags, &chroma_flags);
    let base = cbp_base(intra);
    for q in 0..4 {
        b.bin(base + luma_cbp_ctx(e, cbp, q), cbp & (1 << q) != 0);
    }
    if syntax == ResidualSyntax::Inter && cbp & 15 != 0 {
        b.bin(t8_ctx(e), res.transform_8x8());
    }
    let cb = cbp & 16 != 0;
    b.bin(base + 4 + chroma_cbp_ctx(e, 0, false), cb);
    b.bin(base + 4 + chroma_cbp_ctx(e, 1, cb), cbp & 32 != 0);
    if syntax == ResidualSyntax::Intra16x16 {
        code_luma_dc(b, &res.luma_dc);
    }
    if let Some(b8) = &res.luma8 {
        for (q, block) in b8.iter().enumerate() {
            if cbp & (1 << q) != 0 {
                code_block8(b, class8_base(intra), block);
            }
        }
    }
    let cls = luma_class(syntax).first_context();
    for q in 0..4 {
        if cbp & (1 << q) != 0 && !res.transform_8x8() {
            let group = Group {
                blocks: quadrant_blocks(q),
                width: 4,
                left: &e.luma_left,
                above: &e.luma_above,
            };
            let code = if syntax == ResidualSyntax::Intra16x16 {
                code_block_ac
            } else {
                code_block
            };
            code_group(b, cls, (&res.luma, &luma_flags), &group, true, code);
        }
    }
    for p in 0..2 {
        if cbp & (16 << p) != 0 {
            code_chroma_plane(b, e, intra, p, &res.chroma[p]);
        }
    }
}

/// The bins of a 4x4 block's levels (at least one non-zero) in the class
/// whose first context is `cls`, its coded flag excepted (the
/// macroblock's syntax codes it).
pub fn code_block<B: Bins>(b: &mut B, cls: usize, block: &Block4) {
    code_scan(b, cls, block.as_flattened(), &ZIGZAG, &SCAN4);
}

/// The bins of plane `p`'s (0 Cb, 1 Cr) DC levels `dc` (block order) in
/// intra (`true`) or inter macroblocks: the coded flag, then the levels
/// when any is non-zero.
pub fn code_chroma_dc<B: Bins>(b: &mut B, intra: bool, p: usize, dc: &[i32; 4]) {
    let coded = dc.iter().any(|&v| v != 0);
    b.bin(chroma_dc_flag_context(intra, p), coded);
    if coded {
        code_scan(b, chroma_dc_base(intra), dc, &BLOCK_ORDER, &SCAN_DC);
    }
}

/// The bins of an intra 16x16 macroblock's luma DC levels `dc` (raster
/// order of its blocks): the coded flag, then the levels when any is
/// non-zero.
pub fn code_luma_dc<B: Bins>(b: &mut B, dc: &[i32; 16]) {
    let coded = dc.iter().any(|&v| v != 0);
    b.bin(LUMA_DC_FLAG_CONTEXT, coded);
    if coded {
        code_scan(b, LUMA_DC_BASE, dc, &ZIGZAG, &SCAN_LUMA_DC);
    }
}

/// The bins of a chroma block's AC levels (at least one non-zero; its
/// position 0 is not coded here) in the class whose first context is
/// `cls`.
pub fn code_block_ac<B: Bins>(b: &mut B, cls: usize, block: &Block4) {
    code_scan(b, cls, block.as_flattened(), &ZIGZAG_AC, &SCAN4_AC);
}

/// The bins of an 8x8 block's levels (at least one non-zero) in the class
/// whose first context is `cls` ([`class8_base`]).
pub fn code_block8<B: Bins>(b: &mut B, cls: usize, block: &Block8) {
    code_scan(b, cls, block.as_flattened(), &ZIGZAG8, &SCAN8);
}

/// The bins of an `N`-coefficient block's levels (`flat`, in raster
/// order; `zigzag` its scan) in the contexts `at` lays out: significance
/// and last flags up to the last level, then the levels.
#[inline(always)]
fn code_scan<B: Bins, const N: usize>(
    b: &mut B,
    cls: usize,
    flat: &[i32],
    zigzag: &[usize; N],
    at: &ScanContexts<N>,
) {
    // A plain loop: `array::from_fn` here was a call of its own (about
    // 120 instructions a 4x4 block).
    let mut scan = [0i32; N];
    for (s, &k) in scan.iter_mut().zip(zigzag) {
        *s = flat[k];
    }
    let last = scan.iter().rposition(|&v| v != 0).unwrap_or(0);
    for (i, &v) in scan.iter().enumerate().take(N - 1) {
        b.bin(cls + at.sig[i], v != 0);
        if v != 0 {
            b.bin(cls + at.last[i], i == last);
            if i == last {
                break;
            }
        }
    }
    code_levels(b, cls + at.gt1, cls + at.abs, &scan[..=last]);
}

/// The levels of a block up to its last, in reverse scan order: `> 1` in
/// the contexts from `gt1_ctx`, the rest of the magnitude from `abs_ctx`,
/// the sign.
fn code_levels<B: Bins>(b: &mut B, gt1_ctx: usize, abs_ctx: usize, scan: &[i32]) {
    let (mut eq1, mut gt1) = (0usize, 0usize);
    for &v in scan.iter().rev().filter(|&&v| v != 0) {
        let a = v.unsigned_abs();
        let (first, rest) = level_contexts(eq1, gt1);
        b.bin(gt1_ctx + first, a > 1);
        if a > 1 {
            let m = a - 2;
            let (ones, zero, _) = magnitude_bins(m);
            for _ in 0..ones {
                b.bin(abs_ctx + rest, true);
            }
            if zero {
                b.bin(abs_ctx + rest, false);
            } else {
                put_exp_golomb(b, m - UNARY_MAX, 0);
            }
            gt1 += 1;
        } else {
            eq1 += 1;
        }
        b.bypass(v < 0);
    }
}

/// The residual coder of one frame: the contexts and the coded flags of
/// the macroblocks coded so far (which choose the contexts of the next).
///
/// ```
/// use mocomp_codec::entropy::{RangeDecoder, RangeEncoder};
/// use mocomp_codec::residual::{MbResidual, ResidualCoder, ResidualSyntax};
/// let mut res = MbResidual::default();
/// res.luma[5][0][1] = -3;
/// res.chroma[1][0][0][0] = 1;
/// let mut coder = ResidualCoder::new(2, 1);
/// let mut enc = RangeEncoder::new();
/// coder.write(&mut enc, 0, 0, ResidualSyntax::Inter, &res);
/// coder.write(&mut enc, 1, 0, ResidualSyntax::Intra, &res);
/// let bytes = enc.finish();
/// let mut coder = ResidualCoder::new(2, 1);
/// let mut dec = RangeDecoder::new(&bytes);
/// assert_eq!(coder.read(&mut dec, 0, 0, ResidualSyntax::Inter), Ok(res.clone()));
/// assert_eq!(coder.read(&mut dec, 1, 0, ResidualSyntax::Intra), Ok(res));
/// ```
#[derive(Debug, Clone)]
pub struct ResidualCoder {
    contexts: Box<[Context; CONTEXTS]>,
    mb_cols: usize,
    mb_rows: usize,
    /// Coded flags of the luma 4x4 blocks, `4 mb_cols` a row.
    luma: Vec<bool>,
    /// Per plane, of the chroma 4x4 blocks, `2 mb_cols` a row: any level
    /// (the DC level in its place included).
    chroma: [Vec<bool>; 2],
    /// The same blocks' AC coded flags.
    chroma_ac: [Vec<bool>; 2],
    /// Per macroblock, whether it used the 8x8 transform.
    t8: Vec<bool>,
}

impl ResidualCoder {
    /// A coder at the start of a frame of `mb_cols x mb_rows` macroblocks.
    pub fn new(mb_cols: usize, mb_rows: usize) -> ResidualCoder {
        ResidualCoder {
            contexts: Box::new([Context::new(); CONTEXTS]),
            mb_cols,
            mb_rows,
            luma: vec![false; 16 * mb_cols * mb_rows],
            chroma: [
                vec![false; 4 * mb_cols * mb_rows],
                vec![false; 4 * mb_cols * mb_rows],
            ],
            chroma_ac: [
                vec![false; 4 * mb_cols * mb_rows],
                vec![false; 4 * mb_cols * mb_rows],
            ],
            t8: vec![false; mb_cols * mb_rows],
        }
    }

    /// A coder for the next frame that starts from the contexts this one
    /// has reached (P frames carry them over, FORMAT.md section 3.4).
    pub fn next_frame(&self) -> ResidualCoder {
        let mut next = ResidualCoder::new(self.mb_cols, self.mb_rows);
        next.contexts.clone_from(&self.contexts);
        next
    }

    /// What the next frame carries over of this coder: its contexts, the
    /// blocks' coded flags dropped.
    pub fn carried(mut self) -> ResidualCoder {
        self.luma = Vec::new();
        self.chroma = [Vec::new(), Vec::new()];
        self.chroma_ac = [Vec::new(), Vec::new()];
        self.t8 = Vec::new();
        self
    }

    fn edges(&self, mb_x: usize, mb_y: usize) -> Edges {
        debug_assert!(mb_x < self.mb_cols && mb_y < self.mb_rows);
        let mut e = Edges::default();
        let lw = 4 * self.mb_cols;
        let cw = 2 * self.mb_cols;
        for i in 0..4 {
            if mb_x > 0 {
                e.luma_left[i] = self.luma[(4 * mb_y + i) * lw + 4 * mb_x - 1];
            }
            if mb_y > 0 {
                e.luma_above[i] = self.luma[(4 * mb_y - 1) * lw + 4 * mb_x + i];
            }
        }
        if mb_x > 0 {
            e.t8_left = self.t8[mb_y * self.mb_cols + mb_x - 1];
        }
        if mb_y > 0 {
            e.t8_above = self.t8[(mb_y - 1) * self.mb_cols + mb_x];
        }
        for p in 0..2 {
            for i in 0..2 {
                if mb_x > 0 {
                    let at = (2 * mb_y + i) * cw + 2 * mb_x - 1;
                    (e.chroma_left[p][i], e.ac_left[p][i]) = (self.chroma[p][at], self.chroma_ac[p][at]);
                }
                if mb_y > 0 {
                    let at = (2 * mb_y - 1) * cw + 2 * mb_x + i;
                    (e.chroma_above[p][i], e.ac_above[p][i]) = (self.chroma[p][at], self.chroma_ac[p][at]);
                }
            }
        }
        e
    }

    /// Takes `contexts` (another coder's [`ResidualCoder::contexts`]) as
    /// its own, keeping its record of coded blocks (see
    /// [`crate::modes::ModeCoder::set_contexts`]). Panics if `contexts`
    /// is not another residual coder's (a different length).
    pub fn set_contexts(&mut self, contexts: &[Context]) {
        self.contexts.copy_from_slice(contexts);
    }

    /// Records macroblock (mb_x, mb_y)'s coded blocks as a neighbour
    /// without adapting anything: what another coder committed there.
    pub fn record(&mut self, mb_x: usize, mb_y: usize, syntax: ResidualSyntax, res: &MbResidual) {
        let lw = 4 * self.mb_cols;
        for (k, coded) in res.luma_coded().into_iter().enumerate() {
            self.luma[(4 * mb_y + k / 4) * lw + 4 * mb_x + k % 4] = coded;
        }
        self.t8[mb_y * self.mb_cols + mb_x] = syntax == ResidualSyntax::Intra8x8 || res.transform_8x8();
        let cw = 2 * self.mb_cols;
        for p in 0..2 {
            for (k, b) in res.chroma[p].iter().enumerate() {
                let at = (2 * mb_y + k / 2) * cw + 2 * mb_x + k % 2;
                (self.chroma[p][at], self.chroma_ac[p][at]) = (!is_zero(b), has_ac(b));
            }
        }
    }

    /// Runs the binarisation of `res` as macroblock (mb_x, mb_y) in the
    /// present state into `bins` (the contexts indexed as [`contexts`]
    /// gives them), adapting nothing: what an encoder prices its choices
    /// with ([`crate::entropy::Pricer`]).
    ///
    /// [`contexts`]: ResidualCoder::contexts
    pub fn replay<B: Bins>(
        &self,
        bins: &mut B,
        mb_x: usize,
        mb_y: usize,
        syntax: ResidualSyntax,
        res: &MbResidual,
    ) {
        code_mb(bins, &self.edges(mb_x, mb_y), syntax, res);
    }

    /// The contexts in their present state.
    pub fn contexts(&self) -> &[Context] {
        &self.contexts[..]
    }

    /// Adapts the contexts and records the coded flags as
    /// [`ResidualCoder::write`] does, without writing.
    pub fn commit(&mut self, mb_x: usize, mb_y: usize, syntax: ResidualSyntax, res: &MbResidual) {
        let e = self.edges(mb_x, mb_y);
        code_mb(&mut Adapter(&mut self.contexts[..]), &e, syntax, res);
        self.record(mb_x, mb_y, syntax, res);
    }

    /// Writes macroblock (mb_x, mb_y)'s levels (in the `syntax` its kind
    /// says) and returns their cost in 1/256 bit as the bins were
    /// coded. Macroblocks without residual syntax (skipped) are not
    /// written. Levels above [`MAX_LEVEL`] are an encoder bug: they would
    /// not decode.
    pub fn write(
        &mut self,
        enc: &mut RangeEncoder,
        mb_x: usize,
        mb_y: usize,
        syntax: ResidualSyntax,
        res: &MbResidual,
    ) -> u32 {
        debug_assert!(res
            .luma
            .iter()
            .chain(res.chroma.iter().flatten())
            .flatten()
            .flatten()
            .chain(res.luma8.iter().flat_map(|b| b.as_flattened().as_flattened()))
            .all(|v| v.unsigned_abs() <= MAX_LEVEL));
        debug_assert!(
            res.luma8
                .as_deref()
                .is_none_or(|b| syntax != ResidualSyntax::Intra && b.iter().any(|b| !is_zero8(b))),
            "8x8 transform blocks are for inter or 8x8 intra luma, with levels"
        );
        debug_assert!(
            syntax != ResidualSyntax::Intra8x8 || res.luma.iter().all(is_zero),
            "8x8 intra luma is in 8x8 transform blocks"
        );
        debug_assert!(
            if syntax == ResidualSyntax::Intra16x16 {
                res.luma8.is_none()
                    && res.luma.iter().all(|b| b[0][0] == 0)
                    && res.luma_dc.iter().all(|v| v.unsigned_abs() <= MAX_LEVEL)
            } else {
                res.luma_dc == [0; 16]
            },
            "luma DC levels apart are intra 16x16's, whose blocks hold AC levels alone"
        );
        let e = self.edges(mb_x, mb_y);
        let mut w = Writer::new(enc, &mut self.contexts[..]);
        code_mb(&mut w, &e, syntax, res);
        let cost = w.cost;
        self.record(mb_x, mb_y, syntax, res);
        cost
    }

    /// Reads what [`ResidualCoder::write`] writes.
    pub fn read(
        &mut self,
        dec: &mut RangeDecoder<'_>,
        mb_x: usize,
        mb_y: usize,
        syntax: ResidualSyntax,
    ) -> Result<MbResidual, ResidualError> {
        let intra = syntax.intra();
        let e = self.edges(mb_x, mb_y);
        let c = &mut self.contexts;
        let base = cbp_base(intra);
        let mut cbp = 0u32;
        for q in 0..4 {
            if dec.decode(&mut c[base + luma_cbp_ctx(&e, cbp, q)]) {
                cbp |= 1 << q;
            }
        }
        let t8 = cbp != 0
            && match syntax {
                ResidualSyntax::Inter => dec.decode(&mut c[t8_ctx(&e)]),
                ResidualSyntax::Intra | ResidualSyntax::Intra16x16 => false,
                ResidualSyntax::Intra8x8 => true,
            };
        let cb = dec.decode(&mut c[base + 4 + chroma_cbp_ctx(&e, 0, false)]);
        let cr = dec.decode(&mut c[base + 4 + chroma_cbp_ctx(&e, 1, cb)]);
        cbp |= u32::from(cb) << 4 | u32::from(cr) << 5;
        let mut out = MbResidual::default();
        if syntax == ResidualSyntax::Intra16x16 && dec.decode(&mut c[LUMA_DC_FLAG_CONTEXT]) {
            read_scan(dec, c, LUMA_DC_BASE, (&ZIGZAG, &SCAN_LUMA_DC), &mut out.luma_dc)?;
        }
        if t8 {
            let mut b8 = Box::new([[[0; 8]; 8]; 4]);
            for (q, block) in b8.iter_mut().enumerate() {
                if cbp & (1 << q) != 0 {
                    *block = read_block8(dec, c, class8_base(intra))?;
                }
            }
            out.luma8 = Some(b8);
        }
        let cls = luma_class(syntax).first_context();
        for q in 0..4 {
            if cbp & (1 << q) != 0 && !t8 {
                let group = Group {
                    blocks: quadrant_blocks(q),
                    width: 4,
                    left: &e.luma_left,
                    above: &e.luma_above,
                };
                let read: ReadBlock = if syntax == ResidualSyntax::Intra16x16 {
                    read_block_ac
                } else {
                    read_block
                };
                read_group(dec, c, cls, &mut out.luma, &group, (true, read))?;
            }
        }
        for p in 0..2 {
            if cbp & (16 << p) != 0 {
                read_chroma_plane(dec, c, (&e, intra, p), &mut out.chroma[p])?;
            }
        }
        self.record(mb_x, mb_y, syntax, &out);
        Ok(out)
    }
}

/// How [`read_group`] reads a coded block of the class whose first
/// context is given.
type ReadBlock = fn(&mut RangeDecoder<'_>, &mut [Context; CONTEXTS], usize) -> Result<Block4, ResidualError>;

/// Reads what [`code_group`] writes into `blocks` (all zero where the
/// group lies).
fn read_group(
    dec: &mut RangeDecoder<'_>,
    c: &mut [Context; CONTEXTS],
    cls: usize,
    blocks: &mut [Block4],
    g: &Group<'_>,
    (implied, read): (bool, ReadBlock),
) -> Result<(), ResidualError> {
    // The coded flags so far (blocks not read yet have no levels).
    let mut flags = [false; 16];
    for (f, b) in flags.iter_mut().zip(blocks.iter()) {
        *f = !is_zero(b);
    }
    let mut any = !implied;
    for (i, &k) in g.blocks.iter().enumerate() {
        let coded = if i < 3 || any {
            dec.decode(&mut c[cls + CBF + cbf_ctx(&flags, g.width, k, g.left, g.above)])
        } else {
            true
        };
        any |= coded;
        if coded {
            blocks[k] = read(dec, c, cls)?;
            flags[k] = true;
        }
    }
    Ok(())
}

/// Reads what [`code_chroma_plane`] writes into `blocks` (all zero).
fn read_chroma_plane(
    dec: &mut RangeDecoder<'_>,
    c: &mut [Context; CONTEXTS],
    (e, intra, p): (&Edges, bool, usize),
    blocks: &mut [Block4; 4],
) -> Result<(), ResidualError> {
    let base = chroma_dc_base(intra);
    let dc_coded = dec.decode(&mut c[chroma_dc_flag_context(intra, p)]);
    let mut dc = [0i32; 4];
    if dc_coded {
        read_scan(dec, c, base, (&BLOCK_ORDER, &SCAN_DC), &mut dc)?;
    }
    let group = Group {
        blocks: [0, 1, 2, 3],
        width: 2,
        left: &e.ac_left[p],
        above: &e.ac_above[p],
    };
    let cls = BlockClass::chroma(intra).first_context();
    read_group(dec, c, cls, blocks, &group, (!dc_coded, read_block_ac))?;
    for (b, level) in blocks.iter_mut().zip(dc) {
        b[0][0] = level;
    }
    Ok(())
}

fn read_block_ac(
    dec: &mut RangeDecoder<'_>,
    c: &mut [Context; CONTEXTS],
    cls: usize,
) -> Result<Block4, ResidualError> {
    let mut block = [[0i32; 4]; 4];
    read_scan(dec, c, cls, (&ZIGZAG_AC, &SCAN4_AC), block.as_flattened_mut())?;
    Ok(block)
}

fn read_block(
    dec: &mut RangeDecoder<'_>,
    c: &mut [Context; CONTEXTS],
    cls: usize,
) -> Result<Block4, ResidualError> {
    let mut block = [[0i32; 4]; 4];
    read_scan(dec, c, cls, (&ZIGZAG, &SCAN4), block.as_flattened_mut())?;
    Ok(block)
}

fn read_block8(
    dec: &mut RangeDecoder<'_>,
    c: &mut [Context; CONTEXTS],
    cls: usize,
) -> Result<Block8, ResidualError> {
    let mut block = [[0i32; 8]; 8];
    read_scan(dec, c, cls, (&ZIGZAG8, &SCAN8), block.as_flattened_mut())?;
    Ok(block)
}

/// Reads what [`code_scan`] writes into `flat` (raster order, all zero).
fn read_scan<const N: usize>(
    dec: &mut RangeDecoder<'_>,
    c: &mut [Context; CONTEXTS],
    cls: usize,
    (zigzag, at): (&[usize; N], &ScanContexts<N>),
    flat: &mut [i32],
) -> Result<(), ResidualError> {
    let mut significant = [false; N];
    let mut last = N - 1;
    for (i, s) in significant.iter_mut().enumerate().take(N - 1) {
        *s = dec.decode(&mut c[cls + at.sig[i]]);
        if *s && dec.decode(&mut c[cls + at.last[i]]) {
            last = i;
            break;
        }
    }
    significant[last] = true;
    read_levels(
        dec,
        c,
        cls + at.gt1,
        cls + at.abs,
        &significant[..=last],
        |i, v| flat[zigzag[i]] = v,
    )
}

/// Reads what [`code_levels`] writes for the scan positions flagged in
/// `significant`, handing each position and level to `put`.
fn read_levels(
    dec: &mut RangeDecoder<'_>,
    c: &mut [Context; CONTEXTS],
    gt1_ctx: usize,
    abs_ctx: usize,
    significant: &[bool],
    mut put: impl FnMut(usize, i32),
) -> Result<(), ResidualError> {
    let (mut eq1, mut gt1) = (0usize, 0usize);
    for i in (0..significant.len()).rev().filter(|&i| significant[i]) {
        let (first, rest) = level_contexts(eq1, gt1);
        let mut a = 1u32;
        if dec.decode(&mut c[gt1_ctx + first]) {
            let ctx = abs_ctx + rest;
            let mut m = 0;
            while m < UNARY_MAX && dec.decode(&mut c[ctx]) {
                m += 1;
            }
            if m == UNARY_MAX {
                m += get_exp_golomb(dec, 0, MAX_EG_PREFIX).ok_or(ResidualError::Range {
                    what: "Exp-Golomb prefix",
                    value: u64::from(MAX_EG_PREFIX) + 1,
                    pos: dec.position(),
                })?;
            }
            a = 2 + m;
            if a > MAX_LEVEL {
                return Err(ResidualError::Range {
                    what: "level",
                    value: u64::from(a),
                    pos: dec.position(),
                });
            }
            gt1 += 1;
        } else {
            eq1 += 1;
        }
        let v = if dec.decode_bypass() {
            -(a as i32)
        } else {
            a as i32
        };
        put(i, v);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::entropy::Pricer;

    /// The bits of `res` at (x, y), priced as an encoder prices them.
    fn cost(coder: &ResidualCoder, x: usize, y: usize, syntax: ResidualSyntax, res: &MbResidual) -> u32 {
        let mut p = Pricer::new(coder.contexts(), 0);
        coder.replay(&mut p, x, y, syntax, res);
        p.cost
    }

    /// What `block` adds over an all-zero block, its flag priced with one
    /// coded neighbour.
    fn block_cost(coder: &ResidualCoder, class: BlockClass, block: &Block4) -> u32 {
        if is_zero(block) {
            return 0;
        }
        let flag = &coder.contexts()[class.coded_flag_context(1)];
        let mut p = Pricer::new(coder.contexts(), flag.cost(true));
        code_block(&mut p, class.first_context(), block);
        p.cost.saturating_sub(flag.cost(false))
    }
    use proptest::prelude::*;

    #[test]
    fn the_8x8_pricer_prices_what_the_blocks_add() {
        let mut seed = 77u32;
        let mut next = |n: u32| {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            ((seed >> 16) % n) as i32
        };
        let coder = ResidualCoder::new(1, 1);
        for _ in 0..50 {
            let mut b8 = Box::new([[[0; 8]; 8]; 4]);
            for v in b8.as_flattened_mut().as_flattened_mut() {
                *v = if next(6) == 0 { next(9) - 4 } else { 0 };
            }
            b8[0][0][0] = 2;
            let res = MbResidual {
                luma8: Some(b8.clone()),
                ..Default::default()
            };
            // The macroblock's price is its pattern's and flag's bins
            // (priced here one by one) plus the blocks' prices.
            let blocks: u32 = b8
                .iter()
                .map(|b| {
                    let mut p = Pricer::new(coder.contexts(), 0);
                    code_block8(&mut p, class8_base(false), b);
                    if is_zero8(b) {
                        0
                    } else {
                        p.cost
                    }
                })
                .sum();
            let mut p = Pricer::new(&coder.contexts[..], 0);
            let e = Edges::default();
            let cbp = res.cbp();
            for q in 0..4 {
                p.bin(cbp_base(false) + luma_cbp_ctx(&e, cbp, q), cbp & (1 << q) != 0);
            }
            p.bin(t8_ctx(&e), true);
            p.bin(cbp_base(false) + 4, false);
            p.bin(cbp_base(false) + 4 + 3, false);
            assert_eq!(cost(&coder, 0, 0, ResidualSyntax::Inter, &res), p.cost + blocks);
        }
    }

    #[test]
    fn zigzag_is_a_permutation_walking_the_diagonals() {
        let mut seen = [false; 16];
        for (k, &i) in ZIGZAG.iter().enumerate() {
            assert!(!seen[i]);
            seen[i] = true;
            if k > 0 {
                // Each step moves to a neighbouring cell (including diagonals).
                let (a, b) = (ZIGZAG[k - 1], i);
                assert!(
                    ((a / 4) as i32 - (b / 4) as i32).abs() <= 1
                        && ((a % 4) as i32 - (b % 4) as i32).abs() <= 1
                );
            }
        }
    }

    /// Writes `res` with bins of our own choosing, bypassing the writer's
    /// check on level sizes (to make invalid streams).
    fn write_unchecked(res: &MbResidual) -> Vec<u8> {
        let mut enc = RangeEncoder::new();
        let mut contexts = Box::new([Context::new(); CONTEXTS]);
        let mut w = Writer::new(&mut enc, &mut contexts[..]);
        code_mb(&mut w, &Edges::default(), ResidualSyntax::Inter, res);
        enc.finish()
    }

    #[test]
    fn oversized_levels_are_errors() {
        let mut res = MbResidual::default();
        // Within the Exp-Golomb prefix limit, one above the level limit.
        res.luma[0][0][0] = MAX_LEVEL as i32 + 1;
        let bytes = write_unchecked(&res);
        let got = ResidualCoder::new(1, 1).read(&mut RangeDecoder::new(&bytes), 0, 0, ResidualSyntax::Inter);
        assert!(
            matches!(got, Err(ResidualError::Range { what: "level", .. })),
            "{got:?}"
        );
        // A prefix beyond the limit.
        res.luma[0][0][0] = 1 << 20;
        let bytes = write_unchecked(&res);
        let got = ResidualCoder::new(1, 1).read(&mut RangeDecoder::new(&bytes), 0, 0, ResidualSyntax::Inter);
        assert!(
            matches!(
                got,
                Err(ResidualError::Range {
                    what: "Exp-Golomb prefix",
                    ..
                })
            ),
            "{got:?}"
        );
        // The largest allowed level reads back.
        res.luma[0][0][0] = -(MAX_LEVEL as i32);
        let bytes = write_unchecked(&res);
        assert_eq!(
            ResidualCoder::new(1, 1).read(&mut RangeDecoder::new(&bytes), 0, 0, ResidualSyntax::Inter),
            Ok(res)
        );
    }

    #[test]
    fn the_implied_flag_saves_the_bin() {
        // One coded block, the last of its quadrant: three 0 flags, no fourth.
        let mut one = MbResidual::default();
        one.luma[5][0][0] = 1;
        let mut two = one.clone();
        two.luma[4][0][0] = 1;
        let coder = ResidualCoder::new(1, 1);
        let cls = BlockClass::luma(false).first_context();
        let block_bits = block_cost(&coder, BlockClass::luma(false), &one.luma[5]);
        assert!(block_bits > 0);
        // Pricing follows the coder: with the flag implied, coding block 5
        // costs the flags of 0, 1, 4 (all 0) and no flag of its own.
        let flags: u32 = [0usize, 1, 4]
            .iter()
            .map(|&k| {
                coder.contexts[cls + CBF + cbf_ctx(&coded_flags(&one.luma), 4, k, &[false; 4], &[false; 4])]
                    .cost(false)
            })
            .sum();
        let pattern = cost(&coder, 0, 0, ResidualSyntax::Inter, &MbResidual::default());
        let mut p = Pricer::new(&coder.contexts[..], 0);
        code_block(&mut p, cls, &one.luma[5]);
        // The pattern's first bin differs (quadrant 0 coded): price it apart.
        let base = cbp_base(false);
        let pattern_one = pattern - coder.contexts[base].cost(false) + coder.contexts[base].cost(true);
        // An inter macroblock with luma levels says which transform it uses.
        let t4 = coder.contexts[T8_FLAG].cost(false);
        assert_eq!(
            cost(&coder, 0, 0, ResidualSyntax::Inter, &one),
            pattern_one + t4 + flags + p.cost
        );
        assert!(
            cost(&coder, 0, 0, ResidualSyntax::Inter, &two) > cost(&coder, 0, 0, ResidualSyntax::Inter, &one)
        );
    }

    /// Bins of a plane's syntax: macroblock (0, 0) of a fresh coder with
    /// `res`, minus the same without chroma.
    fn chroma_bins(res: &MbResidual) -> u32 {
        let coder = ResidualCoder::new(1, 1);
        cost(&coder, 0, 0, ResidualSyntax::Inter, res)
    }

    #[test]
    fn a_chroma_plane_codes_its_dc_levels_apart_from_its_ac() {
        let coder = ResidualCoder::new(1, 1);
        let ctx = |k: usize| coder.contexts[k];
        // DC levels alone: the flag and one 4-position block, then four AC
        // flags of 0 (none implied: the DC levels coded the plane).
        let mut dc_only = MbResidual::default();
        dc_only.chroma[0][2][0][0] = -3;
        let mut dc_block = Pricer::new(&coder.contexts[..], 0);
        code_scan(
            &mut dc_block,
            chroma_dc_base(false),
            &[0, 0, -3, 0],
            &BLOCK_ORDER,
            &SCAN_DC,
        );
        let cls = BlockClass::chroma(false).first_context();
        let ac_flags = 4 * ctx(cls + CBF).cost(false);
        let base = cbp_base(false);
        let pattern_cb = ctx(base + 4).cost(true) - ctx(base + 4).cost(false);
        let empty = chroma_bins(&MbResidual::default());
        assert_eq!(
            chroma_bins(&dc_only),
            empty + pattern_cb + ctx(chroma_dc_flag_context(false, 0)).cost(true) + dc_block.cost + ac_flags
        );
        // AC levels alone in the fourth block: no DC level, so its flag
        // is implied after three of 0.
        let mut ac_only = MbResidual::default();
        ac_only.chroma[0][3][1][0] = 2;
        let mut ac_block = Pricer::new(&coder.contexts[..], 0);
        code_block_ac(&mut ac_block, cls, &ac_only.chroma[0][3]);
        let three_zero_flags: u32 = [0usize, 1, 2]
            .iter()
            .map(|&k| ctx(cls + CBF + cbf_ctx(&[false; 4], 2, k, &[false; 2], &[false; 2])).cost(false))
            .sum();
        assert_eq!(
            chroma_bins(&ac_only),
            empty
                + pattern_cb
                + ctx(chroma_dc_flag_context(false, 0)).cost(false)
                + three_zero_flags
                + ac_block.cost
        );
        // Both round-trip, with the DC levels in position 0.
        for res in [dc_only, ac_only] {
            let mut enc = RangeEncoder::new();
            ResidualCoder::new(1, 1).write(&mut enc, 0, 0, ResidualSyntax::Inter, &res);
            let bytes = enc.finish();
            let mut dec = RangeDecoder::new(&bytes);
            assert_eq!(
                ResidualCoder::new(1, 1).read(&mut dec, 0, 0, ResidualSyntax::Inter),
                Ok(res)
            );
        }
    }

    #[test]
    fn an_intra16x16_macroblock_codes_its_luma_dc_apart() {
        let coder = ResidualCoder::new(1, 1);
        let ctx = |k: usize| coder.contexts[k];
        let cost16 = |res: &MbResidual| cost(&coder, 0, 0, ResidualSyntax::Intra16x16, res);
        // Nothing coded: the pattern's bins and the DC flag of 0.
        let empty = cost16(&MbResidual::default());
        let intra_empty = cost(&coder, 0, 0, ResidualSyntax::Intra, &MbResidual::default());
        assert_eq!(empty, intra_empty + ctx(LUMA_DC_FLAG_CONTEXT).cost(false));
        // DC levels alone: the flag and one 16-position block in zig-zag
        // order, no quadrant coded.
        let mut dc_only = MbResidual::default();
        dc_only.luma_dc[0] = 9;
        dc_only.luma_dc[4] = -1;
        let mut dc_block = Pricer::new(&coder.contexts[..], 0);
        code_scan(
            &mut dc_block,
            LUMA_DC_BASE,
            &dc_only.luma_dc,
            &ZIGZAG,
            &SCAN_LUMA_DC,
        );
        assert_eq!(
            cost16(&dc_only),
            intra_empty + ctx(LUMA_DC_FLAG_CONTEXT).cost(true) + dc_block.cost
        );
        // AC levels alone in block 5 (quadrant 0): its scan leaves out
        // position 0, the blocks' flags are the AC ones (the fourth
        // implied after three of 0, as for any quadrant).
        let mut ac_only = MbResidual::default();
        ac_only.luma[5][1][0] = 2;
        let cls = BlockClass::luma_ac16().first_context();
        let mut ac_block = Pricer::new(&coder.contexts[..], 0);
        code_block_ac(&mut ac_block, cls, &ac_only.luma[5]);
        let flags = coded_flags(&ac_only.luma);
        let three_zero_flags: u32 = [0usize, 1, 4]
            .iter()
            .map(|&k| ctx(cls + CBF + cbf_ctx(&flags, 4, k, &[false; 4], &[false; 4])).cost(false))
            .sum();
        let base = cbp_base(true);
        let pattern_q0 = ctx(base).cost(true) - ctx(base).cost(false);
        assert_eq!(
            cost16(&ac_only),
            empty + pattern_q0 + three_zero_flags + ac_block.cost
        );
        // All round-trip; the DC levels are read back apart.
        let mut both = ac_only.clone();
        both.luma_dc = dc_only.luma_dc;
        for res in [dc_only, ac_only, both] {
            let mut enc = RangeEncoder::new();
            ResidualCoder::new(1, 1).write(&mut enc, 0, 0, ResidualSyntax::Intra16x16, &res);
            let bytes = enc.finish();
            let mut dec = RangeDecoder::new(&bytes);
            assert_eq!(
                ResidualCoder::new(1, 1).read(&mut dec, 0, 0, ResidualSyntax::Intra16x16),
                Ok(res)
            );
        }
    }

    fn block_strategy() -> impl Strategy<Value = Block4> {
        // Mostly zeros, as after quantisation.
        proptest::collection::vec(
            prop_oneof![12 => Just(0i32), 6 => -2i32..=2, 2 => -40i32..=40, 1 => -(MAX_LEVEL as i32)..=MAX_LEVEL as i32],
            16,
        )
        .prop_map(|v| {
            let mut b = [[0; 4]; 4];
            for (i, x) in v.into_iter().enumerate() {
                b[i / 4][i % 4] = x;
            }
            b
        })
    }

    fn mb_strategy() -> impl Strategy<Value = (MbResidual, ResidualSyntax)> {
        let syntax = prop_oneof![
            Just(ResidualSyntax::Inter),
            Just(ResidualSyntax::Intra),
            Just(ResidualSyntax::Intra8x8),
            Just(ResidualSyntax::Intra16x16)
        ];
        (
            proptest::collection::vec(block_strategy(), 24),
            any::<u32>(),
            syntax,
            any::<bool>(),
            block_strategy(),
        )
            .prop_map(|(blocks, empty_mask, syntax, t8, dc)| {
                let mut res = MbResidual::default();
                for (i, b) in blocks.into_iter().enumerate() {
                    if empty_mask & (1 << i) == 0 {
                        match i {
                            0..=15 => res.luma[i] = b,
                            _ => res.chroma[(i - 16) / 4][i % 4] = b,
                        }
                    }
                }
                // Inter macroblocks with luma levels may take them as four
                // 8x8 blocks (each quadrant's four 4x4 blocks side by side),
                // 8x8 intra ones always do.
                let t8 = match syntax {
                    ResidualSyntax::Inter => t8,
                    ResidualSyntax::Intra | ResidualSyntax::Intra16x16 => false,
                    ResidualSyntax::Intra8x8 => true,
                };
                // Intra 16x16 luma: DC levels apart (none when the mask
                // says so), AC levels in the blocks.
                if syntax == ResidualSyntax::Intra16x16 {
                    for b in &mut res.luma {
                        b[0][0] = 0;
                    }
                    if empty_mask & (1 << 24) == 0 {
                        res.luma_dc.copy_from_slice(dc.as_flattened());
                    }
                }
                if t8 && res.luma_coded().iter().any(|&c| c) {
                    let mut b8 = Box::new([[[0; 8]; 8]; 4]);
                    for (k, b) in res.luma.iter().enumerate() {
                        let (q, x, y) = ((k / 8) * 2 + (k % 4) / 2, (k % 2) * 4, ((k / 4) % 2) * 4);
                        for (r, row) in b.iter().enumerate() {
                            b8[q][y + r][x..x + 4].copy_from_slice(row);
                        }
                    }
                    res.luma = Default::default();
                    res.luma8 = Some(b8);
                }
                (res, syntax)
            })
    }

    proptest! {
        #[test]
        fn frames_of_macroblocks_round_trip(
            mbs in proptest::collection::vec(proptest::option::of(mb_strategy()), 6)
        ) {
            // 3 x 2 macroblocks; None = skipped (no residual syntax).
            let mut writer = ResidualCoder::new(3, 2);
            let mut shadow = ResidualCoder::new(3, 2);
            let mut enc = RangeEncoder::new();
            for (i, mb) in mbs.iter().enumerate() {
                if let Some((res, syntax)) = mb {
                    writer.write(&mut enc, i % 3, i / 3, *syntax, res);
                    shadow.commit(i % 3, i / 3, *syntax, res);
                }
            }
            // Committing adapts exactly as writing does.
            prop_assert_eq!(&writer.contexts, &shadow.contexts);
            prop_assert_eq!(&writer.luma, &shadow.luma);
            let bytes = enc.finish();
            let mut reader = ResidualCoder::new(3, 2);
            let mut dec = RangeDecoder::new(&bytes);
            for (i, mb) in mbs.iter().enumerate() {
                if let Some((res, syntax)) = mb {
                    prop_assert_eq!(&reader.read(&mut dec, i % 3, i / 3, *syntax)?, res);
                }
            }
            prop_assert!(dec.consumed_all());
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            let mut coder = ResidualCoder::new(2, 2);
            let mut dec = RangeDecoder::new(&bytes);
            let syntaxes = [
                ResidualSyntax::Inter,
                ResidualSyntax::Intra,
                ResidualSyntax::Intra8x8,
                ResidualSyntax::Intra16x16,
            ];
            for (i, syntax) in syntaxes.into_iter().enumerate() {
                let _ = coder.read(&mut dec, i % 2, i / 2, syntax);
            }
        }
    }

    #[test]
    fn priced_bits_track_written_bits() {
        // Sparse small levels, as in real residuals, over a 6 x 4 frame.
        let mut s = 12345u32;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s
        };
        let mut coder = ResidualCoder::new(6, 4);
        let mut enc = RangeEncoder::new();
        let mut priced = 0u64;
        for i in 0..24 {
            let mut res = MbResidual::default();
            for b in res.luma.iter_mut().chain(res.chroma.iter_mut().flatten()) {
                for (k, &z) in ZIGZAG.iter().enumerate() {
                    if next() % (3 + 2 * k as u32) == 0 {
                        b[z / 4][z % 4] = (next() % 5) as i32 - 2;
                    }
                }
            }
            priced += u64::from(cost(&coder, i % 6, i / 6, ResidualSyntax::Inter, &res));
            coder.write(&mut enc, i % 6, i / 6, ResidualSyntax::Inter, &res);
        }
        let written = enc.finish().len() as f64 * 8.0;
        let priced = priced as f64 / 256.0;
        assert!(
            (priced / written - 1.0).abs() < 0.05,
            "priced {priced}, written {written}"
        );
    }
}
