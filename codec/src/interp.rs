//! Sub-pixel interpolation for motion compensation (normative).
//!
//! * Luma: quarter-pel, HEVC's separable 8-tap filters (H.265 8.5.3.3.3.1).
//!   A horizontal pass keeps full precision (gain 64), a vertical pass
//!   divides by 64, and the result is rounded `(v + 32) >> 6` and clipped
//!   to 0..=255. Integer positions are plain copies.
//! * Chroma: bilinear at 1/8 pel (as H.264 8.4.2.2.2):
//!   `((8-fx)(8-fy) A + fx(8-fy) B + (8-fx)fy C + fx fy D + 32) >> 6`.
//!   A luma vector in quarter-pel units is the chroma vector in eighth-pel
//!   units (chroma has half the resolution).
//!
//! The reference picture extends without limit by repeating its edge
//! samples: any vector is valid. The plane's border holds that extension,
//! and a block displaced further out than the border is moved back inside
//! it, which reads the same samples as long as the border is at least the
//! block size plus 8 (checked).
//!
//! ```
//! use mocomp_codec::interp::predict_luma;
//! use mocomp_codec::picture::Plane;
//! let reference = Plane::from_fn(32, 32, |x, _| (x * 4) as u8).unwrap();
//! let mut out = [0u8; 16];
//! // Half a pixel to the right of (8, 8) on a ramp of slope 4: +2.
//! predict_luma(&reference, 8, 8, 2, 0, 4, 4, &mut out, 4);
//! assert_eq!(out[0], 34);
//! ```

use crate::picture::Plane;

/// Luma filter taps for phases 0, 1/4, 1/2, 3/4; each sums to 64. Tap `k`
/// applies to the sample at offset `k - 3`.
pub const LUMA_TAPS: [[i32; 8]; 4] = [
    [0, 0, 0, 64, 0, 0, 0, 0],
    [-1, 4, -10, 58, 17, -5, 1, 0],
    [-1, 4, -11, 40, 40, -11, 4, -1],
    [0, 1, -5, 17, 58, -10, 4, -1],
];

/// Largest block the predictors accept, per side.
pub const MAX_BLOCK: usize = 64;

/// Samples the 8-tap filter reads before and after the block.
const TAPS_BEFORE: isize = 3;
const TAPS_AFTER: isize = 4;

/// Moves a block's top-left coordinate (with `before` and `after` extra
/// samples read around a block of `size`) back into the plane's border
/// when it lies beyond it: the samples read are unchanged, since every
/// sample out there repeats the same edge sample.
#[inline]
fn clamp_into_border(
    pos: isize,
    size: usize,
    extent: usize,
    pad: usize,
    before: isize,
    after: isize,
) -> isize {
    let pad = pad as isize;
    let lo = -pad + before;
    let hi = extent as isize + pad - size as isize - after;
    pos.clamp(lo, hi.max(lo))
}

fn check_block(reference: &Plane, w: usize, h: usize, out: &[u8], out_stride: usize) {
    assert!(
        w <= MAX_BLOCK && h <= MAX_BLOCK && w > 0 && h > 0,
        "block {w}x{h}"
    );
    assert!(
        reference.pad() >= w.max(h) + 8,
        "plane border {} too small for {w}x{h} blocks",
        reference.pad()
    );
    assert!(
        out_stride >= w && out.len() >= (h - 1) * out_stride + w,
        "output too small"
    );
}

/// Luma prediction of the `w x h` block at (x, y) displaced by the
/// quarter-pel vector (mvx, mvy), into `out` (row stride `out_stride`).
///
/// On x86-64 with AVX2 the same code runs compiled for AVX2 (chosen once at
/// run time); the arithmetic is integer, so both give the same samples,
/// which a test holds.
#[allow(clippy::too_many_arguments)]
pub fn predict_luma(
    reference: &Plane,
    x: isize,
    y: isize,
    mvx: i32,
    mvy: i32,
    w: usize,
    h: usize,
    out: &mut [u8],
    out_stride: usize,
) {
    check_block(reference, w, h, out, out_stride);
    #[cfg(target_arch = "x86_64")]
    {
        if crate::cpu::at_least(crate::cpu::CpuLevel::Avx2) {
            // SAFETY: the CPU has AVX2 (checked above); the function is
            // the safe scalar code compiled with AVX2 enabled.
            unsafe { predict_luma_avx2(reference, x, y, mvx, mvy, w, h, out, out_stride) };
            return;
        }
    }
    // SAFETY: no AVX2.
    unsafe { predict_luma_body::<false>(reference, x, y, mvx, mvy, w, h, out, out_stride) };
}

/// [`predict_luma_body`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
unsafe fn predict_luma_avx2(
    reference: &Plane,
    x: isize,
    y: isize,
    mvx: i32,
    mvy: i32,
    w: usize,
    h: usize,
    out: &mut [u8],
    out_stride: usize,
) {
    predict_luma_body::<true>(reference, x, y, mvx, mvy, w, h, out, out_stride);
}

/// The luma predictor, for any instruction set; `AVX2` takes the 16x16
/// vertical pass to AVX2 intrinsics.
///
/// # Safety
/// `AVX2` is true only where the CPU has AVX2.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn predict_luma_body<const AVX2: bool>(
    reference: &Plane,
    x: isize,
    y: isize,
    mvx: i32,
    mvy: i32,
    w: usize,
    h: usize,
    out: &mut [u8],
    out_stride: usize,
) {
    let (fx, fy) = ((mvx & 3) as usize, (mvy & 3) as usize);
    let px = clamp_into_border(
        x + (mvx >> 2) as isize,
        w,
        reference.width(),
        reference.pad(),
        TAPS_BEFORE,
        TAPS_AFTER,
    );
    let py = clamp_into_border(
        y + (mvy >> 2) as isize,
        h,
        reference.height(),
        reference.pad(),
        TAPS_BEFORE,
        TAPS_AFTER,
    );
    let data = reference.data();
    let stride = reference.stride();
    let at = |xx: isize, yy: isize| reference.index(xx, yy);
    if w == 16 && h == 16 && (fx, fy) != (0, 0) {
        // The macroblock case, with sizes the compiler knows.
        let src = at(px - TAPS_BEFORE, py - TAPS_BEFORE);
        let mut block = [0u8; 256];
        // SAFETY: this function's contract passes on.
        luma_16x16::<AVX2>(&data[src..], stride, fx, fy, &mut block);
        for (r, row) in block.chunks_exact(16).enumerate() {
            out[r * out_stride..r * out_stride + 16].copy_from_slice(row);
        }
        return;
    }
    match (fx, fy) {
        (0, 0) => {
            for r in 0..h {
                let src = at(px, py + r as isize);
                out[r * out_stride..r * out_stride + w].copy_from_slice(&data[src..src + w]);
            }
        }
        (_, 0) => {
            let taps = &LUMA_TAPS[fx];
            let mut acc = [0i32; MAX_BLOCK];
            for r in 0..h {
                let src = at(px - TAPS_BEFORE, py + r as isize);
                filter_row(taps, |k| &data[src + k..src + k + w], &mut acc[..w]);
                round_into(&acc[..w], 6, &mut out[r * out_stride..r * out_stride + w]);
            }
        }
        (0, _) => {
            let taps = &LUMA_TAPS[fy];
            let mut acc = [0i32; MAX_BLOCK];
            for r in 0..h {
                let src = at(px, py + r as isize - TAPS_BEFORE);
                filter_row(
                    taps,
                    |k| &data[src + k * stride..src + k * stride + w],
                    &mut acc[..w],
                );
                round_into(&acc[..w], 6, &mut out[r * out_stride..r * out_stride + w]);
            }
        }
        _ => {
            let origin = at(px - TAPS_BEFORE, py - TAPS_BEFORE);
            luma_2d(&data[origin..], stride, (fx, fy), (w, h), out, out_stride);
        }
    }
}

/// A two-dimensional luma phase of a `w x h` block whose taps start at
/// `data[0]`: a horizontal pass over h + 7 rows at full precision (it fits
/// 16 bits: -6120..=22440), then vertical. Inlined into both of
/// [`predict_luma_body`]'s instances.
#[inline(always)]
fn luma_2d(
    data: &[u8],
    stride: usize,
    (fx, fy): (usize, usize),
    (w, h): (usize, usize),
    out: &mut [u8],
    out_stride: usize,
) {
    // Small blocks, the common case, use a small buffer.
    let rows = h + 7;
    let mut small = [0i16; 16 * 23];
    let mut large = Vec::new();
    let tmp: &mut [i16] = if w * rows <= small.len() {
        &mut small[..w * rows]
    } else {
        large.resize(w * rows, 0);
        &mut large
    };
    let (th, tv) = (&LUMA_TAPS[fx], &LUMA_TAPS[fy]);
    let mut acc = [0i32; MAX_BLOCK];
    for r in 0..rows {
        let src = r * stride;
        filter_row(th, |k| &data[src + k..src + k + w], &mut acc[..w]);
        for (t, &a) in tmp[r * w..(r + 1) * w].iter_mut().zip(&acc[..w]) {
            *t = a as i16;
        }
    }
    let mut acc = [0i32; MAX_BLOCK];
    for r in 0..h {
        let acc = &mut acc[..w];
        acc.fill(0);
        for (k, &t) in tv.iter().enumerate() {
            if t != 0 {
                for (a, &v) in acc.iter_mut().zip(&tmp[(r + k) * w..(r + k + 1) * w]) {
                    *a += t * i32::from(v);
                }
            }
        }
        for a in acc.iter_mut() {
            *a >>= 6;
        }
        round_into(acc, 6, &mut out[r * out_stride..r * out_stride + w]);
    }
}

const N16: usize = 16;

/// Row `r` of a 16x16 block's neighbourhood: 16 + 7 samples.
#[inline(always)]
fn row23(data: &[u8], stride: usize, r: usize) -> &[u8; N16 + 7] {
    let s = &data[r * stride..r * stride + N16 + 7];
    s.try_into().unwrap_or(&[0; N16 + 7])
}

/// The horizontal 8-tap filter of 16 samples, full precision, in 16-bit
/// lanes (twice as many a vector as 32-bit ones): every product and
/// partial sum of 8-bit samples with these taps lies within -4080..=20400.
#[inline(always)]
fn hpass16(r: &[u8; N16 + 7], taps: &[i32; 8]) -> [i16; N16] {
    let mut acc = [0i16; N16];
    for (k, &t) in taps.iter().enumerate() {
        let s = &r[k..k + N16];
        let t = t as i16;
        for (a, &v) in acc.iter_mut().zip(s) {
            *a += t * i16::from(v);
        }
    }
    acc
}

/// `clip((acc + 32) >> 6)` of 16 values.
#[inline(always)]
fn round16<T: Copy + Into<i32>>(acc: &[T; N16], o: &mut [u8]) {
    for (o, &a) in o.iter_mut().zip(acc) {
        *o = ((a.into() + 32) >> 6).clamp(0, 255) as u8;
    }
}

/// A 16x16 luma prediction at phase (fx, fy), not both 0, from `data`
/// starting 3 rows above and 3 columns left of the block. (Functions, not
/// closures: closures do not inherit the caller's target features.)
#[inline(always)]
unsafe fn luma_16x16<const AVX2: bool>(
    data: &[u8],
    stride: usize,
    fx: usize,
    fy: usize,
    out: &mut [u8; 256],
) {
    const N: usize = N16;
    const B: usize = TAPS_BEFORE as usize;
    if fy == 0 {
        for r in 0..N {
            let acc = hpass16(row23(data, stride, r + B), &LUMA_TAPS[fx]);
            round16(&acc, &mut out[r * N..(r + 1) * N]);
        }
        return;
    }
    let mut tmp = [[0i16; N]; N + 7];
    for (r, t) in tmp.iter_mut().enumerate() {
        let src = row23(data, stride, r);
        if fx == 0 {
            // Scaled by 64 (at most 16320: still 16 bits) so that one
            // vertical pass serves both cases; its >> 6 below is then
            // exact, as the direct vertical filter's single rounding needs.
            for (t, &v) in t.iter_mut().zip(&src[B..B + N]) {
                *t = i16::from(v) << 6;
            }
        } else {
            *t = hpass16(src, &LUMA_TAPS[fx]);
        }
    }
    let tv = &LUMA_TAPS[fy];
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: the caller's contract: AVX2 only where the CPU has it.
        unsafe { x86::vpass16_avx2(&tmp, tv, out) };
        return;
    }
    for (r, window) in tmp.windows(8).enumerate() {
        let mut acc = [0i32; N];
        for (&t, row) in tv.iter().zip(window) {
            for (a, &v) in acc.iter_mut().zip(row) {
                *a += t * i32::from(v);
            }
        }
        for a in acc.iter_mut() {
            *a >>= 6;
        }
        round16(&acc, &mut out[r * N..(r + 1) * N]);
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::N16;

    /// The vertical 8-tap pass of a 16x16 prediction from its 23 rows of
    /// 16-bit first-pass values: taps in pairs, each pair one `pmaddwd` of
    /// two interleaved rows (exact 32-bit sums, as the scalar pass), then
    /// `>> 6`, `(v + 32) >> 6` and saturation to 8 bits.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn vpass16_avx2(tmp: &[[i16; N16]; N16 + 7], taps: &[i32; 8], out: &mut [u8; 256]) {
        let pair = |k: usize| _mm256_set1_epi32((taps[k + 1] << 16) | (taps[k] & 0xffff));
        let coef = [pair(0), pair(2), pair(4), pair(6)];
        let rows: [__m256i; N16 + 7] = std::array::from_fn(|r| {
            // SAFETY: a row is 16 i16 = 32 bytes; unaligned load.
            unsafe { _mm256_loadu_si256(tmp[r].as_ptr() as *const __m256i) }
        });
        let round = _mm256_set1_epi32(32);
        for (r, o) in out.chunks_exact_mut(N16).enumerate() {
            let (mut lo, mut hi) = (_mm256_setzero_si256(), _mm256_setzero_si256());
            for (p, c) in coef.iter().enumerate() {
                let (a, b) = (rows[r + 2 * p], rows[r + 2 * p + 1]);
                lo = _mm256_add_epi32(lo, _mm256_madd_epi16(_mm256_unpacklo_epi16(a, b), *c));
                hi = _mm256_add_epi32(hi, _mm256_madd_epi16(_mm256_unpackhi_epi16(a, b), *c));
            }
            let finish =
                |v: __m256i| _mm256_srai_epi32::<6>(_mm256_add_epi32(_mm256_srai_epi32::<6>(v), round));
            // Within each 128-bit lane: lo holds columns 0-3 (8-11), hi 4-7
            // (12-15), so the packs restore column order per lane.
            let words = _mm256_packs_epi32(finish(lo), finish(hi));
            let bytes = _mm256_packus_epi16(words, words);
            let row = _mm256_permute4x64_epi64::<0b00_00_10_00>(bytes);
            // SAFETY: `o` is 16 bytes.
            unsafe { _mm_storeu_si128(o.as_mut_ptr() as *mut __m128i, _mm256_castsi256_si128(row)) };
        }
    }
}

/// `acc[c] = sum_k taps[k] * row(k)[c]` over the 8 taps (zero taps
/// skipped); written tap-outer so that the compiler vectorises it.
#[inline(always)]
fn filter_row<'a>(taps: &[i32; 8], row: impl Fn(usize) -> &'a [u8], acc: &mut [i32]) {
    acc.fill(0);
    for (k, &t) in taps.iter().enumerate() {
        if t != 0 {
            for (a, &v) in acc.iter_mut().zip(row(k)) {
                *a += t * i32::from(v);
            }
        }
    }
}

/// `out = clip((acc + 2^(shift-1)) >> shift)`.
#[inline(always)]
fn round_into(acc: &[i32], shift: u32, out: &mut [u8]) {
    let half = 1 << (shift - 1);
    for (o, &a) in out.iter_mut().zip(acc) {
        *o = ((a + half) >> shift).clamp(0, 255) as u8;
    }
}

/// Chroma prediction of the `w x h` block at chroma position (x, y)
/// displaced by the eighth-pel vector (mvx, mvy) (the luma quarter-pel
/// vector), into `out`.
#[allow(clippy::too_many_arguments)]
pub fn predict_chroma(
    reference: &Plane,
    x: isize,
    y: isize,
    mvx: i32,
    mvy: i32,
    w: usize,
    h: usize,
    out: &mut [u8],
    out_stride: usize,
) {
    check_block(reference, w, h, out, out_stride);
    #[cfg(target_arch = "x86_64")]
    {
        if crate::cpu::at_least(crate::cpu::CpuLevel::Avx2) {
            // SAFETY: the CPU has AVX2; the function is the safe code below
            // compiled with AVX2 (integer arithmetic: the same samples).
            unsafe { predict_chroma_avx2(reference, x, y, mvx, mvy, w, h, out, out_stride) };
            return;
        }
    }
    predict_chroma_body(reference, x, y, mvx, mvy, w, h, out, out_stride);
}

/// [`predict_chroma_body`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
unsafe fn predict_chroma_avx2(
    reference: &Plane,
    x: isize,
    y: isize,
    mvx: i32,
    mvy: i32,
    w: usize,
    h: usize,
    out: &mut [u8],
    out_stride: usize,
) {
    predict_chroma_body(reference, x, y, mvx, mvy, w, h, out, out_stride);
}

/// The chroma predictor, for any instruction set.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn predict_chroma_body(
    reference: &Plane,
    x: isize,
    y: isize,
    mvx: i32,
    mvy: i32,
    w: usize,
    h: usize,
    out: &mut [u8],
    out_stride: usize,
) {
    let (fx, fy) = (mvx & 7, mvy & 7);
    let px = clamp_into_border(
        x + (mvx >> 3) as isize,
        w,
        reference.width(),
        reference.pad(),
        0,
        1,
    );
    let py = clamp_into_border(
        y + (mvy >> 3) as isize,
        h,
        reference.height(),
        reference.pad(),
        0,
        1,
    );
    let data = reference.data();
    let stride = reference.stride();
    // Weights at most 64 and a sum at most 64 * 255: 16 bits suffice.
    let (wa, wb, wc, wd) = (
        ((8 - fx) * (8 - fy)) as u16,
        (fx * (8 - fy)) as u16,
        ((8 - fx) * fy) as u16,
        (fx * fy) as u16,
    );
    if w == 8 {
        // The macroblock case, with a width the compiler knows: one vector
        // of eight 16-bit lanes a row.
        for r in 0..h {
            let src = reference.index(px, py + r as isize);
            let row = |at: usize| -> [u16; 9] {
                let s = &data[at..at + 9];
                std::array::from_fn(|i| u16::from(s[i]))
            };
            let (top, below) = (row(src), row(src + stride));
            let o = &mut out[r * out_stride..r * out_stride + 8];
            for c in 0..8 {
                let s = wa * top[c] + wb * top[c + 1] + wc * below[c] + wd * below[c + 1];
                o[c] = ((s + 32) >> 6) as u8;
            }
        }
        return;
    }
    for r in 0..h {
        let src = reference.index(px, py + r as isize);
        let (top, below) = (&data[src..src + w + 1], &data[src + stride..src + stride + w + 1]);
        let o = &mut out[r * out_stride..r * out_stride + w];
        for (c, o) in o.iter_mut().enumerate() {
            let s = wa * u16::from(top[c])
                + wb * u16::from(top[c + 1])
                + wc * u16::from(below[c])
                + wd * u16::from(below[c + 1]);
            *o = ((s + 32) >> 6) as u8;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::picture::PictureError;
    use proptest::prelude::*;

    /// The luma equations written directly: every sample read through
    /// `pixel_clamped` (an infinitely extended picture), no border, no
    /// separable pass.
    fn reference_luma(p: &Plane, x: isize, y: isize, mvx: i32, mvy: i32, w: usize, h: usize) -> Vec<u8> {
        let (ix, iy) = (x + (mvx >> 2) as isize, y + (mvy >> 2) as isize);
        let (fx, fy) = ((mvx & 3) as usize, (mvy & 3) as usize);
        let mut out = Vec::with_capacity(w * h);
        for r in 0..h as isize {
            for c in 0..w as isize {
                let sample = |dx: isize, dy: isize| i64::from(p.pixel_clamped(ix + c + dx, iy + r + dy));
                let v = if fx == 0 && fy == 0 {
                    sample(0, 0)
                } else if fy == 0 {
                    ((0..8)
                        .map(|k| i64::from(LUMA_TAPS[fx][k]) * sample(k as isize - 3, 0))
                        .sum::<i64>()
                        + 32)
                        >> 6
                } else if fx == 0 {
                    ((0..8)
                        .map(|k| i64::from(LUMA_TAPS[fy][k]) * sample(0, k as isize - 3))
                        .sum::<i64>()
                        + 32)
                        >> 6
                } else {
                    let hpass = |dy: isize| {
                        (0..8)
                            .map(|k| i64::from(LUMA_TAPS[fx][k]) * sample(k as isize - 3, dy))
                            .sum::<i64>()
                    };
                    let v = (0..8)
                        .map(|k| i64::from(LUMA_TAPS[fy][k]) * hpass(k as isize - 3))
                        .sum::<i64>()
                        >> 6;
                    (v + 32) >> 6
                };
                out.push(v.clamp(0, 255) as u8);
            }
        }
        out
    }

    fn reference_chroma(p: &Plane, x: isize, y: isize, mvx: i32, mvy: i32, w: usize, h: usize) -> Vec<u8> {
        let (ix, iy) = (x + (mvx >> 3) as isize, y + (mvy >> 3) as isize);
        let (fx, fy) = (i64::from(mvx & 7), i64::from(mvy & 7));
        let mut out = Vec::with_capacity(w * h);
        for r in 0..h as isize {
            for c in 0..w as isize {
                let s = |dx, dy| i64::from(p.pixel_clamped(ix + c + dx, iy + r + dy));
                let v = (8 - fx) * (8 - fy) * s(0, 0)
                    + fx * (8 - fy) * s(1, 0)
                    + (8 - fx) * fy * s(0, 1)
                    + fx * fy * s(1, 1);
                out.push(((v + 32) >> 6) as u8);
            }
        }
        out
    }

    fn noise_plane(w: usize, h: usize, seed: u32) -> Result<Plane, PictureError> {
        Plane::from_fn(w, h, |x, y| {
            let v = (x as u32).wrapping_mul(2_654_435_761) ^ (y as u32).wrapping_mul(40_503) ^ seed;
            (v.wrapping_mul(2_246_822_519) >> 24) as u8
        })
    }

    #[test]
    fn taps_sum_to_64_and_half_pel_is_symmetric() -> Result<(), PictureError> {
        for t in LUMA_TAPS {
            assert_eq!(t.iter().sum::<i32>(), 64);
        }
        let half = LUMA_TAPS[2];
        assert_eq!(
            half,
            [half[7], half[6], half[5], half[4], half[3], half[2], half[1], half[0]]
        );
        // The quarter and three-quarter filters mirror each other.
        let (q, tq) = (LUMA_TAPS[1], LUMA_TAPS[3]);
        for k in 0..8 {
            assert_eq!(q[k], tq[7 - k]);
        }
        Ok(())
    }

    #[test]
    fn the_dispatched_predictors_equal_their_scalar_twins() -> Result<(), PictureError> {
        // On an AVX2 machine the predictors run their AVX2 builds; the bodies
        // called directly here is the baseline build.
        let p = noise_plane(70, 50, 11)?;
        let (mut a, mut b) = (vec![0u8; 64 * 64], vec![0u8; 64 * 64]);
        for mvy in -9..=9 {
            for mvx in -9..=9 {
                for (x, y, w, h) in [(3, 5, 16, 16), (40, 20, 16, 16), (1, 2, 12, 3), (0, 0, 64, 40)] {
                    predict_luma(&p, x, y, mvx, mvy, w, h, &mut a, w);
                    // SAFETY: no AVX2.
                    unsafe { predict_luma_body::<false>(&p, x, y, mvx, mvy, w, h, &mut b, w) };
                    assert_eq!(a[..w * h], b[..w * h], "mv ({mvx},{mvy}) {w}x{h}");
                    predict_chroma(&p, x, y, mvx, mvy, w, h, &mut a, w);
                    predict_chroma_body(&p, x, y, mvx, mvy, w, h, &mut b, w);
                    assert_eq!(a[..w * h], b[..w * h], "chroma mv ({mvx},{mvy}) {w}x{h}");
                }
            }
        }
        Ok(())
    }

    #[test]
    fn every_phase_matches_the_direct_formula() -> Result<(), PictureError> {
        let p = noise_plane(37, 29, 7)?;
        let mut out = vec![0u8; 16 * 16];
        for mvy in -9..=9 {
            for mvx in -9..=9 {
                for (x, y, w, h) in [(0, 0, 16, 16), (21, 13, 16, 16), (5, 7, 4, 8), (33, 25, 8, 4)] {
                    predict_luma(&p, x, y, mvx, mvy, w, h, &mut out, w);
                    assert_eq!(
                        out[..w * h],
                        reference_luma(&p, x, y, mvx, mvy, w, h)[..],
                        "luma mv ({mvx},{mvy}) at ({x},{y})"
                    );
                }
            }
        }
        let c = noise_plane(19, 15, 3)?;
        for mvy in -17..=17 {
            for mvx in -17..=17 {
                for (x, y, w, h) in [(0, 0, 8, 8), (11, 7, 8, 8), (16, 12, 4, 4)] {
                    predict_chroma(&c, x, y, mvx, mvy, w, h, &mut out, w);
                    assert_eq!(
                        out[..w * h],
                        reference_chroma(&c, x, y, mvx, mvy, w, h)[..],
                        "chroma mv ({mvx},{mvy})"
                    );
                }
            }
        }
        Ok(())
    }

    #[test]
    fn integer_vectors_copy_and_flat_pictures_stay_flat() -> Result<(), PictureError> {
        let p = noise_plane(40, 40, 1)?;
        let mut out = [0u8; 64];
        predict_luma(&p, 8, 8, 4 * 3, 4 * -2, 8, 8, &mut out, 8);
        for r in 0..8 {
            for c in 0..8 {
                assert_eq!(out[r * 8 + c], p.get(11 + c, 6 + r));
            }
        }
        let flat = Plane::filled(20, 20, 173)?;
        for phase in 0..16 {
            predict_luma(&flat, 2, 2, phase % 4 + 4, phase / 4 - 8, 8, 8, &mut out, 8);
            assert!(out.iter().all(|&v| v == 173));
            predict_chroma(&flat, 2, 2, phase % 8, phase / 2 - 3, 8, 8, &mut out, 8);
            assert!(out.iter().all(|&v| v == 173));
        }
        Ok(())
    }

    proptest! {
        #[test]
        fn any_vector_reads_the_extended_picture(
            mvx in -40_000i32..40_000, mvy in -40_000i32..40_000,
            x in -20isize..60, y in -20isize..60, size in prop_oneof![Just(4usize), Just(8), Just(16), Just(32)]
        ) {
            let p = noise_plane(45, 38, 11)?;
            let mut out = vec![0u8; size * size];
            predict_luma(&p, x, y, mvx, mvy, size, size, &mut out, size);
            prop_assert_eq!(&out, &reference_luma(&p, x, y, mvx, mvy, size, size));
            let c = noise_plane(23, 19, 5)?;
            let cs = (size / 2).max(2);
            let mut out = vec![0u8; cs * cs];
            predict_chroma(&c, x / 2, y / 2, mvx, mvy, cs, cs, &mut out, cs);
            prop_assert_eq!(&out, &reference_chroma(&c, x / 2, y / 2, mvx, mvy, cs, cs));
        }
    }
}
