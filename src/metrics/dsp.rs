//! The metrics' kernels, one table per CPU level ([`crate::codec::dsp`]):
//! the squared differences under PSNR and every block distortion of the
//! encoder, the Gaussian SSIM's band of rows, and the 4x4 block sums of
//! x264's SSIM. The AVX2 builds of the SSIM kernels are the scalar source
//! compiled for AVX2 (no FMA: every sum rounds as in the scalar build).

use crate::codec::dsp::PerLevel;
use crate::codec::Plane;

/// The Gaussian SSIM window's side.
pub const WIN: usize = 11;
pub(crate) const C1: f64 = (0.01 * 255.0) * (0.01 * 255.0);
pub(crate) const C2: f64 = (0.03 * 255.0) * (0.03 * 255.0);

/// Per 4x4 block: sum of a, sum of b, sum of a^2 + b^2, sum of a * b.
pub type BlockSums = [u32; 4];

/// `sum (a[i] - b[i])^2` over the common length of two slices.
pub type SsdFn = fn(&[u8], &[u8]) -> u64;

/// The Gaussian SSIM map summed over a band of output rows:
/// `(scratch, a, b, window, y0, rows, output_width)`.
pub type GaussianBandFn = fn(&mut BandScratch, &Plane, &Plane, &[f64; WIN], usize, usize, usize) -> f64;

/// The 4x4 block sums of one row of blocks: `(a, b, y0, scratch, out)`.
pub type BlockRowSumsFn = fn(&Plane, &Plane, usize, &mut ColumnSums, &mut [BlockSums]);

/// The metrics' kernels of one CPU level.
#[derive(Debug, Clone, Copy)]
pub struct MetricsDsp {
    /// Squared differences.
    pub ssd: SsdFn,
    /// Gaussian SSIM over a band of rows ([`super::ssim`]).
    pub ssim_band: GaussianBandFn,
    /// x264's SSIM block sums ([`super::ssim_8x8`]).
    pub ssim_8x8_row_sums: BlockRowSumsFn,
}

const SCALAR: MetricsDsp = MetricsDsp {
    ssd: squared_difference_sum_scalar,
    ssim_band: gaussian_band_body,
    ssim_8x8_row_sums: block_row_sums_body,
};

/// The tables, lowest level first.
pub static METRICS: PerLevel<MetricsDsp> = PerLevel([
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    MetricsDsp {
        ssd: x86::ssd_sse2,
        ..SCALAR
    },
    #[cfg(target_arch = "x86_64")]
    MetricsDsp {
        ssd: x86::ssd_avx2,
        ssim_band: avx2::ssim_band,
        ssim_8x8_row_sums: avx2::block_row_sums,
    },
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub fn metrics() -> &'static MetricsDsp {
    METRICS.get()
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{BandScratch, BlockSums, ColumnSums, WIN};
    use crate::codec::Plane;
    crate::codec::compiled_for! { "avx2":
        fn ssim_band(scratch: &mut BandScratch, a: &Plane, b: &Plane, g: &[f64; WIN], y0: usize, rows: usize, ow: usize) -> f64
            => super::gaussian_band_body;
        fn block_row_sums(a: &Plane, b: &Plane, y0: usize, cols: &mut ColumnSums, out: &mut [BlockSums])
            => super::block_row_sums_body;
    }
}

/// SSIM from the window's means, second moments and cross moment.
#[inline(always)]
pub(crate) fn ssim_from_stats(mx: f64, my: f64, xx: f64, yy: f64, xy: f64) -> f64 {
    let (vx, vy, cov) = (xx - mx * mx, yy - my * my, xy - mx * my);
    ((2.0 * mx * my + C1) * (2.0 * cov + C2)) / ((mx * mx + my * my + C1) * (vx + vy + C2))
}

/// Buffers of one band, kept between the bands a worker computes (fresh
/// ones cost more in page faults than the filtering).
#[derive(Default)]
pub struct BandScratch {
    /// Horizontally filtered statistics.
    hf: [Vec<f64>; 5],
    /// One input row's x, y, x^2, y^2, xy.
    products: [Vec<f64>; 5],
    /// One output row's statistics.
    stats: [Vec<f64>; 5],
}

/// The sum of the SSIM map over output rows y0 .. y0 + rows of planes
/// `a` and `b` (`ow` output columns) under window `g`: separable
/// Gaussian statistics, one array per statistic (x, y, x^2, y^2,
/// xy) so that the tap-outer loops vectorise.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // five statistics indexed in step
fn gaussian_band_body(
    scratch: &mut BandScratch,
    a: &Plane,
    b: &Plane,
    g: &[f64; WIN],
    y0: usize,
    rows: usize,
    ow: usize,
) -> f64 {
    let w = a.width();
    let in_rows = rows + WIN - 1;
    let BandScratch { hf, products, stats } = scratch;
    for v in hf.iter_mut() {
        v.clear();
        v.resize(in_rows * ow, 0.0);
    }
    for v in products.iter_mut().chain(stats.iter_mut()) {
        v.resize(w.max(ow), 0.0);
    }
    for r in 0..in_rows {
        let (ra, rb) = (a.row(y0 + r), b.row(y0 + r));
        for x in 0..w {
            let (p, q) = (f64::from(ra[x]), f64::from(rb[x]));
            products[0][x] = p;
            products[1][x] = q;
            products[2][x] = p * p;
            products[3][x] = q * q;
            products[4][x] = p * q;
        }
        for (out, src) in hf.iter_mut().zip(products.iter()) {
            let out = &mut out[r * ow..(r + 1) * ow];
            for (k, &gk) in g.iter().enumerate() {
                for (o, &v) in out.iter_mut().zip(&src[k..k + ow]) {
                    *o += gk * v;
                }
            }
        }
    }
    let mut sum = 0.0;
    for r in 0..rows {
        for (out, src) in stats.iter_mut().zip(hf.iter()) {
            let out = &mut out[..ow];
            out.fill(0.0);
            for (k, &gk) in g.iter().enumerate() {
                for (o, &v) in out.iter_mut().zip(&src[(r + k) * ow..(r + k + 1) * ow]) {
                    *o += gk * v;
                }
            }
        }
        for x in 0..ow {
            sum += ssim_from_stats(stats[0][x], stats[1][x], stats[2][x], stats[3][x], stats[4][x]);
        }
    }
    sum
}

/// Per-column sums of a row of blocks, one array per statistic (so that
/// the column loop vectorises).
#[derive(Default)]
pub struct ColumnSums {
    pub(crate) s: [Vec<u32>; 4],
}

/// The 4x4 block sums of one row of blocks (rows y0 .. y0 + 4), into `out`
/// (one entry per whole block).
#[inline(always)]
fn block_row_sums_body(a: &Plane, b: &Plane, y0: usize, cols: &mut ColumnSums, out: &mut [BlockSums]) {
    let w = out.len() * 4;
    let [s1, s2, ss, s12] = &mut cols.s;
    for v in [&mut *s1, &mut *s2, &mut *ss, &mut *s12] {
        v.clear();
        v.resize(w, 0);
    }
    for r in y0..y0 + 4 {
        let (ra, rb) = (&a.row(r)[..w], &b.row(r)[..w]);
        for (((((c1, c2), css), c12), &p), &q) in s1
            .iter_mut()
            .zip(s2.iter_mut())
            .zip(ss.iter_mut())
            .zip(s12.iter_mut())
            .zip(ra)
            .zip(rb)
        {
            let (p, q) = (u32::from(p), u32::from(q));
            *c1 += p;
            *c2 += q;
            *css += p * p + q * q;
            *c12 += p * q;
        }
    }
    for (x, o) in out.iter_mut().enumerate() {
        for (k, v) in cols.s.iter().enumerate() {
            o[k] = v[4 * x..4 * x + 4].iter().sum();
        }
    }
}

/// The scalar squared-difference kernel.
pub fn squared_difference_sum_scalar(a: &[u8], b: &[u8]) -> u64 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| {
            let d = i64::from(x) - i64::from(y);
            (d * d) as u64
        })
        .sum()
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    /// The sum over the leading multiple of 16 samples and how many that
    /// is: 16-bit differences, `pmaddwd` into 32-bit lanes, which are
    /// widened to 64 bits every 4096 samples (a lane then holds at most
    /// 1024 squares, 1024 * 255^2 < 2^27: far from overflow).
    /// The SSE2 squared differences: the leading multiple of 16 samples
    /// here, the rest in scalar code.
    pub(super) fn ssd_sse2(a: &[u8], b: &[u8]) -> u64 {
        let n = a.len().min(b.len());
        // SAFETY: SSE2 is part of x86-64; the kernel reads n bytes of each.
        let (head, done) = unsafe { ssd_head_sse2(&a[..n], &b[..n]) };
        head + super::squared_difference_sum_scalar(&a[done..n], &b[done..n])
    }

    /// The AVX2 squared differences: 32 samples a step, as
    /// [`ssd_head_sse2`] (the same bound on a lane: the chunk of 4096
    /// samples puts at most 512 squares in each).
    pub(super) fn ssd_avx2(a: &[u8], b: &[u8]) -> u64 {
        let n = a.len().min(b.len());
        // SAFETY: this kernel sits only in the AVX2 table, handed out
        // only where the CPU has AVX2; it reads n bytes of each.
        let (head, done) = unsafe { ssd_head_avx2(&a[..n], &b[..n]) };
        head + ssd_sse2(&a[done..n], &b[done..n])
    }

    #[target_feature(enable = "avx2")]
    unsafe fn ssd_head_avx2(a: &[u8], b: &[u8]) -> (u64, usize) {
        let n = a.len().min(b.len()) / 32 * 32;
        let mut total = 0u64;
        let mut i = 0;
        while i < n {
            let end = (i + 4096).min(n);
            let mut acc = _mm256_setzero_si256();
            while i < end {
                for half in [i, i + 16] {
                    // SAFETY: half + 16 <= n <= both lengths.
                    let (x, y) = unsafe {
                        (
                            _mm_loadu_si128(a.as_ptr().add(half) as *const __m128i),
                            _mm_loadu_si128(b.as_ptr().add(half) as *const __m128i),
                        )
                    };
                    let d = _mm256_sub_epi16(_mm256_cvtepu8_epi16(x), _mm256_cvtepu8_epi16(y));
                    acc = _mm256_add_epi32(acc, _mm256_madd_epi16(d, d));
                }
                i += 32;
            }
            let mut lanes = [0u32; 8];
            // SAFETY: 32 bytes into a 32-byte array.
            unsafe { _mm256_storeu_si256(lanes.as_mut_ptr() as *mut __m256i, acc) };
            total += lanes.iter().map(|&v| u64::from(v)).sum::<u64>();
        }
        (total, n)
    }

    #[target_feature(enable = "sse2")]
    unsafe fn ssd_head_sse2(a: &[u8], b: &[u8]) -> (u64, usize) {
        let n = a.len().min(b.len()) / 16 * 16;
        let zero = _mm_setzero_si128();
        let mut total = 0u64;
        let mut i = 0;
        while i < n {
            let end = (i + 4096).min(n);
            let mut acc = _mm_setzero_si128();
            while i < end {
                // SAFETY: i + 16 <= n <= both lengths.
                let (x, y) = unsafe {
                    (
                        _mm_loadu_si128(a.as_ptr().add(i) as *const __m128i),
                        _mm_loadu_si128(b.as_ptr().add(i) as *const __m128i),
                    )
                };
                let lo = _mm_sub_epi16(_mm_unpacklo_epi8(x, zero), _mm_unpacklo_epi8(y, zero));
                let hi = _mm_sub_epi16(_mm_unpackhi_epi8(x, zero), _mm_unpackhi_epi8(y, zero));
                acc = _mm_add_epi32(acc, _mm_madd_epi16(lo, lo));
                acc = _mm_add_epi32(acc, _mm_madd_epi16(hi, hi));
                i += 16;
            }
            let mut lanes = [0u32; 4];
            // SAFETY: 16 bytes into a 16-byte array.
            unsafe { _mm_storeu_si128(lanes.as_mut_ptr() as *mut __m128i, acc) };
            total += lanes.iter().map(|&v| u64::from(v)).sum::<u64>();
        }
        (total, n)
    }
}
