//! SIMD cost kernels behind one dispatch point, each with the scalar twin in
//! [`super::cost`] that tests hold it equal to.
//!
//! On x86-64 the SAD kernels use `psadbw`: SSE2 (always present) for rows of
//! 8 and 16 samples, AVX2 (detected at run time) for rows of 16 two at a
//! time and rows of 32. Other widths, and other architectures, use the
//! scalar kernel. The choice is made once, by [`kernels`].
//!
//! Measured, for 16x16: one call at a time (`cargo bench --bench me --
//! cost_16x16`, latency) SSE2 is a little faster (25 against 22 Gelem/s),
//! but in the search, where calls overlap, the AVX2 kernel wins (`mocomp me
//! --method esa --range 16 --threads 1` on pan_cif: 7.4-8.0 against
//! 8.2-9.3 ms per pass, 5 runs each, alternated), so AVX2 keeps it. For
//! 32x32 AVX2 is 1.8 times SSE2 in both.

use crate::codec::cpu::{self, CpuLevel};

use super::cost;

/// Signature of a block cost kernel: `(a, a_stride, b, b_stride, w, h)`.
pub type CostFn = fn(&[u8], usize, &[u8], usize, usize, usize) -> u32;

/// Signature of the paired 4x4 SATD: two 4x4 tiles side by side in 8x4
/// blocks (rows of 8 bytes), each tile's SATD (halved, rounded up, as
/// [`cost::satd`] of that tile alone).
pub type PairFn = fn(&[u8; 32], &[u8; 32]) -> [u32; 2];

/// Signature of the capped 16x16 SATD: `(a, a_stride, b, b_stride, cap)`,
/// the SATD of the two 16x16 blocks or, when the SATD of their top 16x8
/// halves already exceeds `cap`, that one: a search's positions that
/// cannot beat its best stop half way (SATD only grows with rows).
pub type CappedFn = fn(&[u8], usize, &[u8], usize, u32) -> u32;

/// The scalar capped 16x16 SATD.
pub fn satd_16x16_capped(a: &[u8], sa: usize, b: &[u8], sb: usize, cap: u32) -> u32 {
    capped_by_halves(cost::satd, a, sa, b, sb, cap)
}

/// [`CappedFn`] from a SATD kernel, one 16x8 half at a time (halves add up
/// exactly: every 4x4 tile's coefficient sum is even).
#[inline]
fn capped_by_halves(satd: CostFn, a: &[u8], sa: usize, b: &[u8], sb: usize, cap: u32) -> u32 {
    let top = satd(a, sa, b, sb, 16, 8);
    if top > cap {
        return top;
    }
    top + satd(&a[8 * sa..], sa, &b[8 * sb..], sb, 16, 8)
}

/// The scalar paired 4x4 SATD.
pub fn satd_4x4_pair(a: &[u8; 32], b: &[u8; 32]) -> [u32; 2] {
    [0, 4].map(|o| cost::satd(&a[o..], 8, &b[o..], 8, 4, 4))
}

/// The kernels selected for this machine.
#[derive(Clone, Copy)]
pub struct Kernels {
    /// Sum of absolute differences.
    pub sad: CostFn,
    /// Sum of absolute 4x4 Hadamard coefficients, halved.
    pub satd: CostFn,
    /// SATD of two 4x4 tiles at once (4x4 intra mode search).
    pub satd_4x4_pair: PairFn,
    /// 16x16 SATD that may stop half way above a cap (block search).
    pub satd_16x16_capped: CappedFn,
    /// Name of the instruction set in use, for reports.
    pub isa: &'static str,
}

impl std::fmt::Debug for Kernels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Kernels").field("isa", &self.isa).finish()
    }
}

/// The scalar kernels (the reference every other set must equal).
pub const SCALAR: Kernels = Kernels {
    sad: cost::sad,
    satd: cost::satd,
    satd_4x4_pair,
    satd_16x16_capped,
    isa: "scalar",
};

/// The kernel set of a CPU level.
pub fn kernels_for(level: CpuLevel) -> &'static Kernels {
    match level {
        CpuLevel::Scalar => &SCALAR,
        #[cfg(target_arch = "x86_64")]
        CpuLevel::Sse2 => &x86::SSE2,
        #[cfg(target_arch = "x86_64")]
        CpuLevel::Avx2 => &x86::AVX2,
        #[cfg(not(target_arch = "x86_64"))]
        _ => &SCALAR,
    }
}

/// The kernels of the CPU level in force ([`crate::codec::cpu`]).
pub fn kernels() -> &'static Kernels {
    kernels_for(cpu::level())
}

/// Every kernel set this CPU can run, scalar first (for tests and benches).
pub fn available() -> Vec<Kernels> {
    cpu::available().into_iter().map(|l| *kernels_for(l)).collect()
}

/// Panics unless both blocks lie inside their slices: the SIMD kernels read
/// through raw pointers and rely on this.
#[inline]
fn check_bounds(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) {
    assert!(
        h == 0 || ((h - 1) * sa + w <= a.len() && (h - 1) * sb + w <= b.len()),
        "block {w}x{h} outside its slice"
    );
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::{capped_by_halves, check_bounds, cost, Kernels};

    pub const SSE2: Kernels = Kernels {
        sad: sad_sse2,
        satd: satd_sse2,
        satd_4x4_pair: satd_4x4_pair_sse2,
        satd_16x16_capped: satd_16x16_capped_sse2,
        isa: "sse2",
    };
    pub const AVX2: Kernels = Kernels {
        sad: sad_avx2,
        satd: satd_avx2,
        satd_4x4_pair: satd_4x4_pair_sse2,
        satd_16x16_capped: satd_16x16_capped_avx2,
        isa: "avx2",
    };

    fn satd_avx2(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) -> u32 {
        check_bounds(a, sa, b, sb, w, h);
        if w % 16 != 0 || h % 4 != 0 {
            return satd_sse2(a, sa, b, sb, w, h);
        }
        // SAFETY (both calls): AVX2 was detected before this set was
        // chosen; every 16x4 region lies inside the checked block.
        if w == 16 && h == 16 {
            // The macroblock: its four strips in one call, one reduction.
            return unsafe { satd_16x16_avx2(a.as_ptr(), sa, b.as_ptr(), sb, u32::MAX) };
        }
        let mut acc = [0u32; 8];
        {
            for ty in (0..h).step_by(4) {
                for tx in (0..w).step_by(16) {
                    unsafe {
                        hadamard_abs_16x4_avx2(
                            a.as_ptr().add(ty * sa + tx),
                            sa,
                            b.as_ptr().add(ty * sb + tx),
                            sb,
                            &mut acc,
                        )
                    };
                }
            }
        }
        acc.iter().sum::<u32>().div_ceil(2)
    }

    fn satd_16x16_capped_sse2(a: &[u8], sa: usize, b: &[u8], sb: usize, cap: u32) -> u32 {
        capped_by_halves(satd_sse2, a, sa, b, sb, cap)
    }

    fn satd_16x16_capped_avx2(a: &[u8], sa: usize, b: &[u8], sb: usize, cap: u32) -> u32 {
        check_bounds(a, sa, b, sb, 16, 16);
        // SAFETY: AVX2 was detected before this set was chosen; the blocks
        // lie inside the checked slices.
        unsafe { satd_16x16_avx2(a.as_ptr(), sa, b.as_ptr(), sb, cap) }
    }

    /// The SATD of a 16x16 block: [`hadamard_abs_16x4_avx2`] over its four
    /// strips with x264's shortcut for the last butterfly, |p + q| +
    /// |p - q| = 2 max(|p|, |q|), so that the halved sum is the sum of the
    /// maxima (at most 8 * 255 each, eight a lane: they add up in 16 bits).
    /// Stops after the top half when its SATD exceeds `cap` ([`CappedFn`]).
    #[target_feature(enable = "avx2")]
    unsafe fn satd_16x16_avx2(a: *const u8, sa: usize, b: *const u8, sb: usize, cap: u32) -> u32 {
        let mut sum16 = _mm256_setzero_si256();
        for ty in (0..16).step_by(4) {
            if ty == 8 {
                let top = sum_u16_lanes(sum16);
                if top > cap {
                    return top;
                }
            }
            let (pq0, pq1) = hadamard_16x4_last_pairs(a.add(ty * sa), sa, b.add(ty * sb), sb);
            for (p, q) in [pq0, pq1] {
                sum16 = _mm256_add_epi16(sum16, _mm256_max_epi16(_mm256_abs_epi16(p), _mm256_abs_epi16(q)));
            }
        }
        sum_u16_lanes(sum16)
    }

    /// The sum of the sixteen 16-bit lanes (each at most 2^15).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn sum_u16_lanes(v: __m256i) -> u32 {
        let v = _mm256_madd_epi16(v, _mm256_set1_epi16(1));
        let s = _mm_add_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
        let s = _mm_add_epi32(s, _mm_shuffle_epi32::<0b01_00_11_10>(s));
        let s = _mm_add_epi32(s, _mm_shuffle_epi32::<0b10_11_00_01>(s));
        _mm_cvtsi128_si32(s) as u32
    }

    /// The 16x4 region's transform up to its last butterfly: the two
    /// (p, q) pairs whose sums and differences are the coefficients.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn hadamard_16x4_last_pairs(
        a: *const u8,
        sa: usize,
        b: *const u8,
        sb: usize,
    ) -> ((__m256i, __m256i), (__m256i, __m256i)) {
        let row = |r: usize| {
            let x = _mm256_cvtepu8_epi16(_mm_loadu_si128(a.add(r * sa) as *const __m128i));
            let y = _mm256_cvtepu8_epi16(_mm_loadu_si128(b.add(r * sb) as *const __m128i));
            _mm256_sub_epi16(x, y)
        };
        let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
        let (s01, d01) = (_mm256_add_epi16(r0, r1), _mm256_sub_epi16(r0, r1));
        let (s23, d23) = (_mm256_add_epi16(r2, r3), _mm256_sub_epi16(r2, r3));
        let v0 = _mm256_add_epi16(s01, s23);
        let v1 = _mm256_sub_epi16(s01, s23);
        let v2 = _mm256_sub_epi16(d01, d23);
        let v3 = _mm256_add_epi16(d01, d23);
        let (t0, t1) = (_mm256_unpacklo_epi16(v0, v1), _mm256_unpacklo_epi16(v2, v3));
        let (t2, t3) = (_mm256_unpackhi_epi16(v0, v1), _mm256_unpackhi_epi16(v2, v3));
        let pair = |lo: __m256i, hi: __m256i| {
            let c01 = _mm256_unpacklo_epi32(lo, hi);
            let c23 = _mm256_unpackhi_epi32(lo, hi);
            let x = _mm256_unpacklo_epi64(c01, c23);
            let y = _mm256_unpackhi_epi64(c01, c23);
            let (s, d) = (_mm256_add_epi16(x, y), _mm256_sub_epi16(x, y));
            (_mm256_unpacklo_epi64(s, d), _mm256_unpackhi_epi64(s, d))
        };
        (pair(t0, t1), pair(t2, t3))
    }

    /// Adds the 16x4 region's absolute Hadamard coefficients to `acc`
    /// (eight partial sums).
    #[target_feature(enable = "avx2")]
    unsafe fn hadamard_abs_16x4_avx2(a: *const u8, sa: usize, b: *const u8, sb: usize, acc: &mut [u32; 8]) {
        let prior = _mm256_loadu_si256(acc.as_ptr() as *const __m256i);
        let v = _mm256_add_epi32(prior, hadamard_abs_16x4_lanes(a, sa, b, sb));
        _mm256_storeu_si256(acc.as_mut_ptr() as *mut __m256i, v);
    }

    /// The 16x4 region's absolute Hadamard coefficients in eight partial
    /// sums (columns 0-7 of the region in the low 128-bit lane, 8-15 in
    /// the high one: AVX2 unpacks work within lanes), by the last
    /// butterfly's shortcut |p + q| + |p - q| = 2 max(|p|, |q|).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn hadamard_abs_16x4_lanes(a: *const u8, sa: usize, b: *const u8, sb: usize) -> __m256i {
        let (pq0, pq1) = hadamard_16x4_last_pairs(a, sa, b, sb);
        let mut acc = _mm256_setzero_si256();
        for (p, q) in [pq0, pq1] {
            let m = _mm256_max_epi16(_mm256_abs_epi16(p), _mm256_abs_epi16(q));
            acc = _mm256_add_epi32(acc, _mm256_madd_epi16(m, _mm256_set1_epi16(2)));
        }
        acc
    }

    fn satd_sse2(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) -> u32 {
        check_bounds(a, sa, b, sb, w, h);
        if w % 8 != 0 || h % 4 != 0 {
            return cost::satd(a, sa, b, sb, w, h);
        }
        let mut sum = 0u32;
        for ty in (0..h).step_by(4) {
            for tx in (0..w).step_by(8) {
                // SAFETY: SSE2 is part of x86-64; the 8x4 region lies inside
                // the checked block.
                sum += unsafe {
                    hadamard_abs_8x4_sse2(a.as_ptr().add(ty * sa + tx), sa, b.as_ptr().add(ty * sb + tx), sb)
                };
            }
        }
        sum.div_ceil(2)
    }

    fn satd_4x4_pair_sse2(a: &[u8; 32], b: &[u8; 32]) -> [u32; 2] {
        // SAFETY: SSE2 is part of x86-64; both 8x4 blocks are the arrays.
        let [l, r] = unsafe { hadamard_abs_tiles_sse2(a.as_ptr(), 8, b.as_ptr(), 8) };
        [l.div_ceil(2), r.div_ceil(2)]
    }

    /// `sum |H D H^T|` over two side-by-side 4x4 tiles of `a - b`.
    #[target_feature(enable = "sse2")]
    unsafe fn hadamard_abs_8x4_sse2(a: *const u8, sa: usize, b: *const u8, sb: usize) -> u32 {
        let [l, r] = hadamard_abs_tiles_sse2(a, sa, b, sb);
        l + r
    }

    /// `sum |H D H^T|` of each of two side-by-side 4x4 tiles of `a - b`.
    #[target_feature(enable = "sse2")]
    unsafe fn hadamard_abs_tiles_sse2(a: *const u8, sa: usize, b: *const u8, sb: usize) -> [u32; 2] {
        let zero = _mm_setzero_si128();
        let row = |r: usize| {
            let x = _mm_unpacklo_epi8(_mm_loadl_epi64(a.add(r * sa) as *const __m128i), zero);
            let y = _mm_unpacklo_epi8(_mm_loadl_epi64(b.add(r * sb) as *const __m128i), zero);
            _mm_sub_epi16(x, y)
        };
        let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
        // Vertical butterflies (across rows), both tiles at once.
        let (s01, d01) = (_mm_add_epi16(r0, r1), _mm_sub_epi16(r0, r1));
        let (s23, d23) = (_mm_add_epi16(r2, r3), _mm_sub_epi16(r2, r3));
        let v0 = _mm_add_epi16(s01, s23);
        let v1 = _mm_sub_epi16(s01, s23);
        let v2 = _mm_sub_epi16(d01, d23);
        let v3 = _mm_add_epi16(d01, d23);
        // Transpose each tile into vectors holding two columns of four.
        let (t0, t1) = (_mm_unpacklo_epi16(v0, v1), _mm_unpacklo_epi16(v2, v3));
        let (t2, t3) = (_mm_unpackhi_epi16(v0, v1), _mm_unpackhi_epi16(v2, v3));
        let mut sums = [0u32; 2];
        for (tile, (lo, hi)) in [(t0, t1), (t2, t3)].into_iter().enumerate() {
            let mut acc = _mm_setzero_si128();
            let c01 = _mm_unpacklo_epi32(lo, hi); // columns 0 | 1
            let c23 = _mm_unpackhi_epi32(lo, hi); // columns 2 | 3
                                                  // Horizontal butterflies (across columns).
            let x = _mm_unpacklo_epi64(c01, c23); // c0 | c2
            let y = _mm_unpackhi_epi64(c01, c23); // c1 | c3
            let (s, d) = (_mm_add_epi16(x, y), _mm_sub_epi16(x, y));
            let p = _mm_unpacklo_epi64(s, d); // c0+c1 | c0-c1
            let q = _mm_unpackhi_epi64(s, d); // c2+c3 | c2-c3
            for v in [_mm_add_epi16(p, q), _mm_sub_epi16(p, q)] {
                // |v| for 16-bit lanes as max(v, -v): values stay within +-4080.
                let abs = _mm_max_epi16(v, _mm_sub_epi16(zero, v));
                acc = _mm_add_epi32(acc, _mm_madd_epi16(abs, _mm_set1_epi16(1)));
            }
            let s = _mm_add_epi32(acc, _mm_shuffle_epi32(acc, 0b01_00_11_10));
            let s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0b10_11_00_01));
            sums[tile] = _mm_cvtsi128_si32(s) as u32;
        }
        sums
    }

    fn sad_sse2(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) -> u32 {
        check_bounds(a, sa, b, sb, w, h);
        // SAFETY: SSE2 is part of x86-64; bounds checked above.
        unsafe {
            match w {
                16 => sad_w16_sse2(a.as_ptr(), sa, b.as_ptr(), sb, h),
                8 => sad_w8_sse2(a.as_ptr(), sa, b.as_ptr(), sb, h),
                _ if w % 16 == 0 => (0..w / 16)
                    .map(|k| sad_w16_sse2(a.as_ptr().add(16 * k), sa, b.as_ptr().add(16 * k), sb, h))
                    .sum(),
                _ => cost::sad(a, sa, b, sb, w, h),
            }
        }
    }

    fn sad_avx2(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) -> u32 {
        check_bounds(a, sa, b, sb, w, h);
        // SAFETY: AVX2 was detected before this set was chosen; bounds
        // checked above.
        unsafe {
            match w {
                16 => sad_w16_avx2(a.as_ptr(), sa, b.as_ptr(), sb, h),
                32 => sad_w32_avx2(a.as_ptr(), sa, b.as_ptr(), sb, h),
                _ => sad_sse2(a, sa, b, sb, w, h),
            }
        }
    }

    #[inline]
    #[target_feature(enable = "sse2")]
    unsafe fn hsum_sad(v: __m128i) -> u32 {
        // psadbw leaves two 64-bit partial sums.
        (_mm_cvtsi128_si32(v) + _mm_cvtsi128_si32(_mm_unpackhi_epi64(v, v))) as u32
    }

    #[target_feature(enable = "sse2")]
    unsafe fn sad_w16_sse2(a: *const u8, sa: usize, b: *const u8, sb: usize, h: usize) -> u32 {
        let mut acc = _mm_setzero_si128();
        for r in 0..h {
            let x = _mm_loadu_si128(a.add(r * sa) as *const __m128i);
            let y = _mm_loadu_si128(b.add(r * sb) as *const __m128i);
            acc = _mm_add_epi64(acc, _mm_sad_epu8(x, y));
        }
        hsum_sad(acc)
    }

    #[target_feature(enable = "sse2")]
    unsafe fn sad_w8_sse2(a: *const u8, sa: usize, b: *const u8, sb: usize, h: usize) -> u32 {
        let mut acc = _mm_setzero_si128();
        for r in 0..h {
            let x = _mm_loadl_epi64(a.add(r * sa) as *const __m128i);
            let y = _mm_loadl_epi64(b.add(r * sb) as *const __m128i);
            acc = _mm_add_epi64(acc, _mm_sad_epu8(x, y));
        }
        hsum_sad(acc)
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn hsum_sad256(v: __m256i) -> u32 {
        let s = _mm_add_epi64(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
        hsum_sad(s)
    }

    #[target_feature(enable = "avx2")]
    unsafe fn sad_w16_avx2(a: *const u8, sa: usize, b: *const u8, sb: usize, h: usize) -> u32 {
        let mut acc = _mm256_setzero_si256();
        let mut r = 0;
        while r + 1 < h {
            let x = _mm256_loadu2_m128i(
                a.add((r + 1) * sa) as *const __m128i,
                a.add(r * sa) as *const __m128i,
            );
            let y = _mm256_loadu2_m128i(
                b.add((r + 1) * sb) as *const __m128i,
                b.add(r * sb) as *const __m128i,
            );
            acc = _mm256_add_epi64(acc, _mm256_sad_epu8(x, y));
            r += 2;
        }
        let mut sum = hsum_sad256(acc);
        if r < h {
            sum += sad_w16_sse2(a.add(r * sa), sa, b.add(r * sb), sb, 1);
        }
        sum
    }

    #[target_feature(enable = "avx2")]
    unsafe fn sad_w32_avx2(a: *const u8, sa: usize, b: *const u8, sb: usize, h: usize) -> u32 {
        let mut acc = _mm256_setzero_si256();
        for r in 0..h {
            let x = _mm256_loadu_si256(a.add(r * sa) as *const __m256i);
            let y = _mm256_loadu_si256(b.add(r * sb) as *const __m256i);
            acc = _mm256_add_epi64(acc, _mm256_sad_epu8(x, y));
        }
        hsum_sad256(acc)
    }
}
