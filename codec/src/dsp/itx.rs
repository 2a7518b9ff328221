//! The inverse transform kernels (normative: FORMAT.md section 10): a
//! block of levels dequantised, inverse transformed and added to its
//! prediction with clipping, for the 4x4 and the 8x8 transforms. The AVX2
//! kernels are intrinsics (integer arithmetic: the same samples).

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
        // The scalar source compiled for AVX2 transposed element by
        // element: 2.5 k instructions a macroblock's four blocks.
        add_8x8: x86::add_8x8_avx2,
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
mod x86 {
    use crate::consts::MB;
    use crate::dsp::x86::transpose8x8_epi32 as transpose8;
    use crate::transform::{Block4, DEQUANT_BY_POSITION};
    use crate::transform8x8::{Block8, DEQUANT8_BY_POSITION};
    use std::arch::x86_64::*;

    /// [`super::add_8x8`] in AVX2: a row of the block in each register's
    /// eight lanes. Levels are first clamped to 16 bits, which changes no
    /// dequantised value (any larger one clamps to the same bound) and
    /// keeps the products within 32 bits; the inverse transform's passes
    /// in the scalar order, with a transpose before each.
    pub(super) fn add_8x8_avx2(levels: &Block8, qp: u8, out: &mut [u8; 256], (x, y): (usize, usize)) {
        if qp > crate::transform::MAX_QP || x > 8 || y > 8 {
            return super::add_8x8(levels, qp, out, (x, y));
        }
        // SAFETY: this kernel sits only in the AVX2 table, handed out only
        // where the CPU has AVX2; the block's eight rows of eight samples
        // from (x, y), both at most 8, lie inside the macroblock.
        unsafe { add_8x8_wide(levels, qp, out, y * MB + x) }
    }

    #[target_feature(enable = "avx2")]
    fn add_8x8_wide(levels: &Block8, qp: u8, out: &mut [u8; 256], at: usize) {
        let p = levels.as_ptr() as *const __m256i;
        let mut rows = [_mm256_setzero_si256(); 8];
        for (r, row) in rows.iter_mut().enumerate() {
            // SAFETY: a Block8 is eight rows of eight i32.
            *row = unsafe { _mm256_loadu_si256(p.add(r)) };
        }
        let any = rows
            .iter()
            .fold(_mm256_setzero_si256(), |a, &r| _mm256_or_si256(a, r));
        if _mm256_testz_si256(any, any) == 1 {
            return;
        }
        let (lo, hi) = (_mm256_set1_epi32(-32768), _mm256_set1_epi32(32767));
        let shift = _mm_cvtsi32_si128(i32::from(qp / 6));
        let deq = &DEQUANT8_BY_POSITION[usize::from(qp % 6)];
        for (r, row) in rows.iter_mut().enumerate() {
            // SAFETY: 32 bytes of the 256-byte table from row r.
            let v = unsafe { _mm256_loadu_si256(deq[8 * r..].as_ptr() as *const __m256i) };
            let w = _mm256_min_epi32(_mm256_max_epi32(*row, lo), hi);
            let w = _mm256_sll_epi32(_mm256_mullo_epi32(w, v), shift);
            let w = _mm256_srai_epi32::<2>(_mm256_add_epi32(w, _mm256_set1_epi32(2)));
            *row = _mm256_min_epi32(_mm256_max_epi32(w, lo), hi);
        }
        let residual = inverse_butterflies8(transpose8(inverse_butterflies8(transpose8(rows))));
        for (r, &d) in residual.iter().enumerate() {
            let d = _mm256_srai_epi32::<6>(_mm256_add_epi32(d, _mm256_set1_epi32(32)));
            let o = &mut out[at + r * MB..at + r * MB + 8];
            // SAFETY: eight bytes of `o` read and written.
            unsafe {
                let pred = _mm256_cvtepu8_epi32(_mm_loadl_epi64(o.as_ptr() as *const __m128i));
                let sum = _mm256_add_epi32(pred, d);
                let words = _mm_packs_epi32(_mm256_castsi256_si128(sum), _mm256_extracti128_si256::<1>(sum));
                _mm_storel_epi64(o.as_mut_ptr() as *mut __m128i, _mm_packus_epi16(words, words));
            }
        }
    }

    /// The inverse 8x8 butterfly (H.264 8.5.13.2) between eight rows, as
    /// [`crate::transform8x8::inverse_8x8`]'s columns.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn inverse_butterflies8(d: [__m256i; 8]) -> [__m256i; 8] {
        let (add, sub) = (_mm256_add_epi32, _mm256_sub_epi32);
        let half = |v: __m256i| _mm256_srai_epi32::<1>(v);
        let quarter = |v: __m256i| _mm256_srai_epi32::<2>(v);
        let e0 = add(d[0], d[4]);
        let e1 = sub(sub(sub(d[5], d[3]), d[7]), half(d[7]));
        let e2 = sub(d[0], d[4]);
        let e3 = sub(sub(add(d[1], d[7]), d[3]), half(d[3]));
        let e4 = sub(half(d[2]), d[6]);
        let e5 = add(add(sub(d[7], d[1]), d[5]), half(d[5]));
        let e6 = add(d[2], half(d[6]));
        let e7 = add(add(add(d[3], d[5]), d[1]), half(d[1]));
        let (f0, f1) = (add(e0, e6), add(e1, quarter(e7)));
        let (f2, f3) = (add(e2, e4), add(e3, quarter(e5)));
        let (f4, f5) = (sub(e2, e4), sub(quarter(e3), e5));
        let (f6, f7) = (sub(e0, e6), sub(e7, quarter(e1)));
        [
            add(f0, f7),
            add(f2, f5),
            add(f4, f3),
            add(f6, f1),
            sub(f6, f1),
            sub(f4, f3),
            sub(f2, f5),
            sub(f0, f7),
        ]
    }

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
