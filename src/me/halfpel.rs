//! Half-pel planes of a reference, for sub-pel search (x264's approach).
//!
//! The three half-pel phases (horizontal, vertical, both) are computed once
//! per reference with the codec's own filter, so every half-pel candidate
//! costs a copy; a quarter-pel candidate is the rounded average of its two
//! nearest full- or half-pel samples, as H.264 interpolates. That average
//! only approximates the codec's 8-tap quarter-pel filter: the search uses
//! it to rank candidates, and what the encoder then predicts with is the
//! codec's exact interpolation.

use std::cell::RefCell;

use crate::codec::Plane;

thread_local! {
    /// Planes of earlier references, reused: a search per frame would
    /// otherwise fault in three fresh planes every time.
    static SPARE: RefCell<Vec<Plane>> = const { RefCell::new(Vec::new()) };
    /// The horizontal pass the planes are filled from, reused likewise.
    static HPASS: RefCell<Vec<i16>> = const { RefCell::new(Vec::new()) };
}

/// A plane of this size and border from the spares, or a new one.
fn take_plane(w: usize, h: usize, pad: usize) -> Option<Plane> {
    let reused = SPARE.with(|s| {
        let mut s = s.borrow_mut();
        let i = s
            .iter()
            .position(|p| (p.width(), p.height(), p.pad()) == (w, h, pad))?;
        Some(s.swap_remove(i))
    });
    reused.or_else(|| Plane::with_padding(w, h, pad).ok())
}

/// How far beyond a sample the 8-tap filter reads (3 before, 4 after).
const FILTER_REACH: usize = 4;

/// The reference's half-pel phases over the picture and a margin around it.
pub(crate) struct HalfPel {
    /// Horizontal, vertical and diagonal half-pel samples: entry (x, y) is
    /// the sample at (x + 1/2, y), (x, y + 1/2), (x + 1/2, y + 1/2).
    /// (Only the picture and margin are written; nothing reads beyond.)
    planes: Vec<Plane>,
    /// How far outside the picture the planes are filled.
    margin: isize,
}

impl HalfPel {
    /// The half-pel planes of `reference`, filled `margin` pixels beyond
    /// each edge; `margin + 4` must not exceed the reference's border.
    pub fn new(reference: &Plane, margin: usize) -> Option<HalfPel> {
        let (w, h, pad) = (reference.width(), reference.height(), reference.pad());
        if margin + FILTER_REACH > pad {
            return None;
        }
        let mut planes = Vec::with_capacity(3);
        for _ in 0..3 {
            planes.push(take_plane(w, h, pad)?);
        }
        fill_planes(reference, margin, &mut planes);
        let m = margin as isize;
        Some(HalfPel { planes, margin: m })
    }

    /// How far beyond the picture the planes are filled.
    pub fn margin(&self) -> usize {
        self.margin as usize
    }

    /// The `b x b` block at (x, y) displaced by the quarter-pel vector
    /// (mvx, mvy), into `out`; `false` (nothing written) when it reaches
    /// beyond the filled margin.
    #[allow(clippy::too_many_arguments)]
    pub fn predict<'a>(
        &'a self,
        reference: &'a Plane,
        x: isize,
        y: isize,
        mvx: i32,
        mvy: i32,
        b: usize,
        out: &mut [u8],
    ) -> bool {
        let (bx, by) = (x + (mvx >> 2) as isize, y + (mvy >> 2) as isize);
        let (w, h) = (reference.width() as isize, reference.height() as isize);
        // Samples read: one beyond the block on each side at most.
        if bx - 1 < -self.margin
            || by - 1 < -self.margin
            || bx + b as isize + 1 > w + self.margin
            || by + b as isize + 1 > h + self.margin
        {
            return false;
        }
        let (fx, fy) = (mvx & 3, mvy & 3);
        // A point of the half-pel grid, in quarter-pels from (bx, by):
        // its plane and integer offset.
        let point = |px: i32, py: i32| -> (&'a Plane, isize, isize) {
            let plane = match (px & 3, py & 3) {
                (0, 0) => reference,
                (2, 0) => &self.planes[0],
                (0, 2) => &self.planes[1],
                _ => &self.planes[2],
            };
            (plane, bx + (px >> 2) as isize, by + (py >> 2) as isize)
        };
        let rows = |(p, px, py): (&'a Plane, isize, isize)| (&p.data()[p.index(px, py)..], p.stride());
        // 16 and 8 passed as constants, so that the rows have lengths the
        // compiler knows (on x86-64 the 16-wide case is SSE2 outright).
        let copy = |(a, sa): (&[u8], usize), out: &mut [u8]| match b {
            #[cfg(target_arch = "x86_64")]
            16 => x86::copy_16x16(a, sa, out),
            #[cfg(not(target_arch = "x86_64"))]
            16 => copy_rows(16, a, sa, out),
            8 => copy_rows(8, a, sa, out),
            _ => copy_rows(b, a, sa, out),
        };
        let average = |from, to, out: &mut [u8]| match b {
            #[cfg(target_arch = "x86_64")]
            16 => x86::average_16x16(rows(from), rows(to), out),
            #[cfg(not(target_arch = "x86_64"))]
            16 => average_rows(16, rows(from), rows(to), out),
            #[cfg(target_arch = "x86_64")]
            8 => x86::average_8x8(rows(from), rows(to), out),
            #[cfg(not(target_arch = "x86_64"))]
            8 => average_rows(8, rows(from), rows(to), out),
            _ => average_rows(b, rows(from), rows(to), out),
        };
        match (fx & 1, fy & 1) {
            (0, 0) => copy(rows(point(fx, fy)), out),
            (1, 0) => average(point(fx - 1, fy), point(fx + 1, fy), out),
            (0, 1) => average(point(fx, fy - 1), point(fx, fy + 1), out),
            _ => average(point(2, 4 * (fy / 2)), point(4 * (fx / 2), 2), out),
        }
        true
    }
}

/// `out` (rows of `n`) = the rounded average of `n x n` blocks `a` and `c`
/// (each a slice from its first sample and a stride).
#[inline(always)]
fn average_rows(n: usize, (a, sa): (&[u8], usize), (c, sc): (&[u8], usize), out: &mut [u8]) {
    for (r, o) in out.chunks_exact_mut(n).take(n).enumerate() {
        for ((o, &u), &v) in o
            .iter_mut()
            .zip(&a[r * sa..r * sa + n])
            .zip(&c[r * sc..r * sc + n])
        {
            *o = ((u16::from(u) + u16::from(v) + 1) >> 1) as u8;
        }
    }
}

/// `out` (rows of `n`) = the `n x n` block `a` (stride `sa`).
#[inline(always)]
fn copy_rows(n: usize, a: &[u8], sa: usize, out: &mut [u8]) {
    for (r, o) in out.chunks_exact_mut(n).take(n).enumerate() {
        o.copy_from_slice(&a[r * sa..r * sa + n]);
    }
}

/// The half-pel filter: the codec's 8-tap luma filter at phase 1/2, in
/// 16 bits for the kernels.
const HALF: [i16; 8] = {
    let taps = crate::codec::interp::LUMA_TAPS[2];
    let mut half = [0i16; 8];
    let mut k = 0;
    while k < 8 {
        half[k] = taps[k] as i16;
        k += 1;
    }
    half
};

/// Writes the three half-pel phases of `reference` over the picture and
/// `margin` pixels around it, row by row (the codec's arithmetic: the
/// diagonal phase filters the unrounded horizontal pass vertically).
fn fill_planes(reference: &Plane, margin: usize, planes: &mut [Plane]) {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::codec::cpu::at_least(crate::codec::cpu::CpuLevel::Avx2) {
            // SAFETY: the CPU has AVX2; the function is the safe code below
            // compiled with AVX2 (integer arithmetic: the same samples).
            unsafe { fill_planes_avx2(reference, margin, planes) };
            return;
        }
    }
    // SAFETY: no AVX2.
    unsafe { fill_planes_body::<false>(reference, margin, planes) };
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fill_planes_avx2(reference: &Plane, margin: usize, planes: &mut [Plane]) {
    fill_planes_body::<true>(reference, margin, planes);
}

/// The planes, for any instruction set; `AVX2` takes the diagonal phase's
/// vertical pass to AVX2 intrinsics.
///
/// # Safety
/// `AVX2` is true only where the CPU has AVX2.
#[inline(always)]
unsafe fn fill_planes_body<const AVX2: bool>(reference: &Plane, margin: usize, planes: &mut [Plane]) {
    let (w, h, m) = (reference.width(), reference.height(), margin as isize);
    let span = w + 2 * margin;
    let clip = |v: i32| v.clamp(0, 255) as u8;
    // Unrounded horizontal pass (within i16: -6120..=22440) of the rows
    // the vertical filters read: -m - 3 .. h + m + 4.
    let rows = h + 2 * margin + 7;
    let mut hpass = HPASS.with(|b| std::mem::take(&mut *b.borrow_mut()));
    // Every entry is assigned by the first tap below: no need to clear
    // what a previous picture left.
    hpass.resize(rows * span, 0);
    for (r, out) in hpass[..rows * span].chunks_exact_mut(span).enumerate() {
        let src = &reference.data()[reference.index(-m - 3, r as isize - m - 3)..];
        for (o, &v) in out.iter_mut().zip(&src[..span]) {
            *o = HALF[0] * i16::from(v);
        }
        for (k, &t) in HALF.iter().enumerate().skip(1) {
            for (o, &v) in out.iter_mut().zip(&src[k..k + span]) {
                *o += t * i16::from(v);
            }
        }
    }
    let hrow = |y: usize| &hpass[y * span..(y + 1) * span];
    let mut acc16 = vec![0i16; span];
    let mut acc32 = vec![0i32; span];
    for y in 0..h + 2 * margin {
        let at = planes[0].index(-m, y as isize - m);
        for (o, &v) in planes[0].data_mut()[at..at + span].iter_mut().zip(hrow(y + 3)) {
            *o = clip((i32::from(v) + 32) >> 6);
        }
        acc16.fill(0);
        for (k, &t) in HALF.iter().enumerate() {
            let at = reference.index(-m, y as isize - m - 3 + k as isize);
            for (a, &v) in acc16.iter_mut().zip(&reference.data()[at..at + span]) {
                *a += t * i16::from(v);
            }
        }
        let at = planes[1].index(-m, y as isize - m);
        for (o, &v) in planes[1].data_mut()[at..at + span].iter_mut().zip(&acc16) {
            *o = clip((i32::from(v) + 32) >> 6);
        }
        let at = planes[2].index(-m, y as isize - m);
        let out = &mut planes[2].data_mut()[at..at + span];
        let rows: [&[i16]; 8] = std::array::from_fn(|k| hrow(y + k));
        #[cfg(target_arch = "x86_64")]
        if AVX2 {
            // SAFETY: the caller's contract: AVX2 only where the CPU has it.
            unsafe { x86::diagonal_row_avx2(&rows, out) };
            continue;
        }
        acc32.fill(0);
        for (&t, row) in HALF.iter().zip(rows) {
            for (a, &v) in acc32.iter_mut().zip(row) {
                *a += i32::from(t) * i32::from(v);
            }
        }
        for (o, &v) in out.iter_mut().zip(&acc32) {
            *o = clip(((v >> 6) + 32) >> 6);
        }
    }
    HPASS.with(|b| *b.borrow_mut() = hpass);
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::HALF;

    /// Panics unless a `16 x 16` block at stride `stride` fits in `len`.
    fn check_16x16(len: usize, stride: usize) {
        assert!(
            stride >= 16 && len >= 15 * stride + 16,
            "16x16 block past its slice"
        );
    }

    /// [`super::copy_rows`] at 16 in SSE2 moves (bounds checked once).
    pub(super) fn copy_16x16(a: &[u8], sa: usize, out: &mut [u8]) {
        check_16x16(a.len(), sa);
        check_16x16(out.len(), 16);
        for r in 0..16 {
            // SAFETY: rows 0..16 of both blocks lie inside their slices
            // (checked above); SSE2 is part of x86-64.
            unsafe {
                let v = _mm_loadu_si128(a.as_ptr().add(r * sa) as *const __m128i);
                _mm_storeu_si128(out.as_mut_ptr().add(r * 16) as *mut __m128i, v);
            }
        }
    }

    /// [`super::average_rows`] at 16: `pavgb` is exactly
    /// `(u + v + 1) >> 1` (bounds checked once).
    pub(super) fn average_16x16((a, sa): (&[u8], usize), (c, sc): (&[u8], usize), out: &mut [u8]) {
        check_16x16(a.len(), sa);
        check_16x16(c.len(), sc);
        check_16x16(out.len(), 16);
        for r in 0..16 {
            // SAFETY: as in copy_16x16.
            unsafe {
                let x = _mm_loadu_si128(a.as_ptr().add(r * sa) as *const __m128i);
                let y = _mm_loadu_si128(c.as_ptr().add(r * sc) as *const __m128i);
                _mm_storeu_si128(out.as_mut_ptr().add(r * 16) as *mut __m128i, _mm_avg_epu8(x, y));
            }
        }
    }

    /// [`super::average_rows`] at 8 (the partitions' blocks), as
    /// [`average_16x16`] with 8-byte loads.
    pub(super) fn average_8x8((a, sa): (&[u8], usize), (c, sc): (&[u8], usize), out: &mut [u8]) {
        let fits = |len: usize, stride: usize| stride >= 8 && len >= 7 * stride + 8;
        assert!(
            fits(a.len(), sa) && fits(c.len(), sc) && fits(out.len(), 8),
            "8x8 block past its slice"
        );
        for r in 0..8 {
            // SAFETY: rows 0..8 of the three blocks lie inside their
            // slices (checked above); SSE2 is part of x86-64.
            unsafe {
                let x = _mm_loadl_epi64(a.as_ptr().add(r * sa) as *const __m128i);
                let y = _mm_loadl_epi64(c.as_ptr().add(r * sc) as *const __m128i);
                _mm_storel_epi64(out.as_mut_ptr().add(r * 8) as *mut __m128i, _mm_avg_epu8(x, y));
            }
        }
    }

    /// One row of the diagonal phase: the half-pel filter down the eight
    /// rows of the unrounded horizontal pass, taps in pairs, each pair one
    /// `pmaddwd` of two interleaved rows (exact 32-bit sums, as the scalar
    /// pass), then `((v >> 6) + 32) >> 6` saturated to 8 bits; the columns
    /// past the last multiple of 16 in scalar code.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn diagonal_row_avx2(rows: &[&[i16]; 8], out: &mut [u8]) {
        let n = out.len();
        let pair =
            |k: usize| _mm256_set1_epi32((i32::from(HALF[k + 1]) << 16) | (i32::from(HALF[k]) & 0xffff));
        let coef = [pair(0), pair(2), pair(4), pair(6)];
        let round = _mm256_set1_epi32(32);
        let finish = |v: __m256i| _mm256_srai_epi32::<6>(_mm256_add_epi32(_mm256_srai_epi32::<6>(v), round));
        let mut x = 0;
        while x + 16 <= n {
            let (mut lo, mut hi) = (_mm256_setzero_si256(), _mm256_setzero_si256());
            for (p, c) in coef.iter().enumerate() {
                let (ra, rb) = (&rows[2 * p][x..x + 16], &rows[2 * p + 1][x..x + 16]);
                // SAFETY: both slices are 16 i16 = 32 bytes.
                let (a, b) = unsafe {
                    (
                        _mm256_loadu_si256(ra.as_ptr() as *const __m256i),
                        _mm256_loadu_si256(rb.as_ptr() as *const __m256i),
                    )
                };
                lo = _mm256_add_epi32(lo, _mm256_madd_epi16(_mm256_unpacklo_epi16(a, b), *c));
                hi = _mm256_add_epi32(hi, _mm256_madd_epi16(_mm256_unpackhi_epi16(a, b), *c));
            }
            // Per 128-bit lane lo holds columns 0-3 and hi 4-7 (then 8-11,
            // 12-15): the packs restore column order within each lane.
            let words = _mm256_packs_epi32(finish(lo), finish(hi));
            let bytes = _mm256_permute4x64_epi64::<0b00_00_10_00>(_mm256_packus_epi16(words, words));
            let o = &mut out[x..x + 16];
            // SAFETY: `o` is 16 bytes.
            unsafe { _mm_storeu_si128(o.as_mut_ptr() as *mut __m128i, _mm256_castsi256_si128(bytes)) };
            x += 16;
        }
        for (c, o) in out.iter_mut().enumerate().skip(x) {
            let v: i32 = HALF
                .iter()
                .zip(rows)
                .map(|(&t, r)| i32::from(t) * i32::from(r[c]))
                .sum();
            *o = (((v >> 6) + 32) >> 6).clamp(0, 255) as u8;
        }
    }
}

impl Drop for HalfPel {
    fn drop(&mut self) {
        SPARE.with(|s| {
            let mut s = s.borrow_mut();
            s.append(&mut self.planes);
            // Enough for two sizes in turn; older ones go.
            let excess = s.len().saturating_sub(6);
            s.drain(..excess);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::interp::predict_luma;

    fn textured(w: usize, h: usize) -> Plane {
        Plane::from_fn(w, h, |x, y| {
            let (x, y) = (x as f64, y as f64);
            (128.0 + 60.0 * (x * 0.31).sin() * (y * 0.23).cos() + 30.0 * ((x + 2.0 * y) * 0.11).sin()) as u8
        })
        .unwrap()
    }

    #[test]
    fn half_pel_phases_equal_the_codec_and_quarter_pel_is_close() {
        let r = textured(64, 48);
        let hp = HalfPel::new(&r, 32).unwrap();
        let (mut a, mut b) = ([0u8; 256], [0u8; 256]);
        for mvy in -9..=9 {
            for mvx in -9..=9 {
                for (x, y) in [(0, 0), (16, 16), (48, 32)] {
                    assert!(hp.predict(&r, x, y, mvx, mvy, 16, &mut a));
                    predict_luma(&r, x, y, mvx, mvy, 16, 16, &mut b, 16);
                    if mvx % 2 == 0 && mvy % 2 == 0 {
                        assert_eq!(a, b, "half-pel ({mvx}, {mvy}) at ({x}, {y})");
                    } else {
                        // The average of neighbours against the 8-tap
                        // filter: close on a smooth texture.
                        let worst = a.iter().zip(&b).map(|(&u, &v)| u.abs_diff(v)).max().unwrap();
                        assert!(worst <= 3, "quarter-pel ({mvx}, {mvy}): {worst}");
                    }
                }
            }
        }
        // Every sample of the three planes, on a picture of odd size.
        let r = textured(37, 21);
        let hp = HalfPel::new(&r, 16).unwrap();
        let mut one = [0u8; 1];
        for (p, (mvx, mvy)) in [(2, 0), (0, 2), (2, 2)].into_iter().enumerate() {
            for y in -16..21 + 16 {
                for x in -16..37 + 16 {
                    predict_luma(&r, x, y, mvx, mvy, 1, 1, &mut one, 1);
                    assert_eq!(hp.planes[p].at(x, y), one[0], "phase {p} at ({x}, {y})");
                }
            }
        }
        let r = textured(64, 48);
        let hp = HalfPel::new(&r, 32).unwrap();
        // Beyond the margin: refused, so that the caller uses the codec.
        assert!(!hp.predict(&r, 0, 0, -4 * 40, 0, 16, &mut a));
    }

    #[test]
    fn the_sse2_copy_and_average_equal_their_scalar_twins() {
        let a: Vec<u8> = (0..40 * 20).map(|i| ((i * 37) % 256) as u8).collect();
        let c: Vec<u8> = (0..33 * 17).map(|i| ((i * 91 + 7) % 256) as u8).collect();
        let (mut x, mut y) = ([0u8; 256], [0u8; 256]);
        #[cfg(target_arch = "x86_64")]
        {
            x86::copy_16x16(&a[3..], 40, &mut x);
            copy_rows(16, &a[3..], 40, &mut y);
            assert_eq!(x, y);
            x86::average_16x16((&a[5..], 40), (&c, 33), &mut x);
            average_rows(16, (&a[5..], 40), (&c, 33), &mut y);
            assert_eq!(x, y);
            x86::average_8x8((&a[7..], 40), (&c[2..], 33), &mut x[..64]);
            average_rows(8, (&a[7..], 40), (&c[2..], 33), &mut y[..64]);
            assert_eq!(x[..64], y[..64]);
        }
        // The scalar rounding itself: (u + v + 1) >> 1.
        average_rows(16, (&[255u8; 256], 16), (&[0u8; 256], 16), &mut y);
        assert!(y.iter().all(|&v| v == 128));
    }

    #[test]
    fn the_dispatched_fill_equals_its_baseline_twin() {
        // Widths with and without a remainder past the 16-column steps.
        for (w, h, margin) in [(37, 21, 16), (64, 16, 32), (5, 9, 0)] {
            let r = Plane::from_fn(w, h, |x, y| {
                if (x * y) % 7 == 0 {
                    255
                } else {
                    ((x * 31 + y * 17) % 256) as u8
                }
            })
            .unwrap();
            let planes = || (0..3).map(|_| Plane::new(w, h).unwrap()).collect::<Vec<_>>();
            let (mut a, mut b) = (planes(), planes());
            fill_planes(&r, margin, &mut a);
            // SAFETY: no AVX2.
            unsafe { fill_planes_body::<false>(&r, margin, &mut b) };
            for (p, q) in a.iter().zip(&b) {
                assert!(p.data() == q.data(), "{w}x{h} margin {margin}");
            }
        }
    }
}
