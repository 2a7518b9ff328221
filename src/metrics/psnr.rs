//! Peak signal-to-noise ratio of 8-bit planes.

use serde::Serialize;

use crate::codec::{Frame, Plane};

/// PSNR reported for identical planes (MSE 0), and the largest value ever
/// reported: a finite number keeps means and plots meaningful where the true
/// value would be infinite. (HM prints 99.99 in that case; ffmpeg `inf`.)
pub const PSNR_CAP_DB: f64 = 100.0;

const PEAK: f64 = 255.0;

fn assert_same_size(a: &Plane, b: &Plane) {
    assert!(
        a.width() == b.width() && a.height() == b.height(),
        "planes of different sizes: {}x{} and {}x{}",
        a.width(),
        a.height(),
        b.width(),
        b.height()
    );
}

/// Sum of squared differences over the visible pixels. Panics if the sizes
/// differ.
pub fn sse(a: &Plane, b: &Plane) -> u64 {
    assert_same_size(a, b);
    a.rows()
        .zip(b.rows())
        .map(|(ra, rb)| squared_difference_sum(ra, rb))
        .sum()
}

/// `sum (a[i] - b[i])^2` over the common length of two sample slices: the
/// kernel under [`sse`] and the encoder's block distortions.
///
/// ```
/// use mocomp::metrics::squared_difference_sum;
/// assert_eq!(squared_difference_sum(&[10, 20, 30], &[13, 16, 30]), 9 + 16);
/// ```
pub fn squared_difference_sum(a: &[u8], b: &[u8]) -> u64 {
    let n = a.len().min(b.len());
    #[cfg(target_arch = "x86_64")]
    if crate::codec::cpu::at_least(crate::codec::cpu::CpuLevel::Sse2) {
        // SAFETY: SSE2 is part of x86-64; the kernel reads n bytes of each.
        let (head, done) = unsafe { x86::ssd_sse2(&a[..n], &b[..n]) };
        return head + squared_difference_sum_scalar(&a[done..n], &b[done..n]);
    }
    squared_difference_sum_scalar(&a[..n], &b[..n])
}

/// The scalar twin of [`squared_difference_sum`].
fn squared_difference_sum_scalar(a: &[u8], b: &[u8]) -> u64 {
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
    #[target_feature(enable = "sse2")]
    pub(super) unsafe fn ssd_sse2(a: &[u8], b: &[u8]) -> (u64, usize) {
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

/// Mean squared error. Panics if the sizes differ.
pub fn mse(a: &Plane, b: &Plane) -> f64 {
    sse(a, b) as f64 / (a.width() * a.height()) as f64
}

/// `10 log10(255^2 / mse)`, at most [`PSNR_CAP_DB`].
pub fn psnr_from_mse(mse: f64) -> f64 {
    if mse <= 0.0 {
        return PSNR_CAP_DB;
    }
    (10.0 * (PEAK * PEAK / mse).log10()).min(PSNR_CAP_DB)
}

/// PSNR of `b` against `a` in dB (peak 255). Panics if the sizes differ.
///
/// ```
/// use mocomp::codec::Plane;
/// let a = Plane::filled(8, 8, 50).unwrap();
/// let b = Plane::filled(8, 8, 52).unwrap(); // MSE 4
/// assert!((mocomp::metrics::psnr(&a, &b) - 42.1102).abs() < 1e-4);
/// assert_eq!(mocomp::metrics::psnr(&a, &a), mocomp::metrics::PSNR_CAP_DB);
/// ```
pub fn psnr(a: &Plane, b: &Plane) -> f64 {
    psnr_from_mse(mse(a, b))
}

/// PSNR of each plane of a frame, and the MSEs they come from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FramePsnr {
    /// Luma PSNR (dB).
    pub y: f64,
    /// Cb PSNR (dB).
    pub u: f64,
    /// Cr PSNR (dB).
    pub v: f64,
    /// MSE of Y, U, V.
    pub mse: [f64; 3],
}

impl FramePsnr {
    /// The 6:1:1 weighted PSNR, `(6 Y + U + V) / 8`, as JCT-VC reports it.
    pub fn yuv(&self) -> f64 {
        (6.0 * self.y + self.u + self.v) / 8.0
    }
}

/// PSNR of every plane of `test` against `reference`. Panics if the sizes
/// differ.
pub fn frame_psnr(reference: &Frame, test: &Frame) -> FramePsnr {
    let mse = [0, 1, 2].map(|i| mse(reference.plane(i), test.plane(i)));
    FramePsnr {
        y: psnr_from_mse(mse[0]),
        u: psnr_from_mse(mse[1]),
        v: psnr_from_mse(mse[2]),
        mse,
    }
}

#[cfg(test)]
mod kernel_tests {
    use super::*;

    #[test]
    fn the_squared_difference_kernel_equals_its_scalar_twin() {
        let mut seed = 7u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (seed >> 16) as u8
        };
        // Lengths around the 16-sample step and past one 4096 block; the
        // extremes 0 and 255 against each other.
        for len in [0, 1, 15, 16, 17, 31, 64, 100, 4095, 4096, 4097, 10_000] {
            let a: Vec<u8> = (0..len).map(|_| next()).collect();
            let b: Vec<u8> = (0..len).map(|_| next()).collect();
            assert_eq!(
                squared_difference_sum(&a, &b),
                squared_difference_sum_scalar(&a, &b),
                "{len}"
            );
            let (lo, hi) = (vec![0u8; len], vec![255u8; len]);
            assert_eq!(squared_difference_sum(&lo, &hi), 65025 * len as u64);
        }
    }
}
