//! The inverse transform kernels (normative: FORMAT.md section 10): a
//! block of levels dequantised, inverse transformed and added to its
//! prediction with clipping, for the 4x4 and the 8x8 transforms. The AVX2
//! 4x4 kernel is intrinsics, the 8x8 one the scalar source compiled for
//! AVX2 (integer arithmetic: the same samples).

use super::PerLevel;
use crate::consts::MB;
use crate::transform::{dequantize, inverse_4x4, Block4};
use crate::transform8x8::{dequantize_8x8, inverse_8x8, Block8};

/// A 4x4 block added to its prediction: `(levels, qp, out, stride, (x,
/// y))`, the block at sample (x, y) of `out` (rows of `stride`).
pub type Add4x4Fn = fn(&Block4, u8, &mut [u8], usize, (usize, usize));

/// An 8x8 block added to a macroblock's luma prediction: `(levels, qp,
/// out, (x, y))`.
pub type Add8x8Fn = fn(&Block8, u8, &mut [u8; 256], (usize, usize));

/// A 4x4 block whose DC coefficient comes dequantised from a DC transform
/// (intra 16x16 luma, chroma) added to its prediction: `(levels, dc, qp,
/// out, stride, (x, y))`, the levels' position 0 not read.
pub type Add4x4DcFn = fn(&Block4, i32, u8, &mut [u8], usize, (usize, usize));

/// The inverse transform kernels of one CPU level.
#[derive(Debug, Clone, Copy)]
pub struct ItxDsp {
    /// Dequantise, inverse 4x4 transform, add.
    pub add_4x4: Add4x4Fn,
    /// Dequantise, inverse 8x8 transform, add.
    pub add_8x8: Add8x8Fn,
    /// Dequantise the AC levels, take the DC given, inverse 4x4
    /// transform, add.
    pub add_4x4_dc: Add4x4DcFn,
}

const SCALAR: ItxDsp = ItxDsp {
    add_4x4,
    add_8x8,
    add_4x4_dc,
};

/// The tables, lowest level first.
pub static ITX: PerLevel<ItxDsp> = PerLevel([
    SCALAR,
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    ItxDsp {
        add_4x4: x86::add_4x4_avx2,
        add_8x8: avx2::add_8x8,
        // The intra 16x16 and chroma blocks with AC levels: their scalar
        // body was 5 % of ultrafast's instructions on diver_vga (10
        // frames, callgrind).
        add_4x4_dc: x86::add_4x4_dc_avx2,
    },
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub fn itx() -> &'static ItxDsp {
    ITX.get()
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use crate::transform8x8::Block8;
    crate::compiled_for! { "avx2":
        fn add_8x8(levels: &Block8, qp: u8, out: &mut [u8; 256], at: (usize, usize)) => super::add_8x8;
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use crate::transform::{Block4, DEQUANT_BY_POSITION};
    use std::arch::x86_64::*;

    /// [`super::add_4x4`] in AVX2's 128-bit instructions: a row of the
    /// block in each register. Levels are first clamped to 16 bits, which
    /// changes no dequantised value (any larger one clamps to the same
    /// bound) and keeps the products within 32 bits; the inverse
    /// transform's passes in the scalar order (rows, then columns: its
    /// halvings round down), with a transpose before each.
    pub(super) fn add_4x4_avx2(
        levels: &Block4,
        qp: u8,
        out: &mut [u8],
        stride: usize,
        (bx, by): (usize, usize),
    ) {
        if qp > crate::transform::MAX_QP {
            // Shifts past 31 bits: the scalar build's 64-bit arithmetic.
            return super::add_4x4(levels, qp, out, stride, (bx, by));
        }
        let last = (by + 3) * stride + bx + 4;
        let out = &mut out[..last];
        // SAFETY: this kernel sits only in the AVX2 table, handed out only
        // where the CPU has AVX2; the block's four rows of four samples
        // end within `out` (sliced to the last one above).
        unsafe { add_4x4_wide(levels, None, qp, out, stride, (bx, by)) }
    }

    /// The AVX2 [`super::Add4x4DcFn`]: [`add_4x4_avx2`]'s body with the
    /// DC coefficient put in after the dequantisation.
    pub(super) fn add_4x4_dc_avx2(
        levels: &Block4,
        dc: i32,
        qp: u8,
        out: &mut [u8],
        stride: usize,
        (bx, by): (usize, usize),
    ) {
        if qp > crate::transform::MAX_QP {
            return super::add_4x4_dc(levels, dc, qp, out, stride, (bx, by));
        }
        let last = (by + 3) * stride + bx + 4;
        let out = &mut out[..last];
        // SAFETY: as [`add_4x4_avx2`]'s.
        unsafe { add_4x4_wide(levels, Some(dc), qp, out, stride, (bx, by)) }
    }

    /// Dequantise, inverse transform and add one block; with `dc`, that
    /// is the block's DC coefficient (its level at position 0 not read)
    /// and the block is transformed even where its AC levels are zero.
    #[target_feature(enable = "avx2")]
    fn add_4x4_wide(
        levels: &Block4,
        dc: Option<i32>,
        qp: u8,
        out: &mut [u8],
        stride: usize,
        (bx, by): (usize, usize),
    ) {
        let p = levels.as_ptr() as *const __m128i;
        // SAFETY: a Block4 is four rows of four i32. (No array map here: a
        // closure is not reliably inlined into a target-feature function.)
        let rows = unsafe {
            [
                _mm_loadu_si128(p),
                _mm_loadu_si128(p.add(1)),
                _mm_loadu_si128(p.add(2)),
                _mm_loadu_si128(p.add(3)),
            ]
        };
        let any = _mm_or_si128(_mm_or_si128(rows[0], rows[1]), _mm_or_si128(rows[2], rows[3]));
        if dc.is_none() && _mm_testz_si128(any, any) == 1 {
            return;
        }
        let (lo, hi) = (_mm_set1_epi32(-32768), _mm_set1_epi32(32767));
        let shift = _mm_cvtsi32_si128(i32::from(qp / 6));
        let deq = &DEQUANT_BY_POSITION[usize::from(qp % 6)];
        let mut c = [_mm_setzero_si128(); 4];
        for (r, (c, &row)) in c.iter_mut().zip(&rows).enumerate() {
            // SAFETY: 16 bytes of the 64-byte row of the table from row r.
            let v = unsafe { _mm_loadu_si128(deq[4 * r..].as_ptr() as *const __m128i) };
            let w = _mm_min_epi32(_mm_max_epi32(row, lo), hi);
            let w = _mm_sll_epi32(_mm_mullo_epi32(w, v), shift);
            *c = _mm_min_epi32(_mm_max_epi32(w, lo), hi);
        }
        if let Some(dc) = dc {
            c[0] = _mm_insert_epi32::<0>(c[0], dc);
        }
        // Rows' pass on the transposed block, then the columns' pass on
        // the block transposed back.
        let residual = butterflies(transpose(butterflies(transpose(c))));
        for (r, &d) in residual.iter().enumerate() {
            let at = (by + r) * stride + bx;
            let d = _mm_srai_epi32::<6>(_mm_add_epi32(d, _mm_set1_epi32(32)));
            let o = &mut out[at..at + 4];
            let pred = _mm_cvtepu8_epi32(_mm_cvtsi32_si128(i32::from_le_bytes([o[0], o[1], o[2], o[3]])));
            let sum = _mm_add_epi32(pred, d);
            let bytes = _mm_packus_epi16(_mm_packs_epi32(sum, sum), _mm_setzero_si128());
            o.copy_from_slice(&_mm_cvtsi128_si32(bytes).to_le_bytes());
        }
    }

    /// The inverse core transform's butterflies between four registers
    /// (H.264 8.5.12.2: the odd inputs halved, rounding down).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn butterflies([a0, a1, a2, a3]: [__m128i; 4]) -> [__m128i; 4] {
        let (e, f) = (_mm_add_epi32(a0, a2), _mm_sub_epi32(a0, a2));
        let g = _mm_sub_epi32(_mm_srai_epi32::<1>(a1), a3);
        let h = _mm_add_epi32(a1, _mm_srai_epi32::<1>(a3));
        [
            _mm_add_epi32(e, h),
            _mm_add_epi32(f, g),
            _mm_sub_epi32(f, g),
            _mm_sub_epi32(e, h),
        ]
    }

    /// A 4x4 block of 32-bit values transposed.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn transpose([a, b, c, d]: [__m128i; 4]) -> [__m128i; 4] {
        let (t0, t1) = (_mm_unpacklo_epi32(a, b), _mm_unpackhi_epi32(a, b));
        let (t2, t3) = (_mm_unpacklo_epi32(c, d), _mm_unpackhi_epi32(c, d));
        [
            _mm_unpacklo_epi64(t0, t2),
            _mm_unpackhi_epi64(t0, t2),
            _mm_unpacklo_epi64(t1, t3),
            _mm_unpackhi_epi64(t1, t3),
        ]
    }
}

/// Adds one 4x4 block of levels, dequantised at `qp`, to the prediction
/// held in `out` (a `stride`-wide block) at (bx, by), clipping; a block
/// without levels leaves it as it is.
#[inline(always)]
fn add_4x4(levels: &Block4, qp: u8, out: &mut [u8], stride: usize, (bx, by): (usize, usize)) {
    if levels.as_flattened().iter().all(|&v| v == 0) {
        return;
    }
    let mut c = *levels;
    dequantize(&mut c, qp);
    let residual = inverse_4x4(&c);
    for (r, res) in residual.iter().enumerate() {
        let i = (by + r) * stride + bx;
        for (o, &d) in out[i..i + 4].iter_mut().zip(res) {
            *o = (i32::from(*o) + d).clamp(0, 255) as u8;
        }
    }
}

/// Adds one 4x4 block to the prediction held in `out` (a `stride`-wide
/// block) at (bx, by), clipping: its AC levels dequantised at `qp` (the
/// level at position 0 not read) and the dequantised DC coefficient `dc`.
fn add_4x4_dc(levels: &Block4, dc: i32, qp: u8, out: &mut [u8], stride: usize, (bx, by): (usize, usize)) {
    let mut c = *levels;
    dequantize(&mut c, qp);
    c[0][0] = dc;
    for (r, res) in inverse_4x4(&c).iter().enumerate() {
        let i = (by + r) * stride + bx;
        for (o, &d) in out[i..i + 4].iter_mut().zip(res) {
            *o = (i32::from(*o) + d).clamp(0, 255) as u8;
        }
    }
}

/// Adds one 8x8 block of levels, dequantised at `qp`, to the macroblock's
/// luma prediction `out` at sample (x, y), clipping.
#[inline(always)]
fn add_8x8(levels: &Block8, qp: u8, out: &mut [u8; 256], (x, y): (usize, usize)) {
    if levels.as_flattened().iter().all(|&v| v == 0) {
        return;
    }
    let mut c = *levels;
    dequantize_8x8(&mut c, qp);
    for (r, res) in inverse_8x8(&c).iter().enumerate() {
        let i = (y + r) * MB + x;
        for (o, &d) in out[i..i + 8].iter_mut().zip(res) {
            *o = (i32::from(*o) + d).clamp(0, 255) as u8;
        }
    }
}
