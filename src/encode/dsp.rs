//! The macroblock coder's kernels, one table per CPU level
//! ([`crate::codec::dsp`]): a 4x4 block's residual, forward transform and
//! quantisation; the greedy rate-distortion optimised quantisation of a
//! 4x4 block; and the luma of a macroblock in the 8x8 transform (inter:
//! zeroing and RDOQ; intra: one block). The quantisers' AVX2 kernels are
//! intrinsics (two blocks' rows in the eight 32-bit lanes: 0.58x the
//! instructions of the scalar source compiled for AVX2, talk_vga
//! ultrafast), and so is the 8x8 transform (a row in the eight lanes:
//! the scalar source's transposes were element by element, and it was
//! not inlined into its AVX2 callers); the other AVX2 builds are the
//! scalar source compiled for
//! AVX2 (the baseline x86-64 build has no 32-bit vector multiply, so
//! RDOQ's error updates would run a coefficient at a time); integer
//! arithmetic and the same floating-point operations without FMA: the
//! same levels.

use super::rate::{
    few_levels, residual_estimate, Block8Pricer, BlockPricer, ScanLevels, TrialPrices, WholeTrials,
};
use super::transform8x8::{inter_luma8, intra_block8, quadrant_forward8};
use crate::codec::dsp::PerLevel;
use crate::codec::residual::{MbResidual, ZIGZAG};
use crate::codec::transform::{
    dequantize, dequantize_level, forward_4x4, inverse_4x4_unrounded, quantize, Block4,
};
use crate::codec::transform8x8::Block8;

/// One 4x4 block of `s - p`: `(s, p, size, (bx, by), qp, rounding)`, the
/// block at column `bx`, row `by` (in blocks) of `size`-sample rows; its
/// residual and its levels, quantised with the rounding offset `rounding`
/// (a fraction of a step) and no RDOQ.
pub type QuantizeFn = fn(&[u8], &[u8], usize, (usize, usize), u8, f64) -> (Block4, Block4);

/// Every 4x4 block of `s - p` (`size x size` samples, blocks in raster
/// order): `(s, p, size, qp, rounding, residuals, levels)`, as
/// [`QuantizeFn`] block by block.
pub type QuantizeBlocksFn = fn(&[u8], &[u8], usize, u8, f64, &mut [Block4], &mut [Block4]);

/// The levels of one 8x8 quadrant of a macroblock's luma `s - p`: `(s,
/// p, quadrant, qp, rounding)`, its four 4x4 blocks in raster order, as
/// [`QuantizeFn`] gives them (the quadrant's index in raster order too).
pub type QuadrantLevelsFn = fn(&[u8; 256], &[u8; 256], usize, u8, f64) -> [Block4; 4];

/// RDOQ of a 4x4 block: `(residual, levels, qp, lambda, rate)` lowers
/// `levels` where squared error + lambda * bits falls ([`rdoq_4x4`]).
pub type RdoqFn = fn(&Block4, &mut Block4, u8, f64, &BlockPricer);

/// Inter luma in the 8x8 transform: `(src, pred, qp, lambda, rate)`, the
/// four blocks' levels (zeroed where they cost little, RDOQ when `rate`
/// is given), `None` when none is left.
pub type InterLuma8Fn =
    fn(&[u8; 256], &[u8; 256], u8, f64, Option<&Block8Pricer>) -> Option<Box<[Block8; 4]>>;

/// One intra 8x8 block's levels: `(src, pred, quadrant, (qp, lambda), rate)`.
pub type IntraBlock8Fn = fn(&[u8; 256], &[u8; 256], usize, (u8, f64), Option<&Block8Pricer>) -> Block8;

/// The 8x8 transform of one quadrant of a macroblock's luma `s - p`:
/// `(s, p, quadrant)` (the quadrant's index in raster order), the
/// coefficients of [`crate::codec::transform8x8::forward_8x8`].
pub type Forward8Fn = fn(&[u8; 256], &[u8; 256], usize) -> Block8;

/// Inter luma's zeroing of costly lone levels ([`decimate_luma`]).
pub type DecimateLumaFn = fn(&mut [Block4; 16]);

/// The summed zeroing cost of blocks' levels (H.264's reference encoder's, as
/// x264's `decimate_score`).
pub type DecimateScoreFn = fn(&[Block4]) -> u32;

/// A macroblock's residual bits estimated from its levels' counts
/// ([`super::rate::residual_estimate`]).
pub type ResidualEstimateFn = fn(&MbResidual) -> f64;

/// The macroblock coder's kernels of one CPU level.
#[derive(Debug, Clone, Copy)]
pub struct CoderDsp {
    /// Residual, transform and quantisation of a 4x4 block.
    pub quantize_4x4: QuantizeFn,
    /// The same over a plane's blocks.
    pub quantize_blocks: QuantizeBlocksFn,
    /// The levels of a luma quadrant.
    pub quadrant_levels: QuadrantLevelsFn,
    /// RDOQ of a 4x4 block.
    pub rdoq_4x4: RdoqFn,
    /// Inter luma's zeroing.
    pub decimate_luma: DecimateLumaFn,
    /// Blocks' zeroing cost.
    pub decimate_score: DecimateScoreFn,
    /// A macroblock's residual bits estimated from its levels.
    pub residual_estimate: ResidualEstimateFn,
    /// Inter luma in the 8x8 transform.
    pub inter_luma8: InterLuma8Fn,
    /// An intra 8x8 block's levels.
    pub intra_block8: IntraBlock8Fn,
    /// A luma quadrant's 8x8 transform (what the two above use).
    pub forward_8x8: Forward8Fn,
}

const SCALAR: CoderDsp = CoderDsp {
    quantize_4x4,
    quantize_blocks,
    quadrant_levels,
    rdoq_4x4,
    decimate_luma,
    decimate_score,
    residual_estimate,
    inter_luma8,
    intra_block8,
    forward_8x8: quadrant_forward8,
};

/// The tables, lowest level first.
pub static CODER: PerLevel<CoderDsp> = PerLevel([
    SCALAR,
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    CoderDsp {
        quantize_4x4: x86::quantize_4x4_avx2,
        quantize_blocks: x86::quantize_blocks_avx2,
        quadrant_levels: x86::quadrant_levels_avx2,
        rdoq_4x4: avx2::rdoq_4x4,
        decimate_luma: avx2::decimate_luma,
        decimate_score: avx2::decimate_score,
        residual_estimate: avx2::residual_estimate,
        inter_luma8: avx2::inter_luma8,
        intra_block8: avx2::intra_block8,
        forward_8x8: x86::forward_8x8_avx2,
    },
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub fn coder() -> &'static CoderDsp {
    CODER.get()
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use crate::codec::residual::MbResidual;
    use crate::codec::transform::Block4;
    use crate::codec::transform8x8::Block8;
    use crate::encode::rate::{Block8Pricer, BlockPricer};
    crate::codec::compiled_for! { "avx2":
        fn quantize_blocks(s: &[u8], p: &[u8], size: usize, qp: u8, rounding: f64, residuals: &mut [Block4], levels: &mut [Block4])
            => super::quantize_blocks;
        fn rdoq_4x4(residual: &Block4, levels: &mut Block4, qp: u8, lambda: f64, rate: &BlockPricer)
            => super::rdoq_4x4;
        fn decimate_luma(luma: &mut [Block4; 16]) => super::decimate_luma;
        fn decimate_score(blocks: &[Block4]) -> u32 => super::decimate_score;
        fn inter_luma8(src: &[u8; 256], pred: &[u8; 256], qp: u8, lambda: f64, rate: Option<&Block8Pricer>) -> Option<Box<[Block8; 4]>>
            => super::x86::inter_luma8_in_avx2;
        fn intra_block8(src: &[u8; 256], pred: &[u8; 256], q: usize, qp_lambda: (u8, f64), rate: Option<&Block8Pricer>) -> Block8
            => super::x86::intra_block8_in_avx2;
    }
    // The counts of non-zero levels are masks counted by POPCNT (which the
    // AVX2 level requires too): without it, bit by bit.
    crate::codec::compiled_for! { "avx2,popcnt":
        fn residual_estimate(res: &MbResidual) -> f64 => crate::encode::rate::residual_estimate;
    }
}

/// H.264 reference-encoder cost of a 4x4 block's levels for the zeroing
/// decision: a level above 1 makes it worth keeping; a lone ±1 costs by
/// how few zeros precede it.
#[inline(always)]
pub(crate) fn coefficient_cost(b: &Block4) -> u32 {
    const COST: [u32; 16] = [3, 2, 2, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
    let Some(raster) = small_levels(b) else {
        return 999;
    };
    // The same bits in scan order.
    let mut mask = u32::from(TO_SCAN[0][raster & 0xff] | TO_SCAN[1][raster >> 8]);
    // Each level costs by the run of zeros since the previous one.
    let (mut cost, mut next) = (0, 0);
    while mask != 0 {
        let k = mask.trailing_zeros();
        cost += COST[(k - next) as usize];
        next = k + 1;
        mask &= mask - 1;
    }
    cost
}

/// The raster bit mask of a block's nonzero levels, `None` when any
/// exceeds 1 in magnitude.
#[inline(always)]
fn small_levels(b: &Block4) -> Option<usize> {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: SSE2 is part of x86-64.
        unsafe { x86::small_levels_sse2(b) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    small_levels_scalar(b)
}

/// The scalar [`small_levels`] (a compare and a bit gather per level).
#[inline(always)]
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
pub(crate) fn small_levels_scalar(b: &Block4) -> Option<usize> {
    let (mut raster, mut big) = (0usize, false);
    for (k, &v) in b.as_flattened().iter().enumerate() {
        raster |= usize::from(v != 0) << k;
        big |= v.unsigned_abs() > 1;
    }
    (!big).then_some(raster)
}

#[cfg(target_arch = "x86_64")]
pub(crate) mod x86 {
    use crate::codec::dsp::x86::transpose8x8_epi32 as transpose8;
    use crate::codec::syntax::MB;
    use crate::codec::transform::{Block4, Quantizer4x4};
    use crate::codec::transform8x8::Block8;
    use crate::encode::rate::Block8Pricer;
    use crate::encode::transform8x8::{inter_luma8_with, intra_block8_with};
    use std::arch::x86_64::*;

    /// The AVX2 [`super::Forward8Fn`].
    #[inline(always)]
    pub(crate) fn forward_8x8_avx2(s: &[u8; 256], p: &[u8; 256], quadrant: usize) -> Block8 {
        // SAFETY: this kernel sits only in the AVX2 table, handed out only
        // where the CPU has AVX2, and is called by the AVX2 builds below.
        unsafe { forward_8x8_body(s, p, quadrant) }
    }

    /// [`super::inter_luma8`] with [`forward_8x8_avx2`], for the AVX2 build.
    #[inline(always)]
    pub(crate) fn inter_luma8_in_avx2(
        src: &[u8; 256],
        pred: &[u8; 256],
        qp: u8,
        lambda: f64,
        rate: Option<&Block8Pricer>,
    ) -> Option<Box<[Block8; 4]>> {
        inter_luma8_with(forward_8x8_avx2, src, pred, (qp, lambda), rate)
    }

    /// [`super::intra_block8`] with [`forward_8x8_avx2`], for the AVX2 build.
    #[inline(always)]
    pub(crate) fn intra_block8_in_avx2(
        src: &[u8; 256],
        pred: &[u8; 256],
        q: usize,
        qp_lambda: (u8, f64),
        rate: Option<&Block8Pricer>,
    ) -> Block8 {
        intra_block8_with(forward_8x8_avx2, src, pred, q, qp_lambda, rate)
    }

    /// The quadrant's eight rows of residual, one in each register's eight
    /// 32-bit lanes; the butterflies between the rows, a transpose, the
    /// butterflies again and the transpose back: the scalar transform's
    /// passes in its order (exact integer arithmetic, so the same values).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn forward_8x8_body(s: &[u8; 256], p: &[u8; 256], quadrant: usize) -> Block8 {
        let at = (quadrant / 2) * 8 * MB + (quadrant % 2) * 8;
        let (s, p) = (&s[at..at + 7 * MB + 8], &p[at..at + 7 * MB + 8]);
        let mut rows = [_mm256_setzero_si256(); 8];
        for (r, row) in rows.iter_mut().enumerate() {
            // SAFETY: 8 bytes from r * MB, r < 8: inside both slices.
            unsafe {
                let x = _mm256_cvtepu8_epi32(_mm_loadl_epi64(s.as_ptr().add(r * MB) as *const __m128i));
                let y = _mm256_cvtepu8_epi32(_mm_loadl_epi64(p.as_ptr().add(r * MB) as *const __m128i));
                *row = _mm256_sub_epi32(x, y);
            }
        }
        let w = transpose8(butterflies8(transpose8(butterflies8(rows))));
        let mut out = [[0; 8]; 8];
        for (row, &v) in out.iter_mut().zip(&w) {
            // SAFETY: a row of a Block8 is 32 contiguous bytes.
            unsafe { _mm256_storeu_si256(row.as_mut_ptr() as *mut __m256i, v) };
        }
        out
    }

    /// `T X` of the 8x8 transform between eight rows (each step row-wide,
    /// as [`crate::codec::transform8x8::forward_8x8`]'s columns).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn butterflies8(x: [__m256i; 8]) -> [__m256i; 8] {
        let (add, sub) = (_mm256_add_epi32, _mm256_sub_epi32);
        let times = |v: __m256i, k: i32| _mm256_mullo_epi32(v, _mm256_set1_epi32(k));
        let (s0, s1, s2, s3) = (add(x[0], x[7]), add(x[1], x[6]), add(x[2], x[5]), add(x[3], x[4]));
        let (d0, d1, d2, d3) = (sub(x[0], x[7]), sub(x[1], x[6]), sub(x[2], x[5]), sub(x[3], x[4]));
        let (a, b) = (add(s0, s3), add(s1, s2));
        let (c, e) = (sub(s0, s3), sub(s1, s2));
        [
            _mm256_slli_epi32::<3>(add(a, b)),
            add(add(times(d0, 12), times(d1, 10)), add(times(d2, 6), times(d3, 3))),
            add(_mm256_slli_epi32::<3>(c), _mm256_slli_epi32::<2>(e)),
            sub(sub(times(d0, 10), times(d1, 3)), add(times(d2, 12), times(d3, 6))),
            _mm256_slli_epi32::<3>(sub(a, b)),
            add(sub(times(d0, 6), times(d1, 12)), add(times(d2, 3), times(d3, 10))),
            sub(_mm256_slli_epi32::<2>(c), _mm256_slli_epi32::<3>(e)),
            add(sub(times(d0, 3), times(d1, 6)), sub(times(d2, 10), times(d3, 12))),
        ]
    }

    /// The AVX2 [`super::QuantizeBlocksFn`]: a macroblock's luma (16) or a
    /// chroma plane (8) two side-by-side blocks at a time, one row of
    /// both in the eight 32-bit lanes; other sizes as the scalar build.
    pub(crate) fn quantize_blocks_avx2(
        s: &[u8],
        p: &[u8],
        size: usize,
        qp: u8,
        rounding: f64,
        residuals: &mut [Block4],
        levels: &mut [Block4],
    ) {
        if size != 16 && size != 8 {
            return super::avx2::quantize_blocks(s, p, size, qp, rounding, residuals, levels);
        }
        // SAFETY: this kernel sits only in the AVX2 table, handed out only
        // where the CPU has AVX2.
        unsafe { quantize_sized_avx2(s, p, size, Quantizer4x4::new(qp, rounding), residuals, levels) }
    }

    /// The AVX2 [`super::QuadrantLevelsFn`]: the quadrant's two rows of
    /// blocks as two pairs.
    pub(crate) fn quadrant_levels_avx2(
        s: &[u8; 256],
        p: &[u8; 256],
        quadrant: usize,
        qp: u8,
        rounding: f64,
    ) -> [Block4; 4] {
        let mut levels = [[[0; 4]; 4]; 4];
        // SAFETY: this kernel sits only in the AVX2 table, handed out only
        // where the CPU has AVX2.
        unsafe { quadrant_levels_body(s, p, quadrant, Quantizer4x4::new(qp, rounding), &mut levels) };
        levels
    }

    #[target_feature(enable = "avx2")]
    fn quadrant_levels_body(
        s: &[u8; 256],
        p: &[u8; 256],
        quadrant: usize,
        q: Quantizer4x4,
        out: &mut [Block4; 4],
    ) {
        let corner = (quadrant / 2) * 128 + (quadrant % 2) * 8;
        for (half, pair) in out.chunks_exact_mut(2).enumerate() {
            let at = corner + half * 64;
            // SAFETY: the pair's four rows of 8 samples, 16 apart, start at
            // most at 192 + 8: inside both 256-sample macroblocks.
            let (_, level) = unsafe { quantize_pair(s.as_ptr().add(at), p.as_ptr().add(at), 16, &q) };
            store_pair(level, pair);
        }
    }

    /// The AVX2 [`super::QuantizeFn`]: one block in the low halves of the
    /// pair kernel's lanes (the high halves hold zeros, not stored).
    pub(crate) fn quantize_4x4_avx2(
        s: &[u8],
        p: &[u8],
        size: usize,
        (bx, by): (usize, usize),
        qp: u8,
        rounding: f64,
    ) -> (Block4, Block4) {
        let at = by * 4 * size + bx * 4;
        let (s, p) = (&s[at..at + 3 * size + 4], &p[at..at + 3 * size + 4]);
        let mut out = ([[0; 4]; 4], [[0; 4]; 4]);
        // SAFETY: this kernel sits only in the AVX2 table, handed out only
        // where the CPU has AVX2; the block's rows lie inside s and p.
        unsafe { quantize_one_avx2(s, p, size, Quantizer4x4::new(qp, rounding), &mut out) };
        out
    }

    #[target_feature(enable = "avx2")]
    fn quantize_one_avx2(s: &[u8], p: &[u8], size: usize, q: Quantizer4x4, out: &mut (Block4, Block4)) {
        // Four samples a row, zero-extended to the pair kernel's eight.
        let rows = |x: &[u8]| -> [u8; 32] {
            let mut r = [0u8; 32];
            for (k, chunk) in r.chunks_exact_mut(8).enumerate() {
                chunk[..4].copy_from_slice(&x[k * size..k * size + 4]);
            }
            r
        };
        let (s, p) = (rows(s), rows(p));
        // SAFETY: rows of 8 bytes, 8 apart, inside the 32-byte arrays.
        let (residual, level) = unsafe { quantize_pair(s.as_ptr(), p.as_ptr(), 8, &q) };
        store_one(residual, &mut out.0);
        store_one(level, &mut out.1);
    }

    /// The low halves of four rows into a block.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn store_one([r0, r1, r2, r3]: [__m256i; 4], out: &mut Block4) {
        let out = out as *mut Block4 as *mut __m256i;
        // SAFETY: a Block4 is 64 contiguous bytes: two unaligned stores.
        unsafe {
            _mm256_storeu_si256(out, _mm256_permute2x128_si256::<0x20>(r0, r1));
            _mm256_storeu_si256(out.add(1), _mm256_permute2x128_si256::<0x20>(r2, r3));
        }
    }

    /// [`quantize_blocks_avx2`] of size 16 or 8, every step inlined here.
    #[target_feature(enable = "avx2")]
    fn quantize_sized_avx2(
        s: &[u8],
        p: &[u8],
        size: usize,
        q: Quantizer4x4,
        residuals: &mut [Block4],
        levels: &mut [Block4],
    ) {
        let cols = size / 4;
        let blocks = cols * cols;
        let (s, p) = (&s[..size * size], &p[..size * size]);
        let (residuals, levels) = (&mut residuals[..blocks], &mut levels[..blocks]);
        // Rows and columns of blocks in two loops, not a division and a
        // remainder by `cols` per pair (`quantize_blocks_16x16/avx2`
        // 111-140 ns against 133-216 ns, five alternate runs).
        for (by, k0) in (0..blocks).step_by(cols).enumerate() {
            for bx in (0..cols).step_by(2) {
                let (k, at) = (k0 + bx, by * 4 * size + bx * 4);
                // SAFETY: the two blocks' four rows of 8 samples lie inside
                // s and p (bx and cols are even: both blocks are on one row
                // of blocks).
                let (residual, level) =
                    unsafe { quantize_pair(s.as_ptr().add(at), p.as_ptr().add(at), size, &q) };
                store_pair(residual, &mut residuals[k..k + 2]);
                store_pair(level, &mut levels[k..k + 2]);
            }
        }
    }

    /// The residual and levels of the two 4x4 blocks at `s` and `p` (rows
    /// `stride` apart): four rows of both blocks each.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn quantize_pair(
        s: *const u8,
        p: *const u8,
        stride: usize,
        q: &Quantizer4x4,
    ) -> ([__m256i; 4], [__m256i; 4]) {
        // No closures or array maps here: they are not inlined into a
        // target-feature function reliably (a build that called them
        // per block took 5x the instructions).
        let mut residual = [_mm256_setzero_si256(); 4];
        for (r, out) in residual.iter_mut().enumerate() {
            // SAFETY: the caller's: 8 bytes of each row lie inside s and p.
            unsafe {
                let x = _mm256_cvtepu8_epi32(_mm_loadl_epi64(s.add(r * stride) as *const __m128i));
                let y = _mm256_cvtepu8_epi32(_mm_loadl_epi64(p.add(r * stride) as *const __m128i));
                *out = _mm256_sub_epi32(x, y);
            }
        }
        // The core transform is exact integer arithmetic, so its passes
        // may run in either order: between the rows first, then
        // (transposed) between the columns, then back to rows.
        let coeffs = transpose(butterflies(transpose(butterflies(residual))));
        let offset = _mm256_set1_epi32(q.offset as i32);
        let shift = _mm_cvtsi32_si128(q.shift as i32);
        let mut levels = [_mm256_setzero_si256(); 4];
        for (r, (out, &w)) in levels.iter_mut().zip(&coeffs).enumerate() {
            // The row's four multipliers for both blocks.
            // SAFETY: 16 bytes of the 64-byte table from row r.
            let m = unsafe { _mm_loadu_si128(q.multipliers[4 * r..].as_ptr() as *const __m128i) };
            let mf = _mm256_broadcastsi128_si256(m);
            // |w| < 2^14 and MF < 2^14: product and offset fit 32 bits.
            let scaled = _mm256_add_epi32(_mm256_mullo_epi32(_mm256_abs_epi32(w), mf), offset);
            *out = _mm256_sign_epi32(_mm256_srl_epi32(scaled, shift), w);
        }
        (residual, levels)
    }

    /// The H.264 core transform's butterflies between four rows.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn butterflies([r0, r1, r2, r3]: [__m256i; 4]) -> [__m256i; 4] {
        let (s03, d03) = (_mm256_add_epi32(r0, r3), _mm256_sub_epi32(r0, r3));
        let (s12, d12) = (_mm256_add_epi32(r1, r2), _mm256_sub_epi32(r1, r2));
        [
            _mm256_add_epi32(s03, s12),
            _mm256_add_epi32(_mm256_add_epi32(d03, d03), d12),
            _mm256_sub_epi32(s03, s12),
            _mm256_sub_epi32(d03, _mm256_add_epi32(d12, d12)),
        ]
    }

    /// Each 128-bit half's 4x4 block of 32-bit values transposed.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn transpose([a, b, c, d]: [__m256i; 4]) -> [__m256i; 4] {
        let (t0, t1) = (_mm256_unpacklo_epi32(a, b), _mm256_unpackhi_epi32(a, b));
        let (t2, t3) = (_mm256_unpacklo_epi32(c, d), _mm256_unpackhi_epi32(c, d));
        [
            _mm256_unpacklo_epi64(t0, t2),
            _mm256_unpackhi_epi64(t0, t2),
            _mm256_unpacklo_epi64(t1, t3),
            _mm256_unpackhi_epi64(t1, t3),
        ]
    }

    /// Rows of two blocks (the left one's in the low halves) into them.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn store_pair([r0, r1, r2, r3]: [__m256i; 4], out: &mut [Block4]) {
        let out = out[..2].as_mut_ptr() as *mut __m256i;
        // SAFETY: two Block4 are 128 contiguous bytes: four unaligned stores.
        unsafe {
            _mm256_storeu_si256(out, _mm256_permute2x128_si256::<0x20>(r0, r1));
            _mm256_storeu_si256(out.add(1), _mm256_permute2x128_si256::<0x20>(r2, r3));
            _mm256_storeu_si256(out.add(2), _mm256_permute2x128_si256::<0x31>(r0, r1));
            _mm256_storeu_si256(out.add(3), _mm256_permute2x128_si256::<0x31>(r2, r3));
        }
    }

    /// [`super::small_levels_scalar`] in SSE2: the levels packed to bytes
    /// with saturation (a magnitude above 1 stays above 1), then a compare
    /// and a byte mask.
    #[inline]
    #[target_feature(enable = "sse2")]
    pub(crate) unsafe fn small_levels_sse2(b: &Block4) -> Option<usize> {
        let p = b.as_ptr() as *const __m128i;
        // SAFETY: a Block4 is 16 contiguous i32, four unaligned loads.
        let (r0, r1, r2, r3) = unsafe {
            (
                _mm_loadu_si128(p),
                _mm_loadu_si128(p.add(1)),
                _mm_loadu_si128(p.add(2)),
                _mm_loadu_si128(p.add(3)),
            )
        };
        let bytes = _mm_packs_epi16(_mm_packs_epi32(r0, r1), _mm_packs_epi32(r2, r3));
        let big = _mm_or_si128(
            _mm_cmpgt_epi8(bytes, _mm_set1_epi8(1)),
            _mm_cmplt_epi8(bytes, _mm_set1_epi8(-1)),
        );
        if _mm_movemask_epi8(big) != 0 {
            return None;
        }
        let zero = _mm_movemask_epi8(_mm_cmpeq_epi8(bytes, _mm_setzero_si128())) as usize;
        Some(!zero & 0xffff)
    }
}

/// `TO_SCAN[h][m]`: the zig-zag-order bit mask of the raster bits `m` of
/// the block's first (`h` 0) or second (`h` 1) eight positions.
const TO_SCAN: [[u16; 256]; 2] = {
    let mut t = [[0u16; 256]; 2];
    let mut h = 0;
    while h < 2 {
        let mut m = 0;
        while m < 256 {
            let mut k = 0;
            while k < 16 {
                let raster = ZIGZAG[k];
                if raster / 8 == h && (m >> (raster % 8)) & 1 == 1 {
                    t[h][m] |= 1 << k;
                }
                k += 1;
            }
            m += 1;
        }
        h += 1;
    }
    t
};

/// [`coefficient_cost`] summed over blocks.
#[inline(always)]
fn blocks_cost<'a>(blocks: impl IntoIterator<Item = &'a Block4>) -> u32 {
    let mut total = 0;
    for b in blocks {
        total += coefficient_cost(b);
    }
    total
}

/// Lone small levels cost more bits than they save distortion: drops an
/// 8x8 quadrant of inter luma whose levels cost < 4, and all of it when
/// the macroblock's total is < 6 (JM's thresholds).
#[inline(always)]
pub fn decimate_luma(luma: &mut [Block4; 16]) {
    let mut total = 0;
    for q in 0..4 {
        let blocks = [0, 1, 4, 5].map(|o| (q % 2) * 2 + (q / 2) * 8 + o);
        let cost = blocks_cost(blocks.iter().map(|&k| &luma[k]));
        if cost < 4 {
            for k in blocks {
                luma[k] = [[0; 4]; 4];
            }
        } else {
            total += cost;
        }
    }
    if total < 6 {
        *luma = [[[0; 4]; 4]; 16];
    }
}

/// The scalar [`DecimateScoreFn`].
#[inline(always)]
pub fn decimate_score(blocks: &[Block4]) -> u32 {
    blocks_cost(blocks)
}

/// The scalar [`QuadrantLevelsFn`].
#[inline(always)]
pub fn quadrant_levels(s: &[u8; 256], p: &[u8; 256], quadrant: usize, qp: u8, rounding: f64) -> [Block4; 4] {
    let (bx, by) = ((quadrant % 2) * 2, (quadrant / 2) * 2);
    std::array::from_fn(|k| quantize_4x4(s, p, 16, (bx + k % 2, by + k / 2), qp, rounding).1)
}

/// The scalar [`QuantizeBlocksFn`].
#[inline(always)]
pub fn quantize_blocks(
    s: &[u8],
    p: &[u8],
    size: usize,
    qp: u8,
    rounding: f64,
    residuals: &mut [Block4],
    levels: &mut [Block4],
) {
    // The macroblock's luma and chroma with their sizes known to the
    // compiler (no division per block, no bounds check per sample).
    match size {
        16 => quantize_sized::<16>(s, p, qp, rounding, residuals, levels),
        8 => quantize_sized::<8>(s, p, qp, rounding, residuals, levels),
        _ => quantize_any(s, p, size, qp, rounding, residuals, levels),
    }
}

#[inline(always)]
fn quantize_sized<const N: usize>(
    s: &[u8],
    p: &[u8],
    qp: u8,
    rounding: f64,
    residuals: &mut [Block4],
    levels: &mut [Block4],
) {
    let blocks = (N / 4) * (N / 4);
    let (residuals, levels) = (&mut residuals[..blocks], &mut levels[..blocks]);
    quantize_any(&s[..N * N], &p[..N * N], N, qp, rounding, residuals, levels)
}

#[inline(always)]
fn quantize_any(
    s: &[u8],
    p: &[u8],
    size: usize,
    qp: u8,
    rounding: f64,
    residuals: &mut [Block4],
    levels: &mut [Block4],
) {
    let cols = size / 4;
    for (k, (d, l)) in residuals.iter_mut().zip(levels.iter_mut()).enumerate() {
        (*d, *l) = quantize_4x4(s, p, size, (k % cols, k / cols), qp, rounding);
    }
}

/// The scalar [`QuantizeFn`].
#[inline(always)]
pub fn quantize_4x4(
    s: &[u8],
    p: &[u8],
    size: usize,
    (bx, by): (usize, usize),
    qp: u8,
    rounding: f64,
) -> (Block4, Block4) {
    let mut b = [[0i32; 4]; 4];
    for (r, row) in b.iter_mut().enumerate() {
        let i = (by * 4 + r) * size + bx * 4;
        for (c, v) in row.iter_mut().enumerate() {
            *v = i32::from(s[i + c]) - i32::from(p[i + c]);
        }
    }
    let mut c = forward_4x4(&b);
    quantize(&mut c, qp, rounding);
    (b, c)
}

/// The inverse transform's basis doubled: row `k` is twice the weight of
/// coefficient `k` on each of the four samples in one butterfly pass.
const INVERSE_BASIS_X2: [[i32; 4]; 4] = [[2, 2, 2, 2], [2, 1, -1, -2], [2, -2, -2, 2], [1, -2, 2, -1]];

/// The basis block of each coefficient (raster position 4r + c) before
/// the inverse transform's final rounding, doubled:
/// `INVERSE_BASIS_X2[r][rr] * INVERSE_BASIS_X2[c][cc]` at (rr, cc),
/// flattened, so that a step's move is one multiply-add over the block.
const INVERSE_BASIS_BLOCKS: [[i32; 16]; 16] = {
    let mut out = [[0; 16]; 16];
    let mut k = 0;
    while k < 16 {
        let mut j = 0;
        while j < 16 {
            out[k][j] = INVERSE_BASIS_X2[k / 4][j / 4] * INVERSE_BASIS_X2[k % 4][j % 4];
            j += 1;
        }
        k += 1;
    }
    out
};

/// Squared error between a residual and the reconstruction whose inverse
/// transform before the final rounding is `unrounded`. Each difference is
/// within 2^15 (dequantised coefficients are within 16 bits, so the
/// unrounded transform is within 20), so its square fits 32 bits: squares
/// in 32-bit lanes, summed in 64 (against 64-bit products, birds_720p's
/// I frame at QP 22 took 0.996x the instructions, with the flattened
/// basis blocks above).
#[inline(always)]
fn rounded_error(residual: &Block4, unrounded: &Block4) -> i64 {
    let (a, u) = (residual.as_flattened(), unrounded.as_flattened());
    let mut squares = [0u32; 16];
    for j in 0..16 {
        let x = a[j] - ((u[j] + 32) >> 6);
        squares[j] = x.unsigned_abs() * x.unsigned_abs();
    }
    squares.iter().map(|&s| u64::from(s)).sum::<u64>() as i64
}

/// The scalar [`RdoqFn`]: rate-distortion optimised quantisation, greedy: from the last level in
/// scan order to the first, each level moves one step toward zero when
/// that lowers squared error + lambda * bits (the residual coder's price
/// of the block; the error measured after the inverse transform, so the
/// transform's unequal gains are accounted for).
///
/// The error of a step is exact and cheap: when the dequantised
/// coefficient changes by a multiple of 4 (every step from QP 12 up), the
/// butterflies' halvings stay exact, so the inverse transform before its
/// final rounding moves by `d/4` times the coefficient's (doubled) basis
/// block. Other steps go through the whole inverse transform.
#[inline(always)]
pub fn rdoq_4x4(residual: &Block4, levels: &mut Block4, qp: u8, lambda: f64, rate: &BlockPricer) {
    if levels.as_flattened().iter().all(|&v| v == 0) {
        return;
    }
    let scan = ScanLevels::gather(levels.as_flattened(), &ZIGZAG);
    // Bits the levels add over an empty block, priced for its class
    // (chroma or luma, intra or inter) in the frame's residual coder as it
    // stands.
    let bits = f64::from(rate.scan_cost(&scan)) / 256.0;
    let quant = (qp, lambda);
    if few_levels(scan.mask) {
        lower_4x4(
            residual,
            levels,
            quant,
            (&scan, bits),
            WholeTrials::new(rate, scan),
        );
    } else {
        lower_4x4(residual, levels, quant, (&scan, bits), rate.trials(&scan));
    }
}

/// [`rdoq_4x4`]'s descent over the levels of `scan`, priced by `trials`.
#[inline(always)]
fn lower_4x4(
    residual: &Block4,
    levels: &mut Block4,
    (qp, lambda): (u8, f64),
    (scan, mut bits): (&ScanLevels<16>, f64),
    mut trials: impl TrialPrices,
) {
    let mut coeffs = *levels;
    dequantize(&mut coeffs, qp);
    let mut unrounded = inverse_4x4_unrounded(&coeffs);
    let mut error = rounded_error(residual, &unrounded);
    // The non-zero levels from the last: a trial changes only its own.
    let mut untried = scan.mask;
    while untried != 0 {
        let i = 63 - untried.leading_zeros() as usize;
        untried &= !(1 << i);
        let k = ZIGZAG[i];
        let (r, c) = (k / 4, k % 4);
        let v = levels[r][c];
        let lowered = v - v.signum();
        let coeff = dequantize_level(lowered, qp, r, c);
        let delta = coeff - coeffs[r][c];
        let moved = if delta % 4 == 0 {
            let mut u = unrounded;
            let step = delta / 4;
            for (x, &b) in u.as_flattened_mut().iter_mut().zip(&INVERSE_BASIS_BLOCKS[k]) {
                *x += step * b;
            }
            u
        } else {
            let mut d = coeffs;
            d[r][c] = coeff;
            inverse_4x4_unrounded(&d)
        };
        let e = rounded_error(residual, &moved);
        // Fewer bits than none cannot pay for more error than this.
        if (e - error) as f64 >= lambda * bits {
            trials.keep(i, v);
            continue;
        }
        let b = f64::from(trials.cost_with(i, lowered)) / 256.0;
        if (e - error) as f64 + lambda * (b - bits) >= 0.0 {
            trials.keep(i, v);
        } else {
            trials.keep(i, lowered);
            levels[r][c] = lowered;
            coeffs[r][c] = coeff;
            unrounded = moved;
            error = e;
            bits = b;
        }
    }
    // Last, the whole block against none of it (whose error is the
    // residual's energy).
    if bits > 0.0 {
        let energy: i64 = residual
            .as_flattened()
            .iter()
            .map(|&a| i64::from(a) * i64::from(a))
            .sum();
        if (energy - error) as f64 <= lambda * bits {
            *levels = [[0; 4]; 4];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::residual::{BlockClass, ResidualCoder};
    use crate::codec::transform::inverse_4x4;

    /// Squared error between a residual and what `levels` reconstruct to.
    fn block_error(residual: &Block4, levels: &Block4, qp: u8) -> i64 {
        let mut d = *levels;
        dequantize(&mut d, qp);
        let r = inverse_4x4(&d);
        let mut e = 0i64;
        for (a, b) in residual.as_flattened().iter().zip(r.as_flattened()) {
            let x = i64::from(a - b);
            e += x * x;
        }
        e
    }

    #[test]
    fn rdoq_only_moves_levels_toward_zero_and_never_raises_the_cost() {
        let qp = 28;
        let lambda = 1.4 * crate::me::lambda_for_qp(crate::me::Metric::Ssd, qp);
        let mut seed = 12345u32;
        for _ in 0..500 {
            let mut residual = [[0i32; 4]; 4];
            for v in residual.iter_mut().flatten() {
                seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
                *v = ((seed >> 16) % 61) as i32 - 30;
            }
            let mut levels = forward_4x4(&residual);
            quantize(&mut levels, qp, 1.0 / 6.0);
            let before = levels;
            let rate = crate::encode::rate::block_pricer(&ResidualCoder::new(1, 1), BlockClass::luma(false));
            rdoq_4x4(&residual, &mut levels, qp, lambda, &rate);
            let cost = |l: &Block4| {
                block_error(&residual, l, qp) as f64 + lambda * f64::from(rate.block_cost(l)) / 256.0
            };
            assert!(cost(&levels) <= cost(&before) + 1e-9);
            for (a, b) in levels.iter().flatten().zip(before.iter().flatten()) {
                assert!(a.abs() <= b.abs() && a * b >= 0, "{a} from {b}");
            }
        }
    }

    #[test]
    fn coefficient_cost_equals_the_scan_walk() {
        // The reference encoder's definition, walked in scan order.
        fn walk(b: &Block4) -> u32 {
            const COST: [u32; 16] = [3, 2, 2, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
            let (mut cost, mut run) = (0, 0);
            for &k in &ZIGZAG {
                let v = b[k / 4][k % 4];
                if v == 0 {
                    run += 1;
                } else if v.abs() > 1 {
                    return 999;
                } else {
                    cost += COST[run];
                    run = 0;
                }
            }
            cost
        }
        let blocks = random_blocks(3, |seed| match (seed >> 16) % 12 {
            0 => 1,
            1 => -1,
            2 if seed % 7 == 0 => 2,
            _ => 0,
        });
        for b in &blocks {
            assert_eq!(coefficient_cost(b), walk(b), "{b:?}");
        }
    }

    /// 20 000 blocks of levels, each `level(seed)` of a fresh LCG state.
    fn random_blocks(mut seed: u32, level: impl Fn(u32) -> i32) -> Vec<Block4> {
        (0..20_000)
            .map(|_| {
                let mut b = [[0i32; 4]; 4];
                for v in b.as_flattened_mut() {
                    seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
                    *v = level(seed);
                }
                b
            })
            .collect()
    }

    #[test]
    fn the_level_mask_in_sse2_equals_the_scalar_one() {
        let blocks = random_blocks(7, |seed| match (seed >> 16) % 16 {
            0 => 1,
            1 => -1,
            2 if seed % 5 == 0 => 2,
            3 if seed % 7 == 0 => -2,
            // Past i16 and i8: saturation must keep them large.
            4 if seed % 11 == 0 => 70_000,
            5 if seed % 11 == 0 => -300,
            6 if seed % 13 == 0 => 65_536,
            _ => 0,
        });
        for b in &blocks {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: SSE2 is part of x86-64.
            assert_eq!(
                unsafe { x86::small_levels_sse2(b) },
                small_levels_scalar(b),
                "{b:?}"
            );
            assert_eq!(small_levels(b), small_levels_scalar(b));
        }
    }

    #[test]
    fn coefficient_cost_keeps_large_levels_and_prices_lone_ones() {
        let mut b = [[0; 4]; 4];
        assert_eq!(coefficient_cost(&b), 0);
        b[0][0] = 1; // first in scan order, no zeros before it
        assert_eq!(coefficient_cost(&b), 3);
        b[3][3] = -1; // last, after 14 zeros
        assert_eq!(coefficient_cost(&b), 3);
        b[1][1] = 2;
        assert_eq!(coefficient_cost(&b), 999);
    }
}
